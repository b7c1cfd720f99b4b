//! A cheap estimate of the largest Lyapunov exponent of the nominal trajectory (docs/method.md §8):
//! is the motion chaotic, so that tiny parameter changes are amplified exponentially?
//!
//! `(nominal model, scene) ⇒ a reference run and a shadow run started SHADOW_SEPARATION away,
//! renormalised every RENORMALISATION_INTERVAL_S ⇒ λ = (1/T) Σ ln(d_k / d_0)`
//!
//! This is the classic two-trajectory method (Benettin et al. 1980): the shadow's separation from the
//! reference is measured and scaled back to `d_0` at regular intervals, so it stays in the linear
//! regime, and the logarithms of the growth factors add up to the exponent. The separation is measured
//! on positions and velocities, `d² = |Δq|² + (VELOCITY_TIME_SCALE_S · |Δq̇|)²`; the exponent does not
//! depend on that choice, only its transient does. Renormalising scales the difference of every
//! vector the integrator carries (state, Newmark velocity, predictor history), so the shadow continues
//! as a consistent HHT trajectory. The initial separation leaves a floating base's quaternion alone
//! (it would no longer be a unit quaternion). Cost: two runs, whatever the number of parameters.

use crate::environment::Environment;
use crate::integrate::HhtIntegrator;
use crate::model::{JointKind, Model};
use crate::scene::Scene;
use crate::simulate::{hht_settings, RobotSystem};
use nalgebra::DVector;
use std::sync::atomic::{AtomicBool, Ordering};

/// Initial and renormalised separation of the shadow run (rad or m, and time-scaled rad/s or m/s):
/// 10⁴ times the integrator's absolute position tolerance (1e-10), so Newton noise does not enter
/// the measured growth, and small enough to stay linear over one interval.
pub const SHADOW_SEPARATION: f64 = 1e-6;

/// Time between renormalisations, s: short enough that a separation growing at 50 /s stays within
/// e² of `SHADOW_SEPARATION`, long enough that Newton noise is not what is measured.
pub const RENORMALISATION_INTERVAL_S: f64 = 0.04;

/// A separation below this counts as collapsed (m or rad; 10⁻¹² of [`SHADOW_SEPARATION`]).
pub const COLLAPSED_SEPARATION: f64 = SHADOW_SEPARATION * 1e-12;

/// Largest factor by which a shrunken separation is scaled back up to [`SHADOW_SEPARATION`]: the
/// accelerations and multipliers it also scales carry rounding noise of ~1e-13 relative, which must
/// stay far below the separation.
pub const MAX_PULL: f64 = 1e3;

/// Weight of velocity differences in the separation, s.
pub const VELOCITY_TIME_SCALE_S: f64 = 0.1;

/// Above this amplification `exp(λ T)` over the horizon the trajectory is reported as chaotic: a
/// parameter change of 1 part in 10⁴ then reaches order one, which no low-order surrogate in the
/// parameters can follow.
pub const CHAOS_AMPLIFICATION: f64 = 1e4;

/// The estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LyapunovEstimate {
    /// The largest Lyapunov exponent, 1/s (negative: separations decay; about 0: regular motion).
    pub exponent_per_s: f64,
    /// `exp(λ T)` over the simulated horizon T: how much a small separation grows by the end.
    pub amplification: f64,
    /// Simulated time the estimate covers, s.
    pub horizon_s: f64,
}

impl LyapunovEstimate {
    /// Whether the motion is chaotic over the horizon (`amplification > CHAOS_AMPLIFICATION`).
    pub fn is_chaotic(&self) -> bool {
        self.amplification > CHAOS_AMPLIFICATION
    }

    /// The time after which an initial relative difference `relative` has grown to order one:
    /// `ln(1/relative) / λ` (infinite for λ ≤ 0).
    pub fn predictability_horizon_s(&self, relative: f64) -> f64 {
        if self.exponent_per_s > 0.0 {
            (1.0 / relative).ln() / self.exponent_per_s
        } else {
            f64::INFINITY
        }
    }
}

/// Estimates the largest Lyapunov exponent of `model` in `environment` (the nominal parameters)
/// in `scene`. Returns
/// `None` when either run fails or is interrupted (the study reports the nominal run's failure
/// itself).
pub fn estimate_lyapunov(
    model: &Model,
    environment: &Environment,
    scene: &Scene,
    interrupt: &AtomicBool,
) -> Option<LyapunovEstimate> {
    let settings = hht_settings(scene);
    let mut reference_system = RobotSystem::new(model.clone(), *environment, scene);
    let mut shadow_system = RobotSystem::new(model.clone(), *environment, scene);
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let mut reference = HhtIntegrator::new(&mut reference_system, settings, 0.0, &q0, &v0).ok()?;
    let perturbed = perturbable_coordinates(model);
    let n_perturbed = perturbed.iter().filter(|&&p| p).count() + model.nv;
    let unit = SHADOW_SEPARATION / (n_perturbed as f64).sqrt();
    let mut q = reference.state().q.clone();
    let mut v = reference.state().v.clone();
    for (x, &p) in q.iter_mut().zip(&perturbed) {
        if p {
            *x += unit;
        }
    }
    v.iter_mut()
        .for_each(|x| *x += unit / VELOCITY_TIME_SCALE_S);
    let mut shadow = HhtIntegrator::new(&mut shadow_system, settings, 0.0, &q, &v).ok()?;
    let steps_per_interval = ((RENORMALISATION_INTERVAL_S / scene.step_s).round() as usize).max(1);
    let mut log_growth = 0.0;
    let mut measured_s = 0.0;
    // The separation at the start of the current interval.
    let mut d_start = SHADOW_SEPARATION;
    let mut step = 0;
    while step < scene.n_steps {
        let steps = steps_per_interval.min(scene.n_steps - step);
        for _ in 0..steps {
            if interrupt.load(Ordering::Relaxed) {
                return None;
            }
            reference.step(&mut reference_system).ok()?;
            shadow.step(&mut shadow_system).ok()?;
        }
        step += steps;
        let (r, s) = (reference.state(), shadow.state());
        let mut d2 = 0.0;
        for (a, b) in s.q.iter().zip(r.q.iter()) {
            d2 += (a - b).powi(2);
        }
        for (a, b) in s.v.iter().zip(r.v.iter()) {
            d2 += (VELOCITY_TIME_SCALE_S * (a - b)).powi(2);
        }
        if !d2.is_finite() {
            return None;
        }
        // A fully prescribed motion (drives and loops leave no freedom) projects the shadow back
        // onto the reference: the separation vanishes, which the floor turns into a large negative
        // exponent instead of ln 0.
        let d = d2.sqrt().max(COLLAPSED_SEPARATION);
        log_growth += (d / d_start).ln();
        measured_s += steps as f64 * scene.step_s;
        d_start = d;
        // Pull back only a separation that has grown, or shrunk by less than MAX_PULL: scaling a
        // collapsed separation up would blow rounding noise in the accelerations up with it.
        if step < scene.n_steps && d * MAX_PULL > SHADOW_SEPARATION {
            d_start = SHADOW_SEPARATION;
            // Back to SHADOW_SEPARATION along the current separation, for every vector the
            // integrator carries (not a restart: that would reset the generalized-α recursion and
            // inject a start transient larger than the separation itself).
            let scale = SHADOW_SEPARATION / d;
            let near = reference.trajectory();
            let mut far = shadow.trajectory();
            far.pull_towards(&near, scale);
            shadow.swap_trajectory(&mut far).ok()?;
        }
    }
    if measured_s <= 0.0 {
        return None;
    }
    let exponent_per_s = log_growth / measured_s;
    Some(LyapunovEstimate {
        exponent_per_s,
        amplification: (exponent_per_s * measured_s).exp(),
        horizon_s: measured_s,
    })
}

/// Which position coordinates the shadow perturbs: all but a floating base's quaternion.
fn perturbable_coordinates(model: &Model) -> Vec<bool> {
    let mut perturbed = vec![true; model.nq];
    for joint in &model.joints {
        if joint.kind == JointKind::Floating {
            for p in &mut perturbed[joint.q_index + 3..joint.q_index + 7] {
                *p = false;
            }
        }
    }
    perturbed
}
