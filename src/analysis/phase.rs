//! What every phase of a study runs on: a [`PhaseContext`] (the study's model, scene, box and
//! options, its threads, the interrupt flag, the report the phases add to, the progress callback)
//! and the one loop that drives a phase's runs block by block over the horizon
//! ([`PhaseContext::run_source`]), applying its [`FailurePolicy`] after every block and handing
//! the block's records to the phase ([`OnBlock`]).
//!
//! ```text
//! run_stage:  the stage's records from where StageRecords says ─┐ (or simulated here:)
//!             (run_stage_beside: the same, into run_source_beside)
//! run_phase:  LockStep of the points (and the nominal run) ─────┴─▶ run_source:
//!             per block: advance ⇒ failure policy ⇒ on_block(block, report) ⇒ progress
//!             at the end: counters, contacts, exclusions and retries into the report
//! run_source_beside: per block: advance (joined with the last block's work) ⇒ failure policy
//!             ⇒ take(block, report): the work on the block ⇒ progress; after the last block,
//!             its work
//! ```
//!
//! A phase (`screening_phase.rs`, `adaptive_phase.rs`, `design_phase.rs`, `check_phase.rs`,
//! `reference.rs`) is a function of a context and what it is given; it does not know the phases
//! before or after it. Does not: decide what a phase runs, or what it does with the records.

use super::engine::{BlockOutcome, LockStep, RecordSource};
use super::error::StudyError;
use super::method::Method;
use super::report::{Progress, SampleRetry, StudyReport};
use super::schedule::RecordSchedule;
use super::stages::StageCursor;
use super::study_plan::StudyOptions;
use crate::effects::ContactStats;
use crate::environment::Environment;
use crate::model::Model;
use crate::scene::Scene;
use crate::simulate::{hht_settings, RobotSystem};
use crate::uncertainty::ParameterSpace;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What every phase of one study run shares: the study (model, scene, box, options) and the run
/// (threads, interrupt, start time, the report the phases add to, the progress callback).
pub(super) struct PhaseContext<'a> {
    /// The nominal model: every run's template.
    pub model: &'a Model,
    /// The scene's environment: every run's template.
    pub environment: &'a Environment,
    /// The scene.
    pub scene: &'a Scene,
    /// The interval parameters.
    pub space: &'a ParameterSpace,
    /// The study's options.
    pub options: &'a StudyOptions,
    /// The study's worker threads.
    pub threads: &'a rayon::ThreadPool,
    /// Set on SIGINT/SIGTERM: a phase stops before its next block (and the lock-step engine before
    /// its next step).
    pub interrupt: &'a AtomicBool,
    /// When the study started (progress reports the elapsed seconds).
    pub started: Instant,
    /// The report the phases add to (runs' counters, timings, exclusions, `partial`).
    pub report: &'a mut StudyReport,
    /// Called after every block with how far the phase is.
    pub progress: &'a mut dyn FnMut(Progress),
}

/// What a phase does with each block of records: `(block, report)`.
pub(super) type OnBlock<'a> =
    dyn FnMut(&PhaseBlock, &mut StudyReport) -> Result<(), StudyError> + 'a;

/// What [`PhaseContext::run_source_beside`] does with each block first: `(block, report)` to the
/// work on it that needs neither (`None`: no work).
pub(super) type TakeBlock<'a, T> =
    dyn FnMut(&PhaseBlock, &mut StudyReport) -> Result<Option<T>, StudyError> + 'a;

/// The work [`PhaseContext::run_source_beside`] runs beside the next block's simulation.
pub(super) type BlockWork<'a, T> = dyn FnMut(T) -> Result<(), StudyError> + Send + 'a;

/// Which runs of a phase may be left out when they fail, and what to tell the user.
#[derive(Clone, Copy)]
pub(super) struct FailurePolicy {
    /// Samples may be excluded (`keep_going` and a method that tolerates it).
    pub can_exclude: bool,
    /// The hint when a sample's failure stops the study.
    pub hint: &'static str,
    /// How messages name the runs of this phase ("sample", "check run").
    pub noun: &'static str,
}

/// Per record of one block of one phase: the samples' values.
pub(super) struct PhaseBlock<'b> {
    /// The block's first record.
    pub first: usize,
    /// Records in the block.
    pub count: usize,
    /// The phase's samples.
    pub lockstep: &'b dyn RecordSource,
}

impl PhaseBlock<'_> {
    /// Record `r` of the block for sample `i` (`dim outputs`).
    pub fn record(&self, i: usize, r: usize) -> &[f64] {
        self.lockstep.record(i, r)
    }
}

impl<'a> PhaseContext<'a> {
    /// The failure policy of the design's runs: only `scan` and `monte-carlo` may leave a failing
    /// sample out (a fit needs every design point).
    pub fn design_failure_policy(&self, method: Method) -> FailurePolicy {
        let keep_going = self.options.keep_going;
        let can_exclude = keep_going && matches!(method, Method::Scan | Method::MonteCarlo);
        FailurePolicy {
            can_exclude,
            hint: if keep_going && !can_exclude {
                "--keep-going cannot help this method: its fit needs every design point; use --method scan or monte-carlo, or narrow the box"
            } else {
                "Use --keep-going to exclude failing samples (scan and monte-carlo), or narrow the box"
            },
            noun: "sample",
        }
    }

    /// The failure policy of a phase of true-model runs that any run may be left out of (with
    /// `--keep-going`): `noun` names its runs in messages.
    pub fn exclusion_policy(&self, noun: &'static str) -> FailurePolicy {
        FailurePolicy {
            can_exclude: self.options.keep_going,
            hint: "The box contains a point where the model cannot be simulated; use --keep-going to exclude it (it is listed in the summary), or narrow the box",
            noun,
        }
    }

    /// The lock-step simulation of `points` (row-major `n × d`) and, when given, the nominal run
    /// after them, with the study's model, scene and box.
    pub fn lockstep(&self, points: &[f64], nominal_xi: Option<&[f64]>) -> LockStep<'a> {
        lockstep(
            self.model,
            self.environment,
            self.scene,
            self.space,
            points,
            nominal_xi,
        )
    }

    /// [`PhaseContext::run_phase`] of the next stage: its records read from where `stages` says,
    /// or simulated here.
    pub fn run_stage(
        &mut self,
        stages: &mut StageCursor,
        phase: &'static str,
        points: &[f64],
        nominal_xi: Option<&[f64]>,
        policy: FailurePolicy,
        on_block: &mut OnBlock<'_>,
    ) -> Result<bool, StudyError> {
        self.run_stage_beside(
            stages,
            phase,
            points,
            nominal_xi,
            policy,
            &mut |block, report| on_block(block, report).map(|()| None::<()>),
            &mut |()| Ok(()),
        )
    }

    /// [`PhaseContext::run_source_beside`] of the next stage: its records read from where
    /// `stages` says, or simulated here.
    #[allow(clippy::too_many_arguments)]
    pub fn run_stage_beside<T: Send>(
        &mut self,
        stages: &mut StageCursor,
        phase: &'static str,
        points: &[f64],
        nominal_xi: Option<&[f64]>,
        policy: FailurePolicy,
        take: &mut TakeBlock<'_, T>,
        work: &mut BlockWork<'_, T>,
    ) -> Result<bool, StudyError> {
        match stages.source(phase, points, nominal_xi.is_some())? {
            Some(mut source) => self.run_source_beside(phase, &mut *source, policy, take, work),
            None => {
                let mut lockstep = self.lockstep(points, nominal_xi);
                self.run_source_beside(phase, &mut lockstep, policy, take, work)
            }
        }
    }

    /// Simulates `points` (and the nominal run when given) in lock-step over the whole horizon,
    /// calling `on_block` after each block. Returns whether the phase ran to the end (false when
    /// interrupted: `report.partial` is then set).
    pub fn run_phase(
        &mut self,
        phase: &'static str,
        points: &[f64],
        nominal_xi: Option<&[f64]>,
        policy: FailurePolicy,
        on_block: &mut OnBlock<'_>,
    ) -> Result<bool, StudyError> {
        let mut lockstep = self.lockstep(points, nominal_xi);
        self.run_source(phase, &mut lockstep, policy, on_block)
    }

    /// [`PhaseContext::run_phase`] over any source of recorded values: block by block over the
    /// horizon, the failure policy applied after each block, then `on_block`.
    pub fn run_source(
        &mut self,
        phase: &'static str,
        lockstep: &mut dyn RecordSource,
        policy: FailurePolicy,
        on_block: &mut OnBlock<'_>,
    ) -> Result<bool, StudyError> {
        self.run_source_beside(
            phase,
            lockstep,
            policy,
            &mut |block, report| on_block(block, report).map(|()| None::<()>),
            &mut |()| Ok(()),
        )
    }

    /// [`PhaseContext::run_source`] whose `take` may hand back work on a block's records (taken
    /// out of the source, which the next block overwrites) that needs neither the source nor the
    /// report: `work` does it on the same threads while the next block is simulated, or after the
    /// last block. The blocks' work runs in their order, each after the `take` of its block and
    /// before the `take` of the next, so what it computes does not depend on the overlap; the
    /// wall seconds of work beside a simulation go to `report.beside_simulation_seconds`.
    pub fn run_source_beside<T: Send>(
        &mut self,
        phase: &'static str,
        lockstep: &mut dyn RecordSource,
        policy: FailurePolicy,
        take: &mut TakeBlock<'_, T>,
        work: &mut BlockWork<'_, T>,
    ) -> Result<bool, StudyError> {
        let (threads, interrupt, started) = (self.threads, self.interrupt, self.started);
        let report = &mut *self.report;
        let progress = &mut *self.progress;
        let scene = self.scene;
        let runs = lockstep.len();
        let n_outputs = scene.outputs.len();
        let schedule = RecordSchedule::of(scene);
        let n_records = schedule.len();
        let block_records = schedule.block_records(runs, n_outputs);
        let mut first = 0;
        let mut complete = true;
        let mut pending: Option<T> = None;
        while first < n_records {
            if interrupt.load(Ordering::SeqCst) {
                complete = false;
                break;
            }
            let count = block_records.min(n_records - first);
            let t_simulate = Instant::now();
            let (outcome, simulate_seconds) = match pending.take() {
                None => {
                    let outcome = lockstep.advance(first, count, threads, interrupt)?;
                    (outcome, t_simulate.elapsed().as_secs_f64())
                }
                Some(job) => {
                    let source = &mut *lockstep;
                    let ((outcome, simulate_seconds), (worked, work_seconds)) =
                        threads.install(|| {
                            rayon::join(
                                || {
                                    let outcome = source.advance(first, count, threads, interrupt);
                                    (outcome, t_simulate.elapsed().as_secs_f64())
                                },
                                || (work(job), t_simulate.elapsed().as_secs_f64()),
                            )
                        });
                    report.beside_simulation_seconds += work_seconds.min(simulate_seconds);
                    worked?;
                    (outcome?, simulate_seconds)
                }
            };
            report.simulate_seconds += simulate_seconds;
            if outcome == BlockOutcome::Interrupted {
                complete = false;
                break;
            }
            let failures = lockstep.failures();
            let nominal = lockstep.nominal_index();
            if let Some(failure) = failures
                .iter()
                .find(|f| Some(f.index) == nominal || !policy.can_exclude)
            {
                let (run, hint) = if Some(failure.index) == nominal {
                    (
                        "the nominal run".to_string(),
                        "The nominal run must succeed; check the scene and the URDF values",
                    )
                } else {
                    let total = runs - usize::from(nominal.is_some());
                    (
                        format!("{} {} of {total}", policy.noun, failure.index + 1),
                        policy.hint,
                    )
                };
                return Err(StudyError::SampleFailed {
                    run,
                    failure: Box::new(failure.clone()),
                    hint,
                });
            }
            pending = take(
                &PhaseBlock {
                    first,
                    count,
                    lockstep: &*lockstep,
                },
                report,
            )?;
            first += count;
            progress(Progress {
                phase,
                records_done: first,
                records_total: n_records,
                runs,
                elapsed_s: started.elapsed().as_secs_f64(),
            });
        }
        if let Some(job) = pending {
            work(job)?;
        }
        let (newton_iterations, steps) = lockstep.counters();
        report.newton_iterations += newton_iterations;
        report.steps += steps;
        if let Some(counters) = lockstep.contact_counters() {
            report
                .contacts
                .get_or_insert_with(ContactStats::default)
                .merge(&counters);
        }
        report.excluded.extend(lockstep.failures());
        let nominal = lockstep.nominal_index();
        let samples = runs - usize::from(nominal.is_some());
        report
            .retried
            .extend(
                lockstep
                    .retries()
                    .into_iter()
                    .map(|fixed_step_failure| SampleRetry {
                        phase,
                        run: if Some(fixed_step_failure.index) == nominal {
                            "the nominal run".to_string()
                        } else {
                            format!(
                                "{} {} of {samples}",
                                policy.noun,
                                fixed_step_failure.index + 1
                            )
                        },
                        fixed_step_failure,
                    }),
            );
        if !complete {
            report.partial = true;
        }
        Ok(complete)
    }
}

/// The lock-step simulation of `points` (row-major `n × d`) and, when given, the nominal run
/// after them, with `model` in `environment` (the template of every run), `scene` and the box
/// `space`.
pub(super) fn lockstep<'a>(
    model: &Model,
    environment: &Environment,
    scene: &'a Scene,
    space: &'a ParameterSpace,
    points: &[f64],
    nominal_xi: Option<&[f64]>,
) -> LockStep<'a> {
    let template = RobotSystem::new(model.clone(), *environment, scene);
    LockStep::new(
        template,
        space,
        scene,
        hht_settings(scene),
        points,
        nominal_xi,
    )
}
