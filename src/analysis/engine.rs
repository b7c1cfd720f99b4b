//! Lock-step simulation of many samples: every sample advances through one block of record times,
//! then the next, so memory holds one block of records, never a whole trajectory per sample.
//!
//! A sample keeps only its trajectory state ([`HhtTrajectory`]: a few vectors of length nv); each
//! worker thread owns one [`RobotSystem`] (a model copy and its work buffers) and one integrator
//! workspace, writes the sample's parameter values into its model ([`ParameterSpace::apply`]), swaps
//! the sample's trajectory in, steps it through the block, and swaps it out. Each sample (or group)
//! is a job of its own, so that the threads end a block together: rayon's default splitting over
//! two threads left one thread alone with a long run of groups at the end of many blocks while the
//! other waited (the d = 72 study's two threads were busy 92 % of its wall, median of eight runs;
//! 94 % with a job per group). A thread's worker is made on its first job and kept in its own slot
//! (`ThreadWorkers`, never contended). The result of a sample does not depend on which thread ran
//! it, so studies are deterministic for any thread count.
//!
//! Scenes the batched step suits ([`BatchStepper::suits`]: no contacts, no reuse of the Newton
//! matrix) go in groups of four samples instead, each group through the block with one
//! [`BatchStepper`] per thread (the batched CRBA and RNEA, docs/batch.md §5; `engine/batched.rs`).
//! Every sample's steps are bitwise the per-sample path's, so nothing downstream can tell the two
//! apart ([`LockStep::disable_batching`] forces the per-sample path).
//!
//! Interruption: every sample checks the study's interrupt flag before each step, so a signal takes
//! effect after at most one step per worker thread, also inside a long block or a single long run.
//!
//! A sample whose step fails at the study's fixed step is re-run at once from t = 0 with the
//! adaptive step on the same record grid (`step_control = "adaptive"`, docs/step-control.md §3):
//! its records from the record the fixed step failed to reach on are the adaptive run's, and it
//! steps adaptively (per sample, in the scalar path) to the end of the horizon. The switch is at
//! that record, not at a block, so the records do not depend on how the horizon is cut into
//! blocks (a shard of `ribbon run` cuts it differently from `analyze`), and the retry depends on
//! the sample's parameters alone, so the results are the same for any thread count. The fixed
//! step's failure is kept as the sample's retry note ([`RecordSource::retries`]). A sample that
//! fails both ways fails with the fixed step's failure, as without the retry.

mod batched;

use super::error::StudyError;
use super::report::SampleFailure;
use super::schedule::RecordSchedule;
use crate::dynamics::batch::LANES;
use crate::effects::{ContactState, ContactStats};
use crate::integrate::{
    HhtIntegrator, HhtSettings, HhtState, HhtTrajectory, IntegrateError, ReportedVelocity,
    StepControl,
};
use crate::scene::Scene;
use crate::simulate::{
    BatchStepper, FailureContext, InitialOrientations, Recorder, RobotSystem, SimulationError,
};
use crate::uncertainty::ParameterSpace;
use nalgebra::DVector;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, TryLockError};

/// Where the recorded values of a phase's samples come from, one block of record times at a time:
/// simulated here ([`LockStep`]) or read from the record blocks of shards simulated elsewhere
/// (`crate::distributed`). A study's stages only see this interface, so that a merged study and a
/// single-machine one compute the same numbers from the same values in the same order.
pub trait RecordSource: Send + Sync {
    /// Number of samples (the nominal run included).
    fn len(&self) -> usize;

    /// Whether there are no samples.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of the nominal run among the samples, when the source has one.
    fn nominal_index(&self) -> Option<usize>;

    /// Makes the records `first..first + count` available ([`RecordSource::record`]).
    fn advance(
        &mut self,
        first: usize,
        count: usize,
        threads: &rayon::ThreadPool,
        interrupt: &AtomicBool,
    ) -> Result<BlockOutcome, StudyError>;

    /// Record `r` of the current block for sample `i` (`dim outputs`).
    fn record(&self, i: usize, r: usize) -> &[f64];

    /// The nominal run's configuration at record `r` of the current block (empty without one).
    fn nominal_positions(&self, r: usize) -> &[f64];

    /// Whether sample `i` failed at or before the current block's last record.
    fn failed(&self, i: usize) -> bool;

    /// Failures at or before the current block's last record, by sample index.
    fn failures(&self) -> Vec<SampleFailure>;

    /// Samples that failed at the fixed step at or before the current block's last record and
    /// were re-run with the adaptive step: the fixed step's failure of each, by sample index.
    fn retries(&self) -> Vec<SampleFailure> {
        Vec::new()
    }

    /// Total Newton iterations and steps of the samples' runs so far.
    fn counters(&self) -> (u64, u64);

    /// The contact counters of the samples' runs so far, summed (the deepest penetration: the
    /// largest); `None` when the scene declares no contacts or the source does not count them.
    fn contact_counters(&self) -> Option<ContactStats> {
        None
    }
}

/// One sample's carried state.
struct Sample {
    xi: Vec<f64>,
    trajectory: Option<HhtTrajectory>,
    initial: InitialOrientations,
    /// This block's records: `records × outputs`, record-major.
    block: Vec<f64>,
    /// This block's configurations (`records × nq`), kept for the nominal run only.
    positions: Option<Vec<f64>>,
    failure: Option<SampleFailure>,
    /// The fixed step's failure when the sample was re-run with the adaptive step (it then steps
    /// adaptively to the end).
    retry: Option<SampleFailure>,
    /// The sample's contact state (counters, touching pairs), swapped into the thread's system
    /// while the sample steps; `None` without contacts.
    contacts: Option<ContactState>,
}

impl Sample {
    /// Marks the sample (index `index` of the study) failed at `time_s`, heading for `record`.
    fn fail(
        &mut self,
        index: usize,
        space: &ParameterSpace,
        time_s: f64,
        record: usize,
        message: String,
    ) {
        self.failure = Some(self.failure_at(index, space, time_s, record, message));
    }

    /// The failure of this sample (index `index` of the study) at `time_s`, heading for `record`.
    fn failure_at(
        &self,
        index: usize,
        space: &ParameterSpace,
        time_s: f64,
        record: usize,
        message: String,
    ) -> SampleFailure {
        SampleFailure {
            index,
            xi: self.xi.clone(),
            values: space.values_at(&self.xi),
            time_s,
            record,
            message,
        }
    }

    /// The sample's Newton iterations and steps so far (0 before its start).
    fn counters(&self) -> (u64, u64) {
        self.trajectory
            .as_ref()
            .map_or((0, 0), |t| (t.stats.newton_iterations, t.stats.steps))
    }
}

/// How a call to [`LockStep::advance`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockOutcome {
    /// Every live sample reached the block's last record.
    Complete,
    /// The interrupt flag was raised: the block's records are incomplete and must not be used.
    Interrupted,
}

/// All samples of a study, advanced together.
pub struct LockStep<'a> {
    template: RobotSystem,
    space: &'a ParameterSpace,
    scene: &'a Scene,
    settings: HhtSettings,
    recorder: Recorder,
    samples: Vec<Sample>,
    /// Steps taken so far (the same for every live sample).
    step: usize,
    newton_iterations: u64,
    steps_taken: u64,
    /// Index of the nominal run among the samples, when there is one.
    nominal: Option<usize>,
    /// Step the samples in groups with the batched kernels ([`BatchStepper`]).
    batched: bool,
}

/// The adaptive step on the grid of `settings` that a sample failing at the fixed step is re-run
/// with: `step_control = "adaptive"` with the scene's tolerance and halvings, everything else
/// as the study steps. `None` when the study already steps adaptively (nothing to retry with).
fn retry_settings(settings: &HhtSettings) -> Option<HhtSettings> {
    (settings.step_control == StepControl::Fixed).then_some(HhtSettings {
        step_control: StepControl::Adaptive,
        ..*settings
    })
}

impl<'a> LockStep<'a> {
    /// Prepares the samples at `points` (row-major, `n × d`) and, when `nominal_xi` is given, the
    /// nominal run after them ([`LockStep::nominal_index`]), which also keeps its configurations.
    pub fn new(
        template: RobotSystem,
        space: &'a ParameterSpace,
        scene: &'a Scene,
        settings: HhtSettings,
        points: &[f64],
        nominal_xi: Option<&[f64]>,
    ) -> LockStep<'a> {
        let d = space.len().max(1);
        let contacts = template.effects.fresh_contact_state();
        let mut samples: Vec<Sample> = points
            .chunks_exact(d)
            .map(|xi| Sample {
                xi: xi.to_vec(),
                trajectory: None,
                initial: Vec::new(),
                block: Vec::new(),
                positions: None,
                failure: None,
                retry: None,
                contacts: contacts.clone(),
            })
            .collect();
        let nominal = nominal_xi.map(|xi| {
            samples.push(Sample {
                xi: xi.to_vec(),
                trajectory: None,
                initial: Vec::new(),
                block: Vec::new(),
                positions: Some(Vec::new()),
                failure: None,
                retry: None,
                contacts: contacts.clone(),
            });
            samples.len() - 1
        });
        let batched = BatchStepper::suits(&template, &settings);
        LockStep {
            batched,
            template,
            space,
            scene,
            settings,
            recorder: Recorder::for_study(&scene.outputs),
            samples,
            step: 0,
            newton_iterations: 0,
            steps_taken: 0,
            nominal,
        }
    }

    /// Whether the samples are stepped in groups with the batched kernels (docs/batch.md §5): on
    /// when the scene suits it ([`BatchStepper::suits`]), off otherwise.
    pub fn batched(&self) -> bool {
        self.batched
    }

    /// Steps every sample alone with the scalar integrator, even where the batched kernels would
    /// apply. The results are bitwise the same either way (`tests/batch_step.rs` compares them);
    /// this is the reference the batched path is tested against.
    pub fn disable_batching(&mut self) {
        self.batched = false;
    }

    /// Number of samples (the nominal run included).
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Index of the nominal run, when the lock-step has one.
    pub fn nominal_index(&self) -> Option<usize> {
        self.nominal
    }

    /// Total Newton iterations and steps so far (all samples).
    pub fn counters(&self) -> (u64, u64) {
        (self.newton_iterations, self.steps_taken)
    }

    /// The contact counters of all samples so far, merged ([`ContactStats::merge`]); `None`
    /// without contacts.
    pub fn contact_counters(&self) -> Option<ContactStats> {
        let mut states = self.samples.iter().filter_map(|s| s.contacts.as_ref());
        let mut total = states.next()?.stats();
        for state in states {
            total.merge(&state.stats());
        }
        Some(total)
    }

    /// Failures so far, by sample index.
    pub fn failures(&self) -> Vec<SampleFailure> {
        self.samples
            .iter()
            .filter_map(|s| s.failure.clone())
            .collect()
    }

    /// Whether sample `i` has failed.
    pub fn failed(&self, i: usize) -> bool {
        self.samples[i].failure.is_some()
    }

    /// Samples re-run with the adaptive step so far: the fixed step's failure of each, by sample
    /// index ([`RecordSource::retries`]).
    pub fn retries(&self) -> Vec<SampleFailure> {
        self.samples
            .iter()
            .filter_map(|s| s.retry.clone())
            .collect()
    }

    /// Simulates every live sample through the records `first..first + count` (record `r` is at
    /// step `min(r · record_every, n_steps)`), filling each sample's block. Checks `interrupt`
    /// before every step; once it is set, the block is abandoned ([`BlockOutcome::Interrupted`])
    /// and the lock-step must not be advanced again.
    pub fn advance(
        &mut self,
        first_record: usize,
        count: usize,
        threads: &rayon::ThreadPool,
        interrupt: &AtomicBool,
    ) -> BlockOutcome {
        let context = SampleContext {
            template: &self.template,
            space: self.space,
            scene: self.scene,
            recorder: &self.recorder,
            settings: self.settings,
            retry_settings: retry_settings(&self.settings),
        };
        let schedule = RecordSchedule::of(self.scene);
        let record_step = |r: usize| schedule.step_of(r);
        let block = SampleBlock {
            start_step: self.step,
            first_record,
            count,
            record_from: first_record,
            record_step: &record_step,
            interrupt,
        };
        // One job per group (or sample), so that a thread that runs out of work takes a single
        // one from another's and the block's last jobs end together; each thread keeps one worker
        // for the whole block (`ThreadWorkers`), since making one costs a model copy.
        let counters: Vec<(u64, u64)> = if self.batched {
            let workers = ThreadWorkers::new(threads);
            threads.install(|| {
                self.samples
                    .par_chunks_mut(LANES)
                    .enumerate()
                    .with_max_len(1)
                    .map(|(group_index, group)| {
                        workers.with(
                            || batched::GroupWorker::new(context.template),
                            |worker| {
                                worker.advance_group(group, group_index * LANES, &context, &block)
                            },
                        )
                    })
                    .collect()
            })
        } else {
            let workers = ThreadWorkers::new(threads);
            threads.install(|| {
                self.samples
                    .par_iter_mut()
                    .enumerate()
                    .with_max_len(1)
                    .map(|(index, sample)| {
                        if sample.failure.is_some() {
                            return (0, 0);
                        }
                        workers.with(
                            || SampleWorker::new(context.template),
                            |worker| worker.advance(sample, index, &context, &block),
                        )
                    })
                    .collect()
            })
        };
        self.finish_block(counters, first_record, count, interrupt, &record_step)
    }

    /// Adds a block's per-sample (or per-group) counters and moves the lock-step to the block's
    /// last record, unless the block was interrupted.
    fn finish_block(
        &mut self,
        counters: Vec<(u64, u64)>,
        first_record: usize,
        count: usize,
        interrupt: &AtomicBool,
        record_step: &dyn Fn(usize) -> usize,
    ) -> BlockOutcome {
        for (iterations, steps) in counters {
            self.newton_iterations += iterations;
            self.steps_taken += steps;
        }
        if interrupt.load(Ordering::Relaxed) {
            return BlockOutcome::Interrupted;
        }
        self.step = record_step(first_record + count - 1);
        BlockOutcome::Complete
    }

    /// Record `r` of the current block for sample `i` (`dim outputs`).
    pub fn record(&self, i: usize, r: usize) -> &[f64] {
        let n = self.scene.outputs.len();
        &self.samples[i].block[r * n..(r + 1) * n]
    }

    /// The nominal run's configuration at record `r` of the current block (empty without a
    /// nominal run).
    pub fn nominal_positions(&self, r: usize) -> &[f64] {
        let nq = self.template.model.nq;
        let positions = self
            .nominal
            .and_then(|i| self.samples[i].positions.as_ref())
            .map_or(&[][..], |p| p.as_slice());
        positions.get(r * nq..(r + 1) * nq).unwrap_or(&[])
    }
}

impl RecordSource for LockStep<'_> {
    fn len(&self) -> usize {
        LockStep::len(self)
    }

    fn nominal_index(&self) -> Option<usize> {
        LockStep::nominal_index(self)
    }

    fn advance(
        &mut self,
        first: usize,
        count: usize,
        threads: &rayon::ThreadPool,
        interrupt: &AtomicBool,
    ) -> Result<BlockOutcome, StudyError> {
        Ok(LockStep::advance(self, first, count, threads, interrupt))
    }

    fn record(&self, i: usize, r: usize) -> &[f64] {
        LockStep::record(self, i, r)
    }

    fn nominal_positions(&self, r: usize) -> &[f64] {
        LockStep::nominal_positions(self, r)
    }

    fn failed(&self, i: usize) -> bool {
        LockStep::failed(self, i)
    }

    fn failures(&self) -> Vec<SampleFailure> {
        LockStep::failures(self)
    }

    fn retries(&self) -> Vec<SampleFailure> {
        LockStep::retries(self)
    }

    fn counters(&self) -> (u64, u64) {
        LockStep::counters(self)
    }

    fn contact_counters(&self) -> Option<ContactStats> {
        LockStep::contact_counters(self)
    }
}

/// What every sample of a block shares: the study's template system, box, scene, recorder and
/// step settings.
struct SampleContext<'a> {
    /// The system every thread's copy is made from.
    template: &'a RobotSystem,
    space: &'a ParameterSpace,
    scene: &'a Scene,
    recorder: &'a Recorder,
    /// The study's step settings.
    settings: HhtSettings,
    /// The adaptive step a sample failing at the fixed step is re-run with ([`retry_settings`]).
    retry_settings: Option<HhtSettings>,
}

/// Which part of the horizon one call of [`run_sample`] covers.
#[derive(Clone, Copy)]
struct SampleBlock<'a> {
    /// The step the samples are at.
    start_step: usize,
    /// The block's first record.
    first_record: usize,
    /// Records in the block.
    count: usize,
    /// The first record written into the sample's block (`first_record`, or for a retry from
    /// t = 0 the record the fixed step failed to reach: the block's records before it are the
    /// fixed step's). The steps into earlier records leave out the reported velocity.
    record_from: usize,
    /// The step of record `r`.
    record_step: &'a (dyn Fn(usize) -> usize + Sync),
    /// Checked before every step.
    interrupt: &'a AtomicBool,
}

/// Why a sample stopped before the end of its block.
enum SampleStop {
    /// The simulation failed at this time, s, heading for this record, for this reason (rows and
    /// joints named); `in_step` when a step failed (not the start, which a smaller step cannot
    /// change).
    Failed {
        time_s: f64,
        record: usize,
        message: String,
        in_step: bool,
    },
    /// The interrupt flag was raised.
    Interrupted,
}

/// A failure before the first step (the start, or the engine's own bookkeeping).
fn failed(time_s: f64, record: usize, message: String) -> SampleStop {
    SampleStop::Failed {
        time_s,
        record,
        message,
        in_step: false,
    }
}

/// One thread's scalar system and integrators: the fixed-step one of the study's settings and,
/// made on first use, the adaptive one that retried samples step with.
struct SampleWorker {
    system: RobotSystem,
    fixed: Option<HhtIntegrator>,
    adaptive: Option<HhtIntegrator>,
}

/// One worker per thread of a pool, made on the thread's first job and kept for its later ones
/// (a worker's state never carries from one sample to the next: any worker gives a sample the
/// same steps). A job that finds its thread's worker in use — only if a worker's call let the
/// thread take another job, which none does — makes a worker of its own.
struct ThreadWorkers<W> {
    slots: Vec<Mutex<Option<W>>>,
}

impl<W> ThreadWorkers<W> {
    /// No worker yet, one slot per thread of `threads`.
    fn new(threads: &rayon::ThreadPool) -> Self {
        ThreadWorkers {
            slots: (0..threads.current_num_threads().max(1))
                .map(|_| Mutex::new(None))
                .collect(),
        }
    }

    /// `job` with the current thread's worker (made by `make` if it has none).
    fn with<R>(&self, make: impl FnOnce() -> W, job: impl FnOnce(&mut W) -> R) -> R {
        let index = rayon::current_thread_index().unwrap_or(0) % self.slots.len();
        match self.slots[index].try_lock() {
            Ok(mut slot) => job(slot.get_or_insert_with(make)),
            Err(TryLockError::Poisoned(poisoned)) => {
                job(poisoned.into_inner().get_or_insert_with(make))
            }
            Err(TryLockError::WouldBlock) => job(&mut make()),
        }
    }
}

impl SampleWorker {
    fn new(template: &RobotSystem) -> SampleWorker {
        SampleWorker {
            system: template.clone(),
            fixed: None,
            adaptive: None,
        }
    }

    /// Advances `sample` (index `index` of the study, not failed) through `block`: at the fixed
    /// step, or adaptively once it was retried; a step that fails at the fixed step re-runs it
    /// ([`SampleWorker::retry`]); a failure that stays marks it failed. Returns the Newton
    /// iterations and steps taken.
    fn advance(
        &mut self,
        sample: &mut Sample,
        index: usize,
        context: &SampleContext<'_>,
        block: &SampleBlock<'_>,
    ) -> (u64, u64) {
        let n_outputs = context.recorder.outputs().len();
        sample.block.clear();
        sample.block.resize(block.count * n_outputs, 0.0);
        if let Some(positions) = &mut sample.positions {
            positions.clear();
            positions.resize(block.count * self.system.model.nq, 0.0);
        }
        context.space.apply(
            &mut self.system.model,
            &mut self.system.environment,
            &sample.xi,
        );
        // A `[bind]` value no model can have is named with its expression and symbol values,
        // before the integrator meets it.
        if let Err(error) = context
            .space
            .check_bound_values(&self.system.model, &sample.xi)
        {
            let time_s = block.start_step as f64 * context.scene.step_s;
            sample.fail(
                index,
                context.space,
                time_s,
                block.first_record,
                error.to_string(),
            );
            return (0, 0);
        }
        let before = sample.counters();
        let (integrator, settings) = match (&sample.retry, context.retry_settings) {
            (Some(_), Some(adaptive)) => (&mut self.adaptive, adaptive),
            _ => (&mut self.fixed, context.settings),
        };
        let result = run_sample(
            &mut self.system,
            integrator,
            sample,
            settings,
            context.scene,
            context.recorder,
            *block,
        );
        let after = sample.counters();
        let taken = (after.0 - before.0, after.1 - before.1);
        match result {
            Ok(()) | Err(SampleStop::Interrupted) => taken,
            Err(SampleStop::Failed {
                time_s,
                record,
                message,
                in_step,
            }) => {
                let failure = sample.failure_at(index, context.space, time_s, record, message);
                add(taken, self.retry(sample, failure, in_step, context, block))
            }
        }
    }

    /// After `failure` of `sample` in `block` (its parameters applied to the thread's system):
    /// when the fixed step failed in a step (`in_step`) and the study steps at a fixed step, the
    /// sample is re-run from t = 0 with the adaptive step through the block, its records from
    /// the failure's record on replaced, and keeps the failure as its retry note; otherwise the
    /// sample is marked failed with `failure`. When the adaptive run fails too, the sample fails
    /// with the failure of the run whose records it stops at: the fixed step's when the adaptive
    /// run failed before passing its record (today's failure, as without the retry), else the
    /// adaptive run's, with the retry note kept — the same whichever block holds either record,
    /// so that a shard and `analyze` say the same. Returns the retry's Newton iterations and
    /// steps.
    fn retry(
        &mut self,
        sample: &mut Sample,
        failure: SampleFailure,
        in_step: bool,
        context: &SampleContext<'_>,
        block: &SampleBlock<'_>,
    ) -> (u64, u64) {
        let adaptive = match context.retry_settings {
            Some(adaptive) if in_step && sample.retry.is_none() => adaptive,
            _ => {
                sample.failure = Some(failure);
                return (0, 0);
            }
        };
        // A new run: its own trajectory, start and contact counters.
        sample.trajectory = None;
        sample.contacts = self.system.effects.fresh_contact_state();
        let from_start = SampleBlock {
            start_step: 0,
            record_from: failure.record,
            ..*block
        };
        let result = run_sample(
            &mut self.system,
            &mut self.adaptive,
            sample,
            adaptive,
            context.scene,
            context.recorder,
            from_start,
        );
        match result {
            Ok(()) | Err(SampleStop::Interrupted) => sample.retry = Some(failure),
            Err(SampleStop::Failed {
                time_s,
                record,
                message,
                ..
            }) if record > failure.record => {
                sample.fail(failure.index, context.space, time_s, record, message);
                sample.retry = Some(failure);
            }
            Err(SampleStop::Failed { .. }) => sample.failure = Some(failure),
        }
        sample.counters()
    }
}

/// The sum of two `(Newton iterations, steps)` counters.
fn add(a: (u64, u64), b: (u64, u64)) -> (u64, u64) {
    (a.0 + b.0, a.1 + b.1)
}

/// Advances one sample through a block ([`step_sample`]) with the sample's contact state swapped
/// into `system` for the time, so that its counters and its Newton coupling state are its own
/// whichever samples ran before it on the thread. The thread's integrator workspace is made first,
/// outside any sample's state (its start is no sample's run).
fn run_sample(
    system: &mut RobotSystem,
    integrator: &mut Option<HhtIntegrator>,
    sample: &mut Sample,
    settings: HhtSettings,
    scene: &Scene,
    recorder: &Recorder,
    block: SampleBlock,
) -> Result<(), SampleStop> {
    let hht = match integrator {
        Some(hht) => hht,
        None => {
            let (q0, v0) = start_state(scene);
            match HhtIntegrator::new(system, settings, 0.0, &q0, &v0) {
                Ok(h) => integrator.insert(h),
                Err(error) => {
                    return Err(failed(
                        0.0,
                        block.first_record,
                        describe_failure(error, system, scene, &scene.initial_q),
                    ))
                }
            }
        }
    };
    let mut contacts = sample.contacts.take();
    if let Some(state) = &mut contacts {
        system.effects.swap_contact_state(state);
    }
    let result = step_sample(system, hht, sample, settings, scene, recorder, block);
    if let Some(state) = &mut contacts {
        system.effects.swap_contact_state(state);
    }
    sample.contacts = contacts;
    result
}

/// The scene's initial position and velocity.
fn start_state(scene: &Scene) -> (DVector<f64>, DVector<f64>) {
    (
        DVector::from_column_slice(&scene.initial_q),
        DVector::from_column_slice(&scene.initial_v),
    )
}

/// The message of a failed run at `q`, with the rows named.
fn describe_failure(
    error: IntegrateError,
    system: &mut RobotSystem,
    scene: &Scene,
    q: &[f64],
) -> String {
    let violation = crate::simulate::initial_violation(system, scene);
    let context = FailureContext {
        model: &system.model,
        scene,
        q,
        initial_violation: violation,
    };
    SimulationError::from_failure(error, &context).to_string()
}

/// Starts (at the sample's first block) and advances one sample through a block; on failure
/// returns the time and the message with the rows named.
fn step_sample(
    system: &mut RobotSystem,
    hht: &mut HhtIntegrator,
    sample: &mut Sample,
    settings: HhtSettings,
    scene: &Scene,
    recorder: &Recorder,
    block: SampleBlock,
) -> Result<(), SampleStop> {
    let SampleBlock {
        start_step,
        first_record,
        count,
        record_from,
        record_step,
        interrupt,
    } = block;
    let describe = |error: IntegrateError, system: &mut RobotSystem, q: &[f64]| {
        describe_failure(error, system, scene, q)
    };
    let start = || start_state(scene);
    // A sample's first block starts its trajectory with the sample's parameters (already applied
    // to `system.model`).
    if sample.trajectory.is_none() {
        let (q0, v0) = start();
        if let Err(error) = hht.restart(system, 0.0, &q0, &v0) {
            return Err(failed(
                0.0,
                first_record,
                describe(error, system, &scene.initial_q),
            ));
        }
        sample.initial = Recorder::initial_orientations(&system.model, hht.state().q.as_slice());
        sample.trajectory = Some(hht.trajectory());
    }
    let Some(trajectory) = sample.trajectory.as_mut() else {
        return Err(failed(
            0.0,
            first_record,
            "internal: sample has no trajectory".to_string(),
        ));
    };
    hht.swap_trajectory(trajectory)
        .map_err(|e| failed(0.0, first_record, e.to_string()))?;
    let mut step = start_step;
    let mut outcome = Ok(());
    'records: for r in 0..count {
        let target = record_step(first_record + r);
        while step < target {
            if interrupt.load(Ordering::Relaxed) {
                outcome = Err(SampleStop::Interrupted);
                break 'records;
            }
            // Only the step into a record written computes the reported velocity
            // (docs/method.md §5, "Velocity drift"), and every step with contacts (their
            // bookkeeping reads it).
            let into_record = step + 1 == target && first_record + r >= record_from;
            let report = if into_record || system.effects.has_contacts() {
                ReportedVelocity::Computed
            } else {
                ReportedVelocity::Skipped
            };
            if let Err(error) = hht.advance(system, report) {
                // The step that failed was heading for t_n + h.
                let time = hht.state().t + settings.step_s;
                let q = hht.state().q.as_slice().to_vec();
                outcome = Err(SampleStop::Failed {
                    time_s: time,
                    record: first_record + r,
                    message: describe(error, system, &q),
                    in_step: true,
                });
                break 'records;
            }
            step += 1;
            if system.effects.has_contacts() {
                // Contacts made and broken, deepest penetration: counted as `simulate` does.
                let state = hht.state();
                system.effects.observe_contacts(
                    &system.model,
                    &mut system.data,
                    state.q.as_slice(),
                    state.v.as_slice(),
                );
            }
        }
        if first_record + r >= record_from {
            record_sample(recorder, system, hht.state(), sample, r);
        }
    }
    let Some(trajectory) = sample.trajectory.as_mut() else {
        return Err(failed(
            0.0,
            first_record,
            "internal: sample has no trajectory".to_string(),
        ));
    };
    hht.swap_trajectory(trajectory)
        .map_err(|e| failed(0.0, first_record, e.to_string()))?;
    outcome
}

/// Writes record `r` of the current block of `sample` from its `state`: the outputs, and the
/// configuration when the sample keeps its positions (the nominal run).
fn record_sample(
    recorder: &Recorder,
    system: &mut RobotSystem,
    state: &HhtState,
    sample: &mut Sample,
    r: usize,
) {
    let (n_outputs, nq) = (recorder.outputs().len(), system.model.nq);
    recorder.record_state(
        system,
        state,
        &sample.initial,
        &mut sample.block[r * n_outputs..(r + 1) * n_outputs],
    );
    if let Some(positions) = &mut sample.positions {
        positions[r * nq..(r + 1) * nq].copy_from_slice(state.q.as_slice());
    }
}
