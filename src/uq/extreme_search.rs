//! A local search for the extremes of a function on the box `[-1, 1]^d` that is known only by
//! evaluating it: projected steepest ascent (or descent) with central-difference gradients, every
//! evaluation requested from the caller in batches (docs/method.md §12).
//!
//! `targets (start ξ, its value, which side) ⇒ probes (points to evaluate) ⇒ caller runs them ⇒
//! absorb(values) ⇒ next probes … ⇒ best point and value per target`
//!
//! Each target keeps a current point with its value and gradient and a step length `s` (a
//! fraction of the box's half-width). One iteration evaluates the trial point
//! `Π(ξ + s · g / ‖g‖∞)` (`−g` for a minimum; `Π` clips to the box) together with its
//! central-difference stencil, so that an accepted trial already has its gradient. A trial that
//! improves the value is accepted and the step kept; one that does not halves the step. A target
//! stops after [`ExtremeSearchSettings::max_iterations`], when the step falls below
//! [`ExtremeSearchSettings::min_step`], when the projected move is nil (a vertex or a flat
//! gradient), or when a probe fails (the caller gives a non-finite value).
//!
//! The result is a *local* optimum of what was evaluated — never an enclosure: every value it
//! reports was evaluated by the caller, so it is an inner bound of the function's range.
//!
//! [`FlipSearch`] is the search for responses whose extremes sit on the box's vertices (a fast
//! divergence, where a few per cent of every parameter spread the motion to its own size): from a
//! point with a known value, the `d` points one *flip* away (one coordinate moved to the opposite
//! face) are evaluated; when several improve, the point with *all* of them flipped is evaluated
//! next (one more evaluation: a response nearly separable at the scale of the box improves on
//! every flip at once), and the search moves to the better of it and the best single flip; the
//! rounds repeat until no flip improves. A round costs `d` (+ 1) evaluations where a
//! central-difference gradient costs `2d`, and it moves by whole faces where a gradient step
//! moves by a fraction of the half-width. [`FlipSearch::single_flips_only`] drops the combined
//! step: each round moves to the best single flip (the vertex reference of `ribbon compare` keeps
//! that plain greedy search, so that its numbers stay comparable across versions).
//!
//! What neither does: second-order steps, restarts, or any use of a surrogate.

/// Which extreme a target looks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SearchSide {
    /// The smallest value.
    Min,
    /// The largest value.
    Max,
}

impl SearchSide {
    /// Whether `candidate` is better than `incumbent` on this side (strictly).
    pub fn improves(self, candidate: f64, incumbent: f64) -> bool {
        match self {
            SearchSide::Min => candidate < incumbent,
            SearchSide::Max => candidate > incumbent,
        }
    }
}

/// The settings of an [`ExtremeSearch`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtremeSearchSettings {
    /// First step length, as a fraction of the half-width (default 0.25: a quarter of the way
    /// from the centre to a face).
    pub initial_step: f64,
    /// A target stops when its step falls below this (default 1/64).
    pub min_step: f64,
    /// Most iterations (trial points) per target (default 6).
    pub max_iterations: usize,
    /// The central differences' step in ξ (default 1e-3, as the sensitivities' checked fallback:
    /// `crate::simulate::CENTRAL_DIFFERENCE_STEP_XI`).
    pub difference_step: f64,
}

impl Default for ExtremeSearchSettings {
    fn default() -> Self {
        ExtremeSearchSettings {
            initial_step: 0.25,
            min_step: 1.0 / 64.0,
            max_iterations: 6,
            difference_step: 1e-3,
        }
    }
}

/// One extreme to look for: of which function (the caller's `label`), on which side, from where.
#[derive(Clone, Debug, PartialEq)]
pub struct SearchTarget {
    /// What the caller evaluates for this target (e.g. an output at a record time); returned
    /// with each probe.
    pub label: usize,
    /// Which side.
    pub side: SearchSide,
    /// The starting point (length d, inside the box).
    pub start: Vec<f64>,
}

/// A point the caller is asked to evaluate, for target `target` (its `label` beside it).
#[derive(Clone, Debug, PartialEq)]
pub struct Probe {
    /// Index into the targets.
    pub target: usize,
    /// The target's label.
    pub label: usize,
    /// The point, length d.
    pub point: Vec<f64>,
}

/// Where a target's search stands.
#[derive(Clone, Debug)]
struct TargetState {
    side: SearchSide,
    label: usize,
    /// The accepted point, its value and gradient (unknown before the first batch).
    current: Vec<f64>,
    value: f64,
    gradient: Option<Vec<f64>>,
    step: f64,
    iterations: usize,
    done: bool,
    /// The trial of the batch under way: its point (the start in the first batch).
    trial: Vec<f64>,
    /// The stencil of the trial: for each dimension, the points `+h` and `−h` (or one-sided at a
    /// face) and the distance between them.
    stencil: Vec<(Vec<f64>, Vec<f64>, f64)>,
}

/// The search for several extremes at once (see the module docs).
#[derive(Clone, Debug)]
pub struct ExtremeSearch {
    dim: usize,
    settings: ExtremeSearchSettings,
    targets: Vec<TargetState>,
    /// The probes of the batch under way, in the order handed out.
    pending: Vec<Probe>,
    /// Evaluations requested so far.
    evaluations: usize,
}

impl ExtremeSearch {
    /// A search of `targets` in `dim` dimensions. Starting points outside the box are clipped
    /// into it.
    pub fn new(
        dim: usize,
        targets: Vec<SearchTarget>,
        settings: ExtremeSearchSettings,
    ) -> ExtremeSearch {
        let targets = targets
            .into_iter()
            .map(|target| {
                let start: Vec<f64> = target.start.iter().map(|x| x.clamp(-1.0, 1.0)).collect();
                TargetState {
                    side: target.side,
                    label: target.label,
                    current: start.clone(),
                    value: f64::NAN,
                    gradient: None,
                    step: settings.initial_step,
                    iterations: 0,
                    done: dim == 0,
                    trial: start,
                    stencil: Vec::new(),
                }
            })
            .collect();
        ExtremeSearch {
            dim,
            settings,
            targets,
            pending: Vec::new(),
            evaluations: 0,
        }
    }

    /// Whether every target has stopped.
    pub fn is_done(&self) -> bool {
        self.targets.iter().all(|t| t.done)
    }

    /// Evaluations requested so far.
    pub fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// The points to evaluate next: for each active target its trial point, then its stencil
    /// (`2d` points). Empty when the search is done. Each call starts a new batch; the values of
    /// the previous one must have been given to [`ExtremeSearch::absorb`].
    pub fn next_probes(&mut self) -> Vec<Probe> {
        let h = self.settings.difference_step;
        let mut probes = Vec::new();
        for (index, target) in self.targets.iter_mut().enumerate() {
            if target.done {
                continue;
            }
            if let Some(gradient) = target.gradient.clone() {
                // A new trial from the accepted point.
                let sign = match target.side {
                    SearchSide::Max => 1.0,
                    SearchSide::Min => -1.0,
                };
                // The direction projected onto the box's tangent cone: a component that pushes
                // against a face the point lies on is dropped, so the step is spent along it.
                let direction: Vec<f64> = target
                    .current
                    .iter()
                    .zip(&gradient)
                    .map(|(&x, &g)| {
                        let d = sign * g;
                        if (x >= 1.0 && d > 0.0) || (x <= -1.0 && d < 0.0) {
                            0.0
                        } else {
                            d
                        }
                    })
                    .collect();
                let scale = direction.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
                let trial: Vec<f64> = target
                    .current
                    .iter()
                    .zip(&direction)
                    .map(|(&x, &d)| {
                        let unit = if scale > 0.0 { d / scale } else { 0.0 };
                        (x + target.step * unit).clamp(-1.0, 1.0)
                    })
                    .collect();
                let moved = trial
                    .iter()
                    .zip(&target.current)
                    .any(|(a, b)| (a - b).abs() > 0.5 * h);
                if !moved {
                    target.done = true;
                    continue;
                }
                target.trial = trial;
                target.iterations += 1;
            }
            target.stencil = (0..self.dim)
                .map(|j| {
                    let mut plus = target.trial.clone();
                    let mut minus = target.trial.clone();
                    plus[j] = (plus[j] + h).min(1.0);
                    minus[j] = (minus[j] - h).max(-1.0);
                    let spacing = plus[j] - minus[j];
                    (plus, minus, spacing)
                })
                .collect();
            probes.push(Probe {
                target: index,
                label: target.label,
                point: target.trial.clone(),
            });
            for (plus, minus, _) in &target.stencil {
                for point in [plus, minus] {
                    probes.push(Probe {
                        target: index,
                        label: target.label,
                        point: point.clone(),
                    });
                }
            }
        }
        self.evaluations += probes.len();
        self.pending = probes.clone();
        probes
    }

    /// The values of the last batch's probes, in the order [`ExtremeSearch::next_probes`] gave
    /// them (a non-finite value: that run failed). Accepts or rejects each target's trial.
    pub fn absorb(&mut self, values: &[f64]) {
        assert_eq!(
            values.len(),
            self.pending.len(),
            "one value per probe of the batch"
        );
        let per_target = 1 + 2 * self.dim;
        let mut offset = 0;
        let pending = std::mem::take(&mut self.pending);
        while offset < pending.len() {
            let target = &mut self.targets[pending[offset].target];
            let batch = &values[offset..offset + per_target];
            offset += per_target;
            let trial_value = batch[0];
            let gradient: Option<Vec<f64>> = target
                .stencil
                .iter()
                .enumerate()
                .map(|(j, (_, _, spacing))| {
                    let (plus, minus) = (batch[1 + 2 * j], batch[2 + 2 * j]);
                    (plus.is_finite() && minus.is_finite() && *spacing > 0.0)
                        .then(|| (plus - minus) / spacing)
                })
                .collect();
            if !trial_value.is_finite() {
                target.done = true;
                continue;
            }
            let first = target.gradient.is_none();
            if first || target.side.improves(trial_value, target.value) {
                target.current = target.trial.clone();
                target.value = trial_value;
                match gradient {
                    Some(g) => target.gradient = Some(g),
                    None => target.done = true,
                }
            } else {
                target.step *= 0.5;
            }
            if target.step < self.settings.min_step
                || target.iterations >= self.settings.max_iterations
            {
                target.done = true;
            }
        }
    }

    /// Each target's best point and value so far (`NaN` before its start was evaluated).
    pub fn best(&self) -> Vec<(Vec<f64>, f64)> {
        self.targets
            .iter()
            .map(|t| (t.current.clone(), t.value))
            .collect()
    }
}

/// The pending entry of a [`FlipSearch`] probe that is a target's combined flips, not one flip.
const COMBINED_FLIP: usize = usize::MAX;

/// A target of a [`FlipSearch`]: a point whose value is already known.
#[derive(Clone, Debug, PartialEq)]
pub struct FlipTarget {
    /// The caller's label, returned with each probe.
    pub label: usize,
    /// Which side.
    pub side: SearchSide,
    /// The starting point (length d; coordinates outside the box are clipped).
    pub start: Vec<f64>,
    /// Its value (a non-finite value: any finite value improves on it).
    pub value: f64,
}

/// Where a flip target stands.
#[derive(Clone, Debug)]
struct FlipState {
    side: SearchSide,
    label: usize,
    current: Vec<f64>,
    value: f64,
    done: bool,
    /// After a round in which several flips improved: the point with all of them flipped, to be
    /// evaluated, and the best single flip (point, value) to fall back on.
    combined: Option<(Vec<f64>, Vec<f64>, f64)>,
}

/// Greedy one-flip search over the box's vertices for several targets at once (module docs).
#[derive(Clone, Debug)]
pub struct FlipSearch {
    dim: usize,
    targets: Vec<FlipState>,
    /// The target whose round comes first in the next batch (rounds rotate so that a budget
    /// too small for every target's round is shared among them).
    cursor: usize,
    /// The probes of the batch under way: (target, flipped coordinate).
    pending: Vec<(usize, usize)>,
    evaluations: usize,
    /// Whether a round in which several flips improve evaluates them all flipped at once.
    combine_flips: bool,
}

impl FlipSearch {
    /// A search of `targets` in `dim` dimensions.
    pub fn new(dim: usize, targets: Vec<FlipTarget>) -> FlipSearch {
        let targets = targets
            .into_iter()
            .map(|t| FlipState {
                side: t.side,
                label: t.label,
                current: t.start.iter().map(|x| x.clamp(-1.0, 1.0)).collect(),
                value: t.value,
                done: dim == 0,
                combined: None,
            })
            .collect();
        FlipSearch {
            dim,
            targets,
            cursor: 0,
            pending: Vec::new(),
            evaluations: 0,
            combine_flips: true,
        }
    }

    /// The same search without the combined step: a round always moves to its best single flip
    /// (the first coordinate among equal values) or stops.
    pub fn single_flips_only(mut self) -> FlipSearch {
        self.combine_flips = false;
        self
    }

    /// Whether every target has stopped.
    pub fn is_done(&self) -> bool {
        self.targets.iter().all(|t| t.done)
    }

    /// Evaluations requested so far.
    pub fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// The flip of coordinate `j` of `point`: to the opposite face (an interior coordinate to the
    /// face farther from it; the middle to +1).
    fn flipped(point: &[f64], j: usize) -> Vec<f64> {
        let mut flipped = point.to_vec();
        flipped[j] = if point[j] > 0.0 { -1.0 } else { 1.0 };
        flipped
    }

    /// The next batch: for active targets, starting after the last one served, each its whole
    /// next step — a round of `d` flips, or the one point of its combined flips — while they fit
    /// in `max_probes`. Empty when the search is done or not one step fits. The previous batch's
    /// values must have been given to [`FlipSearch::absorb`].
    pub fn next_probes(&mut self, max_probes: usize) -> Vec<Probe> {
        let n = self.targets.len();
        let mut probes = Vec::new();
        self.pending.clear();
        let first = self.cursor;
        for k in 0..n {
            let index = (first + k) % n;
            let target = &self.targets[index];
            if target.done {
                continue;
            }
            let points: Vec<(usize, Vec<f64>)> = match &target.combined {
                Some((combined, _, _)) => vec![(COMBINED_FLIP, combined.clone())],
                None => (0..self.dim)
                    .map(|j| (j, Self::flipped(&target.current, j)))
                    .collect(),
            };
            if probes.len() + points.len() > max_probes {
                break;
            }
            for (j, point) in points {
                probes.push(Probe {
                    target: index,
                    label: target.label,
                    point,
                });
                self.pending.push((index, j));
            }
            self.cursor = (index + 1) % n;
        }
        self.evaluations += probes.len();
        probes
    }

    /// The values of the last batch's probes, in order (non-finite: that run failed, no
    /// improvement). A served round's target moves to its only improving flip, waits for the
    /// evaluation of several combined, or stops when none improves; a served combined point's
    /// target moves to the better of it and its best single flip.
    pub fn absorb(&mut self, values: &[f64]) {
        assert_eq!(
            values.len(),
            self.pending.len(),
            "one value per probe of the batch"
        );
        let pending = std::mem::take(&mut self.pending);
        let n = self.targets.len();
        // Per served target: its improving flips (coordinate, value), or the combined value.
        let mut improving: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        let mut combined_value: Vec<Option<f64>> = vec![None; n];
        let mut served = vec![false; n];
        for (&(t, j), &value) in pending.iter().zip(values) {
            served[t] = true;
            let target = &self.targets[t];
            if j == COMBINED_FLIP {
                combined_value[t] = Some(value);
            } else if value.is_finite()
                && (!target.value.is_finite() || target.side.improves(value, target.value))
            {
                improving[t].push((j, value));
            }
        }
        for (t, target) in self.targets.iter_mut().enumerate() {
            if !served[t] {
                continue;
            }
            if let Some(value) = combined_value[t] {
                let (combined, single, single_value) = target
                    .combined
                    .take()
                    .expect("a combined point was pending");
                if value.is_finite() && target.side.improves(value, single_value) {
                    target.current = combined;
                    target.value = value;
                } else {
                    target.current = single;
                    target.value = single_value;
                }
                continue;
            }
            let side = target.side;
            let Some(&(j, value)) =
                improving[t]
                    .iter()
                    .fold(None, |best: Option<&(usize, f64)>, c| match best {
                        Some(b) if !side.improves(c.1, b.1) => Some(b),
                        _ => Some(c),
                    })
            else {
                target.done = true;
                continue;
            };
            let single = Self::flipped(&target.current, j);
            if self.combine_flips && improving[t].len() > 1 {
                let mut combined = target.current.clone();
                for &(k, _) in &improving[t] {
                    combined[k] = Self::flipped(&target.current, k)[k];
                }
                target.combined = Some((combined, single, value));
            } else {
                target.current = single;
                target.value = value;
            }
        }
    }

    /// Each target's best point and value so far.
    pub fn best(&self) -> Vec<(Vec<f64>, f64)> {
        self.targets
            .iter()
            .map(|t| (t.current.clone(), t.value))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs a search of `f` to the end; returns the best points and values and the evaluations.
    fn run(
        f: &dyn Fn(&[f64]) -> f64,
        dim: usize,
        targets: Vec<SearchTarget>,
    ) -> (Vec<(Vec<f64>, f64)>, usize) {
        let mut search = ExtremeSearch::new(dim, targets, ExtremeSearchSettings::default());
        let mut guard = 0;
        while !search.is_done() {
            let probes = search.next_probes();
            if probes.is_empty() {
                break;
            }
            let values: Vec<f64> = probes.iter().map(|p| f(&p.point)).collect();
            search.absorb(&values);
            guard += 1;
            assert!(guard < 100, "the search does not stop");
        }
        (search.best(), search.evaluations())
    }

    #[test]
    fn climbs_a_kinked_ridge_to_the_corner_it_rises_to() {
        // A clamp: max(0, ξ1 + 0.5 ξ2), largest at (1, 1) with 1.5, flat 0 on half the box.
        let f = |x: &[f64]| (x[0] + 0.5 * x[1]).max(0.0);
        let (best, evaluations) = run(
            &f,
            2,
            vec![SearchTarget {
                label: 7,
                side: SearchSide::Max,
                start: vec![0.2, 0.0],
            }],
        );
        assert!((best[0].1 - 1.5).abs() < 1e-12, "{best:?}");
        assert!(evaluations <= 7 * 5, "{evaluations}");
    }

    #[test]
    fn finds_an_interior_minimum_to_the_step_resolution() {
        // (ξ1 − 0.3)² + 2 (ξ2 + 0.4)², minimum 0 at (0.3, −0.4).
        let f = |x: &[f64]| (x[0] - 0.3).powi(2) + 2.0 * (x[1] + 0.4).powi(2);
        let (best, _) = run(
            &f,
            2,
            vec![SearchTarget {
                label: 0,
                side: SearchSide::Min,
                start: vec![0.0, 0.0],
            }],
        );
        // Six steps of a quarter, halving on failure: within a few hundredths of the minimiser
        // (the search starts where a surrogate put the extreme, not across the box).
        assert!(best[0].1 < 0.005, "{best:?}");
    }

    #[test]
    fn never_reports_a_value_it_was_not_given_and_stops_on_a_failed_run() {
        // Fails (NaN) beyond ξ1 = 0.5: the search keeps the best evaluated value.
        let f = |x: &[f64]| if x[0] > 0.5 { f64::NAN } else { x[0] };
        let (best, _) = run(
            &f,
            1,
            vec![SearchTarget {
                label: 0,
                side: SearchSide::Max,
                start: vec![0.0],
            }],
        );
        assert!(best[0].1 <= 0.5 && best[0].1 >= 0.25, "{best:?}");
        assert_eq!(f(&best[0].0), best[0].1);
    }

    #[test]
    fn several_targets_share_batches_and_keep_their_own_sides() {
        let f = |x: &[f64]| x[0] - x[1];
        let (best, _) = run(
            &f,
            2,
            vec![
                SearchTarget {
                    label: 0,
                    side: SearchSide::Max,
                    start: vec![0.0, 0.0],
                },
                SearchTarget {
                    label: 1,
                    side: SearchSide::Min,
                    start: vec![0.0, 0.0],
                },
            ],
        );
        assert_eq!(best[0], (vec![1.0, -1.0], 2.0));
        assert_eq!(best[1], (vec![-1.0, 1.0], -2.0));
    }

    #[test]
    fn flips_climb_to_the_best_vertex_and_share_a_small_budget() {
        // A separable response largest at (1, −1, 1): every flip towards it improves.
        let f = |x: &[f64]| x[0] - 2.0 * x[1] + 0.5 * x[2];
        let targets = vec![
            FlipTarget {
                label: 3,
                side: SearchSide::Max,
                start: vec![-1.0, 1.0, -1.0],
                value: f(&[-1.0, 1.0, -1.0]),
            },
            FlipTarget {
                label: 4,
                side: SearchSide::Min,
                start: vec![0.2, 0.0, 0.3],
                value: f(&[0.2, 0.0, 0.3]),
            },
        ];
        let mut search = FlipSearch::new(3, targets);
        // A budget of one round per batch: the two targets take turns.
        let mut served = Vec::new();
        while !search.is_done() {
            let probes = search.next_probes(4);
            assert!(!probes.is_empty() && probes.len() <= 4, "{probes:?}");
            served.push(probes[0].label);
            let values: Vec<f64> = probes.iter().map(|p| f(&p.point)).collect();
            search.absorb(&values);
            assert!(served.len() < 20, "the search does not stop");
        }
        assert_eq!(&served[..2], &[3, 4]);
        let best = search.best();
        assert_eq!(best[0], (vec![1.0, -1.0, 1.0], 3.5));
        assert_eq!(best[1], (vec![-1.0, 1.0, -1.0], -3.5));
        // A round that does not fit is not started.
        assert!(FlipSearch::new(3, vec![]).next_probes(2).is_empty());
    }

    #[test]
    fn a_failed_flip_never_becomes_the_best() {
        let f = |x: &[f64]| if x[0] > 0.0 { f64::NAN } else { -x[1] };
        let mut search = FlipSearch::new(
            2,
            vec![FlipTarget {
                label: 0,
                side: SearchSide::Max,
                start: vec![-1.0, 1.0],
                value: -1.0,
            }],
        );
        while !search.is_done() {
            let probes = search.next_probes(10);
            let values: Vec<f64> = probes.iter().map(|p| f(&p.point)).collect();
            search.absorb(&values);
        }
        assert_eq!(search.best()[0], (vec![-1.0, -1.0], 1.0));
    }

    #[test]
    fn combined_flips_fall_back_to_the_best_single_one() {
        // Each flip alone improves (−5 → 3); both together do not (−1).
        let f = |x: &[f64]| x[0] + x[1] - 3.0 * x[0] * x[1];
        let mut search = FlipSearch::new(
            2,
            vec![FlipTarget {
                label: 0,
                side: SearchSide::Max,
                start: vec![-1.0, -1.0],
                value: -5.0,
            }],
        );
        let mut batches = 0;
        while !search.is_done() {
            let probes = search.next_probes(10);
            let values: Vec<f64> = probes.iter().map(|p| f(&p.point)).collect();
            search.absorb(&values);
            batches += 1;
        }
        // A round, its combined point, a round that finds nothing.
        assert_eq!((batches, search.evaluations()), (3, 5));
        assert_eq!(search.best()[0], (vec![1.0, -1.0], 3.0));
    }

    #[test]
    fn a_batch_with_room_for_every_round_serves_each_target_once() {
        // Nothing improves: every target is served once, in order, then stops.
        let targets: Vec<FlipTarget> = (0..5)
            .map(|label| FlipTarget {
                label,
                side: SearchSide::Max,
                start: vec![1.0, -1.0],
                value: 10.0,
            })
            .collect();
        let mut search = FlipSearch::new(2, targets);
        let probes = search.next_probes(usize::MAX);
        let served: Vec<usize> = probes.iter().map(|p| p.target).collect();
        assert_eq!(served, vec![0, 0, 1, 1, 2, 2, 3, 3, 4, 4]);
        search.absorb(&vec![0.0; probes.len()]);
        assert!(search.is_done());
    }

    #[test]
    fn single_flips_only_moves_to_the_best_flip_without_combining() {
        // Every flip improves from (−1, −1, 1) (−3.5 → −1.5, 0.5, −2.5): the combined search would
        // next evaluate all three flipped; this one moves to the best single flip, x1.
        let f = |x: &[f64]| x[0] + 2.0 * x[1] - 0.5 * x[2];
        let start = vec![-1.0, -1.0, 1.0];
        let mut search = FlipSearch::new(
            3,
            vec![FlipTarget {
                label: 0,
                side: SearchSide::Max,
                value: f(&start),
                start,
            }],
        )
        .single_flips_only();
        let mut moves = Vec::new();
        while !search.is_done() {
            let probes = search.next_probes(10);
            assert!(probes.iter().all(|p| p.point.len() == 3), "{probes:?}");
            assert_eq!(probes.len(), 3, "every batch is a round of single flips");
            let values: Vec<f64> = probes.iter().map(|p| f(&p.point)).collect();
            search.absorb(&values);
            moves.push(search.best()[0].clone());
        }
        // One flip per round, the best each time, then a round that finds none.
        assert_eq!(moves[0], (vec![-1.0, 1.0, 1.0], 0.5));
        assert_eq!(moves[1], (vec![1.0, 1.0, 1.0], 2.5));
        assert_eq!(moves[2], (vec![1.0, 1.0, -1.0], 3.5));
        assert_eq!(moves.len(), 4);
        assert_eq!(search.evaluations(), 12);
    }
}
