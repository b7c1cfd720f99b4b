//! A nominal run: consistent start, fixed steps, records at the scene's rate.

use super::{Recorder, RobotSystem};
use crate::constraints::ConstraintSet;
use crate::integrate::{HhtIntegrator, HhtSettings, HhtStats, IntegrateError, WorstEntry};
use crate::model::Model;
use crate::scene::{Output, Scene};
use nalgebra::DVector;

/// Recorded series of one run.
#[derive(Clone, Debug)]
pub struct Trajectory {
    /// Record times, s.
    pub times: Vec<f64>,
    /// The outputs, in column order.
    pub outputs: Vec<Output>,
    /// `values[i][k]`: output `i` at `times[k]`.
    pub values: Vec<Vec<f64>>,
    /// `positions[k]`: the configuration `q` at `times[k]` (for frames on `/tf`).
    pub positions: Vec<Vec<f64>>,
    /// Integrator statistics.
    pub stats: HhtStats,
}

/// The integrator settings a scene asks for (tolerances at their documented defaults).
pub fn hht_settings(scene: &Scene) -> HhtSettings {
    HhtSettings {
        alpha: scene.alpha,
        step_s: scene.step_s,
        velocity_projection: scene.velocity_projection,
        ..HhtSettings::default()
    }
}

/// Why a run failed, with the constraint rows named.
#[derive(Debug, thiserror::Error)]
pub enum SimulationError {
    /// The declared constraints cannot hold: they cannot be closed from the initial state, or some
    /// rows are redundant. Bad input.
    #[error("{message}")]
    Constraints {
        /// What is wrong, naming the loop, drive or mimic joint.
        message: String,
    },
    /// The integration failed (divergence, NaN, singular matrix), with the row named when one is
    /// to blame.
    #[error("simulation failed: {source}{context}")]
    Integrate {
        /// The integrator's error (names time and step).
        source: IntegrateError,
        /// ", worst row: …" or empty.
        context: String,
    },
}

impl SimulationError {
    /// Names the rows an integrator error points at. `initial_violation` is `max |Φ(q0)|`: rows
    /// that become dependent while a far-off loop is being closed mean the loop cannot close (the
    /// projection stretched the linkage into a singular pose), not that the rows are redundant.
    pub fn from_integrate(
        source: IntegrateError,
        constraints: &ConstraintSet,
        initial_violation: f64,
    ) -> SimulationError {
        match &source {
            IntegrateError::RedundantConstraints { row, .. } if initial_violation > CLOSED_AT_START => {
                SimulationError::Constraints {
                    message: format!(
                        "the constraints cannot be closed from the initial state: {} is violated by {initial_violation:.3e} at t = 0 and the rows become dependent while closing it (the linkage stretches into a singular pose: the points cannot meet); check the loop's points, link lengths and initial.q ({source})",
                        constraints.row_name(*row)
                    ),
                }
            }
            IntegrateError::CannotClose { worst_row, violation, .. } => SimulationError::Constraints {
                message: format!(
                    "the constraints cannot be closed from the initial state: {} is still violated by {violation:.3e} after the start projection; check the loop's points and initial.q ({source})",
                    constraints.row_name(*worst_row)
                ),
            },
            IntegrateError::RedundantConstraints { row, .. } => SimulationError::Constraints {
                message: format!(
                    "redundant constraint rows: {} depends on the others; declare loops with the rows they really constrain (a planar pin is 2 rows, not a 3-row ball) ({source})",
                    constraints.row_name(*row)
                ),
            },
            IntegrateError::NewtonNotConverged { worst: WorstEntry::Constraint { index: row, .. }, .. } => {
                let context = format!("; worst row: {}", constraints.row_name(*row));
                SimulationError::Integrate { source, context }
            }
            _ => SimulationError::Integrate {
                source,
                context: String::new(),
            },
        }
    }
}

/// Above this `max |Φ(q0)|` (m or rad) the initial state is "not closed": the start projection has
/// real work to do, and rows that turn dependent during it mean the loop cannot close.
const CLOSED_AT_START: f64 = 1e-6;

/// `max |Φ(q0)|` of the scene's initial state (0 without rows).
pub fn initial_violation(system: &mut RobotSystem, scene: &Scene) -> f64 {
    if system.constraints.is_empty() {
        return 0.0;
    }
    let mut phi = DVector::zeros(system.constraints.len());
    system.constraints.evaluate(
        &system.model,
        &mut system.data,
        0.0,
        &scene.initial_q,
        &mut phi,
    );
    phi.amax()
}

/// Simulates `model` through `scene` from `t = 0` and records every output.
pub fn simulate(model: Model, scene: &Scene) -> Result<Trajectory, SimulationError> {
    let mut system = RobotSystem::new(model, scene);
    let violation = initial_violation(&mut system, scene);
    simulate_system(system, scene)
        .map_err(|e| SimulationError::from_integrate(e, &scene.constraints, violation))
}

fn simulate_system(mut system: RobotSystem, scene: &Scene) -> Result<Trajectory, IntegrateError> {
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut integrator = HhtIntegrator::new(&mut system, hht_settings(scene), 0.0, &q0, &v0)?;
    let recorder = Recorder::new(&scene.outputs);
    let initial = Recorder::initial_orientations(&system.model, integrator.state().q.as_slice());
    let n_records = scene.n_steps / scene.record_every + 2;
    let mut times = Vec::with_capacity(n_records);
    let mut values: Vec<Vec<f64>> = vec![Vec::with_capacity(n_records); scene.outputs.len()];
    let mut row = vec![0.0; scene.outputs.len()];
    let mut positions = Vec::with_capacity(n_records);
    for k in 0..=scene.n_steps {
        if k > 0 {
            integrator.step(&mut system)?;
        }
        if scene.records_step(k) {
            let state = integrator.state();
            recorder.record_state(&system.model, &mut system.data, state, &initial, &mut row);
            times.push(state.t);
            positions.push(state.q.as_slice().to_vec());
            for (series, value) in values.iter_mut().zip(&row) {
                series.push(*value);
            }
        }
    }
    Ok(Trajectory {
        times,
        outputs: scene.outputs.clone(),
        values,
        positions,
        stats: *integrator.stats(),
    })
}
