//! After a run: joints that went past their URDF position limits in a scene that does not enforce
//! them.
//!
//! Without the `joint_limits` effect a joint moves freely past the range its URDF `<limit>` gives,
//! and a light finger or an unsupported link can swing radians beyond where the real robot's stop
//! would hold it (a Kinova gripper finger from a public description reached −3.4 rad against its
//! [0, 1.51] rad in 0.2 s of falling). The numbers are right for the scene as declared, but not
//! for the robot, and nothing else in the output says so. [`limit_excursions`] finds each such
//! joint's deepest excursion, so that the commands can warn and the summary can record it.

use super::{Output, OutputKind, Scene};
use crate::model::{Joint, JointKind, Model};
use serde::Serialize;

/// How far past a limit (rad or m) a recorded position must be to count: above the rounding of a
/// joint that rests on its limit, far below any excursion that changes a motion.
pub const LIMIT_EXCURSION_TOLERANCE: f64 = 1e-9;

/// How close to a limit (rad or m) an envelope bound must come, or how far past it, for the joint
/// to count as reaching an enforced stop ([`outputs_at_enforced_limits`]): a joint resting on a
/// limit sits a little inside the penalty, a joint that only approaches it stays well away.
pub const LIMIT_CONTACT_TOLERANCE: f64 = 1e-6;

/// How many joints the warning names before it says "and N more" (the summary lists all).
const NAMED_IN_WARNING: usize = 5;

/// One joint's deepest excursion past its URDF position limits.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LimitExcursion {
    /// The joint.
    pub joint: String,
    /// Its URDF `<limit lower>`.
    pub lower: f64,
    /// Its URDF `<limit upper>`.
    pub upper: f64,
    /// The recorded position (or envelope bound) farthest past the limits.
    pub reached: f64,
    /// When it was recorded, s.
    pub time_s: f64,
    /// Whether that is the first record: the joint starts outside its limits. (Said in the
    /// warning; the summary's `time_s` shows it.)
    #[serde(skip)]
    pub at_start: bool,
    /// `rad` or `m`.
    pub unit: &'static str,
    /// The index of the joint's position among the outputs it was found in.
    #[serde(skip)]
    pub output: usize,
}

impl LimitExcursion {
    /// How far past the nearer limit `reached` is (> 0).
    pub fn depth(&self) -> f64 {
        depth_past([self.lower, self.upper], self.reached)
    }
}

/// How far `reached` is past the nearer of `[lower, upper]` (≤ 0 inside).
fn depth_past([lower, upper]: [f64; 2], reached: f64) -> f64 {
    (lower - reached).max(reached - upper)
}

/// The joints whose recorded position goes past their URDF limits by more than
/// [`LIMIT_EXCURSION_TOLERANCE`], deepest first; empty when `scene` declares `joint_limits` (the
/// effect holds them). `lowest[i][k]` and `highest[i][k]` are output `i`'s smallest and largest
/// value at `times[k]`: the same series for one run, the envelope's lower and upper bounds for a
/// study. Only joint-position outputs of joints with finite limits `lower < upper` count (URDF
/// `lower > upper` loads with a warning and is skipped by the effect too).
pub fn limit_excursions(
    model: &Model,
    scene: &Scene,
    outputs: &[Output],
    times: &[f64],
    lowest: &[Vec<f64>],
    highest: &[Vec<f64>],
) -> Vec<LimitExcursion> {
    if scene.effects.joint_limits {
        return Vec::new();
    }
    let mut found = Vec::new();
    for (i, output) in outputs.iter().enumerate() {
        let Some((joint, [lower, upper])) = limited_joint(model, output) else {
            continue;
        };
        // The deepest point: (depth, record, value), the first of equals.
        let mut deepest: Option<(f64, usize, f64)> = None;
        for k in 0..times.len() {
            for reached in [lowest[i][k], highest[i][k]] {
                let depth = depth_past([lower, upper], reached);
                if depth > LIMIT_EXCURSION_TOLERANCE && deepest.is_none_or(|(d, _, _)| depth > d) {
                    deepest = Some((depth, k, reached));
                }
            }
        }
        found.extend(deepest.map(|(_, k, reached)| LimitExcursion {
            joint: joint.name.clone(),
            lower,
            upper,
            reached,
            time_s: times[k],
            at_start: k == 0,
            unit: output.unit,
            output: i,
        }));
    }
    found.sort_by(|a, b| b.depth().total_cmp(&a.depth()));
    found
}

/// The outputs among `candidates` (indices into `outputs`) that are positions of joints whose
/// envelope reaches an enforced URDF limit (within [`LIMIT_CONTACT_TOLERANCE`] or past it) when
/// `scene` declares `joint_limits`; empty otherwise. A stop makes the response kink in the
/// parameters — whether and when the joint hits moves with them — which is why a surrogate of
/// such an output fails its check. `lowest`/`highest` as in [`limit_excursions`].
pub fn outputs_at_enforced_limits(
    model: &Model,
    scene: &Scene,
    outputs: &[Output],
    candidates: &[usize],
    lowest: &[Vec<f64>],
    highest: &[Vec<f64>],
) -> Vec<usize> {
    if !scene.effects.joint_limits {
        return Vec::new();
    }
    candidates
        .iter()
        .copied()
        .filter(|&i| {
            let Some((_, [lower, upper])) = limited_joint(model, &outputs[i]) else {
                return false;
            };
            let low = lowest[i].iter().copied().fold(f64::INFINITY, f64::min);
            let high = highest[i].iter().copied().fold(f64::NEG_INFINITY, f64::max);
            low <= lower + LIMIT_CONTACT_TOLERANCE || high >= upper - LIMIT_CONTACT_TOLERANCE
        })
        .collect()
}

/// How far past an enforced limit (rad or m) a surrogate's bounds and predictions of the joint's
/// position may reach ([`surrogate_ranges`]): the depth at which the limit's penalty holds an
/// acceleration of 1000 rad/s² or m/s² (`a / ω²`, ω = `JOINT_LIMIT_FREQUENCY` = 200 rad/s;
/// docs/step-control.md §4), far beyond what a joint pressed into its stop by its own mechanism
/// meets (2.5e-4 rad at 10 rad/s²). Impacts put a joint on its limit exactly; only slow crossings
/// and resting loads go past it, by that penalty depth.
pub const ENFORCED_LIMIT_BOUND_MARGIN: f64 =
    1000.0 / (crate::effects::JOINT_LIMIT_FREQUENCY * crate::effects::JOINT_LIMIT_FREQUENCY);

/// Per output of `scene`: the range a surrogate's bounds and predicted extremes are clipped to
/// (docs/method.md §12, "Known ranges") — the output's own known range
/// ([`OutputKind::known_range`]), or, for the position of a joint whose URDF limits the scene
/// enforces (`joint_limits`), those limits widened by [`ENFORCED_LIMIT_BOUND_MARGIN`]. True values
/// are not clamped to the latter: a run that goes deeper still widens the envelope and the check.
pub fn surrogate_ranges(model: &Model, scene: &Scene) -> Vec<Option<(f64, f64)>> {
    scene
        .outputs
        .iter()
        .map(|output| {
            output.kind.known_range().or_else(|| {
                let (_, [lower, upper]) = scene
                    .effects
                    .joint_limits
                    .then(|| limited_joint(model, output))
                    .flatten()?;
                Some((
                    lower - ENFORCED_LIMIT_BOUND_MARGIN,
                    upper + ENFORCED_LIMIT_BOUND_MARGIN,
                ))
            })
        })
        .collect()
}

/// The 1-dof joint whose position `output` is, with its finite URDF limits `[lower, upper]`
/// (`lower < upper`), if it is one and has them.
fn limited_joint<'m>(model: &'m Model, output: &Output) -> Option<(&'m Joint, [f64; 2])> {
    let OutputKind::Position { q_index } = output.kind else {
        return None;
    };
    let joint = model
        .joints
        .iter()
        .find(|j| j.q_index == q_index && j.kind != JointKind::Floating)?;
    let [lower, upper] = model.description.joints[joint.source?].limits;
    (lower.is_finite() && upper.is_finite() && lower < upper).then_some((joint, [lower, upper]))
}

/// The warning for `excursions` (not empty): each joint (the deepest five), how
/// far it went, and what to do. `envelope`: the values are a study's bounds, not one run's.
pub fn describe_limit_excursions(excursions: &[LimitExcursion], envelope: bool) -> String {
    let subject = if envelope { "the envelope of" } else { "joint" };
    let named: Vec<String> = excursions
        .iter()
        .take(NAMED_IN_WARNING)
        .map(|e| {
            let when = if e.at_start {
                "at the start".to_string()
            } else {
                format!("at t = {} s", crate::text::message_time(e.time_s))
            };
            format!(
                "{subject} '{}' reaches {:.4} {} {when}, {} {} past its limits [{}, {}]",
                e.joint,
                e.reached,
                e.unit,
                significant(e.depth()),
                e.unit,
                e.lower,
                e.upper
            )
        })
        .collect();
    let more = excursions.len().saturating_sub(NAMED_IN_WARNING);
    let more = if more > 0 {
        format!(" (and {more} more joints; the summary's limit_excursions lists all)")
    } else {
        String::new()
    };
    let starts_outside = excursions.iter().filter(|e| e.at_start).count();
    let start_advice = if starts_outside > 0 {
        format!(
            " ({starts_outside} of them start outside their limits: with \"joint_limits\", set [scene] initial.q inside them too)"
        )
    } else {
        String::new()
    };
    format!(
        "{} joint(s) went past their URDF position limits, which this scene does not enforce (its effects do not include \"joint_limits\"): {}{more}. A real robot stops at its limits, so from those times on these results describe the robot without its stops; add \"joint_limits\" to [scene] effects to simulate them{start_advice}, or correct the URDF <limit> if the range is wrong",
        excursions.len(),
        named.join("; ")
    )
}

/// `x` (> 0) to three significant digits, without an exponent between 1e-3 and 1e4.
fn significant(x: f64) -> String {
    if (1e-3..1e4).contains(&x) {
        let decimals = (2 - x.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{parse_description, LoadOptions};
    use crate::scene::{parse_sidecar, SceneOverrides};

    /// A bar along +x hinged about z, limited to [−0.5, 0.5] rad, and a second bar on a
    /// continuous joint (no limits); gravity along −y swings the first one down past −0.5.
    fn hinged_bars() -> Model {
        let text = r#"<robot name="p"><link name="w"/>
          <link name="bar"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
          <inertia ixx="0" ixy="0" ixz="0" iyy="0.08" iyz="0" izz="0.08"/></inertial></link>
          <link name="tip"><inertial><origin xyz="0.1 0 0"/><mass value="0.1"/>
          <inertia ixx="0" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial></link>
          <joint name="hinge" type="revolute"><parent link="w"/><child link="bar"/><axis xyz="0 0 1"/>
          <limit lower="-0.5" upper="0.5" effort="1" velocity="1"/></joint>
          <joint name="spin" type="continuous"><parent link="bar"/><child link="tip"/>
          <origin xyz="1 0 0"/><axis xyz="0 0 1"/></joint></robot>"#;
        Model::from_description(
            parse_description(text, "p.urdf").unwrap(),
            LoadOptions::default(),
            "p.urdf",
        )
        .unwrap()
    }

    fn scene(model: &Model, extra: &str) -> Scene {
        let text = format!("[scene]\nduration = 0.6\ngravity = [0.0, -9.81, 0.0]\n{extra}");
        let file = parse_sidecar(&text).unwrap();
        Scene::resolve(&file, model, "s.toml", SceneOverrides::default()).unwrap()
    }

    #[test]
    fn a_swing_past_an_unenforced_limit_is_found_at_its_deepest_and_described() {
        let model = hinged_bars();
        let free = scene(&model, "");
        let run = crate::simulate::simulate(model.clone(), free.environment(), &free).unwrap();
        let found = limit_excursions(
            &model,
            &free,
            &run.outputs,
            &run.times,
            &run.values,
            &run.values,
        );
        assert_eq!(found.len(), 1, "only the limited joint: {found:?}");
        let hinge = &found[0];
        let series = &run.values[run
            .outputs
            .iter()
            .position(|o| o.name == "q.hinge")
            .unwrap()];
        let lowest = series.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest < -0.6, "the bar swings well past −0.5: {lowest}");
        assert_eq!((hinge.joint.as_str(), hinge.reached), ("hinge", lowest));
        assert_eq!((hinge.lower, hinge.upper, hinge.unit), (-0.5, 0.5, "rad"));
        assert!(hinge.time_s > 0.0);
        assert_eq!(hinge.depth(), -0.5 - lowest);
        let text = describe_limit_excursions(&found, false);
        assert!(text.starts_with("1 joint(s) went past"), "{text}");
        assert!(text.contains("joint 'hinge' reaches"), "{text}");
        assert!(
            text.contains("add \"joint_limits\" to [scene] effects"),
            "{text}"
        );
        assert!(!text.contains("start outside"), "{text}");

        // With the effect the limits are the scene's: nothing to report.
        let held = scene(&model, "effects = [\"gravity\", \"joint_limits\"]\n");
        assert!(limit_excursions(
            &model,
            &held,
            &run.outputs,
            &run.times,
            &run.values,
            &run.values
        )
        .is_empty());
    }

    #[test]
    fn an_envelope_bound_and_a_start_outside_count_and_the_tolerance_is_kept() {
        let model = hinged_bars();
        let free = scene(&model, "");
        let outputs: Vec<Output> = free
            .outputs
            .iter()
            .filter(|o| o.name == "q.hinge")
            .cloned()
            .collect();
        let times = [0.0, 0.1, 0.2];
        // The upper bound starts outside; the lower one stays inside.
        let lower = vec![vec![0.4, 0.3, 0.2]];
        let upper = vec![vec![0.7, 0.5 + 0.5 * LIMIT_EXCURSION_TOLERANCE, 0.45]];
        let found = limit_excursions(&model, &free, &outputs, &times, &lower, &upper);
        assert_eq!(found.len(), 1);
        assert_eq!((found[0].reached, found[0].time_s), (0.7, 0.0));
        let text = describe_limit_excursions(&found, true);
        assert!(
            text.contains(
                "the envelope of 'hinge' reaches 0.7000 rad at the start, 0.200 rad past"
            ),
            "{text}"
        );
        assert!(
            text.contains("1 of them start outside their limits"),
            "{text}"
        );
        // Within the tolerance of a limit is on it.
        let upper = vec![vec![0.45, 0.5 + 0.5 * LIMIT_EXCURSION_TOLERANCE, 0.45]];
        assert!(limit_excursions(&model, &free, &outputs, &times, &lower, &upper).is_empty());
    }

    #[test]
    fn outputs_reaching_an_enforced_stop_are_found_only_with_the_effect() {
        let model = hinged_bars();
        let held = scene(&model, "effects = [\"gravity\", \"joint_limits\"]\n");
        let outputs = held.outputs.clone();
        let hinge = outputs.iter().position(|o| o.name == "q.hinge").unwrap();
        let spin = outputs.iter().position(|o| o.name == "q.spin").unwrap();
        let series = |hinge_values: [f64; 2]| {
            let mut s = vec![vec![0.0, 0.0]; outputs.len()];
            s[hinge] = hinge_values.to_vec();
            s[spin] = vec![-40.0, 40.0]; // no limits: never at a stop
            s
        };
        let both = [hinge, spin];
        // Resting a little inside the penalty, past the lower limit: at the stop.
        let (lower, upper) = (series([-0.1, -0.5000003]), series([0.2, 0.1]));
        assert_eq!(
            outputs_at_enforced_limits(&model, &held, &outputs, &both, &lower, &upper),
            vec![hinge]
        );
        // Within the tolerance of the upper limit counts; 1e-3 away does not.
        let upper_on = series([0.2, 0.5 - 0.5 * LIMIT_CONTACT_TOLERANCE]);
        let inside = series([-0.499, 0.1]);
        assert_eq!(
            outputs_at_enforced_limits(&model, &held, &outputs, &both, &inside, &upper_on),
            vec![hinge]
        );
        assert!(
            outputs_at_enforced_limits(&model, &held, &outputs, &both, &inside, &upper).is_empty()
        );
        // Only the candidates asked about, and nothing without the effect.
        assert!(
            outputs_at_enforced_limits(&model, &held, &outputs, &[spin], &lower, &upper).is_empty()
        );
        let free = scene(&model, "");
        assert!(
            outputs_at_enforced_limits(&model, &free, &outputs, &both, &lower, &upper).is_empty()
        );
    }
}
