//! The lock-step engine's batched path: samples in groups of [`LANES`], each group stepped through
//! a block by one [`BatchStepper`] (the batched kernels, docs/batch.md §5). Every sample takes
//! exactly the steps, records, counters and failures of the per-sample path ([`super::run_sample`]):
//! the stepper's lanes are bitwise the scalar integrator, and everything around the steps here
//! (starts, records, failure messages) is the per-sample path's, lane by lane. A lane that fails
//! at the fixed step is retried, and a retried sample steps, by the per-sample path's
//! [`SampleWorker`] (the adaptive step is per sample), so the retry is the same on both paths.

use super::{
    add, describe_failure, record_sample, start_state, Sample, SampleBlock, SampleContext,
    SampleWorker,
};
use crate::dynamics::batch::LANES;
use crate::integrate::{IntegrateError, ReportedVelocity};
use crate::scene::Scene;
use crate::simulate::{BatchStepper, Recorder, RobotSystem};
use nalgebra::DVector;
use std::sync::atomic::Ordering;

/// One thread's batched stepper and, made on first use, the scalar worker of the samples that
/// failed at the fixed step.
pub(super) struct GroupWorker {
    stepper: Option<BatchStepper>,
    scalar: Option<SampleWorker>,
}

impl GroupWorker {
    /// The thread's worker; its stepper is made from the study's template.
    pub(super) fn new(template: &RobotSystem) -> GroupWorker {
        GroupWorker {
            stepper: BatchStepper::new(template, LANES).ok(),
            scalar: None,
        }
    }

    /// [`advance_group`], then the group's retried samples by the scalar worker: those that
    /// failed at the fixed step in this block (re-run from t = 0) and those retried before
    /// (stepped adaptively through the block).
    pub(super) fn advance_group(
        &mut self,
        group: &mut [Sample],
        first_index: usize,
        context: &SampleContext<'_>,
        block: &SampleBlock<'_>,
    ) -> (u64, u64) {
        let retried_before: Vec<bool> = group.iter().map(|s| s.retry.is_some()).collect();
        let (mut counters, mut pending) =
            advance_group(&mut self.stepper, group, first_index, context, block);
        for (lane, sample) in group.iter_mut().enumerate() {
            let retry = pending[lane].take();
            if retry.is_none() && (!retried_before[lane] || sample.failure.is_some()) {
                continue;
            }
            let scalar = self
                .scalar
                .get_or_insert_with(|| SampleWorker::new(context.template));
            let taken = match retry {
                Some((failure, in_step)) => {
                    context.space.apply(
                        &mut scalar.system.model,
                        &mut scalar.system.environment,
                        &sample.xi,
                    );
                    scalar.retry(sample, failure, in_step, context, block)
                }
                None => scalar.advance(sample, first_index + lane, context, block),
            };
            counters = add(counters, taken);
        }
        counters
    }
}

/// A lane's failure at the fixed step, for [`SampleWorker::retry`]: the failure and whether a
/// step failed.
type PendingRetry = Option<(crate::analysis::SampleFailure, bool)>;

/// Advances the live samples of `group` (at most [`LANES`]; sample `first_index + lane` of the
/// study) through `block` together, except those already retried; returns the Newton iterations
/// and steps they took, and per lane the failure that the per-sample path retries.
fn advance_group(
    stepper: &mut Option<BatchStepper>,
    group: &mut [Sample],
    first_index: usize,
    context: &SampleContext<'_>,
    block: &SampleBlock<'_>,
) -> ((u64, u64), [PendingRetry; LANES]) {
    let SampleContext {
        space,
        settings,
        scene,
        recorder,
        ..
    } = *context;
    let mut pending: [PendingRetry; LANES] = Default::default();
    let first_record = block.first_record;
    // A failure before the first step of the block: at t = 0 (the per-sample path's convention).
    let fail_at_start = |sample: &mut Sample, lane: usize, message: String| {
        sample.fail(first_index + lane, space, 0.0, first_record, message)
    };
    let Some(stepper) = stepper.as_mut() else {
        for (lane, sample) in group.iter_mut().enumerate() {
            if sample.failure.is_none() {
                let message = "internal: the batched stepper could not be made".to_string();
                fail_at_start(sample, lane, message);
            }
        }
        return ((0, 0), pending);
    };
    let n_outputs = recorder.outputs().len();
    let nq = stepper.system_mut(0).model.nq;
    let (q0, v0) = start_state(scene);
    let mut active = [false; LANES];
    let mut before = [(0_u64, 0_u64); LANES];
    for (lane, sample) in group.iter_mut().enumerate() {
        if sample.failure.is_some() || sample.retry.is_some() {
            continue;
        }
        sample.block.clear();
        sample.block.resize(block.count * n_outputs, 0.0);
        if let Some(positions) = &mut sample.positions {
            positions.clear();
            positions.resize(block.count * nq, 0.0);
        }
        match load_lane(stepper, lane, sample, context, (&q0, &v0)) {
            Ok(counters) => before[lane] = counters,
            Err(message) => {
                fail_at_start(sample, lane, message);
                continue;
            }
        }
        active[lane] = true;
    }
    let swapped = active;

    let mut step = block.start_step;
    'records: for r in 0..block.count {
        let target = (block.record_step)(first_record + r);
        while step < target {
            if block.interrupt.load(Ordering::Relaxed) {
                break 'records;
            }
            // Only the step into a record computes the reported velocity (docs/method.md §5,
            // "Velocity drift"): the records have the bits of stepping with it every time.
            let report = if step + 1 == target {
                ReportedVelocity::Computed
            } else {
                ReportedVelocity::Skipped
            };
            let mut failures: [Option<IntegrateError>; LANES] = Default::default();
            for (lane, error) in stepper.step(&active, report).iter_mut().enumerate() {
                failures[lane] = error.take();
            }
            for (lane, error) in failures.into_iter().enumerate() {
                let Some(error) = error else {
                    continue;
                };
                active[lane] = false;
                let (system, integrator) = stepper.lane_mut(lane);
                let Some(hht) = integrator else {
                    continue;
                };
                // The step that failed was heading for t_n + h; the per-sample path retries it.
                let time = hht.state().t + settings.step_s;
                let q = hht.state().q.as_slice().to_vec();
                let message = describe_failure(error, system, scene, &q);
                let failure = group[lane].failure_at(
                    first_index + lane,
                    space,
                    time,
                    first_record + r,
                    message,
                );
                pending[lane] = Some((failure, true));
            }
            step += 1;
        }
        for (lane, sample) in group.iter_mut().enumerate() {
            if !active[lane] {
                continue;
            }
            let (system, integrator) = stepper.lane_mut(lane);
            let Some(hht) = integrator else {
                continue;
            };
            record_sample(recorder, system, hht.state(), sample, r);
        }
    }

    let mut counters = (0, 0);
    for (lane, sample) in group.iter_mut().enumerate() {
        if !swapped[lane] {
            continue;
        }
        let (_, integrator) = stepper.lane_mut(lane);
        let (Some(hht), Some(trajectory)) = (integrator, sample.trajectory.as_mut()) else {
            continue;
        };
        if let Err(error) = hht.swap_trajectory(trajectory) {
            if sample.failure.is_none() {
                fail_at_start(sample, lane, error.to_string());
            }
            continue;
        }
        counters.0 += trajectory.stats.newton_iterations - before[lane].0;
        counters.1 += trajectory.stats.steps - before[lane].1;
    }
    (counters, pending)
}

/// Puts `sample` into lane `lane`: its parameter values into the lane's model, the lane's
/// integrator made if it has none, the sample's trajectory started (its first block) and swapped
/// in. Returns the trajectory's Newton iterations and steps so far; `Err`: why the sample cannot
/// step (its message as the per-sample path words it).
fn load_lane(
    stepper: &mut BatchStepper,
    lane: usize,
    sample: &mut Sample,
    context: &SampleContext<'_>,
    (q0, v0): (&DVector<f64>, &DVector<f64>),
) -> Result<(u64, u64), String> {
    let scene = context.scene;
    let system = stepper.system_mut(lane);
    context
        .space
        .apply(&mut system.model, &mut system.environment, &sample.xi);
    // A `[bind]` value no model can have is named with its expression and symbol values.
    context
        .space
        .check_bound_values(&stepper.system_mut(lane).model, &sample.xi)
        .map_err(|error| error.to_string())?;
    stepper
        .sync_lane(lane)
        .map_err(|error| format!("internal: {error}"))?;
    if let Err(error) = stepper.start_lane(lane, context.settings, q0, v0) {
        return Err(describe_start(error, stepper.system_mut(lane), scene));
    }
    let (system, integrator) = stepper.lane_mut(lane);
    let hht = integrator.ok_or("internal: the lane has no integrator")?;
    // A sample's first block starts its trajectory with the sample's parameters.
    if sample.trajectory.is_none() {
        if let Err(error) = hht.restart(system, 0.0, q0, v0) {
            return Err(describe_start(error, system, scene));
        }
        sample.initial = Recorder::initial_orientations(&system.model, hht.state().q.as_slice());
        sample.trajectory = Some(hht.trajectory());
    }
    let trajectory = sample
        .trajectory
        .as_mut()
        .ok_or("internal: sample has no trajectory")?;
    let counters = (trajectory.stats.newton_iterations, trajectory.stats.steps);
    hht.swap_trajectory(trajectory)
        .map_err(|error| error.to_string())?;
    Ok(counters)
}

/// The message of a start that failed (at the scene's initial configuration).
fn describe_start(error: IntegrateError, system: &mut RobotSystem, scene: &Scene) -> String {
    describe_failure(error, system, scene, &scene.initial_q)
}
