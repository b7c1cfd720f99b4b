//! Unit tests of the forward sensitivities on small systems written out by hand: a nonlinear
//! oscillator with configuration-dependent mass (unconstrained start, `K_t` and `D_t` both analytic
//! and by central differences) and a Cartesian pendulum whose length is a parameter (a constraint
//! that depends on the parameter, a start that must be projected, the reported velocity's
//! projection). The reference is a central difference of whole trajectories run with tight Newton
//! tolerances.

use nalgebra::{DMatrix, DVector};

use super::*;
use crate::integrate::tests::alloc_counter::allocations;
use crate::integrate::{
    Constraints, DaeState, HhtSettings, NewtonDiagonal, Parameters, ResidualJacobians, SystemError,
};

/// Agreement of direct differentiation with the central-difference reference, relative to
/// `max(|reference|, floor)` with the floor at `REFERENCE_FLOOR` of the quantity's largest reference
/// value over time: the reference's own error is ~1e-10 here, the sensitivities' ~1e-9.
const AGREEMENT: f64 = 1e-6;
/// The relative floor above: derivatives crossing zero are judged against 1e-3 of their peak.
const REFERENCE_FLOOR: f64 = 1e-3;
/// Step in p of the 4-point central difference of whole trajectories of the oscillator: truncation
/// ~ε⁴/30 ≈ 3e-10 of the fifth derivative, Newton noise ~1e-15/ε.
const REFERENCE_STEP: f64 = 1e-2;
/// The same for the constrained pendulum, larger: with constraint rows `q̈` and `λ` carry the
/// rounding of `Φ` divided by `β'h²` (measured ~1e-11 at h = 10 ms, ~1e-9 at 1 ms), which the step
/// turns into ~2·noise/ε in the reference. Measured at h = 10 ms: the reference's `∂q̈/∂p` moves by
/// 3e-9 between ε = 5e-3 and 2e-2 and settles on the direct value (to 1e-10) at 4e-2; the
/// truncation error ε⁴/30 ≈ 1e-7 of the fifth derivative is still below the agreement asked.
const CONSTRAINED_REFERENCE_STEP: f64 = 4e-2;

/// The reference runs' Newton tolerances relative to the direct run's: 100× tighter. At the direct
/// run's own tolerances the constrained pendulum's runs at `p ± ε` stopped one iteration apart at
/// some steps (the rate-based acceptance), which put ~5e-10 of relative noise into each trajectory
/// and 6e-6 into the reference; at 1e-2 and 1e-3 of them the agreement is 1.3e-7 and 1.4e-7
/// (measured with the quadratic predictor; 8.6e-8 with the linear one it replaced).
const REFERENCE_TOLERANCE_FACTOR: f64 = 1e-2;

fn tight(h: f64) -> HhtSettings {
    HhtSettings {
        alpha: -0.1,
        step_s: h,
        reltol: 1e-13,
        abstol_position: 1e-17,
        abstol_multiplier: 1e-12,
        // The projection the sensitivities differentiate (SensitivityError::ProjectionMetric).
        projection_keeps_newton_mass: false,
        ..HhtSettings::default()
    }
}

/// `m (2 + cos q) q̈ = −k sin q − c q̇ + ½ m sin q q̇²` with `m = m0 (1 + 0.1 p0)`, `k = k0 (1 + 0.2 p1)`.
#[derive(Clone)]
struct Oscillator {
    offset: [f64; 2],
    analytic_jacobians: bool,
}

impl Oscillator {
    const MASS: f64 = 1.3;
    const STIFFNESS: f64 = 40.0;
    const DAMPING: f64 = 0.7;
    fn mass(&self) -> f64 {
        Self::MASS * (1.0 + 0.1 * self.offset[0])
    }
    fn stiffness(&self) -> f64 {
        Self::STIFFNESS * (1.0 + 0.2 * self.offset[1])
    }
}

impl DaeSystem for Oscillator {
    fn nq(&self) -> usize {
        1
    }
    fn nv(&self) -> usize {
        1
    }
    fn mass_matrix(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = self.mass() * (2.0 + q[0].cos());
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -self.stiffness() * q[0].sin() - Self::DAMPING * v[0]
            + 0.5 * self.mass() * q[0].sin() * v[0] * v[0];
        Ok(())
    }
    fn as_residual_jacobians(&mut self) -> Option<&mut dyn ResidualJacobians> {
        if self.analytic_jacobians {
            Some(self)
        } else {
            None
        }
    }
    fn as_newton_diagonal(&mut self) -> Option<&mut dyn NewtonDiagonal> {
        Some(self)
    }
    fn as_parameters(&mut self) -> Option<&mut dyn Parameters> {
        Some(self)
    }
}

impl NewtonDiagonal for Oscillator {
    fn newton_diagonal(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        _v: &DVector<f64>,
        stiffness_out: &mut DVector<f64>,
        damping_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        stiffness_out[0] = self.stiffness();
        damping_out[0] = Self::DAMPING;
        Ok(())
    }
}

impl Parameters for Oscillator {
    fn n_parameters(&self) -> usize {
        2
    }
    fn parameter_jacobians(
        &mut self,
        state: &DaeState<'_>,
        dynamics_out: &mut DMatrix<f64>,
        _constraints_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let DaeState { q, v, qdd, .. } = *state;
        let (s, c) = q[0].sin_cos();
        dynamics_out[(0, 0)] = 0.1 * Self::MASS * ((2.0 + c) * qdd[0] - 0.5 * s * v[0] * v[0]);
        dynamics_out[(0, 1)] = 0.2 * Self::STIFFNESS * s;
        Ok(())
    }
    fn set_parameter_offset(&mut self, k: usize, offset: f64) -> Result<(), SystemError> {
        self.offset = [0.0; 2];
        self.offset[k] = offset;
        Ok(())
    }
}

impl ResidualJacobians for Oscillator {
    fn residual_jacobians(
        &mut self,
        state: &DaeState<'_>,
        stiffness_out: &mut DMatrix<f64>,
        damping_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let DaeState { q, v, qdd, .. } = *state;
        let (m, k) = (self.mass(), self.stiffness());
        let (s, c) = q[0].sin_cos();
        stiffness_out[(0, 0)] = -m * s * qdd[0] + k * c - 0.5 * m * c * v[0] * v[0];
        damping_out[(0, 0)] = Self::DAMPING - m * s * v[0];
        Ok(())
    }
}

/// A point mass on a massless rod, `x² + y² = L²`, with `L = L0 (1 + 0.05 p0)` and
/// `m = m0 (1 + 0.1 p1)`, gravity −y and a linear damper.
#[derive(Clone)]
struct Pendulum {
    offset: [f64; 2],
    analytic_jacobians: bool,
}

impl Pendulum {
    const LENGTH: f64 = 0.8;
    const MASS: f64 = 2.0;
    const GRAVITY: f64 = 9.81;
    const DAMPING: f64 = 0.3;
    fn length(&self) -> f64 {
        Self::LENGTH * (1.0 + 0.05 * self.offset[0])
    }
    fn mass(&self) -> f64 {
        Self::MASS * (1.0 + 0.1 * self.offset[1])
    }
}

impl DaeSystem for Pendulum {
    fn nq(&self) -> usize {
        2
    }
    fn nv(&self) -> usize {
        2
    }
    fn mass_matrix(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out.fill_with_identity();
        *out *= self.mass();
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -Self::DAMPING * v[0];
        out[1] = -self.mass() * Self::GRAVITY - Self::DAMPING * v[1];
        Ok(())
    }
    fn as_residual_jacobians(&mut self) -> Option<&mut dyn ResidualJacobians> {
        if self.analytic_jacobians {
            Some(self)
        } else {
            None
        }
    }
    fn as_constraints(&mut self) -> Option<&mut dyn Constraints> {
        Some(self)
    }
    fn as_parameters(&mut self) -> Option<&mut dyn Parameters> {
        Some(self)
    }
}

impl Constraints for Pendulum {
    fn n_constraints(&self) -> usize {
        1
    }
    fn constraints(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let l = self.length();
        out[0] = q[0] * q[0] + q[1] * q[1] - l * l;
        Ok(())
    }
    fn constraint_jacobian(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = 2.0 * q[0];
        out[(0, 1)] = 2.0 * q[1];
        Ok(())
    }
    fn constraint_acceleration_bias(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -2.0 * (v[0] * v[0] + v[1] * v[1]);
        Ok(())
    }
}

impl Parameters for Pendulum {
    fn n_parameters(&self) -> usize {
        2
    }
    fn parameter_jacobians(
        &mut self,
        state: &DaeState<'_>,
        dynamics_out: &mut DMatrix<f64>,
        constraints_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let DaeState { qdd, .. } = *state;
        // r = m q̈ + Φ_qᵀ λ − Q: Φ_q does not depend on L; Φ does.
        dynamics_out[(0, 0)] = 0.0;
        dynamics_out[(1, 0)] = 0.0;
        constraints_out[(0, 0)] = -2.0 * self.length() * 0.05 * Self::LENGTH;
        dynamics_out[(0, 1)] = 0.1 * Self::MASS * qdd[0];
        dynamics_out[(1, 1)] = 0.1 * Self::MASS * (qdd[1] + Self::GRAVITY);
        constraints_out[(0, 1)] = 0.0;
        Ok(())
    }
    fn set_parameter_offset(&mut self, k: usize, offset: f64) -> Result<(), SystemError> {
        self.offset = [0.0; 2];
        self.offset[k] = offset;
        Ok(())
    }
}

impl ResidualJacobians for Pendulum {
    fn residual_jacobians(
        &mut self,
        state: &DaeState<'_>,
        stiffness_out: &mut DMatrix<f64>,
        damping_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let DaeState { lambda, .. } = *state;
        stiffness_out.fill_with_identity();
        *stiffness_out *= 2.0 * lambda[0];
        damping_out.fill_with_identity();
        *damping_out *= Self::DAMPING;
        Ok(())
    }
}

/// One recorded state: `(q, reported v, q̈, λ)` flattened.
fn record(integrator: &HhtIntegrator) -> Vec<f64> {
    let s = integrator.state();
    s.q.iter()
        .chain(s.v.iter())
        .chain(s.qdd.iter())
        .chain(s.lambda.iter())
        .copied()
        .collect()
}

/// The trajectory of `system` (states every `every` steps).
fn trajectory<S: DaeSystem + Clone>(
    system: &S,
    settings: HhtSettings,
    q0: &DVector<f64>,
    v0: &DVector<f64>,
    steps: usize,
    every: usize,
) -> Vec<Vec<f64>> {
    let mut system = system.clone();
    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, q0, v0).unwrap();
    let mut out = vec![record(&hht)];
    for k in 1..=steps {
        hht.step(&mut system).unwrap();
        if k % every == 0 {
            out.push(record(&hht));
        }
    }
    out
}

/// The sensitivities of the same records, flattened like [`record`]: `[record][entry][parameter]`.
fn sensitivities<S: DaeSystem + Clone>(
    system: &S,
    settings: HhtSettings,
    q0: &DVector<f64>,
    v0: &DVector<f64>,
    steps: usize,
    every: usize,
) -> (Vec<Vec<Vec<f64>>>, SensitivityStats) {
    let mut system = system.clone();
    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, q0, v0).unwrap();
    let mut sens = HhtSensitivity::new(&mut system, &hht, q0, v0).unwrap();
    let snapshot = |sens: &mut HhtSensitivity, system: &mut S, hht: &HhtIntegrator| {
        let p = sens.n_parameters();
        let mut rows: Vec<Vec<f64>> = Vec::new();
        let v = sens.reported_velocity(system, hht).unwrap().clone();
        for matrix in [sens.position().clone(), v, sens.acceleration().clone()] {
            for i in 0..matrix.nrows() {
                rows.push((0..p).map(|k| matrix[(i, k)]).collect());
            }
        }
        let l = sens.multipliers();
        for j in 0..l.nrows() {
            rows.push((0..p).map(|k| l[(j, k)]).collect());
        }
        rows
    };
    let mut out = vec![snapshot(&mut sens, &mut system, &hht)];
    for k in 1..=steps {
        sens.step(&mut system, &mut hht).unwrap();
        if k % every == 0 {
            out.push(snapshot(&mut sens, &mut system, &hht));
        }
    }
    (out, *sens.stats())
}

/// 4-point central difference of whole trajectories along each parameter.
fn reference<S: DaeSystem + Parameters + Clone>(
    system: &S,
    settings: HhtSettings,
    q0: &DVector<f64>,
    v0: &DVector<f64>,
    steps: usize,
    every: usize,
    step: f64,
) -> Vec<Vec<Vec<f64>>> {
    let p = system.n_parameters();
    // Every run's Newton converged to rounding, not just to the tolerance: a reused matrix, or the
    // rate-based acceptances, stop at iterates anywhere below it (at an iteration count that can
    // change from one run to the next), and the difference quotient divides that by ε.
    let settings = HhtSettings {
        reuse_newton_matrix: false,
        accept_by_carried_contraction: false,
        reltol: settings.reltol * REFERENCE_TOLERANCE_FACTOR,
        abstol_multiplier: settings.abstol_multiplier * REFERENCE_TOLERANCE_FACTOR,
        ..settings
    };
    let runs: Vec<Vec<[Vec<Vec<f64>>; 4]>> = (0..p)
        .map(|k| {
            let run = |offset: f64| {
                let mut s = system.clone();
                s.set_parameter_offset(k, offset).unwrap();
                trajectory(&s, settings, q0, v0, steps, every)
            };
            let e = step;
            vec![[run(2.0 * e), run(e), run(-e), run(-2.0 * e)]]
        })
        .collect();
    let records = runs[0][0][0].len();
    let entries = runs[0][0][0][0].len();
    (0..records)
        .map(|r| {
            (0..entries)
                .map(|i| {
                    (0..p)
                        .map(|k| {
                            let [a, b, c, d] = &runs[k][0];
                            (-a[r][i] + 8.0 * b[r][i] - 8.0 * c[r][i] + d[r][i]) / (12.0 * step)
                        })
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// Largest error of `direct` against `reference` over the entries `entries` and every parameter,
/// relative to `max(|reference|, floor · peak)` with the peak over records.
fn worst_relative_error(
    direct: &[Vec<Vec<f64>>],
    reference: &[Vec<Vec<f64>>],
    entries: std::ops::Range<usize>,
    floor: f64,
) -> f64 {
    let p = reference[0][0].len();
    let mut worst: f64 = 0.0;
    for i in entries {
        for k in 0..p {
            let peak = reference.iter().map(|r| r[i][k].abs()).fold(0.0, f64::max);
            if peak == 0.0 {
                continue;
            }
            for (d, r) in direct.iter().zip(reference) {
                let scale = r[i][k].abs().max(floor * peak);
                worst = worst.max((d[i][k] - r[i][k]).abs() / scale);
            }
        }
    }
    worst
}

#[test]
fn oscillator_sensitivities_match_central_differences() {
    let q0 = DVector::from_element(1, 1.1);
    let v0 = DVector::from_element(1, -0.4);
    let (steps, every) = (1000, 50);
    let settings = tight(1e-3);
    let base = Oscillator {
        offset: [0.0; 2],
        analytic_jacobians: false,
    };
    let reference = reference(&base, settings, &q0, &v0, steps, every, REFERENCE_STEP);
    for analytic in [false, true] {
        let system = Oscillator {
            analytic_jacobians: analytic,
            ..base.clone()
        };
        let (direct, stats) = sensitivities(&system, settings, &q0, &v0, steps, every);
        let error = worst_relative_error(&direct, &reference, 0..3, REFERENCE_FLOOR);
        eprintln!("oscillator, analytic Jacobians {analytic}: worst relative error {error:.3e}");
        assert!(
            error < AGREEMENT,
            "analytic Jacobians {analytic}: worst relative error {error:.3e}"
        );
        let expected_fd = if analytic { 0 } else { 4 * steps as u64 };
        assert_eq!(stats.jacobian_residual_evaluations, expected_fd);
        assert_eq!(
            (stats.steps, stats.solves),
            (steps as u64, 2 * (steps as u64 + 1)),
            "one solve per parameter per step, plus the start's"
        );
        assert_eq!(stats.start_evaluations, 0, "no rows: the start is exact");
    }
}

#[test]
fn constrained_sensitivities_match_central_differences() {
    // Started off the circle (radius 0.85 instead of 0.8), so the start projection depends on L.
    let theta: f64 = 0.9;
    let q0 = DVector::from_column_slice(&[0.85 * theta.sin(), -0.85 * theta.cos()]);
    let v0 = DVector::from_column_slice(&[0.4, 0.1]);
    // h = 20 ms: with constraint rows q̈ and λ carry the rounding of Φ divided by β'h² (measured
    // ~1e-9 at h = 1 ms), which the reference's central difference magnifies by 1/ε; at 20 ms that
    // floor is 400× lower and the reference resolves 1e-6 of every entry (worst measured: 3e-7).
    let (steps, every) = (50, 5);
    let settings = tight(2e-2);
    let base = Pendulum {
        offset: [0.0; 2],
        analytic_jacobians: false,
    };
    let reference = reference(
        &base,
        settings,
        &q0,
        &v0,
        steps,
        every,
        CONSTRAINED_REFERENCE_STEP,
    );
    let mut results = Vec::new();
    for analytic in [false, true] {
        let system = Pendulum {
            analytic_jacobians: analytic,
            ..base.clone()
        };
        let (direct, stats) = sensitivities(&system, settings, &q0, &v0, steps, every);
        let error = worst_relative_error(&direct, &reference, 0..7, REFERENCE_FLOOR);
        eprintln!("pendulum, analytic Jacobians {analytic}: worst relative error {error:.3e}");
        assert!(
            error < AGREEMENT,
            "analytic Jacobians {analytic}: worst relative error {error:.3e}"
        );
        results.push((direct, stats));
    }
    let (direct, stats) = results.swap_remove(0);
    let system = base;
    assert_eq!(stats.start_evaluations, 8, "4-point stencil × 2 parameters");
    assert_eq!(
        stats.projection_evaluations,
        4 * 2 * (steps / every) as u64,
        "4-point stencil × 2 parameters per record"
    );
    // Without the projection's own sensitivity the reported velocity is off by more than the
    // agreement: the test can tell.
    let mut no_projection = direct.clone();
    for (row, newmark) in no_projection.iter_mut().zip({
        let mut s = system.clone();
        let mut hht = HhtIntegrator::new(&mut s, settings, 0.0, &q0, &v0).unwrap();
        let mut sens = HhtSensitivity::new(&mut s, &hht, &q0, &v0).unwrap();
        let mut out = vec![sens.newmark_velocity().clone()];
        for k in 1..=steps {
            sens.step(&mut s, &mut hht).unwrap();
            if k % every == 0 {
                out.push(sens.newmark_velocity().clone());
            }
        }
        out
    }) {
        for i in 0..2 {
            for k in 0..2 {
                row[2 + i][k] = newmark[(i, k)];
            }
        }
    }
    let error = worst_relative_error(&no_projection, &reference, 2..4, REFERENCE_FLOOR);
    assert!(
        error > 10.0 * AGREEMENT,
        "the Newmark velocity's sensitivity alone is {error:.3e} off"
    );
}

#[test]
fn a_sensitivity_step_allocates_nothing() {
    let q0 = DVector::from_column_slice(&[0.5, -0.6]);
    let v0 = DVector::zeros(2);
    let mut system = Pendulum {
        offset: [0.0; 2],
        analytic_jacobians: false,
    };
    let settings = HhtSettings {
        projection_keeps_newton_mass: false,
        ..HhtSettings::default()
    };
    let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).unwrap();
    let mut sens = HhtSensitivity::new(&mut system, &hht, &q0, &v0).unwrap();
    sens.step(&mut system, &mut hht).unwrap();
    let before = allocations();
    for _ in 0..50 {
        sens.step(&mut system, &mut hht).unwrap();
        sens.reported_velocity(&mut system, &hht).unwrap();
    }
    assert_eq!(allocations() - before, 0);
}

#[test]
fn misuse_is_refused_clearly() {
    let q0 = DVector::from_element(1, 0.3);
    let v0 = DVector::zeros(1);
    let mut system = Oscillator {
        offset: [0.0; 2],
        analytic_jacobians: true,
    };
    let mut hht = HhtIntegrator::new(&mut system, HhtSettings::default(), 0.0, &q0, &v0).unwrap();
    let mut sens = HhtSensitivity::new(&mut system, &hht, &q0, &v0).unwrap();
    hht.step(&mut system).unwrap();
    let message = sens.step(&mut system, &mut hht).unwrap_err().to_string();
    assert!(
        message.contains("integrator is at step 1 but the sensitivities at step 0"),
        "{message}"
    );
    let message = HhtSensitivity::new(&mut system, &hht, &q0, &v0)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("must start with the trajectory"),
        "{message}"
    );
    // A constrained system whose projection keeps the Newton matrix's M: not what the
    // sensitivities differentiate.
    let q0 = DVector::from_column_slice(&[0.5, -0.6]);
    let v0 = DVector::zeros(2);
    let mut pendulum = Pendulum {
        offset: [0.0; 2],
        analytic_jacobians: false,
    };
    let hht = HhtIntegrator::new(&mut pendulum, HhtSettings::default(), 0.0, &q0, &v0).unwrap();
    let message = HhtSensitivity::new(&mut pendulum, &hht, &q0, &v0)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("projection_keeps_newton_mass = false"),
        "{message}"
    );
}

/// The adaptive step covers plain steps at its default tolerance (the sensitivities then work as
/// with the fixed step) and refuses clearly once a grid step is subdivided.
#[test]
fn subdivided_steps_are_refused_and_plain_adaptive_steps_differentiated() {
    let q0 = DVector::from_element(1, 1.1);
    let v0 = DVector::from_element(1, -0.4);
    let system = Oscillator {
        offset: [0.0; 2],
        analytic_jacobians: true,
    };
    // Default tolerance: every grid step is one plain step, identical to the fixed step's.
    let fixed = tight(1e-3);
    let adaptive = HhtSettings {
        step_control: crate::integrate::StepControl::Adaptive,
        ..fixed
    };
    let (direct_fixed, _) = sensitivities(&system, fixed, &q0, &v0, 200, 50);
    let (direct_adaptive, _) = sensitivities(&system, adaptive, &q0, &v0, 200, 50);
    assert_eq!(direct_fixed, direct_adaptive);
    // A tolerance that forces sub-steps: refused with the reason.
    let mut system = system;
    let tight_tolerance = HhtSettings {
        tolerance: 1e-12,
        ..adaptive
    };
    let mut hht = HhtIntegrator::new(&mut system, tight_tolerance, 0.0, &q0, &v0).unwrap();
    let mut sens = HhtSensitivity::new(&mut system, &hht, &q0, &v0).unwrap();
    let message = sens.step(&mut system, &mut hht).unwrap_err().to_string();
    assert!(message.contains("plain steps only"), "{message}");
}
