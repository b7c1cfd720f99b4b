//! A nominal run: consistent start, fixed steps, records at the scene's rate; interruptible once
//! per step.

use super::error::FailureContext;
use super::{Recorder, RobotSystem, SimulationError};
use crate::environment::Environment;
use crate::integrate::{HhtIntegrator, HhtSettings, HhtStats, IntegrateError};
use crate::model::Model;
use crate::scene::{Output, Scene};
use nalgebra::{DMatrix, DVector, UnitQuaternion};
use std::sync::atomic::{AtomicBool, Ordering};

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
    /// Contact counters (`None` when the scene declares no contacts).
    pub contacts: Option<crate::effects::ContactStats>,
    /// Whether the run stopped early (interrupted): the series end at the last record before the
    /// stop.
    pub partial: bool,
}

/// Records the outputs of `integrator`'s current state into `row` (`dim recorder.outputs()`,
/// overwritten) and returns that state's time, s: the record step of the nominal run and of the
/// sensitivity runs, written once. `initial`: the floating joints' start orientations
/// ([`Recorder::initial_orientations`]). Called on record steps only, never inside the step loop.
pub(super) fn record_current_state(
    recorder: &Recorder,
    system: &mut RobotSystem,
    integrator: &HhtIntegrator,
    initial: &[Option<UnitQuaternion<f64>>],
    row: &mut [f64],
) -> f64 {
    let state = integrator.state();
    recorder.record_state(system, state, initial, row);
    state.t
}

/// The integrator settings a scene asks for (tolerances at their documented defaults).
pub fn hht_settings(scene: &Scene) -> HhtSettings {
    HhtSettings {
        alpha: scene.alpha,
        step_s: scene.step_s,
        velocity_projection: scene.velocity_projection,
        step_control: scene.step_control,
        tolerance: scene.step_tolerance,
        max_step_halvings: scene.max_step_halvings,
        reuse_newton_matrix: scene.reuse_newton_matrix,
        ..HhtSettings::default()
    }
}

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

/// A given initial position that the start projection changed by more than this (rad or m, plus
/// the same fraction of its size) is reported, as [`VELOCITY_PROJECTION_NOTE`] for velocities:
/// positions that already close the rows move only by rounding.
pub const POSITION_PROJECTION_NOTE: f64 = 1e-9;

/// A given initial velocity that the start projection changed by more than this (rad/s or m/s,
/// plus the same fraction of its size) is reported: the projection of an already consistent
/// velocity changes it only by rounding (~1e-15).
pub const VELOCITY_PROJECTION_NOTE: f64 = 1e-9;

/// Checks that `model` can start `scene` (the consistent start of docs/method.md §5: position and
/// velocity projection, initial accelerations and multipliers) and returns warnings about what the
/// start changed: positions given in `initial.q` (or `initial.base`) that the rows moved, and
/// velocities given in `initial.v` that the constraint rows did not allow, with the
/// values before and after and, when the given ones can be kept, the velocities of the other
/// joints that keep them.
///
/// Errors: a start that fails (a singular mass matrix, constraints that cannot close, …) is a
/// [`SimulationError`] naming the joints and the likely cause (exit 2).
pub fn check_start(
    model: &Model,
    environment: &Environment,
    scene: &Scene,
) -> Result<Vec<String>, SimulationError> {
    let mut system = RobotSystem::new(model.clone(), *environment, scene);
    let violation = initial_violation(&mut system, scene);
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let integrator =
        HhtIntegrator::new(&mut system, hht_settings(scene), 0.0, &q0, &v0).map_err(|e| {
            SimulationError::from_failure(
                e,
                &FailureContext {
                    model,
                    scene,
                    q: &scene.initial_q,
                    initial_violation: violation,
                },
            )
        })?;
    let state = integrator.state();
    let mut warnings = Vec::new();
    let moved_positions: Vec<String> = moved_by_projection(
        scene.initial_q_given.iter().copied(),
        &scene.initial_q,
        state.q.as_slice(),
        POSITION_PROJECTION_NOTE,
    )
    .into_iter()
    .map(|i| {
        format!(
            "{} {} → {:.6}",
            crate::dynamics::joint_of_position(model, i),
            scene.initial_q[i],
            state.q[i]
        )
    })
    .collect();
    if !moved_positions.is_empty() {
        warnings.push(format!(
            "{}: [scene] initial.q does not satisfy the constraint rows; the start projection changed it: {}. Give positions that close the loops and mimic rows (a mimic joint left out of initial.q starts at its leader's)",
            scene.origins.sidecar,
            moved_positions.join(", ")
        ));
    }
    let changed = moved_by_projection(
        scene.initial_v_given.iter().copied(),
        &scene.initial_v,
        state.v.as_slice(),
        VELOCITY_PROJECTION_NOTE,
    );
    if !changed.is_empty() {
        let name = |i: usize| crate::dynamics::joint_of_velocity(model, i).to_string();
        let moved: Vec<String> = moved_by_projection(
            0..model.nv,
            &scene.initial_v,
            state.v.as_slice(),
            VELOCITY_PROJECTION_NOTE,
        )
        .into_iter()
        .map(|i| format!("{} {} → {:.6}", name(i), scene.initial_v[i], state.v[i]))
        .collect();
        let mut warning = format!(
            "{}: [scene] initial.v does not satisfy the constraint rows; the start projection changed it: {}",
            scene.origins.sidecar,
            moved.join(", ")
        );
        if let Some(kept) = keep_given_velocities(&mut system, scene, state.q.as_slice()) {
            let suggestion: Vec<String> = kept
                .iter()
                .map(|(i, v)| format!("{} = {v:.12}", name(*i)))
                .collect();
            warning.push_str(&format!(
                ". To start with the given velocities, also give {} in initial.v",
                suggestion.join(", ")
            ));
        } else {
            warning.push_str(
                ". The given velocities themselves violate the rows: give consistent ones",
            );
        }
        warnings.push(warning);
    }
    Ok(warnings)
}

/// Of the coordinates `indices`, those the start projection moved from `before` to `after` by more
/// than `note` (plus the same fraction of the value's size), in order.
fn moved_by_projection(
    indices: impl Iterator<Item = usize>,
    before: &[f64],
    after: &[f64],
    note: f64,
) -> Vec<usize> {
    indices
        .filter(|&i| (after[i] - before[i]).abs() > note * (1.0 + before[i].abs()))
        .collect()
}

/// The velocities of the joints not given in `initial.v` that make the given ones consistent with
/// the rows at the (projected) configuration `q`: `Φ_q[:, free] v_free = −Φ_t − Φ_q[:, given]
/// v_given`, least-norm; `None` when no such velocities exist (residual above the tolerance).
fn keep_given_velocities(
    system: &mut RobotSystem,
    scene: &Scene,
    q: &[f64],
) -> Option<Vec<(usize, f64)>> {
    /// Residual of the completed velocity constraint accepted as "satisfied", relative to the size
    /// of its right-hand side (least squares in f64 leaves ~1e-14).
    const CONSISTENT_RELATIVE: f64 = 1e-9;
    let (m, nv) = (system.constraints.len(), system.model.nv);
    let mut jacobian = DMatrix::zeros(m, nv);
    system
        .constraints
        .jacobian(&system.model, &mut system.data, q, &mut jacobian);
    let mut phi_t = DVector::zeros(m);
    system.constraints.time_derivative(0.0, &mut phi_t);
    let given = &scene.initial_v_given;
    let free: Vec<usize> = (0..nv).filter(|i| !given.contains(i)).collect();
    if free.is_empty() {
        return None;
    }
    let mut rhs = -phi_t;
    for &i in given {
        rhs.axpy(-scene.initial_v[i], &jacobian.column(i), 1.0);
    }
    let reduced = DMatrix::from_fn(m, free.len(), |r, c| jacobian[(r, free[c])]);
    let solution = reduced.clone().svd(true, true).solve(&rhs, 1e-12).ok()?;
    let residual = (&reduced * &solution - &rhs).amax();
    if residual > CONSISTENT_RELATIVE * rhs.amax().max(1.0) {
        return None;
    }
    Some(free.into_iter().zip(solution.iter().copied()).collect())
}

/// Simulates `model` in `environment` through `scene` from `t = 0` and records every output
/// (never interrupted).
pub fn simulate(
    model: Model,
    environment: Environment,
    scene: &Scene,
) -> Result<Trajectory, SimulationError> {
    simulate_interruptible(model, environment, scene, &AtomicBool::new(false))
}

/// Like [`simulate`], but checks `stop` once per step: when it is set, the run ends after the
/// current step with the records made so far and `partial = true` (the work between a request and
/// the stop is at most one HHT step). Errors name the joints and likely causes
/// ([`SimulationError::from_failure`]).
pub fn simulate_interruptible(
    model: Model,
    environment: Environment,
    scene: &Scene,
    stop: &AtomicBool,
) -> Result<Trajectory, SimulationError> {
    let mut system = RobotSystem::new(model, environment, scene);
    let violation = initial_violation(&mut system, scene);
    let mut last_q = scene.initial_q.clone();
    simulate_system(&mut system, scene, stop, &mut last_q).map_err(|e| {
        SimulationError::from_failure(
            e,
            &FailureContext {
                model: &system.model,
                scene,
                q: &last_q,
                initial_violation: violation,
            },
        )
    })
}

fn simulate_system(
    system: &mut RobotSystem,
    scene: &Scene,
    stop: &AtomicBool,
    last_q: &mut Vec<f64>,
) -> Result<Trajectory, IntegrateError> {
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut integrator = HhtIntegrator::new(system, hht_settings(scene), 0.0, &q0, &v0)?;
    let recorder = Recorder::new(&scene.outputs);
    let initial = Recorder::initial_orientations(&system.model, integrator.state().q.as_slice());
    // The scene's size was checked when it was resolved (at most MAX_STEPS steps), and the
    // command checked the memory of the records before the run.
    let n_records = scene.record_count() as usize;
    let mut times = Vec::with_capacity(n_records);
    let mut values: Vec<Vec<f64>> = vec![Vec::with_capacity(n_records); scene.outputs.len()];
    let mut row = vec![0.0; scene.outputs.len()];
    let mut positions = Vec::with_capacity(n_records);
    let mut partial = false;
    for k in 0..=scene.n_steps {
        if k > 0 {
            if stop.load(Ordering::Relaxed) {
                partial = true;
                break;
            }
            last_q.clear();
            last_q.extend_from_slice(integrator.state().q.as_slice());
            integrator.step(system)?;
            if system.effects.has_contacts() {
                let state = integrator.state();
                system.effects.observe_contacts(
                    &system.model,
                    &mut system.data,
                    state.q.as_slice(),
                    state.v.as_slice(),
                );
            }
        }
        if scene.records_step(k) {
            times.push(record_current_state(
                &recorder,
                system,
                &integrator,
                &initial,
                &mut row,
            ));
            positions.push(integrator.state().q.as_slice().to_vec());
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
        contacts: system.effects.contact_stats(),
        partial,
    })
}
