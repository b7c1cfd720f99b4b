//! The horizon check of an untrusted study (docs/method.md §7, "What to do about a miss"). A
//! study whose surrogate the check does not trust over the whole horizon often passes the same
//! checks up to an earlier record `X` (the prefix test of [`super::check_phase::judge`]) — but
//! those checks were aimed at each output's widest records, mostly after `X`, so the earlier
//! records were judged by runs that happened to land there. This phase aims checks at them:
//! the predicted extremes at the widest records up to `X` that no check has run
//! ([`CheckCandidates::select_until`]). When the prefix test with every check's misfits still
//! passes at `X` — and again after the points the first check of a study ending at `X` would
//! run ([`CheckCandidates::first_check_until`]): such a study has the same surrogates up to `X`
//! when its design does not depend on the duration, and then finds no misfit this one has not
//! judged — the envelopes up to `X` rest on checks aimed there and `X` is *verified*;
//! otherwise `X` moves back to where the prefix test now passes and the next round aims there,
//! up to [`HORIZON_MAX_ROUNDS`] rounds. A round with nothing left to aim at (every prediction up
//! to `X` already ran) goes straight to the confirmation.
//!
//! ```text
//! X = passes_until ─▶ select_until(X) ─▶ check runs (widen, misfits) ─▶ judge ─┬ fails at X ──┐
//!                                                                              └ passes at X  │
//!     first_check_until(X) ─▶ check runs ─▶ judge ─┬ passes at X: verified          ▼         │
//!                                                  └ fails at X ─▶ X = min(passes_until,      │
//!                                                      BACKOFF · X), the next round ◀─────────┘
//!                                                      (at most HORIZON_MAX_ROUNDS rounds)
//! ```
//!
//! The predictions are those of the study's surrogates: the root's, or, after element rounds,
//! every leaf's (the study's envelope is their union; the budget is shared among them). Each run
//! widens the envelopes like any check run. Does not: choose the first check's points
//! (`check.rs`) or word the advice (`check.rs`: [`super::untrusted_advice`]).

use super::accumulator::Accumulator;
use super::check::{CheckCandidates, CheckPlan};
use super::check_phase::{check, judge, prefix_verdicts, CheckOutcome, CheckRuns};
use super::error::StudyError;
use super::phase::PhaseContext;
use super::report::{CheckReport, HorizonCheck};

/// Most rounds of the horizon check: each moves the aim back to where the prefix test passes
/// with the new misfits, and a fall that separates fast needs several (a limp iiwa falling from
/// upright over 1 s: four, to 0.24 s, docs/method.md §7).
pub const HORIZON_MAX_ROUNDS: usize = 6;

/// After a round that did not confirm its aim, the next aims at most this share of the way to it
/// (or where the prefix test passes, if earlier): a surrogate that misses just past each aim
/// would otherwise be walked back one record per round (measured with rounds of 4 runs on the
/// double pendulum from upright: 1.38, 1.36, 1.34, 1.32 … s). At 0.9 the same pendulum's 3 s
/// study without elements aimed at 2.24, 2.0, 1.8, 1.54, 1.34 and 1.2 s and confirmed none; at
/// 0.8 it aims at 2.24, 1.78, 1.42 and 1.12 s and confirms 1.12 s (a 1.12 s study is trusted).
pub const HORIZON_BACKOFF: f64 = 0.8;

/// All rounds together run at most this many times the runs of the study's checks before them
/// (the first check's, the overshoot check's and the elements' checks): a round aims at every
/// untrusted surrogate's records up to its aim about as densely as those checks aimed at theirs.
pub const HORIZON_RUNS_PER_CHECK_RUN: usize = 2;

/// The horizon check of a study with one surrogate (no elements: `--elements off`, or a method
/// other than legendre-scan) whose check did not trust it: [`verify_horizon`] with that
/// surrogate's predictions (`candidates`) after the check `outcome`. Returns the verdict (the
/// check's own when it trusted every output or did not finish).
pub(super) fn verify_horizon_of_one_surrogate(
    context: &mut PhaseContext<'_>,
    candidates: &CheckCandidates,
    outcome: CheckOutcome,
    accumulator: &mut Accumulator,
) -> Result<CheckReport, StudyError> {
    let CheckOutcome { report, mut misfit } = outcome;
    if report.untrusted_outputs.is_empty() || !report.complete || context.report.partial {
        return Ok(report);
    }
    let mut runs = CheckRuns::of(&report);
    verify_horizon(
        context,
        &[candidates],
        report.runs,
        &mut runs,
        &mut misfit,
        accumulator,
        report,
    )
}

/// Runs the horizon check of `verdict` (the study's verdict after its checks, `runs` and `misfit`
/// behind it) with the predictions of `candidates` (each surrogate's): each round's probes at
/// most an even share of [`HORIZON_RUNS_PER_CHECK_RUN`] times the runs of those checks; a round
/// whose probes pass at its aim then runs the points a study ending there would check first
/// with `first_check_runs` runs (those not run yet, within what is left of the budget), and the
/// aim is verified when the prefix test still passes there. The runs join `runs`, their misfits
/// `misfit`, and every run widens `accumulator`. Returns the verdict with every check's misfits
/// and [`CheckReport::horizon`] set (the verdict unchanged when no round ran).
pub(super) fn verify_horizon(
    context: &mut PhaseContext<'_>,
    candidates: &[&CheckCandidates],
    first_check_runs: usize,
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
    // All rounds within HORIZON_RUNS_PER_CHECK_RUN times the checks so far, each round's
    // probes within an even share of it.
    let budget = HORIZON_RUNS_PER_CHECK_RUN * runs.runs;
    let round_runs = budget.div_ceil(HORIZON_MAX_ROUNDS);
    let mut previous_aim: Option<usize> = None;
    for _ in 0..HORIZON_MAX_ROUNDS {
        if verdict.untrusted_outputs.is_empty() {
            break;
        }
        // The last record where the prefix test passes now (what a study ending there would
        // be judged by), after a round that did not confirm its aim at least a step of
        // HORIZON_BACKOFF back from it.
        let cap = previous_aim.map_or(last_record, |previous| {
            (HORIZON_BACKOFF * previous as f64) as usize
        });
        let verdicts = prefix_verdicts(context.scene, misfit, accumulator);
        let Some(aim) = verdicts[..=cap.min(last_record)]
            .iter()
            .rposition(|&passes| passes)
        else {
            break;
        };
        if aim == 0 || aim >= last_record {
            break;
        }
        previous_aim = Some(aim);
        let plan = combine(
            candidates,
            round_runs.min(budget.saturating_sub(horizon.runs)),
            &|surrogate, share| surrogate.select_until(aim, share, &runs.points),
        );
        // No probe left means every prediction up to the aim has been run already: the aim
        // then rests on those runs, and the confirmation below decides.
        let probed = !plan.points.is_empty();
        if probed {
            horizon.rounds += 1;
            let complete;
            (verdict, complete) =
                run_plan(context, &plan, runs, misfit, accumulator, &mut horizon)?;
            if !complete {
                break;
            }
            if !passes_at(context, misfit, accumulator, aim) {
                continue;
            }
        }
        // Confirmed by this round's probes: then the points a study ending at the aim would
        // check first, so that such a study (the same surrogates up to there) finds no misfit
        // this one has not judged.
        let confirmation_runs = first_check_runs.min(budget.saturating_sub(horizon.runs));
        let confirmation = combine(candidates, confirmation_runs, &|surrogate, share| {
            surrogate.first_check_until(aim, share, &runs.points)
        });
        if !confirmation.points.is_empty() {
            if !probed {
                horizon.rounds += 1;
            }
            let complete;
            (verdict, complete) = run_plan(
                context,
                &confirmation,
                runs,
                misfit,
                accumulator,
                &mut horizon,
            )?;
            if !complete {
                break;
            }
        }
        if passes_at(context, misfit, accumulator, aim) {
            horizon.verified_until_record = Some(aim);
            break;
        }
    }
    if horizon.rounds > 0 || horizon.verified_until_record.is_some() {
        verdict.horizon = Some(horizon);
    }
    Ok(verdict)
}

/// Whether the trust test of a run that ended at `record` passes with the study's `misfit[o][r]`
/// against the envelopes in `accumulator` (the prefix test at that record, not the last record
/// it passes at: a fast-widening envelope can pass again after a miss).
fn passes_at(
    context: &PhaseContext<'_>,
    misfit: &[Vec<f64>],
    accumulator: &Accumulator,
    record: usize,
) -> bool {
    prefix_verdicts(context.scene, misfit, accumulator)
        .get(record)
        .copied()
        .unwrap_or(false)
}

/// Runs the points of `plan`: the runs join `runs` and `horizon.runs`, their misfits
/// `misfit[o][r]` (the larger of each), every run widens `accumulator`. Returns the study's
/// verdict with them, and whether the runs covered the whole horizon.
fn run_plan(
    context: &mut PhaseContext<'_>,
    plan: &CheckPlan,
    runs: &mut CheckRuns,
    misfit: &mut [Vec<f64>],
    accumulator: &mut Accumulator,
    horizon: &mut HorizonCheck,
) -> Result<(CheckReport, bool), StudyError> {
    let outcome = check(context, plan, accumulator)?;
    horizon.runs += outcome.report.runs;
    for (worst, found) in misfit.iter_mut().zip(&outcome.misfit) {
        for (w, &m) in worst.iter_mut().zip(found) {
            *w = w.max(m);
        }
    }
    runs.absorb(&outcome.report);
    let verdict = judge(context.scene, runs.clone(), misfit, accumulator);
    Ok((verdict, outcome.report.complete))
}

/// One plan of a horizon round over the study's surrogates (`candidates`: the root's, or every
/// leaf's of an element tree, whose envelopes the study's is the union of): each surrogate's
/// share of `budget` runs, chosen by `select(surrogate, share)`. The shares differ by at most
/// one run.
fn combine(
    candidates: &[&CheckCandidates],
    budget: usize,
    select: &dyn Fn(&CheckCandidates, usize) -> CheckPlan,
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
        let part = select(surrogate, share);
        plan.points.extend(part.points);
        plan.checks.extend(part.checks);
        plan.unique_candidates += part.unique_candidates;
    }
    plan
}
