//! The a-posteriori check (docs/method.md §7): true-model runs at the points where the
//! surrogates predict their extremes, so that no reported bound rests on the surrogate alone.
//!
//! `(per output and record: predicted argmin/argmax and value) ⇒ deduplicated candidate points ⇒
//! a budgeted selection ⇒ (after the runs) observed misfits per output and record`
//!
//! Selection: candidates are taken round-robin over outputs and sides (min, max), each output's
//! records in order of decreasing envelope width, so every output's widest time is checked first and
//! the budget then spreads over the others. Points closer than [`CHECK_POINT_TOLERANCE`] (max-norm in
//! ξ) are one run. The check never narrows anything: the study widens its envelopes to contain the
//! check runs and reports the misfit ([`super::CheckMisfit`]: `|true − predicted|` where a
//! candidate of a scan was run, the excess past the envelope for outer and approximate methods).

use super::lyapunov::LyapunovEstimate;
use super::method::Method;
use super::report::CheckReport;
// Re-exported: the path by which elements_phase.rs and refine_phase.rs name it.
pub(super) use super::envelope::Side;
use std::collections::HashMap;

/// Two predicted extremisers closer than this in every coordinate of ξ are checked by one run: a
/// thousandth of the half-width moves a smooth response by ~1e-3 of its slope, well below the misfits
/// the check is there to find.
pub const CHECK_POINT_TOLERANCE: f64 = 1e-3;

/// Smallest automatic check budget (runs).
pub const MIN_CHECK_RUNS: usize = 8;

/// The automatic check budget as a fraction of the design's runs.
pub const CHECK_RUNS_FRACTION: f64 = 0.1;

/// A surrogate whose check runs miss its predicted extremes by more than this fraction of the
/// output's largest envelope width is reported as not trustworthy (stderr and summary).
pub const TRUST_RELATIVE_MISFIT: f64 = 0.05;

/// A misfit counts against a surrogate only above this multiple of the output's resolution
/// ([`output_resolution`]): 1, so a misfit smaller than what the integrator may be off by within one
/// step is not taken as evidence (docs/method.md §7, "The resolution floor").
pub const TRUST_RESOLUTION_FACTOR: f64 = 1.0;

/// What the trust test says of one output ([`trust_verdict`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrustVerdict {
    /// Its misfit is within [`TRUST_RELATIVE_MISFIT`] of its width.
    Trusted,
    /// Its misfit is beyond that but within the output's resolution: numerical noise.
    BelowResolution,
    /// Its surrogate cannot be trusted.
    Untrusted,
}

/// The trust test of an output whose checks missed by at most `misfit` and whose envelope is at
/// most `width` wide (over the records judged), with the output's `resolution`
/// ([`output_resolution`]): the relative misfit `misfit / width` (0 for a zero width) and the
/// verdict. The one rule for the whole run and for its prefixes
/// ([`CheckReport::passes_until_record`]).
pub fn trust_verdict(misfit: f64, width: f64, resolution: Option<f64>) -> (f64, TrustVerdict) {
    let relative = if width > 0.0 { misfit / width } else { 0.0 };
    let verdict = if relative > TRUST_RELATIVE_MISFIT {
        if resolution.is_some_and(|floor| misfit <= TRUST_RESOLUTION_FACTOR * floor) {
            TrustVerdict::BelowResolution
        } else {
            TrustVerdict::Untrusted
        }
    } else {
        TrustVerdict::Trusted
    };
    (relative, verdict)
}

/// Above this amplification `exp(λ T)` of nearby trajectories over the horizon, the advice for an
/// untrusted surrogate names the separation as the likely cause: a 1 % box then spreads to the
/// order of the motion itself, which a low-order polynomial in the parameters cannot follow. (The
/// chaos warning's threshold, [`super::lyapunov::CHAOS_AMPLIFICATION`], is for any box.)
pub const SEPARATION_ADVICE_AMPLIFICATION: f64 = 1e2;

/// What to do about a surrogate the check did not trust, for the warning and the exit-4 error:
/// when the first miss happened, up to when the same checks would pass
/// ([`CheckReport::passes_until_record`]: a run shortened to then may be trusted; check again),
/// which untrusted outputs reach an enforced joint limit (`at_stops`, their names: a stop makes
/// the response kink in the parameters), whether the nominal motion separates nearby trajectories
/// fast (`lyapunov`), and which method can replace the surrogate at `dimensions` parameters (a
/// scan only up to [`super::auto::AUTO_TENSOR_MAX_DIM`]). A higher order is offered only when
/// neither a stop nor the separation explains the miss, and only to a `method` that has one
/// (not `taylor`).
pub fn untrusted_advice(
    check: &CheckReport,
    times: &[f64],
    dimensions: usize,
    lyapunov: Option<&LyapunovEstimate>,
    at_stops: &[&str],
    method: Method,
) -> String {
    let mut parts = Vec::new();
    // Times as a person reads and types them (`0.35`, not the grid's `0.35000000000000003`).
    let times: Vec<f64> = times
        .iter()
        .map(|&t| crate::text::message_time(t))
        .collect();
    let first_miss = check
        .first_miss_record
        .and_then(|r| times.get(r).copied())
        .map(|t| {
            let earlier = match check.checks_before_first_miss {
                0 => String::new(),
                1 => " (the one check at earlier times agreed)".to_string(),
                n => format!(" (the {n} checks at earlier times agreed)"),
            };
            format!("the first miss is at t = {t} s{earlier}")
        });
    // The check restricted to the records up to some time passes when a shorter run would be
    // judged by the same checks: worth naming only if it is not the start.
    let last = times.len().saturating_sub(1);
    let verified = check
        .horizon
        .as_ref()
        .and_then(|h| h.verified_until_record.map(|r| (h, r)));
    let shorter = match (verified, check.passes_until_record) {
        (Some((horizon, r)), _) if r > 0 && r < last => {
            let t = times[r];
            parts.push(if horizon.runs == 0 {
                format!(
                    "every extreme the surrogate predicts up to t = {t} s is among the points checked, which agree with it: its envelopes up to then pass the trust test"
                )
            } else {
                format!(
                    "checks aimed at the times up to t = {t} s agree with the surrogate ({} more run{} in {} round{}): its envelopes up to then pass the trust test",
                    horizon.runs,
                    if horizon.runs == 1 { "" } else { "s" },
                    horizon.rounds,
                    if horizon.rounds == 1 { "" } else { "s" },
                )
            });
            Some(format!("shorten --duration to {t} s"))
        }
        (_, Some(r)) if r > 0 && r < last => {
            let t = times[r];
            parts.push(format!(
                "judged against the envelope widths up to then, the checks pass up to t = {t} s"
            ));
            Some(format!("shorten --duration to {t} s and check again"))
        }
        _ => None,
    };
    // The first miss comes first; beside a shorter horizon it needs its yardstick: it is judged
    // against the whole run's envelopes, which a fast-widening motion makes far wider than those
    // up to the shorter horizon (a limp arm over 1 s: first miss at 0.5 s, verified to 0.24 s).
    if let Some(first_miss) = first_miss {
        let first_miss = if shorter.is_some() {
            format!("judged against the whole run's envelope widths, {first_miss}")
        } else {
            first_miss
        };
        parts.insert(0, first_miss);
    }
    if !at_stops.is_empty() {
        parts.push(format!(
            "{} reach{} a joint limit, where the joint stops: whether and when it hits moves with the parameters, which puts a kink in the response that no polynomial follows",
            at_stops.join(", "),
            if at_stops.len() == 1 { "es" } else { "" }
        ));
    }
    let separating = lyapunov
        .filter(|l| l.exponent_per_s > 0.0 && l.amplification >= SEPARATION_ADVICE_AMPLIFICATION);
    if let Some(l) = separating {
        parts.push(format!(
            "the nominal motion separates nearby trajectories at {:.2} /s ({:.1e}-fold over {:.3} s), faster than a polynomial in the parameters can follow for long",
            l.exponent_per_s, l.amplification, l.horizon_s
        ));
    }
    let replacement = if dimensions <= super::auto::AUTO_TENSOR_MAX_DIM {
        "use --method scan or monte-carlo".to_string()
    } else {
        format!("use --method monte-carlo (a scan is out of reach at d = {dimensions})")
    };
    let mut actions: Vec<String> = shorter.into_iter().collect();
    if separating.is_none() && at_stops.is_empty() && method.family().is_some() {
        actions.push("raise --order".to_string());
    }
    actions.push("narrow the box".to_string());
    actions.push(replacement);
    let actions = match actions.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{}, or {last}", rest.join(", ")),
        None => String::new(),
    };
    if parts.is_empty() {
        actions
    } else {
        format!("{}; {actions}", parts.join("; "))
    }
}

/// How finely the true model resolves an output, in its unit, or `None` where no floor is known.
///
/// For position-like outputs (joint positions, link frame positions, a floating base's position and
/// rotation vector; m or rad) the integrator's own tolerance on positions: the Newton test's
/// `abstol_position + reltol · magnitude` (`magnitude` the output's largest `|value|`; an upper
/// estimate of the per-coordinate weights, which use `|q|` of prismatic and translational
/// coordinates only), and with the adaptive step also its local error tolerance per step, which
/// decides where sub-steps fall and so moves trajectories by up to that much between neighbouring
/// parameter points. Velocities, accelerations, forces and multipliers get no floor: their
/// resolution depends on the step and on stiffnesses, and a missing floor errs on the loud side.
pub fn output_resolution(
    kind: &crate::scene::OutputKind,
    magnitude: f64,
    settings: &crate::integrate::HhtSettings,
) -> Option<f64> {
    use crate::scene::OutputKind;
    match kind {
        OutputKind::Position { .. }
        | OutputKind::FramePosition { .. }
        | OutputKind::BasePosition { .. }
        | OutputKind::BaseRotation { .. } => {
            let newton = settings.abstol_position + settings.reltol * magnitude.abs();
            Some(match settings.step_control {
                crate::integrate::StepControl::Adaptive => newton.max(settings.tolerance),
                crate::integrate::StepControl::Fixed => newton,
            })
        }
        OutputKind::Velocity { .. }
        | OutputKind::Acceleration { .. }
        | OutputKind::ContactNormalForce { .. }
        | OutputKind::Multiplier { .. } => None,
    }
}

/// The automatic number of check runs for a design of `design_runs` runs.
pub fn automatic_check_runs(design_runs: usize) -> usize {
    MIN_CHECK_RUNS.max((CHECK_RUNS_FRACTION * design_runs as f64).ceil() as usize)
}

/// A coordinate of a candidate point quantised to [`CHECK_POINT_TOLERANCE`]: points whose keys
/// agree are one run.
fn point_key(x: f64) -> i64 {
    (x.clamp(-1.0, 1.0) / CHECK_POINT_TOLERANCE).round() as i64
}

/// One predicted extreme: output `output` at record `record` takes `predicted` at point `point`.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    record: usize,
    output: usize,
    side: Side,
    point: usize,
    predicted: f64,
    width: f64,
}

/// The predicted extremisers of a study, deduplicated as they arrive.
#[derive(Clone, Debug)]
pub struct CheckCandidates {
    dim: usize,
    /// Unique points, row-major `n × dim`.
    points: Vec<f64>,
    /// Quantised point → index into `points`.
    index: HashMap<Vec<i64>, usize>,
    candidates: Vec<Candidate>,
    key: Vec<i64>,
}

/// A selected check: the runs to make and, per run, the predictions it checks.
#[derive(Clone, Debug)]
pub struct CheckPlan {
    /// Points to run, row-major `runs × d`.
    pub points: Vec<f64>,
    /// For run `i`, the `(record, output, side, predicted)` it checks.
    pub checks: Vec<Vec<(usize, usize, Side, f64)>>,
    /// Unique candidate points there were to choose from.
    pub unique_candidates: usize,
}

impl CheckCandidates {
    /// No candidates yet, for `dim` parameters.
    pub fn new(dim: usize) -> CheckCandidates {
        CheckCandidates {
            dim,
            points: Vec::new(),
            index: HashMap::new(),
            candidates: Vec::new(),
            key: vec![0; dim],
        }
    }

    /// Number of distinct points so far.
    pub fn unique_points(&self) -> usize {
        self.points.len() / self.dim.max(1)
    }

    /// Adds the prediction that `output` at `record` takes `predicted` at `point` (length d, in
    /// [−1, 1]); `width` is the envelope's width there (the selection's priority).
    pub fn add(
        &mut self,
        record: usize,
        output: usize,
        side: Side,
        point: &[f64],
        predicted: f64,
        width: f64,
    ) {
        if !(predicted.is_finite() && point.iter().all(|x| x.is_finite())) {
            return;
        }
        for (k, &x) in self.key.iter_mut().zip(point) {
            *k = point_key(x);
        }
        let next = self.unique_points();
        let index = *self.index.entry(self.key.clone()).or_insert(next);
        if index == next {
            self.points.extend(point.iter().map(|x| x.clamp(-1.0, 1.0)));
        }
        self.candidates.push(Candidate {
            record,
            output,
            side,
            point: index,
            predicted,
            width: if width.is_finite() { width } else { 0.0 },
        });
    }

    /// Where `output` at `record` was predicted to take its extreme on `side`, and the predicted
    /// value (the last such prediction added; `None` when there was none).
    pub fn extreme(&self, record: usize, output: usize, side: Side) -> Option<(&[f64], f64)> {
        let d = self.dim;
        self.candidates
            .iter()
            .rev()
            .find(|c| c.record == record && c.output == output && c.side == side)
            .map(|c| (&self.points[c.point * d..(c.point + 1) * d], c.predicted))
    }

    /// Chooses at most `budget` distinct points (see the module documentation).
    pub fn select(&self, budget: usize) -> CheckPlan {
        self.select_after(Vec::new(), budget)
    }

    /// Chooses at most `budget` distinct points: first, for each of `outputs` and side, the
    /// prediction furthest past what true runs showed ([`Self::select_overshoots`]), then the
    /// others as [`Self::select`] does. An element's check (docs/method.md §12, "Overshoots").
    pub fn select_with_overshoots(
        &self,
        budget: usize,
        outputs: &[usize],
        hull: &dyn Fn(usize, usize) -> (f64, f64),
        min_excess: &[f64],
    ) -> CheckPlan {
        let mut first = self.overshoots(outputs, hull, min_excess, &[]);
        first.truncate(budget);
        self.select_after(first, budget)
    }

    /// Chooses at most `budget` distinct points as [`Self::select`] does, but only among the
    /// predictions at records up to `last_record` and not at the points `ran` (row-major, already
    /// run: their misfits are known) — the horizon check's selection (docs/method.md §7, "What
    /// to do about a miss"). Every candidate at a chosen point is checked, at any record.
    pub fn select_until(&self, last_record: usize, budget: usize, ran: &[f64]) -> CheckPlan {
        let skip = self.indices_of(ran);
        self.select_among(Vec::new(), budget, &|c: &Candidate| {
            c.record <= last_record && !skip.contains(&c.point)
        })
    }

    /// [`Self::select`] after the points `chosen` (indices into `points`, run first).
    fn select_after(&self, chosen: Vec<usize>, budget: usize) -> CheckPlan {
        self.select_among(chosen, budget, &|_| true)
    }

    /// The points the first check of a study that ended at `last_record` would run with `budget`
    /// runs ([`Self::select`] among the predictions up to it), less those already run (`ran`,
    /// row-major: their misfits are known) — the horizon check's confirmation of a duration it
    /// advises (docs/method.md §7, "What to do about a miss"). Every candidate at a chosen point
    /// is checked, at any record.
    pub fn first_check_until(&self, last_record: usize, budget: usize, ran: &[f64]) -> CheckPlan {
        let skip = self.indices_of(ran);
        let chosen: Vec<usize> = self
            .choose_among(Vec::new(), budget, &|c: &Candidate| c.record <= last_record)
            .into_iter()
            .filter(|p| !skip.contains(p))
            .collect();
        self.plan_of(&chosen, self.unique_points())
    }

    /// [`Self::select_after`] among the candidates `eligible` accepts.
    fn select_among(
        &self,
        chosen: Vec<usize>,
        budget: usize,
        eligible: &dyn Fn(&Candidate) -> bool,
    ) -> CheckPlan {
        let chosen = self.choose_among(chosen, budget, eligible);
        self.plan_of(&chosen, self.unique_points())
    }

    /// The points (indices into `points`, in run order) [`Self::select_among`] runs: `chosen`
    /// first, then round-robin over outputs and sides, widest record first.
    fn choose_among(
        &self,
        mut chosen: Vec<usize>,
        budget: usize,
        eligible: &dyn Fn(&Candidate) -> bool,
    ) -> Vec<usize> {
        let unique_candidates = self.unique_points();
        // Per (output, side): candidates by decreasing width (ties: earlier record first).
        let mut queues: HashMap<(usize, bool), Vec<usize>> = HashMap::new();
        for (c, candidate) in self.candidates.iter().enumerate() {
            if !eligible(candidate) {
                continue;
            }
            queues
                .entry((candidate.output, candidate.side == Side::Upper))
                .or_default()
                .push(c);
        }
        let mut keys: Vec<(usize, bool)> = queues.keys().copied().collect();
        keys.sort_unstable();
        for queue in queues.values_mut() {
            queue.sort_by(|&a, &b| {
                let (a, b) = (&self.candidates[a], &self.candidates[b]);
                b.width.total_cmp(&a.width).then(a.record.cmp(&b.record))
            });
        }
        let mut chosen_slot: HashMap<usize, usize> = chosen
            .iter()
            .enumerate()
            .map(|(slot, &p)| (p, slot))
            .collect();
        let mut cursor = vec![0usize; keys.len()];
        while chosen.len() < budget.min(unique_candidates) {
            let mut advanced = false;
            for (q, key) in keys.iter().enumerate() {
                let queue = &queues[key];
                // Skip candidates whose point is already chosen.
                while cursor[q] < queue.len()
                    && chosen_slot.contains_key(&self.candidates[queue[cursor[q]]].point)
                {
                    cursor[q] += 1;
                }
                if cursor[q] < queue.len() && chosen.len() < budget {
                    let point = self.candidates[queue[cursor[q]]].point;
                    chosen_slot.insert(point, chosen.len());
                    chosen.push(point);
                    cursor[q] += 1;
                    advanced = true;
                }
            }
            if !advanced {
                break;
            }
        }
        chosen
    }

    /// The predictions furthest past what true runs showed (docs/method.md §12, "Overshoots"):
    /// for each of `outputs` and each side, the candidate whose prediction lies furthest beyond
    /// `hull(record, output)` on its side, when that is more than `min_excess[output]` and its
    /// point is not one of `ran` (row-major, already run: its misfits are known). One run per
    /// point, in the order outputs × (lower, upper); every candidate at a chosen point is checked.
    pub fn select_overshoots(
        &self,
        outputs: &[usize],
        hull: &dyn Fn(usize, usize) -> (f64, f64),
        min_excess: &[f64],
        ran: &[f64],
    ) -> CheckPlan {
        let chosen = self.overshoots(outputs, hull, min_excess, ran);
        self.plan_of(&chosen, self.unique_points())
    }

    /// The points of [`Self::select_overshoots`], in run order.
    fn overshoots(
        &self,
        outputs: &[usize],
        hull: &dyn Fn(usize, usize) -> (f64, f64),
        min_excess: &[f64],
        ran: &[f64],
    ) -> Vec<usize> {
        let ran = self.indices_of(ran);
        let mut chosen: Vec<usize> = Vec::new();
        for &o in outputs {
            for side in [Side::Lower, Side::Upper] {
                let furthest = self
                    .candidates
                    .iter()
                    .filter(|c| c.output == o && c.side == side && !ran.contains(&c.point))
                    .map(|c| {
                        let (lowest, highest) = hull(c.record, o);
                        let past = match side {
                            Side::Lower => lowest - c.predicted,
                            Side::Upper => c.predicted - highest,
                        };
                        (past, c.point)
                    })
                    .filter(|(past, _)| past.is_finite() && *past > min_excess[o])
                    .fold(
                        None,
                        |best: Option<(f64, usize)>, (past, point)| match best {
                            Some((b, _)) if b >= past => best,
                            _ => Some((past, point)),
                        },
                    );
                if let Some((_, point)) = furthest {
                    if !chosen.contains(&point) {
                        chosen.push(point);
                    }
                }
            }
        }
        chosen
    }

    /// The indices of the candidate points within [`CHECK_POINT_TOLERANCE`] of the points
    /// `points` (row-major).
    fn indices_of(&self, points: &[f64]) -> std::collections::HashSet<usize> {
        points
            .chunks_exact(self.dim.max(1))
            .filter_map(|point| self.index_of(point))
            .collect()
    }

    /// The index of the candidate point within [`CHECK_POINT_TOLERANCE`] of `point`, if any.
    fn index_of(&self, point: &[f64]) -> Option<usize> {
        let key: Vec<i64> = point.iter().map(|&x| point_key(x)).collect();
        self.index.get(&key).copied()
    }

    /// The plan that runs the candidate points `chosen` (indices into `points`, in run order).
    fn plan_of(&self, chosen: &[usize], unique_candidates: usize) -> CheckPlan {
        let d = self.dim;
        let mut points = Vec::with_capacity(chosen.len() * d);
        for &p in chosen {
            points.extend_from_slice(&self.points[p * d..(p + 1) * d]);
        }
        let chosen_slot: HashMap<usize, usize> = chosen
            .iter()
            .enumerate()
            .map(|(slot, &p)| (p, slot))
            .collect();
        let mut checks = vec![Vec::new(); chosen.len()];
        for candidate in &self.candidates {
            if let Some(&slot) = chosen_slot.get(&candidate.point) {
                checks[slot].push((
                    candidate.record,
                    candidate.output,
                    candidate.side,
                    candidate.predicted,
                ));
            }
        }
        CheckPlan {
            points,
            checks,
            unique_candidates,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn untrusted_check(
        first_miss_record: Option<usize>,
        checks_before: usize,
        passes_until_record: Option<usize>,
    ) -> CheckReport {
        CheckReport {
            runs: 8,
            unique_candidates: 8,
            points: Vec::new(),
            max_misfit: vec![0.5],
            relative_misfit: vec![0.5],
            untrusted_outputs: vec![0],
            resolution: vec![None],
            below_resolution_outputs: Vec::new(),
            complete: true,
            checked: Vec::new(),
            first_miss_record,
            checks_before_first_miss: checks_before,
            passes_until_record,
            horizon: None,
        }
    }

    #[test]
    fn the_trust_verdict_is_the_relative_misfit_against_the_tolerance_then_the_resolution() {
        let at = |misfit, width, resolution| trust_verdict(misfit, width, resolution);
        assert_eq!(at(0.05, 1.0, None), (0.05, TrustVerdict::Trusted));
        assert_eq!(at(0.06, 1.0, None).1, TrustVerdict::Untrusted);
        assert_eq!(at(0.06, 1.0, Some(0.06)).1, TrustVerdict::BelowResolution);
        assert_eq!(at(0.06, 1.0, Some(0.05)).1, TrustVerdict::Untrusted);
        // A zero width has nothing to miss.
        assert_eq!(at(1.0, 0.0, None), (0.0, TrustVerdict::Trusted));
    }

    #[test]
    fn untrusted_advice_names_the_first_miss_the_separation_and_a_method_that_fits_d() {
        // The last time as a step grid makes it, 350 · 1e-3 = 0.35000000000000003: messages say 0.35.
        let times = [0.0, 0.1, 0.2, 350.0 * 1e-3];
        let separating = LyapunovEstimate {
            exponent_per_s: 9.0,
            amplification: 8.1e3,
            horizon_s: 1.0,
        };
        let advice = untrusted_advice(
            &untrusted_check(Some(2), 5, Some(1)),
            &times,
            38,
            Some(&separating),
            &[],
            Method::LegendreScan,
        );
        assert_eq!(
            advice,
            "judged against the whole run's envelope widths, the first miss is at t = 0.2 s (the 5 \
             checks at earlier times agreed); judged against \
             the envelope widths up to then, the checks pass up to t = 0.1 s; the nominal motion \
             separates nearby trajectories at 9.00 /s (8.1e3-fold over 1.000 s), faster than a \
             polynomial in the parameters can follow for long; shorten --duration to 0.1 s and \
             check again, narrow the box, or use --method monte-carlo (a scan is out of reach at \
             d = 38)"
        );
        // A check that passes only at the start gives no shorter horizon; slow separation is not
        // named and a higher order is worth a try; at d ≤ 4 a scan is.
        let calm = LyapunovEstimate {
            amplification: SEPARATION_ADVICE_AMPLIFICATION / 2.0,
            ..separating
        };
        let advice = untrusted_advice(
            &untrusted_check(Some(1), 0, Some(0)),
            &times,
            2,
            Some(&calm),
            &[],
            Method::LegendreScan,
        );
        assert_eq!(
            advice,
            "the first miss is at t = 0.1 s; raise --order, narrow the box, or use --method scan \
             or monte-carlo"
        );
        let advice = untrusted_advice(
            &untrusted_check(None, 9, Some(3)),
            &times,
            4,
            None,
            &[],
            Method::LegendreIa,
        );
        assert_eq!(
            advice,
            "raise --order, narrow the box, or use --method scan or monte-carlo"
        );
        // `taylor` has no order to raise.
        let advice = untrusted_advice(
            &untrusted_check(None, 9, Some(3)),
            &times,
            4,
            None,
            &[],
            Method::Taylor,
        );
        assert_eq!(
            advice,
            "narrow the box, or use --method scan or monte-carlo"
        );
        // Outputs at a stop are named as the cause, with no higher order offered; one earlier
        // check is "the one check"; no passing prefix, no shorter duration.
        let advice = untrusted_advice(
            &untrusted_check(Some(3), 1, None),
            &times,
            9,
            None,
            &["q.finger"],
            Method::LegendreScan,
        );
        assert_eq!(
            advice,
            "the first miss is at t = 0.35 s (the one check at earlier times agreed); q.finger \
             reaches a joint limit, where the joint stops: whether and when it hits moves with the \
             parameters, which puts a kink in the response that no polynomial follows; narrow the \
             box, or use --method monte-carlo (a scan is out of reach at d = 9)"
        );
    }

    #[test]
    fn positions_are_resolved_to_the_integrators_tolerance_and_forces_are_not() {
        use crate::integrate::{HhtSettings, StepControl};
        use crate::scene::OutputKind;
        let fixed = HhtSettings::default();
        let position = OutputKind::FramePosition { link: 0, axis: 1 };
        let expected = fixed.abstol_position + fixed.reltol * 2.0;
        assert_eq!(output_resolution(&position, -2.0, &fixed), Some(expected));
        let adaptive = HhtSettings {
            step_control: StepControl::Adaptive,
            ..HhtSettings::default()
        };
        // The adaptive step's per-step tolerance (1e-5) dominates the Newton test's at 2 m.
        assert_eq!(
            output_resolution(&position, 2.0, &adaptive),
            Some(adaptive.tolerance)
        );
        for kind in [
            OutputKind::Velocity { v_index: 0 },
            OutputKind::Acceleration { v_index: 0 },
            OutputKind::ContactNormalForce { pair: 0 },
            OutputKind::Multiplier { row: 0, sign: -1.0 },
        ] {
            assert_eq!(output_resolution(&kind, 1.0, &fixed), None, "{kind:?}");
        }
    }

    #[test]
    fn nearby_points_are_one_candidate_and_far_ones_are_two() {
        let mut c = CheckCandidates::new(2);
        c.add(0, 0, Side::Upper, &[1.0, -1.0], 2.0, 1.0);
        c.add(
            1,
            0,
            Side::Upper,
            &[1.0, -1.0 + 0.2 * CHECK_POINT_TOLERANCE],
            2.1,
            1.0,
        );
        c.add(1, 1, Side::Lower, &[0.25, 0.0], -1.0, 1.0);
        assert_eq!(c.unique_points(), 2);
        // Non-finite predictions are dropped.
        c.add(2, 1, Side::Lower, &[0.5, 0.0], f64::NAN, 1.0);
        assert_eq!(c.unique_points(), 2);
    }

    #[test]
    fn selection_serves_every_output_widest_time_first_within_the_budget() {
        let mut c = CheckCandidates::new(1);
        // Output 0: widest at record 2 (point 0.9); output 1: widest at record 0 (point −0.3).
        c.add(0, 0, Side::Upper, &[0.1], 1.0, 0.1);
        c.add(2, 0, Side::Upper, &[0.9], 1.0, 5.0);
        c.add(0, 1, Side::Upper, &[-0.3], 1.0, 3.0);
        c.add(1, 1, Side::Upper, &[0.5], 1.0, 1.0);
        let plan = c.select(2);
        assert_eq!(plan.points, vec![0.9, -0.3]);
        assert_eq!(plan.unique_candidates, 4);
        assert_eq!(plan.checks[0], vec![(2, 0, Side::Upper, 1.0)]);
        let all = c.select(10);
        assert_eq!(
            all.points.len(),
            4,
            "the budget is capped by the candidates"
        );
    }

    #[test]
    fn overshoots_are_the_predictions_furthest_past_the_runs_on_each_side() {
        let mut c = CheckCandidates::new(1);
        // Output 0's maximum: 0.5 past the runs at record 1 (point 0.7), 0.2 at record 0.
        c.add(0, 0, Side::Upper, &[0.1], 1.2, 5.0);
        c.add(1, 0, Side::Upper, &[0.7], 1.5, 1.0);
        // Its minimum: inside the runs (no overshoot).
        c.add(1, 0, Side::Lower, &[-0.4], 0.5, 1.0);
        // Output 1: 0.05 past the runs, under the smallest overshoot worth a run.
        c.add(0, 1, Side::Upper, &[-0.9], 1.05, 1.0);
        let hull = |_: usize, _: usize| (0.0, 1.0);
        let plan = c.select_overshoots(&[0, 1], &hull, &[0.1, 0.1], &[]);
        assert_eq!(plan.points, vec![0.7]);
        assert_eq!(plan.checks[0], vec![(1, 0, Side::Upper, 1.5)]);
        // A point already run is not run again: the next furthest is.
        let plan = c.select_overshoots(&[0, 1], &hull, &[0.1, 0.1], &[0.7]);
        assert_eq!(plan.points, vec![0.1]);
        // Outputs not asked for are not looked at.
        assert!(c
            .select_overshoots(&[1], &hull, &[0.1, 0.1], &[])
            .points
            .is_empty());
        // In an element's check the overshoot comes first, then the widest records round-robin
        // (output 0's minimum first).
        let plan = c.select_with_overshoots(2, &[0], &hull, &[0.1, 0.1]);
        assert_eq!(plan.points, vec![0.7, -0.4]);
        assert_eq!(
            c.select_with_overshoots(1, &[0], &hull, &[0.1, 0.1]).points,
            vec![0.7]
        );
        assert_eq!(
            c.select_with_overshoots(2, &[], &hull, &[0.1, 0.1]).points,
            c.select(2).points,
            "without outputs to look at, the selection is the plain one"
        );
    }

    /// Four predictions in one dimension, output 0: the maximum at records 3 (width 9), 2 (4) and
    /// 1 (2), the minimum at record 2 (4).
    fn candidates_around_record_2() -> CheckCandidates {
        let mut c = CheckCandidates::new(1);
        c.add(3, 0, Side::Upper, &[0.9], 2.0, 9.0);
        c.add(2, 0, Side::Upper, &[0.5], 1.5, 4.0);
        c.add(1, 0, Side::Upper, &[0.2], 1.0, 2.0);
        c.add(2, 0, Side::Lower, &[-0.5], -1.5, 4.0);
        c
    }

    #[test]
    fn the_horizon_selection_aims_at_records_up_to_its_limit_and_skips_what_ran() {
        // Output 0: its widest record (3) is after the limit; records 1 and 2 are within it.
        let mut c = candidates_around_record_2();
        assert_eq!(c.select(1).points, vec![-0.5]);
        // Up to record 2, widest first per side: the maximum at record 2, the minimum there.
        let plan = c.select_until(2, 2, &[]);
        assert_eq!(plan.points, vec![-0.5, 0.5]);
        // A point already run is not run again: the next widest up to the limit is.
        assert_eq!(c.select_until(2, 1, &[0.5, -0.5]).points, vec![0.2]);
        // Nothing up to record 0.
        assert!(c.select_until(0, 4, &[]).points.is_empty());
        // Every prediction at a chosen point is checked, whatever its record.
        c.add(3, 1, Side::Lower, &[0.2], -3.0, 1.0);
        let plan = c.select_until(1, 1, &[]);
        assert_eq!(
            plan.checks[0],
            vec![(1, 0, Side::Upper, 1.0), (3, 1, Side::Lower, -3.0)]
        );
    }

    #[test]
    fn a_confirmation_runs_what_a_shorter_study_would_check_first_less_what_ran() {
        let c = candidates_around_record_2();
        // A study ending at record 2 with two check runs would run the two widest there.
        assert_eq!(c.first_check_until(2, 2, &[]).points, vec![-0.5, 0.5]);
        // One of them already ran: only the other, not the next widest in its place (the
        // horizon's own rounds go deeper: select_until).
        assert_eq!(c.first_check_until(2, 2, &[0.5]).points, vec![-0.5]);
        assert_eq!(c.select_until(2, 2, &[0.5]).points, vec![-0.5, 0.2]);
        assert!(c.first_check_until(2, 2, &[0.5, -0.5]).points.is_empty());
    }

    #[test]
    fn a_verified_horizon_is_named_with_the_runs_that_verified_it() {
        let times: Vec<f64> = (0..=10).map(|k| 0.05 * f64::from(k)).collect();
        let mut check = untrusted_check(Some(6), 2, Some(3));
        check.horizon = Some(super::super::report::HorizonCheck {
            rounds: 2,
            runs: 12,
            verified_until_record: Some(3),
        });
        let advice = untrusted_advice(&check, &times, 38, None, &[], Method::LegendreScan);
        assert_eq!(
            advice,
            "judged against the whole run's envelope widths, the first miss is at t = 0.3 s (the 2 \
             checks at earlier times agreed); checks aimed \
             at the times up to t = 0.15 s agree with the surrogate (12 more runs in 2 rounds): its \
             envelopes up to then pass the trust test; shorten --duration to 0.15 s, raise \
             --order, narrow the box, or use --method monte-carlo (a scan is out of reach at d = \
             38)"
        );
        // Rounds that confirmed no aim: the prefix as before, to be checked again.
        check.horizon = Some(super::super::report::HorizonCheck {
            rounds: 6,
            runs: 40,
            verified_until_record: None,
        });
        let advice = untrusted_advice(&check, &times, 38, None, &[], Method::LegendreScan);
        assert!(
            advice.contains("the checks pass up to t = 0.15 s")
                && advice.contains("shorten --duration to 0.15 s and check again"),
            "{advice}"
        );
    }

    #[test]
    fn automatic_budget_has_a_floor_and_grows_with_the_design() {
        assert_eq!(automatic_check_runs(25), MIN_CHECK_RUNS);
        assert_eq!(automatic_check_runs(1891), 190);
    }
}
