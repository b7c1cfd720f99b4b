//! Unit tests of the HHT-I3 integrator on small systems with known solutions: convergence order
//! (scalar system with configuration-dependent mass, Cartesian pendulum, prescribed motion), energy
//! behaviour, stiff springs (diagonal Newton terms), conditioning of the iteration matrix, the
//! consistent start, settings validation, NaN detection, the manifold update and allocation-free
//! steps.
//!
//! This file holds what the tests share: the named tolerances, the helpers (`simulate`, RK4) and
//! the test systems. The tests are in `tests/`: `order.rs` (convergence order, energy),
//! `stiffness.rs`, `constraints.rs` (with conditioning and the consistent start), `settings.rs`,
//! `failures.rs` (with allocation and restart), `newton_reuse.rs`; `alloc_counter.rs` is the
//! counting allocator.
//!
//! Note: this test binary installs a counting global allocator (see `alloc_counter`) to prove that a
//! step allocates nothing. A crate can have only one `#[global_allocator]`; share this one if another
//! module needs the same measurement.

use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector};

use super::*;

pub(crate) mod alloc_counter;
mod constraints;
mod failures;
mod newton_reuse;
mod order;
mod settings;
mod stiffness;

// ---------------------------------------------------------------------------------------------
// Tolerances and thresholds (named, with reasons)
// ---------------------------------------------------------------------------------------------

/// A second-order method divides its error by 4 when h halves; 3.5 leaves room for the
/// higher-order terms at the coarsest step while failing clearly for a first-order method (ratio 2).
const MIN_SECOND_ORDER_RATIO: f64 = 3.5;
/// Above this ratio a "halving" is not first order: used to check the discriminating power of the
/// order test on the Negrut form (which measures ≈ 2).
const MAX_FIRST_ORDER_RATIO: f64 = 2.5;
/// Tight Newton tolerances for the convergence-order tests, so that Newton error (not the
/// discretisation) never decides a ratio.
const TIGHT_RELTOL: f64 = 1e-12;
const TIGHT_ABSTOL_POSITION: f64 = 1e-15;
const TIGHT_ABSTOL_MULTIPLIER: f64 = 1e-12;
/// Position-level constraint after each accepted step, m: Newton drives Φ to rounding level.
const MAX_CONSTRAINT_VIOLATION: f64 = 1e-10;
/// Velocity-level constraint after projection, m/s: the projection solves it to rounding level.
const MAX_PROJECTED_VELOCITY_VIOLATION: f64 = 1e-10;
/// Bound on the scaled iteration matrix's condition number for h from 1e-2 to 1e-6 (docs/method.md
/// measured ≈ 59 on its test system).
const MAX_SCALED_CONDITION: f64 = 1e3;
/// The unscaled condition number grows like h⁻²: a factor 100 per decade of h; accept 50..200.
const UNSCALED_DECADE_GROWTH: (f64, f64) = (50.0, 200.0);
/// RK4 reference step, s: RK4's error at this step (~1e-20·C) is far below every compared error.
const REFERENCE_STEP: f64 = 1e-5;

fn tight_settings(alpha: f64, h: f64) -> HhtSettings {
    HhtSettings {
        alpha,
        step_s: h,
        reltol: TIGHT_RELTOL,
        abstol_position: TIGHT_ABSTOL_POSITION,
        abstol_multiplier: TIGHT_ABSTOL_MULTIPLIER,
        ..HhtSettings::default()
    }
}

fn dvec(x: &[f64]) -> DVector<f64> {
    DVector::from_column_slice(x)
}

/// Number of steps of size `h` in `duration` (exact multiples in all tests).
fn n_steps(duration: f64, h: f64) -> usize {
    (duration / h).round() as usize
}

/// Integrates `sys` from `(q0, v0)` for `duration` seconds; returns the integrator at the end.
fn simulate<S: DaeSystem>(
    sys: &mut S,
    settings: HhtSettings,
    q0: &[f64],
    v0: &[f64],
    duration: f64,
) -> HhtIntegrator {
    let mut hht = HhtIntegrator::new(sys, settings, 0.0, &dvec(q0), &dvec(v0)).expect("start");
    for _ in 0..n_steps(duration, settings.step_s) {
        hht.step(sys).expect("step");
    }
    hht
}

/// Classical RK4 for `ẏ = f(t, y)` with `N` states, `n` steps of size `h`.
fn rk4<const N: usize>(
    f: impl Fn(f64, &[f64; N]) -> [f64; N],
    y0: [f64; N],
    h: f64,
    n: usize,
) -> [f64; N] {
    let mut y = y0;
    let add = |y: &[f64; N], k: &[f64; N], s: f64| {
        let mut out = *y;
        for i in 0..N {
            out[i] += s * k[i];
        }
        out
    };
    for step in 0..n {
        let t = step as f64 * h;
        let k1 = f(t, &y);
        let k2 = f(t + 0.5 * h, &add(&y, &k1, 0.5 * h));
        let k3 = f(t + 0.5 * h, &add(&y, &k2, 0.5 * h));
        let k4 = f(t + h, &add(&y, &k3, h));
        for i in 0..N {
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    y
}

/// `[1.234e-5, …]` for test output.
fn sci(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|v| format!("{v:.3e}")).collect();
    format!("[{}]", items.join(", "))
}

fn ratios(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| w[0] / w[1]).collect()
}

// ---------------------------------------------------------------------------------------------
// Test systems
// ---------------------------------------------------------------------------------------------

/// `(2 + cos q) q̈ = −3 sin q + ½ sin q q̇²`: one coordinate, configuration-dependent mass,
/// conservative with energy `½ (2 + cos q) q̇² − 3 cos q`.
struct Scalar {
    /// Provide `dynamics_residual` (RNEA-style path) instead of mass matrix + forces.
    residual: bool,
    /// Return NaN forces after this time, s.
    nan_after_s: f64,
}

impl Scalar {
    fn new() -> Self {
        Self {
            residual: false,
            nan_after_s: f64::INFINITY,
        }
    }
    fn mass(q: f64) -> f64 {
        2.0 + q.cos()
    }
    fn force(q: f64, v: f64) -> f64 {
        -3.0 * q.sin() + 0.5 * q.sin() * v * v
    }
    fn energy(q: f64, v: f64) -> f64 {
        0.5 * Self::mass(q) * v * v - 3.0 * q.cos()
    }
    fn reference(q0: f64, v0: f64, duration: f64) -> f64 {
        let y = rk4(
            |_, y: &[f64; 2]| [y[1], Self::force(y[0], y[1]) / Self::mass(y[0])],
            [q0, v0],
            REFERENCE_STEP,
            n_steps(duration, REFERENCE_STEP),
        );
        y[0]
    }
}

impl DaeSystem for Scalar {
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
        out[(0, 0)] = Self::mass(q[0]);
        Ok(())
    }
    fn forces(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = if t > self.nan_after_s {
            f64::NAN
        } else {
            Self::force(q[0], v[0])
        };
        Ok(())
    }
    fn as_inverse_dynamics(&mut self) -> Option<&mut dyn InverseDynamics> {
        if self.residual {
            Some(self)
        } else {
            None
        }
    }
}

impl InverseDynamics for Scalar {
    fn dynamics_residual(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = Self::mass(q[0]) * qdd[0] - Self::force(q[0], v[0]);
        Ok(())
    }
}

/// Linear spring-mass-damper `m q̈ + c q̇ + k q = 0`, reporting `k`, `c` as Newton diagonal terms.
struct Oscillator {
    mass_kg: f64,
    stiffness: f64,
    damping: f64,
}

impl Oscillator {
    /// Closed-form position for `ζ < 1` from `(q0, v0)` at `t`.
    fn exact(&self, q0: f64, v0: f64, t: f64) -> f64 {
        let wn = (self.stiffness / self.mass_kg).sqrt();
        let zeta = self.damping / (2.0 * (self.stiffness * self.mass_kg).sqrt());
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        (-zeta * wn * t).exp() * (q0 * (wd * t).cos() + (v0 + zeta * wn * q0) / wd * (wd * t).sin())
    }
    fn energy(&self, q: f64, v: f64) -> f64 {
        0.5 * self.mass_kg * v * v + 0.5 * self.stiffness * q * q
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
        _q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = self.mass_kg;
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -self.stiffness * q[0] - self.damping * v[0];
        Ok(())
    }
    fn as_newton_diagonal(&mut self) -> Option<&mut dyn NewtonDiagonal> {
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
        stiffness_out[0] = self.stiffness;
        damping_out[0] = self.damping;
        Ok(())
    }
}

/// Planar pendulum in Cartesian coordinates `(x, y)`: point mass `m` under gravity `−g ŷ`,
/// `Φ = x² + y² − L²` (one row). Variants for the consistent-start errors.
struct CartesianPendulum {
    mass_kg: f64,
    length_m: f64,
    gravity: f64,
    variant: PendulumVariant,
}

#[derive(Clone, Copy, PartialEq)]
enum PendulumVariant {
    /// One row `x² + y² − L²`.
    Plain,
    /// The same row twice: Φ_q rank deficient.
    DuplicatedRow,
    /// Plus the row `y − 2L`: the circle and the line do not meet.
    CannotClose,
}

impl CartesianPendulum {
    fn new(variant: PendulumVariant) -> Self {
        Self {
            mass_kg: 1.0,
            length_m: 1.0,
            gravity: 9.81,
            variant,
        }
    }
    /// Reference `(θ, θ̇)` with `x = L sin θ`, `y = −L cos θ`.
    fn reference(&self, theta0: f64, duration: f64) -> [f64; 2] {
        let (g, l) = (self.gravity, self.length_m);
        rk4(
            |_, y: &[f64; 2]| [y[1], -(g / l) * y[0].sin()],
            [theta0, 0.0],
            REFERENCE_STEP,
            n_steps(duration, REFERENCE_STEP),
        )
    }
    /// Exact multiplier for `M q̈ + Φ_qᵀ λ = Q` at `(θ, θ̇)`: `λ = m (L² θ̇² + g L cos θ) / (2 L²)`.
    fn lambda(&self, theta: f64, theta_dot: f64) -> f64 {
        let (m, g, l) = (self.mass_kg, self.gravity, self.length_m);
        m * (l * l * theta_dot * theta_dot + g * l * theta.cos()) / (2.0 * l * l)
    }
}

impl DaeSystem for CartesianPendulum {
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
        *out *= self.mass_kg;
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        _v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = 0.0;
        out[1] = -self.mass_kg * self.gravity;
        Ok(())
    }
    fn as_constraints(&mut self) -> Option<&mut dyn Constraints> {
        Some(self)
    }
}

impl Constraints for CartesianPendulum {
    fn n_constraints(&self) -> usize {
        match self.variant {
            PendulumVariant::Plain => 1,
            _ => 2,
        }
    }
    fn constraints(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let l = self.length_m;
        out[0] = q[0] * q[0] + q[1] * q[1] - l * l;
        match self.variant {
            PendulumVariant::Plain => {}
            PendulumVariant::DuplicatedRow => out[1] = out[0],
            PendulumVariant::CannotClose => out[1] = q[1] - 2.0 * l,
        }
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
        match self.variant {
            PendulumVariant::Plain => {}
            PendulumVariant::DuplicatedRow => {
                out[(1, 0)] = 2.0 * q[0];
                out[(1, 1)] = 2.0 * q[1];
            }
            PendulumVariant::CannotClose => {
                out[(1, 0)] = 0.0;
                out[(1, 1)] = 1.0;
            }
        }
        Ok(())
    }
    fn constraint_acceleration_bias(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        // Φ_q q̈ = −(Φ_q q̇)_q q̇ = −2 (ẋ² + ẏ²)
        out[0] = -2.0 * (v[0] * v[0] + v[1] * v[1]);
        if out.len() > 1 {
            out[1] = if self.variant == PendulumVariant::DuplicatedRow {
                out[0]
            } else {
                0.0
            };
        }
        Ok(())
    }
}

/// A mass on a spring and damper, driven by the rheonomic row `Φ = q − sin(2π t)`.
/// Exact: `q̈ = −4π² sin(2π t)`, `λ = Q − M q̈`.
struct Prescribed {
    mass_kg: f64,
    stiffness: f64,
    damping: f64,
}

impl Prescribed {
    const OMEGA: f64 = 2.0 * PI;
    fn exact_qdd(t: f64) -> f64 {
        -Self::OMEGA * Self::OMEGA * (Self::OMEGA * t).sin()
    }
    fn exact_lambda(&self, t: f64) -> f64 {
        let q = (Self::OMEGA * t).sin();
        let v = Self::OMEGA * (Self::OMEGA * t).cos();
        -self.stiffness * q - self.damping * v - self.mass_kg * Self::exact_qdd(t)
    }
}

impl DaeSystem for Prescribed {
    fn nq(&self) -> usize {
        1
    }
    fn nv(&self) -> usize {
        1
    }
    fn mass_matrix(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = self.mass_kg;
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -self.stiffness * q[0] - self.damping * v[0];
        Ok(())
    }
    fn as_constraints(&mut self) -> Option<&mut dyn Constraints> {
        Some(self)
    }
}

impl Constraints for Prescribed {
    fn n_constraints(&self) -> usize {
        1
    }
    fn constraints(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = q[0] - (Self::OMEGA * t).sin();
        Ok(())
    }
    fn constraint_jacobian(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = 1.0;
        Ok(())
    }
    fn constraint_time_derivative(
        &mut self,
        t: f64,
        _q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -Self::OMEGA * (Self::OMEGA * t).cos();
        Ok(())
    }
    fn constraint_acceleration_bias(
        &mut self,
        t: f64,
        _q: &DVector<f64>,
        _v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        // −Φ_tt = −ω² sin(ω t)
        out[0] = Self::exact_qdd(t);
        Ok(())
    }
}

/// A rotor whose angle is stored as a unit complex number `q = (cos θ, sin θ)` (nq = 2, nv = 1):
/// `θ̈ = −3 sin θ`. Exercises `integrate_position` on a manifold, like a quaternion base.
struct Rotor;

impl DaeSystem for Rotor {
    fn nq(&self) -> usize {
        2
    }
    fn nv(&self) -> usize {
        1
    }
    fn mass_matrix(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = 1.0;
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        _v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -3.0 * q[1];
        Ok(())
    }
    fn as_position_group(&self) -> Option<&dyn PositionGroup> {
        Some(self)
    }
    fn as_position_scale(&self) -> Option<&dyn PositionScale> {
        Some(self)
    }
}

impl PositionGroup for Rotor {
    fn integrate_position(
        &self,
        q: &DVector<f64>,
        dq: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let (c, s) = (dq[0].cos(), dq[0].sin());
        let (x, y) = (q[0] * c - q[1] * s, q[0] * s + q[1] * c);
        let n = (x * x + y * y).sqrt();
        out[0] = x / n;
        out[1] = y / n;
        Ok(())
    }
    /// The rotation group of the plane is commutative: a perturbation passes through unchanged.
    fn integrate_position_jacobians(
        &self,
        _q: &DVector<f64>,
        _dq: &DVector<f64>,
        wrt_q_out: &mut DMatrix<f64>,
        wrt_dq_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        wrt_q_out.fill_with_identity();
        wrt_dq_out.fill_with_identity();
        Ok(())
    }
    /// The angle of `q0⁻¹ q1`.
    fn difference_position(
        &self,
        q0: &DVector<f64>,
        q1: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let (x, y) = (q0[0] * q1[0] + q0[1] * q1[1], q0[0] * q1[1] - q0[1] * q1[0]);
        out[0] = y.atan2(x);
        Ok(())
    }
}

impl PositionScale for Rotor {
    fn position_scale(&self, q: &DVector<f64>, out: &mut DVector<f64>) {
        out[0] = q[1].atan2(q[0]).abs();
    }
}

/// The same rotor with the angle as coordinate.
struct AngleRotor;

impl DaeSystem for AngleRotor {
    fn nq(&self) -> usize {
        1
    }
    fn nv(&self) -> usize {
        1
    }
    fn mass_matrix(
        &mut self,
        _t: f64,
        _q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out[(0, 0)] = 1.0;
        Ok(())
    }
    fn forces(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        _v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        out[0] = -3.0 * q[0].sin();
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Starting points and steps the test files share
// ---------------------------------------------------------------------------------------------

const SCALAR_Q0: f64 = 1.0;
const SCALAR_V0: f64 = 0.5;
const ORDER_STEPS: [f64; 3] = [2e-3, 1e-3, 5e-4];

const PENDULUM_THETA0: f64 = 1.0;

fn pendulum_start() -> ([f64; 2], [f64; 2]) {
    let l = 1.0;
    (
        [l * PENDULUM_THETA0.sin(), -l * PENDULUM_THETA0.cos()],
        [0.0, 0.0],
    )
}
