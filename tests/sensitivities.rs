//! Sensitivities of every output to every dimension of a box (docs/sensitivities.md): direct
//! differentiation of the HHT-I3 step ([`sensitivity_run`]) against central differences of whole
//! runs ([`central_difference_run_with`]) on the shipped robots — ur5 (masses, centres of mass,
//! inertia entries, joint origins, the payload, a merged link), the double pendulum (lengths through
//! `[bind]`), the four-bar (a loop, and a drive added) and the slider-crank (loop and drive) — and
//! on a floating ur5 tumbling in free fall; plus a closed form (a mass on a spring, `∂x/∂m`).
//!
//! The reference: Richardson's combination `R = (4 D(h) − D(2h)) / 3` of two central differences
//! of whole runs in ξ (a 4-point stencil, truncation O(h⁴)), each run with Newton tolerances near
//! rounding ([`settings`]); the direct run uses the same tolerances, so that
//! both differentiate the same trajectory (on the chaotic double pendulum the default tolerance's
//! noise grows to 6e-5 of a joint angle within 2 s).
//!
//! "Relative" is per output, dimension and record time: `|direct − R| / max(|R|, floor · peak,
//! ABSOLUTE_FLOOR)` with the peak the output's largest `|R|` over every dimension and time, so that
//! derivatives crossing zero, and dimensions that barely move an output, are judged against a
//! fraction of the output's sensitivity instead of against zero. Asked: [`AGREEMENT`] = 1e-6 with
//! floor [`FLOOR`] = 1e-3 for every output of every scene, except accelerations and multipliers
//! (efforts, constraint forces) of scenes with constraint rows, which the reference cannot resolve
//! that well: index-3 integration cannot test positions tighter than the rounding of `Φ/(β'h²)`
//! allows, so each run's `q̈` and `λ` carry ~`abstol_position/(β'h²)` = 4e-9 rad/s² of Newton noise
//! at h = 1 ms, which the difference magnifies by ~1.5/h_ξ to ~6e-7 per unit ξ (measured: the
//! four-bar's `∂q̈/∂m` scatters by 5e-7 between reference steps 1e-3 and 3e-2). Those outputs are
//! judged against their peak ([`ROUNDING_LIMITED`]), and the constrained robots are also checked
//! at a 5 ms step, where that noise is 25× lower (the differentiation itself is exact for any
//! step). Every check prints each output's worst error.

mod common;

use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{read_sidecar, wants_floating_base, OutputKind, Scene, SceneOverrides};
use ribbon::simulate::{
    central_difference_run_with, central_difference_settings, sensitivity_run,
    sensitivity_run_with, SensitivityRun,
};
use ribbon::uncertainty::ParameterSpace;

/// Agreement asked (the issue's figure).
const AGREEMENT: f64 = 1e-6;
/// Derivatives are judged against `max(|reference|, FLOOR · peak)`, the peak being the output's
/// largest reference derivative over every dimension and time: a dimension whose effect on an
/// output is a millionth of the strongest one (the forearm's product of inertia on the ur5's
/// joints: 1e-9 rad) is judged on the output's scale, not on its own.
const FLOOR: f64 = 1e-3;
/// An output whose reference derivatives all stay below this (output unit per unit ξ, i.e. per
/// half-width of the box) does not depend on the box to any useful precision — a driven joint's
/// coordinate, a floating base's spin that no mass changes: both methods return rounding there.
/// Its direct derivatives must stay below it too.
const NEGLIGIBLE: f64 = 1e-7;
/// An absolute floor under `FLOOR · peak`, in output units per unit ξ: an output that barely
/// depends on the box (a floating base's height while it tumbles: 2e-5 m per half-width) is judged
/// to `AGREEMENT · ABSOLUTE_FLOOR` = 1e-12 absolute, the reference's own Newton noise on positions
/// (`1.5 · √nv · 1e-15 / h` ≈ 5e-13).
const ABSOLUTE_FLOOR: f64 = 1e-6;
/// Step h in ξ of the reference's central differences (h and 2h): 1 % of each half-width.
/// Truncation of `R` ~h⁴/30 ≈ 3e-10 of the fifth derivative; Newton noise ~1e-15/h on positions.
const REFERENCE_STEP: f64 = 1e-2;

/// How accelerations and multipliers of a scene with constraint rows are judged, by integration
/// step: `(step s, agreement, floor, negligible)`. The floor is the peak (1); at 1 ms the agreement
/// is what the reference resolves there (~6e-7 per unit ξ of Newton noise against peaks of ~0.01–1,
/// measured worst 8e-5), at 5 ms the noise is 25× lower. A driven joint's acceleration has
/// reference derivatives of pure noise, ~4e-7 at 1 ms: negligible below 1e-5.
const ROUNDING_LIMITED: [(f64, f64, f64, f64); 2] =
    [(1e-3, 2e-4, 1.0, 1e-5), (5e-3, 1e-5, 1.0, 1e-5)];

use common::manifest;

/// A robot with its shipped sidecar, edited by `edit` (parameters, outputs, scene), and the scene
/// overrides given.
fn load(
    robot: &str,
    overrides: SceneOverrides,
    edit: impl FnOnce(&mut ribbon::scene::SidecarFile),
) -> (Model, Scene, ParameterSpace) {
    let urdf = manifest(&format!("robots/{robot}/{robot}.urdf"));
    let (mut file, _) = read_sidecar(&urdf.with_extension("uncertainty.toml")).expect("sidecar");
    edit(&mut file);
    let floating_base = wants_floating_base(&file, "test").expect("base");
    let model = Model::from_urdf_file(&urdf, LoadOptions { floating_base }).expect("robot loads");
    let scene = Scene::resolve(&file, &model, "test", overrides).expect("scene resolves");
    let space =
        ParameterSpace::from_sidecar(&file, &model, &scene.environment(), "test").expect("box");
    (model, scene, space)
}

/// The Newton tolerances of the reference and of the direct run: the checked fallback's, and 1e-18
/// at the position level without constraint rows (100× tighter than the fallback's default, which
/// leaves room for stiffer scenes; an arm's rounding floor there is ~1e-21). With 1e-16 the
/// floating ur5's reference is noisy at 1e-6 of its tool frame's `∂x/∂m`.
fn settings(scene: &Scene) -> ribbon::integrate::HhtSettings {
    let mut settings = central_difference_settings(scene);
    if scene.constraints.is_empty() {
        settings.abstol_position = 1e-18;
    }
    settings
}

/// The reference `R = (4 D(h) − D(2h)) / 3`.
fn reference(model: &Model, scene: &Scene, space: &ParameterSpace, xi: &[f64]) -> SensitivityRun {
    let settings = settings(scene);
    let run = |step: f64| {
        central_difference_run_with(
            model.clone(),
            scene.environment(),
            scene,
            space,
            xi,
            step,
            settings,
        )
        .expect("reference runs")
    };
    let (fine, coarse) = (run(REFERENCE_STEP), run(2.0 * REFERENCE_STEP));
    let mut combined = fine.clone();
    for (c, (f, g)) in combined
        .jacobian
        .iter_mut()
        .zip(fine.jacobian.iter().zip(&coarse.jacobian))
    {
        *c = (4.0 * f - g) / 3.0;
    }
    combined
}

/// How one output is judged: `(agreement, floor, negligible)`.
fn judge(kind: &OutputKind, scene: &Scene) -> (f64, f64, f64) {
    let rough = matches!(
        kind,
        OutputKind::Acceleration { .. } | OutputKind::Multiplier { .. }
    );
    if rough && !scene.constraints.is_empty() {
        for (step, agreement, floor, negligible) in ROUNDING_LIMITED {
            if (scene.step_s - step).abs() < 1e-12 {
                return (agreement, floor, negligible);
            }
        }
        panic!(
            "no rule for constrained accelerations at a {} s step",
            scene.step_s
        );
    }
    (AGREEMENT, FLOOR, NEGLIGIBLE)
}

/// Per output: (name, worst relative error, agreement asked).
fn errors(
    direct: &SensitivityRun,
    reference: &SensitivityRun,
    scene: &Scene,
) -> Vec<(String, f64, f64)> {
    assert_eq!(direct.times.len(), reference.times.len());
    let (n, d, records) = (
        direct.n_outputs(),
        direct.n_dimensions(),
        direct.n_records(),
    );
    let mut out = Vec::new();
    for o in 0..n {
        let name = &direct.outputs[o].name;
        let (agreement, floor, negligible) = judge(&direct.outputs[o].kind, scene);
        let output_peak = (0..records)
            .flat_map(|r| (0..d).map(move |j| (r, j)))
            .map(|(r, j)| reference.derivative(r, o, j).abs())
            .fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for j in 0..d {
            for r in 0..records {
                let (a, b) = (direct.derivative(r, o, j), reference.derivative(r, o, j));
                if output_peak < negligible {
                    assert!(
                        a.abs() <= negligible,
                        "{name} does not depend on the box (reference below {negligible:e}) but \
                         its direct derivative by {} is {a:e} at t = {}",
                        direct.dimensions[j],
                        direct.times[r]
                    );
                    continue;
                }
                let scale = b.abs().max(floor * output_peak).max(ABSOLUTE_FLOOR);
                worst = worst.max((a - b).abs() / scale);
            }
        }
        let label = if output_peak < negligible {
            format!("{name} (negligible)")
        } else if floor == 1.0 {
            format!("{name} (of its peak)")
        } else {
            name.clone()
        };
        out.push((label, worst, agreement));
    }
    out
}

/// Runs both, prints every output's worst error and asserts the agreement.
fn check(
    label: &str,
    model: &Model,
    scene: &Scene,
    space: &ParameterSpace,
    xi: &[f64],
) -> SensitivityRun {
    // The reference's tolerances (see the module documentation).
    let direct = sensitivity_run_with(
        model.clone(),
        scene.environment(),
        scene,
        space,
        xi,
        settings(scene),
    )
    .expect("sensitivity run");
    let reference = reference(model, scene, space, xi);
    for (a, b) in direct.values.iter().zip(&reference.values) {
        assert_eq!(a, b, "{label}: the values are not those of a plain run");
    }
    let errors = errors(&direct, &reference, scene);
    let worst = errors
        .iter()
        .filter(|e| e.2 == AGREEMENT)
        .map(|e| e.1)
        .fold(0.0, f64::max);
    eprintln!(
        "{label}: d = {}, {} outputs × {} records: worst relative error {worst:.2e}",
        direct.n_dimensions(),
        direct.n_outputs(),
        direct.n_records()
    );
    for (name, error, agreement) in &errors {
        eprintln!("  {name}: {error:.2e} (asked {agreement:.0e})");
    }
    for (name, error, agreement) in &errors {
        assert!(
            error <= agreement,
            "{label}: {name}: direct differentiation is {error:.2e} off the central differences \
             (asked {agreement:.0e})"
        );
    }
    direct
}

fn duration(seconds: f64) -> SceneOverrides {
    SceneOverrides {
        duration_s: Some(seconds),
        ..SceneOverrides::default()
    }
}

fn with_step(seconds: f64, step: f64) -> SceneOverrides {
    SceneOverrides {
        duration_s: Some(seconds),
        step_s: Some(step),
        ..SceneOverrides::default()
    }
}

fn add_parameters(file: &mut ribbon::scene::SidecarFile, text: &str) {
    let extra: toml::Table = toml::from_str(text).expect("parameters parse");
    file.parameters.extend(extra);
}

#[test]
fn ur5_every_kind_of_value() {
    let (model, scene, space) = load("ur5", duration(1.0), |file| {
        add_parameters(
            file,
            r#"
            "link.forearm_link.com.x" = { abs = 0.002 }
            "link.wrist_3_link.inertia.izz" = { rel = 0.05 }
            "link.forearm_link.inertia.ixy" = { abs = 0.0003 }
            "joint.elbow_joint.origin.x" = { rel = 0.01 }
            "joint.wrist_1_joint.origin.z" = { abs = 0.0005 }
            "joint.shoulder_lift_joint.origin.roll" = { abs = 0.002 }
            "link.tool0.mass" = [0.0, 0.5]
            "joint.wrist_3_link-tool0_fixed_joint.origin.z" = { abs = 0.001 }
            "#,
        );
        file.outputs.velocities = Some(true);
        file.outputs.accelerations = Some(true);
    });
    assert_eq!(space.len(), 11);
    let nominal = space.nominal_xi();
    check("ur5 at the nominal point", &model, &scene, &space, &nominal);
    let elsewhere: Vec<f64> = (0..space.len()).map(|j| [0.6, -0.8, 0.3][j % 3]).collect();
    check("ur5 off-centre", &model, &scene, &space, &elsewhere);
}

#[test]
fn double_pendulum_lengths() {
    let (model, scene, space) = load("double_pendulum", duration(2.0), |file| {
        file.outputs.velocities = Some(true);
        file.outputs.accelerations = Some(true);
    });
    check(
        "double pendulum",
        &model,
        &scene,
        &space,
        &space.nominal_xi(),
    );
}

/// The four-bar's loop (constraint forces) with its uncertain masses and ground pivot, released with
/// the crank turning (as shipped), and driven by a sine on the crank.
#[test]
fn four_bar_loop_and_drive() {
    let add_outputs = |file: &mut ribbon::scene::SidecarFile| {
        file.outputs.velocities = Some(true);
        file.outputs.accelerations = Some(true);
    };
    let (model, scene, space) = load("four_bar", duration(1.0), add_outputs);
    let xi = space.nominal_xi();
    check("four-bar, 1 ms", &model, &scene, &space, &xi);
    let (model, scene, space) = load("four_bar", with_step(1.0, 5e-3), add_outputs);
    check("four-bar, 5 ms", &model, &scene, &space, &xi);

    let driven = |file: &mut ribbon::scene::SidecarFile| {
        add_outputs(file);
        file.outputs.efforts = Some(true);
        let drive = ribbon::scene::parse_sidecar(
            "[[scene.drive]]\nname = \"motor\"\njoint = \"crank_joint\"\nprofile = \"sine\"\n\
             offset = 0.0\namplitude = 0.8\nfrequency = 1.5\nphase = 0.0",
        )
        .expect("drive parses");
        file.scene.drive = drive.scene.drive;
        file.scene.initial.v.clear();
    };
    let (model, scene, space) = load("four_bar", duration(1.0), driven);
    check("four-bar driven, 1 ms", &model, &scene, &space, &xi);
    let (model, scene, space) = load("four_bar", with_step(1.0, 5e-3), driven);
    check("four-bar driven, 5 ms", &model, &scene, &space, &xi);
}

#[test]
fn slider_crank_loop_and_drive() {
    let edit = |file: &mut ribbon::scene::SidecarFile| {
        file.outputs.velocities = Some(true);
        file.outputs.accelerations = Some(true);
    };
    let (model, scene, space) = load("slider_crank", duration(1.0), edit);
    let xi = space.nominal_xi();
    check("slider-crank, 1 ms", &model, &scene, &space, &xi);
    let (model, scene, space) = load("slider_crank", with_step(1.0, 5e-3), edit);
    check("slider-crank, 5 ms", &model, &scene, &space, &xi);
}

/// A floating ur5 tumbling in free fall: the base's pose outputs (position and rotation vector),
/// its velocities, and the joints, against link masses, a COM and a link length.
#[test]
fn floating_base_tumbling() {
    let (model, scene, space) = load("ur5", duration(0.5), |file| {
        file.parameters.clear();
        file.bind.clear();
        add_parameters(
            file,
            r#"
            "link.upper_arm_link.mass" = { rel = 0.05 }
            "link.wrist_3_link.mass" = { rel = 0.1 }
            "link.forearm_link.com.x" = { abs = 0.002 }
            "joint.elbow_joint.origin.x" = { rel = 0.01 }
            "#,
        );
        let scene = ribbon::scene::parse_sidecar(
            "[scene]\nbase = \"floating\"\neffects = [\"gravity\"]\n\
             initial.base = { xyz = [0.0, 0.0, 1.0], rpy = [0.1, 0.2, 0.3], v = [0.3, 0.0, 0.1], w = [0.5, -0.2, 0.1] }\n\
             initial.v = { elbow_joint = 1.0, wrist_2_joint = -2.0 }",
        )
        .expect("scene parses");
        file.scene = scene.scene;
        file.outputs.velocities = Some(true);
    });
    assert!(model.floating_base);
    check("floating ur5", &model, &scene, &space, &space.nominal_xi());
}

/// A 1-DOF closed form: a mass m on a spring k released from x0 at rest, `x = x0 cos(√(k/m) t)`, so
/// `∂x/∂m = x0 sin(ωt) ω t / (2m)`. The discrete derivative differs from it by the integrator's
/// O(h²) phase error: checked to `CLOSED_FORM_AGREEMENT` at h = 0.1 ms, and second order in h.
#[test]
fn spring_mass_against_its_closed_form() {
    const CLOSED_FORM_AGREEMENT: f64 = 1e-6;
    let urdf = r#"<robot name="slider"><link name="world"/>
      <link name="block"><inertial><origin xyz="0 0 0"/><mass value="2.0"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
      <joint name="x" type="prismatic"><parent link="world"/><child link="block"/><axis xyz="1 0 0"/>
        <limit lower="-10" upper="10" effort="1" velocity="1"/></joint></robot>"#;
    let sidecar = "[parameters]\n\"link.block.mass\" = [1.8, 2.2]\n\
                   [scene]\nduration = 1.0\neffects = [\"joint_springs\"]\ninitial.q = { x = 0.1 }\n\
                   [[scene.spring]]\njoint = \"x\"\nstiffness = 50.0\n[outputs]\nrate = 100";
    let model = Model::from_description(
        ribbon::model::parse_description(urdf, "slider.urdf").unwrap(),
        LoadOptions::default(),
        "slider.urdf",
    )
    .unwrap();
    let file = ribbon::scene::parse_sidecar(sidecar).unwrap();
    let space =
        ParameterSpace::from_sidecar(&file, &model, &Environment::default(), "s.toml").unwrap();
    let (x0, k, m, radius): (f64, f64, f64, f64) = (0.1, 50.0, 2.0, 0.2);
    let mut errors = Vec::new();
    for step in [4e-4, 2e-4, 1e-4] {
        let overrides = SceneOverrides {
            step_s: Some(step),
            ..SceneOverrides::default()
        };
        let scene = Scene::resolve(&file, &model, "s.toml", overrides).unwrap();
        let run = sensitivity_run(
            model.clone(),
            scene.environment(),
            &scene,
            &space,
            &space.nominal_xi(),
        )
        .unwrap();
        let omega: f64 = (k / m).sqrt();
        let mut worst: f64 = 0.0;
        for (r, t) in run.times.iter().enumerate() {
            let exact = x0 * (omega * t).sin() * omega * t / (2.0 * m) * radius;
            worst = worst.max((run.derivative(r, 0, 0) - exact).abs());
        }
        let peak = x0 * omega / (2.0 * m) * radius;
        errors.push(worst / peak);
    }
    eprintln!(
        "spring-mass: ∂x/∂ξ against the closed form, h = 0.4, 0.2, 0.1 ms: {}",
        errors
            .iter()
            .map(|e| format!("{e:.2e}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    assert!(errors[2] < CLOSED_FORM_AGREEMENT, "{errors:?}");
    for pair in errors.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!(
            (3.5..4.5).contains(&ratio),
            "error ratio {ratio} per halving: not second order ({errors:?})"
        );
    }
}

/// The public entry points at their defaults: the checked fallback agrees with direct
/// differentiation to its own accuracy (a 2-point difference at h = 1e-3 in ξ: truncation ~h²/6 of
/// the third derivative, asked 1e-5 against the same floors); bad points and steps are refused
/// with messages that say what is wrong.
#[test]
fn defaults_agree_and_bad_input_is_refused() {
    const FALLBACK_AGREEMENT: f64 = 1e-5;
    let (model, scene, space) = load("double_pendulum", duration(0.5), |_| {});
    let xi = space.nominal_xi();
    let direct = sensitivity_run(model.clone(), scene.environment(), &scene, &space, &xi)
        .expect("sensitivity run");
    let fallback = ribbon::simulate::central_difference_run(
        model.clone(),
        scene.environment(),
        &scene,
        &space,
        &xi,
    )
    .expect("runs");
    assert_eq!(fallback.stats.runs, 2 * space.len() + 1);
    assert_eq!(direct.stats.runs, 1);
    let worst = errors(&direct, &fallback, &scene)
        .iter()
        .map(|e| e.1)
        .fold(0.0, f64::max);
    eprintln!("double pendulum, 0.5 s: checked fallback vs direct, worst relative {worst:.2e}");
    assert!(worst < FALLBACK_AGREEMENT, "{worst:e}");

    let message = sensitivity_run(model.clone(), scene.environment(), &scene, &space, &[0.0])
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("1 coordinates but the box has 2 dimensions"),
        "{message}"
    );
    let message = sensitivity_run(
        model.clone(),
        scene.environment(),
        &scene,
        &space,
        &[0.0, f64::NAN],
    )
    .unwrap_err()
    .to_string();
    assert!(message.contains("coordinate 1 (l2) is NaN"), "{message}");
    let message = central_difference_run_with(
        model,
        scene.environment(),
        &scene,
        &space,
        &xi,
        0.0,
        central_difference_settings(&scene),
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.contains("step in ξ is 0; it must be finite and > 0"),
        "{message}"
    );
}

/// The dimensions the pattern expansion makes: `link.NAME.scale` (exact, through the inertia's
/// linearity in it), a shared factor group over every link mass, and an offset group; at a point
/// where the scales are not 1 (so the mass derivatives carry the scale factor).
#[test]
fn ur5_scales_and_shared_groups() {
    let (model, scene, space) = load("ur5", duration(0.5), |file| {
        file.parameters.clear();
        file.bind.clear();
        add_parameters(
            file,
            r#"
            "link.*.scale" = { rel = 0.05 }
            "link.*.mass" = { rel = 0.03, shared = true }
            "link.*.com.y" = { abs = 0.002, shared = true }
            "#,
        );
    });
    assert_eq!(space.len(), 6 + 2);
    let point: Vec<f64> = (0..space.len())
        .map(|j| [0.7, -0.5, 0.2, 0.9][j % 4])
        .collect();
    check("ur5 scales and groups", &model, &scene, &space, &point);
}
