//! The horizon check of an untrusted study (docs/method.md §7, "What to do about a miss"). A
//! study whose surrogate the check does not trust over the whole horizon often passes the same
//! checks up to an earlier record `X` (the prefix test of [`super::check_phase::judge`]) — but
//! those checks were aimed at each output's widest records, mostly after `X`, so the earlier
//! records were judged by runs that happened to land there. This phase aims checks at them:
//! the predicted extremes at the widest records up to `X` that no check has run
//! ([`CheckCandidates::select_until`]). When the prefix test with every check's misfits still
//! passes at `X`, the envelopes up to `X` rest on checks aimed there and `X` is *verified*;
//! otherwise `X` moves back to where the prefix test now passes and the next round aims there,
//! up to [`HORIZON_MAX_ROUNDS`] rounds.
//!
//! ```text
//! X = passes_until ─▶ select_until(X) ─▶ check runs (widen, misfits) ─▶ judge ─┬ passes at X: verified
//!        ▲                                                                     └ else X = passes_until
//!        └──────────────────────────── (at most HORIZON_MAX_ROUNDS rounds) ────┘
//! ```
//!
//! The predictions are those of the study's surrogates: the root's, or, after element rounds,
//! every leaf's (the study's envelope is their union; the budget is shared among them). Each run
//! widens the envelopes like any check run. Does not: choose the first check's points
//! (`check.rs`) or word the advice (`check.rs`: [`super::untrusted_advice`]).

use super::accumulator::Accumulator;
use super::check::{CheckCandidates, CheckPlan};
use super::check_phase::{check, judge, CheckRuns};
use super::error::StudyError;
use super::phase::PhaseContext;
use super::report::{CheckReport, HorizonCheck};

/// Most rounds of the horizon check: each moves the aim back to where the prefix test passes
/// with the new misfits, and a fall that separates fast needs several (a limp iiwa falling from
/// upright over 1 s: six, 0.65 → 0.57 → 0.46 → 0.36 → 0.30 → 0.26 s, docs/method.md §7).
pub const HORIZON_MAX_ROUNDS: usize = 6;

/// After a round that did not confirm its aim, the next aims at most this share of the way to it
/// (or where the prefix test passes, if earlier): a surrogate that misses just past each aim
/// would otherwise be walked back one record per round (measured with rounds of 4 runs on the
/// double pendulum from upright: 1.38, 1.36, 1.34, 1.32 … s).
pub const HORIZON_BACKOFF: f64 = 0.9;

/// All rounds together run at most this many times the runs of the study's checks before them
/// (the first check's, the overshoot check's and the elements' checks): a round aims at every
/// untrusted surrogate's records up to its aim about as densely as those checks aimed at theirs.
pub const HORIZON_RUNS_PER_CHECK_RUN: usize = 2;

/// Runs the horizon check of `verdict` (the study's verdict after its checks, `runs` and `misfit`
/// behind it) with the predictions of `candidates` (each surrogate's), each round at most
/// `round_runs` runs; the runs join `runs`, their misfits `misfit`, and every run widens
/// `accumulator`. Returns the verdict with every check's misfits and [`CheckReport::horizon`] set
/// (the verdict unchanged when no round ran).
pub(super) fn verify_horizon(
    context: &mut PhaseContext<'_>,
    candidates: &[&CheckCandidates],
    round_runs: usize,
    runs: &mut CheckRuns,
    misfit: &mut [Vec<f64>],
    accumulator: &mut Accumulator,
    mut verdict: CheckReport,
) -> Result<CheckReport, StudyError> {
    let last_record = accumulator.times.len().saturating_sub(1);
    let mut horizon = HorizonCheck {
        rounds: 0,
        runs: 0,
        verified_until_record: None,
    };
    let mut previous_aim: Option<usize> = None;
    for _ in 0..HORIZON_MAX_ROUNDS {
        if verdict.untrusted_outputs.is_empty() {
            break;
        }
        // Where the prefix test passes now, and after a round that did not confirm its aim at
        // least a step of HORIZON_BACKOFF back from it.
        let passes = verdict.passes_until_record;
        let aim = match (previous_aim, passes) {
            (Some(previous), Some(r)) => r.min((HORIZON_BACKOFF * previous as f64) as usize),
            (None, Some(r)) => r,
            (_, None) => break,
        };
        if aim == 0 || aim >= last_record {
            break;
        }
        previous_aim = Some(aim);
        let plan = select_until(candidates, aim, round_runs, &runs.points);
        if plan.points.is_empty() {
            break;
        }
        let outcome = check(context, &plan, accumulator)?;
        horizon.rounds += 1;
        horizon.runs += outcome.report.runs;
        for (worst, found) in misfit.iter_mut().zip(&outcome.misfit) {
            for (w, &m) in worst.iter_mut().zip(found) {
                *w = w.max(m);
            }
        }
        runs.absorb(&outcome.report);
        verdict = judge(context.scene, runs.clone(), misfit, accumulator);
        if !outcome.report.complete {
            break;
        }
        if verdict.passes_until_record.is_some_and(|r| r >= aim) {
            horizon.verified_until_record = Some(aim);
            break;
        }
    }
    if horizon.rounds > 0 {
        verdict.horizon = Some(horizon);
    }
    Ok(verdict)
}

/// The horizon check's runs of a round: from each surrogate's `candidates` (the root's, or every
/// leaf's of an element tree, whose envelopes the study's is the union of), its share of
/// `budget` runs aimed at the records up to `last_record` and not at the points `ran`
/// ([`CheckCandidates::select_until`]), in one plan. The shares differ by at most one run.
fn select_until(
    candidates: &[&CheckCandidates],
    last_record: usize,
    budget: usize,
    ran: &[f64],
) -> CheckPlan {
    let mut plan = CheckPlan {
        points: Vec::new(),
        checks: Vec::new(),
        unique_candidates: 0,
    };
    let n = candidates.len().max(1);
    for (k, surrogate) in candidates.iter().enumerate() {
        let share = budget / n + usize::from(k < budget % n);
        if share == 0 {
            continue;
        }
        let part = surrogate.select_until(last_record, share, ran);
        plan.points.extend(part.points);
        plan.checks.extend(part.checks);
        plan.unique_candidates += part.unique_candidates;
    }
    plan
}
