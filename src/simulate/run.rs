//! A nominal run: consistent start, fixed steps, records at the scene's rate.

use super::{Recorder, RobotSystem};
use crate::integrate::{HhtIntegrator, HhtSettings, HhtStats, IntegrateError};
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

/// Simulates `model` through `scene` from `t = 0` and records every output.
pub fn simulate(model: Model, scene: &Scene) -> Result<Trajectory, IntegrateError> {
    let mut system = RobotSystem::new(model, scene);
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut integrator = HhtIntegrator::new(&mut system, hht_settings(scene), 0.0, &q0, &v0)?;
    let recorder = Recorder::new(
        &system.model,
        &scene.outputs,
        integrator.state().q.as_slice(),
    );
    let n_records = scene.n_steps / scene.record_every + 2;
    let mut times = Vec::with_capacity(n_records);
    let mut values: Vec<Vec<f64>> = vec![Vec::with_capacity(n_records); scene.outputs.len()];
    let mut row = vec![0.0; scene.outputs.len()];
    for k in 0..=scene.n_steps {
        if k > 0 {
            integrator.step(&mut system)?;
        }
        if scene.records_step(k) {
            let state = integrator.state();
            recorder.record(
                &system.model,
                &mut system.data,
                state.q.as_slice(),
                state.v.as_slice(),
                state.qdd.as_slice(),
                &mut row,
            );
            times.push(state.t);
            for (series, value) in values.iter_mut().zip(&row) {
                series.push(*value);
            }
        }
    }
    Ok(Trajectory {
        times,
        outputs: scene.outputs.clone(),
        values,
        stats: *integrator.stats(),
    })
}
