//! One study: plan → lock-step simulation in blocks of record times → fit and bound each block →
//! hand the block's envelopes to the caller's sink → drop the samples' records.
//!
//! `(model, scene, parameter space, options) ⇒ blocks of EnvelopePoints ⇒ Envelope`

use super::bounds::{Bounder, EnvelopePoint};
use super::engine::{LockStep, SampleFailure};
use super::plan::{Plan, MAX_RUNS};
use super::Method;
use crate::model::Model;
use crate::scene::{Output, Scene};
use crate::simulate::{hht_settings, RobotSystem};
use crate::uncertainty::ParameterSpace;
use crate::uq::{Truncation, UqError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use thiserror::Error;

/// Values (samples × outputs × records) one block may hold: 4 M values = 32 MB.
pub const BLOCK_VALUE_BUDGET: usize = 4_000_000;
/// Most record times per block: keeps memory flat in the horizon (the 10×-longer-run test) while a
/// block still amortises the threads' start-up.
pub const MAX_BLOCK_RECORDS: usize = 50;

/// Options of a study (command-line flags override the sidecar's `[analysis]`).
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Method.
    pub method: Method,
    /// Polynomial order `k` of surrogate methods.
    pub order: usize,
    /// `tensor` or `total` truncation of surrogate methods (both on the tensor Gauss grid).
    pub truncation: Truncation,
    /// Points per dimension of the true-model `scan` (odd).
    pub grid: usize,
    /// Points per dimension of the surrogate scan (odd); `None` for the default (21 for d ≤ 2, 11
    /// for d ≥ 3).
    pub scan_grid: Option<usize>,
    /// Monte Carlo runs.
    pub samples: usize,
    /// Monte Carlo seed.
    pub seed: u64,
    /// Worker threads (0: all cores).
    pub threads: usize,
    /// Exclude failing samples instead of stopping (`scan` and `monte-carlo` only).
    pub keep_going: bool,
}

/// Why a study could not run or finish.
#[derive(Debug, Error)]
pub enum StudyError {
    /// Options that cannot work.
    #[error("{0}")]
    BadOptions(String),
    /// The interval mathematics refused (e.g. an order beyond its range).
    #[error("interval mathematics: {0}")]
    Uq(#[from] UqError),
    /// A sample failed and the study cannot go on.
    #[error("{}", describe_failure(.failure, *.total, .hint))]
    SampleFailed {
        /// The failure.
        failure: SampleFailure,
        /// Number of samples.
        total: usize,
        /// What to do.
        hint: &'static str,
    },
    /// A sink (MCAP, …) failed.
    #[error(transparent)]
    Sink(Box<crate::Error>),
    /// The worker threads could not be started.
    #[error("cannot start {threads} worker threads: {message}")]
    Threads {
        /// Requested count.
        threads: usize,
        /// The reason.
        message: String,
    },
}

fn describe_failure(failure: &SampleFailure, total: usize, hint: &str) -> String {
    let point = if failure.index + 1 == total {
        "the nominal run".to_string()
    } else {
        format!("sample {} of {}", failure.index + 1, total - 1)
    };
    format!(
        "{point} failed at t = {} s, at parameter values {:?} (ξ = {:?}): {}. {hint}",
        failure.time_s, failure.values, failure.xi, failure.message
    )
}

/// One block of envelopes, as handed to the sink.
pub struct BlockView<'a> {
    /// Index of the block's first record.
    pub first_record: usize,
    /// Record times of the block, s.
    pub times: &'a [f64],
    /// `records × outputs` envelope points, record-major.
    pub points: &'a [EnvelopePoint],
    /// The nominal run's values, `records × outputs`.
    pub nominal: &'a [f64],
    /// The nominal run's configuration per record (`records × nq`).
    pub nominal_positions: &'a [f64],
}

/// Progress after a block.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Records done.
    pub records_done: usize,
    /// Records in all.
    pub records_total: usize,
    /// Model runs (samples including the nominal one).
    pub runs: usize,
    /// Seconds since the start.
    pub elapsed_s: f64,
}

/// The envelopes of a whole study (kept: a few numbers per output per record time).
#[derive(Clone, Debug)]
pub struct Envelope {
    /// The outputs.
    pub outputs: Vec<Output>,
    /// Record times, s.
    pub times: Vec<f64>,
    /// `lower[o][k]`.
    pub lower: Vec<Vec<f64>>,
    /// `upper[o][k]`.
    pub upper: Vec<Vec<f64>>,
    /// `nominal[o][k]`.
    pub nominal: Vec<Vec<f64>>,
    /// `error[o][k]`, where the method has an estimate.
    pub error: Option<Vec<Vec<f64>>>,
}

/// What a study did.
#[derive(Clone, Debug)]
pub struct StudyReport {
    /// The envelopes.
    pub envelope: Envelope,
    /// Model runs, the nominal one included.
    pub runs: usize,
    /// Samples left out with `keep_going`.
    pub excluded: Vec<SampleFailure>,
    /// Whether the study stopped early (interrupted): the envelopes cover the times done.
    pub partial: bool,
    /// Seconds spent simulating.
    pub simulate_seconds: f64,
    /// Seconds spent fitting and bounding.
    pub bound_seconds: f64,
    /// Newton iterations of all samples.
    pub newton_iterations: u64,
    /// Steps of all samples.
    pub steps: u64,
    /// Worker threads used.
    pub threads: usize,
    /// Record times per block.
    pub block_records: usize,
}

/// A study ready to run.
pub struct Study<'a> {
    /// The nominal model (scene gravity applied).
    pub model: Model,
    /// The scene.
    pub scene: &'a Scene,
    /// The interval parameters.
    pub space: &'a ParameterSpace,
    /// The options.
    pub options: StudyOptions,
}

impl Study<'_> {
    /// Number of model runs the plan asks for, nominal included; errors for plans that cannot run.
    pub fn plan(&self) -> Result<(Plan, usize), StudyError> {
        let o = &self.options;
        let d = self.space.len();
        if d == 0 {
            return Err(StudyError::BadOptions(
                "the sidecar declares no [parameters]: there is nothing to bound (use `ribbon simulate` for one nominal run)".to_string(),
            ));
        }
        if o.method == Method::Scan && (o.grid < 2 || o.grid.is_multiple_of(2)) {
            return Err(StudyError::BadOptions(format!(
                "--grid {} must be odd and ≥ 3 so that the centre of the box is on the grid",
                o.grid
            )));
        }
        if let Some(n) = o.scan_grid {
            if n < 3 || n.is_multiple_of(2) {
                return Err(StudyError::BadOptions(format!(
                    "--scan-grid {n} must be odd and ≥ 3 so that the centre of the box is on the grid"
                )));
            }
        }
        if o.method == Method::MonteCarlo && o.samples == 0 {
            return Err(StudyError::BadOptions("--samples must be ≥ 1".to_string()));
        }
        let plan = Plan::new(
            o.method,
            d,
            o.order,
            o.truncation,
            o.grid,
            o.samples,
            o.seed,
        )?;
        let runs = plan.runs(d).filter(|r| *r <= MAX_RUNS).ok_or_else(|| {
            StudyError::BadOptions(format!(
                "{} with {d} parameters needs more than {MAX_RUNS} model runs; lower --order/--grid/--samples or use fewer parameters",
                o.method.name()
            ))
        })?;
        Ok((plan, runs + 1))
    }

    /// Runs the study: `progress` after each block, `sink` with each block's envelopes. Stops after
    /// the current block when `interrupt` is set (the report is then `partial`).
    pub fn run(
        &self,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), crate::Error>,
    ) -> Result<StudyReport, StudyError> {
        let started = Instant::now();
        let (plan, runs) = self.plan()?;
        let o = &self.options;
        let d = self.space.len();
        let threads = rayon::ThreadPoolBuilder::new()
            .num_threads(o.threads)
            .build()
            .map_err(|e| StudyError::Threads {
                threads: o.threads,
                message: e.to_string(),
            })?;
        let points = plan.points(d);
        let bounder = Bounder::new(o.method, &plan, d, o.order, o.scan_grid)?;
        let scene = self.scene;
        let template = RobotSystem::new(self.model.clone(), scene);
        let nominal_xi = self.space.nominal_xi();
        let mut lockstep = LockStep::new(
            template,
            self.space,
            scene,
            hht_settings(scene),
            &points,
            &nominal_xi,
        );
        let n_outputs = scene.outputs.len();
        let n_records = scene.n_steps.div_ceil(scene.record_every) + 1;
        let block_records = (BLOCK_VALUE_BUDGET / (runs * n_outputs).max(1))
            .clamp(1, MAX_BLOCK_RECORDS)
            .min(n_records);
        let nominal_index = runs - 1;
        let can_exclude = matches!(o.method, Method::Scan | Method::MonteCarlo);

        let mut envelope = Envelope {
            outputs: scene.outputs.clone(),
            times: Vec::with_capacity(n_records),
            lower: vec![Vec::with_capacity(n_records); n_outputs],
            upper: vec![Vec::with_capacity(n_records); n_outputs],
            nominal: vec![Vec::with_capacity(n_records); n_outputs],
            error: None,
        };
        let mut simulate_seconds = 0.0;
        let mut bound_seconds = 0.0;
        let mut partial = false;
        let mut first = 0;
        while first < n_records {
            if interrupt.load(Ordering::SeqCst) {
                partial = true;
                break;
            }
            let count = block_records.min(n_records - first);
            let t_simulate = Instant::now();
            lockstep.advance(first, count, &threads);
            simulate_seconds += t_simulate.elapsed().as_secs_f64();
            let failures = lockstep.failures();
            if let Some(failure) = failures
                .iter()
                .find(|f| f.index == nominal_index || !(o.keep_going && can_exclude))
            {
                let hint = if failure.index == nominal_index {
                    "The nominal run must succeed; check the scene and the URDF values"
                } else if o.keep_going {
                    "--keep-going cannot help this method: its fit needs every design point; use --method scan or monte-carlo, or narrow the box"
                } else {
                    "Use --keep-going to exclude failing samples (scan and monte-carlo), or narrow the box"
                };
                return Err(StudyError::SampleFailed {
                    failure: failure.clone(),
                    total: runs,
                    hint,
                });
            }
            let t_bound = Instant::now();
            let plan_samples = runs - 1;
            let lockstep_ref = &lockstep;
            let values = move |r: usize| -> Vec<f64> {
                let mut row = Vec::with_capacity(plan_samples * n_outputs);
                for i in 0..plan_samples {
                    row.extend_from_slice(lockstep_ref.record(i, r));
                }
                row
            };
            let excluded = |i: usize| lockstep_ref.failed(i);
            let block_points =
                bounder.bound_records(count, n_outputs, &values, &excluded, &threads)?;
            let mut nominal = Vec::with_capacity(count * n_outputs);
            let mut nominal_positions = Vec::new();
            let mut times = Vec::with_capacity(count);
            for r in 0..count {
                let record = first + r;
                times.push((record * scene.record_every).min(scene.n_steps) as f64 * scene.step_s);
                nominal.extend_from_slice(lockstep.record(nominal_index, r));
                nominal_positions.extend_from_slice(lockstep.nominal_positions(r));
            }
            // The nominal run is a true response inside the box: the envelope contains it.
            let mut block_points = block_points;
            for (point, value) in block_points.iter_mut().zip(&nominal) {
                point.lower = point.lower.min(*value);
                point.upper = point.upper.max(*value);
            }
            bound_seconds += t_bound.elapsed().as_secs_f64();
            for (r, t) in times.iter().enumerate() {
                envelope.times.push(*t);
                for o in 0..n_outputs {
                    let point = block_points[r * n_outputs + o];
                    envelope.lower[o].push(point.lower);
                    envelope.upper[o].push(point.upper);
                    envelope.nominal[o].push(nominal[r * n_outputs + o]);
                    if let Some(error) = point.error {
                        envelope
                            .error
                            .get_or_insert_with(|| vec![Vec::with_capacity(n_records); n_outputs])
                            [o]
                            .push(error);
                    }
                }
            }
            sink(&BlockView {
                first_record: first,
                times: &times,
                points: &block_points,
                nominal: &nominal,
                nominal_positions: &nominal_positions,
            })
            .map_err(|e| StudyError::Sink(Box::new(e)))?;
            first += count;
            progress(Progress {
                records_done: first,
                records_total: n_records,
                runs,
                elapsed_s: started.elapsed().as_secs_f64(),
            });
        }
        let (newton_iterations, steps) = lockstep.counters();
        Ok(StudyReport {
            envelope,
            runs,
            excluded: lockstep.failures(),
            partial,
            simulate_seconds,
            bound_seconds,
            newton_iterations,
            steps,
            threads: threads.current_num_threads(),
            block_records,
        })
    }
}
