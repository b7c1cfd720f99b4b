//! Lock-step simulation of many samples: every sample advances through one block of record times,
//! then the next, so memory holds one block of records, never a whole trajectory per sample.
//!
//! A sample keeps only its trajectory state ([`HhtTrajectory`]: a few vectors of length nv); each
//! worker thread owns one [`RobotSystem`] (a model copy and its work buffers) and one integrator
//! workspace, writes the sample's parameter values into its model ([`ParameterSpace::apply`]), swaps
//! the sample's trajectory in, steps it through the block, and swaps it out. No locks; the result of
//! a sample does not depend on which thread ran it, so studies are deterministic for any thread
//! count.
//!
//! Scenes the batched step suits ([`BatchStepper::suits`]: no contacts, no reuse of the Newton
//! matrix) go in groups of four samples instead, each group through the block with one
//! [`BatchStepper`] per thread (the batched CRBA and RNEA, docs/batch.md §5; `engine/batched.rs`).
//! Every sample's steps are bitwise the per-sample path's, so nothing downstream can tell the two
//! apart ([`LockStep::disable_batching`] forces the per-sample path).
//!
//! Interruption: every sample checks the study's interrupt flag before each step, so a signal takes
//! effect after at most one step per worker thread, also inside a long block or a single long run.

mod batched;

use super::error::StudyError;
use super::report::SampleFailure;
use super::schedule::RecordSchedule;
use crate::dynamics::batch::LANES;
use crate::effects::{ContactState, ContactStats};
use crate::integrate::{
    HhtIntegrator, HhtSettings, HhtState, HhtTrajectory, IntegrateError, ReportedVelocity,
};
use crate::scene::Scene;
use crate::simulate::{
    BatchStepper, FailureContext, InitialOrientations, Recorder, RobotSystem, SimulationError,
};
use crate::uncertainty::ParameterSpace;
use nalgebra::DVector;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Where the recorded values of a phase's samples come from, one block of record times at a time:
/// simulated here ([`LockStep`]) or read from the record blocks of shards simulated elsewhere
/// (`crate::distributed`). A study's stages only see this interface, so that a merged study and a
/// single-machine one compute the same numbers from the same values in the same order.
pub trait RecordSource: Sync {
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
        self.failure = Some(SampleFailure {
            index,
            xi: self.xi.clone(),
            values: space.values_at(&self.xi),
            time_s,
            record,
            message,
        });
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
            recorder: Recorder::new(&scene.outputs),
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
        let n_outputs = self.scene.outputs.len();
        let nq = self.template.model.nq;
        let scene = self.scene;
        let space = self.space;
        let settings = self.settings;
        let recorder = &self.recorder;
        let template = &self.template;
        let start_step = self.step;
        let schedule = RecordSchedule::of(scene);
        let record_step = |r: usize| schedule.step_of(r);
        if self.batched {
            let context = batched::GroupContext {
                space,
                settings,
                scene,
                recorder,
            };
            let block = SampleBlock {
                start_step,
                first_record,
                count,
                record_step: &record_step,
                interrupt,
            };
            let counters: Vec<(u64, u64)> = threads.install(|| {
                self.samples
                    .par_chunks_mut(LANES)
                    .enumerate()
                    .map_init(
                        || batched::new_stepper(template),
                        |stepper, (group_index, group)| {
                            batched::advance_group(
                                stepper,
                                group,
                                group_index * LANES,
                                &context,
                                &block,
                            )
                        },
                    )
                    .collect()
            });
            return self.finish_block(counters, first_record, count, interrupt, &record_step);
        }
        let counters: Vec<(u64, u64)> = threads.install(|| {
            self.samples
                .par_iter_mut()
                .enumerate()
                .map_init(
                    || (template.clone(), None::<HhtIntegrator>),
                    |(system, integrator), (index, sample)| {
                        if sample.failure.is_some() {
                            return (0, 0);
                        }
                        sample.block.clear();
                        sample.block.resize(count * n_outputs, 0.0);
                        if let Some(positions) = &mut sample.positions {
                            positions.clear();
                            positions.resize(count * nq, 0.0);
                        }
                        space.apply(&mut system.model, &sample.xi);
                        // A `[bind]` value no model can have is named with its expression and
                        // symbol values, before the integrator meets it.
                        if let Err(error) = space.check_bound_values(&system.model, &sample.xi) {
                            let time_s = start_step as f64 * scene.step_s;
                            sample.fail(index, space, time_s, first_record, error.to_string());
                            return (0, 0);
                        }
                        let before = sample
                            .trajectory
                            .as_ref()
                            .map(|t| (t.stats.newton_iterations, t.stats.steps));
                        let result = run_sample(
                            system,
                            integrator,
                            sample,
                            settings,
                            scene,
                            recorder,
                            SampleBlock {
                                start_step,
                                first_record,
                                count,
                                record_step: &record_step,
                                interrupt,
                            },
                        );
                        if let Err(SampleStop::Failed {
                            time_s,
                            record,
                            message,
                        }) = result
                        {
                            sample.fail(index, space, time_s, record, message);
                        }
                        let after = sample
                            .trajectory
                            .as_ref()
                            .map(|t| (t.stats.newton_iterations, t.stats.steps));
                        match (before, after) {
                            (Some(b), Some(a)) => (a.0 - b.0, a.1 - b.1),
                            (None, Some(a)) => a,
                            _ => (0, 0),
                        }
                    },
                )
                .collect()
        });
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

    fn counters(&self) -> (u64, u64) {
        LockStep::counters(self)
    }

    fn contact_counters(&self) -> Option<ContactStats> {
        LockStep::contact_counters(self)
    }
}

/// Which part of the horizon one call of [`run_sample`] covers.
struct SampleBlock<'a> {
    /// The step the samples are at.
    start_step: usize,
    /// The block's first record.
    first_record: usize,
    /// Records in the block.
    count: usize,
    /// The step of record `r`.
    record_step: &'a (dyn Fn(usize) -> usize + Sync),
    /// Checked before every step.
    interrupt: &'a AtomicBool,
}

/// Why a sample stopped before the end of its block.
enum SampleStop {
    /// The simulation failed at this time, s, heading for this record, for this reason (rows and
    /// joints named).
    Failed {
        time_s: f64,
        record: usize,
        message: String,
    },
    /// The interrupt flag was raised.
    Interrupted,
}

fn failed(time_s: f64, record: usize, message: String) -> SampleStop {
    SampleStop::Failed {
        time_s,
        record,
        message,
    }
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
            // Only the step into a record computes the reported velocity (docs/method.md §5,
            // "Velocity drift"), and every step with contacts (their bookkeeping reads it).
            let report = if step + 1 == target || system.effects.has_contacts() {
                ReportedVelocity::Computed
            } else {
                ReportedVelocity::Skipped
            };
            if let Err(error) = hht.advance(system, report) {
                // The step that failed was heading for t_n + h.
                let time = hht.state().t + settings.step_s;
                let q = hht.state().q.as_slice().to_vec();
                outcome = Err(failed(time, first_record + r, describe(error, system, &q)));
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
        record_sample(recorder, system, hht.state(), sample, r);
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
        &system.model,
        &mut system.data,
        &mut system.effects,
        state,
        &sample.initial,
        &mut sample.block[r * n_outputs..(r + 1) * n_outputs],
    );
    if let Some(positions) = &mut sample.positions {
        positions[r * nq..(r + 1) * nq].copy_from_slice(state.q.as_slice());
    }
}
