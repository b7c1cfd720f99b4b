//! Unit tests of the HHT-I3 integrator on small systems with known solutions: convergence order
//! (scalar system with configuration-dependent mass, Cartesian pendulum, prescribed motion), energy
//! behaviour, stiff springs (diagonal Newton terms), conditioning of the iteration matrix, the
//! consistent start, settings validation, NaN detection, the manifold update and allocation-free
//! steps.
//!
//! Note: this test binary installs a counting global allocator (see `alloc_counter`) to prove that a
//! step allocates nothing. A crate can have only one `#[global_allocator]`; share this one if another
//! module needs the same measurement.

use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector};

use super::*;

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
    fn n_constraints(&self) -> usize {
        match self.variant {
            PendulumVariant::Plain => 1,
            _ => 2,
        }
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
    fn n_constraints(&self) -> usize {
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
    fn position_scale(&self, q: &DVector<f64>, out: &mut DVector<f64>) {
        out[0] = q[1].atan2(q[0]).abs();
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
// Convergence order
// ---------------------------------------------------------------------------------------------

const SCALAR_Q0: f64 = 1.0;
const SCALAR_V0: f64 = 0.5;
const ORDER_STEPS: [f64; 3] = [2e-3, 1e-3, 5e-4];

#[test]
fn scalar_system_is_second_order_in_position() {
    let reference = Scalar::reference(SCALAR_Q0, SCALAR_V0, 1.0);
    for alpha in [-0.1, -0.3] {
        let mut errors = Vec::new();
        let mut iterations = Vec::new();
        for h in ORDER_STEPS {
            let mut sys = Scalar::new();
            let hht = simulate(
                &mut sys,
                tight_settings(alpha, h),
                &[SCALAR_Q0],
                &[SCALAR_V0],
                1.0,
            );
            errors.push((hht.state().q[0] - reference).abs());
            iterations.push(hht.stats().newton_iterations as f64 / hht.stats().steps as f64);
        }
        let r = ratios(&errors);
        let errors_sci = sci(&errors);
        println!(
            "scalar α = {alpha}: |q(1) − q_ref| = {errors_sci}, ratios {r:.3?}, Newton it/step {iterations:.2?}"
        );
        for ratio in r {
            assert!(
                ratio >= MIN_SECOND_ORDER_RATIO,
                "α = {alpha}: ratio {ratio}"
            );
        }
    }
}

/// One step of the form printed by Negrut et al. (Chrono's `ChTimestepperHHT`) on the scalar system:
/// `M(q₁) q̈₁/(1+α) − Q₁ + α/(1+α) Q₀ = 0` with plain Newmark updates in `q̈` (`γ = ½ − α`,
/// `β = (1−α)²/4`). Scalar secant-Newton to rounding level.
fn negrut_scalar(alpha: f64, h: f64, duration: f64) -> f64 {
    let gamma = 0.5 - alpha;
    let beta = 0.25 * (1.0 - alpha) * (1.0 - alpha);
    let (mut q, mut v) = (SCALAR_Q0, SCALAR_V0);
    let mut qdd = Scalar::force(q, v) / Scalar::mass(q);
    for _ in 0..n_steps(duration, h) {
        let q0_force = Scalar::force(q, v);
        let kin = |a1: f64| {
            let q1 = q + h * v + h * h * ((0.5 - beta) * qdd + beta * a1);
            let v1 = v + h * ((1.0 - gamma) * qdd + gamma * a1);
            (q1, v1)
        };
        let residual = |a1: f64| {
            let (q1, v1) = kin(a1);
            Scalar::mass(q1) * a1 / (1.0 + alpha) - Scalar::force(q1, v1)
                + alpha / (1.0 + alpha) * q0_force
        };
        let mut a1 = qdd;
        for _ in 0..50 {
            let r = residual(a1);
            let d = 1e-7 * (1.0 + a1.abs());
            let slope = (residual(a1 + d) - r) / d;
            let delta = -r / slope;
            a1 += delta;
            if delta.abs() < 1e-15 * (1.0 + a1.abs()) {
                break;
            }
        }
        let (q1, v1) = kin(a1);
        q = q1;
        v = v1;
        qdd = a1;
    }
    q
}

/// The order test above discriminates: the Negrut/Chrono form (first order when M depends on q)
/// measures a ratio ≈ 2 on the same system, steps and reference.
#[test]
fn negrut_form_is_first_order_on_the_scalar_system() {
    let reference = Scalar::reference(SCALAR_Q0, SCALAR_V0, 1.0);
    for alpha in [-0.1, -0.3] {
        let errors: Vec<f64> = ORDER_STEPS
            .iter()
            .map(|&h| (negrut_scalar(alpha, h, 1.0) - reference).abs())
            .collect();
        let r = ratios(&errors);
        let errors_sci = sci(&errors);
        println!("Negrut form α = {alpha}: errors {errors_sci}, ratios {r:.3?}");
        for ratio in r {
            assert!(ratio < MAX_FIRST_ORDER_RATIO, "α = {alpha}: ratio {ratio}");
        }
    }
}

/// The residual through `dynamics_residual` (inverse dynamics) and through `mass_matrix` + `forces`
/// give the same trajectory up to rounding.
#[test]
fn dynamics_residual_path_matches_mass_matrix_path() {
    /// Different summation order only: a few rounding units after 1000 steps.
    const SAME_TRAJECTORY: f64 = 1e-12;
    let settings = HhtSettings::default();
    let mut plain = Scalar::new();
    let mut rnea = Scalar {
        residual: true,
        ..Scalar::new()
    };
    let a = simulate(&mut plain, settings, &[SCALAR_Q0], &[SCALAR_V0], 1.0);
    let b = simulate(&mut rnea, settings, &[SCALAR_Q0], &[SCALAR_V0], 1.0);
    let dq = (a.state().q[0] - b.state().q[0]).abs();
    println!(
        "residual paths: |Δq| = {dq:.2e}, iterations {} vs {}",
        a.stats().newton_iterations,
        b.stats().newton_iterations
    );
    assert!(dq < SAME_TRAJECTORY);
}

/// Default settings (not the tight ones) are accurate enough for second order at 1 ms.
#[test]
fn default_tolerances_keep_second_order() {
    let reference = Scalar::reference(SCALAR_Q0, SCALAR_V0, 1.0);
    let errors: Vec<f64> = ORDER_STEPS
        .iter()
        .map(|&h| {
            let mut sys = Scalar::new();
            let settings = HhtSettings {
                step_s: h,
                ..HhtSettings::default()
            };
            let hht = simulate(&mut sys, settings, &[SCALAR_Q0], &[SCALAR_V0], 1.0);
            (hht.state().q[0] - reference).abs()
        })
        .collect();
    let r = ratios(&errors);
    let errors_sci = sci(&errors);
    println!("scalar, default tolerances: errors {errors_sci}, ratios {r:.3?}");
    for ratio in r {
        assert!(ratio >= MIN_SECOND_ORDER_RATIO, "ratio {ratio}");
    }
}

// ---------------------------------------------------------------------------------------------
// Linear oscillator and energy
// ---------------------------------------------------------------------------------------------

#[test]
fn damped_oscillator_matches_closed_form_at_second_order() {
    let osc = || Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0 * PI * PI, // 1 Hz
        damping: 0.5,
    };
    let (q0, v0, duration) = (0.1, 0.3, 2.0);
    let exact = osc().exact(q0, v0, duration);
    for alpha in [-0.1, -0.3] {
        let errors: Vec<f64> = ORDER_STEPS
            .iter()
            .map(|&h| {
                let mut sys = osc();
                let hht = simulate(&mut sys, tight_settings(alpha, h), &[q0], &[v0], duration);
                (hht.state().q[0] - exact).abs()
            })
            .collect();
        let r = ratios(&errors);
        let errors_sci = sci(&errors);
        println!("damped oscillator α = {alpha}: errors {errors_sci}, ratios {r:.3?}");
        for ratio in r {
            assert!(
                ratio >= MIN_SECOND_ORDER_RATIO,
                "α = {alpha}: ratio {ratio}"
            );
        }
    }
}

/// α = 0 (trapezoidal) on an undamped oscillator: the energy error is O(h²) — on the linear
/// oscillator it is even zero up to rounding (the trapezoidal rule conserves quadratic invariants);
/// on the nonlinear scalar system it is O(h²) and bounded (no drift) over 20 s.
#[test]
fn energy_error_with_alpha_zero_is_second_order() {
    /// Energy error bound for the linear oscillator: rounding and Newton tolerance only.
    const LINEAR_ENERGY_REL: f64 = 1e-9;
    let mut osc = Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0 * PI * PI,
        damping: 0.0,
    };
    let settings = HhtSettings {
        alpha: 0.0,
        step_s: 1e-2,
        ..tight_settings(0.0, 1e-2)
    };
    let e0 = osc.energy(0.1, 0.0);
    let mut hht =
        HhtIntegrator::new(&mut osc, settings, 0.0, &dvec(&[0.1]), &dvec(&[0.0])).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..n_steps(20.0, 1e-2) {
        hht.step(&mut osc).unwrap();
        let s = hht.state();
        worst = worst.max((osc.energy(s.q[0], s.v[0]) - e0).abs() / e0);
    }
    println!("linear oscillator, α = 0, h = 1e-2, 20 s: max relative energy error {worst:.2e}");
    assert!(worst < LINEAR_ENERGY_REL);

    let mut errors = Vec::new();
    for h in [1e-2, 5e-3, 2.5e-3] {
        let mut sys = Scalar::new();
        let e0 = Scalar::energy(SCALAR_Q0, SCALAR_V0);
        let mut hht = HhtIntegrator::new(
            &mut sys,
            tight_settings(0.0, h),
            0.0,
            &dvec(&[SCALAR_Q0]),
            &dvec(&[SCALAR_V0]),
        )
        .unwrap();
        let mut worst: f64 = 0.0;
        let mut final_error = 0.0;
        for _ in 0..n_steps(20.0, h) {
            hht.step(&mut sys).unwrap();
            let s = hht.state();
            final_error = Scalar::energy(s.q[0], s.v[0]) - e0;
            worst = worst.max(final_error.abs());
        }
        println!("scalar, α = 0, h = {h}: max |E − E0| over 20 s = {worst:.3e}, at 20 s {final_error:.3e}");
        errors.push(worst);
    }
    let r = ratios(&errors);
    println!("scalar energy error ratios {r:.3?}");
    for ratio in r {
        assert!(ratio >= MIN_SECOND_ORDER_RATIO, "ratio {ratio}");
    }
}

/// Largest one-step rise of the oscillator's physical energy, relative to E0, with α = −0.3 and
/// h = T/100: measured 8.7e-6 (the state's energy oscillates about the monotone algorithmic energy
/// by O(h²)); a tenfold margin.
const MAX_STEP_ENERGY_RISE: f64 = 1e-4;

/// With α < 0 the linear oscillator loses energy (numerical damping of high frequencies), and never
/// gains any over the run. The physical energy `½mv² + ½kq²` of the step's state is not the
/// method's (monotone) algorithmic energy: within a period it may rise by a little from one step
/// to the next. How little is asserted: at most [`MAX_STEP_ENERGY_RISE`] of E0 per step.
#[test]
fn negative_alpha_dissipates_on_linear_oscillator() {
    let mut osc = Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0 * PI * PI,
        damping: 0.0,
    };
    let h = 1e-2;
    let e0 = osc.energy(0.1, 0.0);
    let mut hht = HhtIntegrator::new(
        &mut osc,
        tight_settings(-0.3, h),
        0.0,
        &dvec(&[0.1]),
        &dvec(&[0.0]),
    )
    .unwrap();
    let mut previous = e0;
    let mut max_rise: f64 = 0.0;
    let mut max_energy: f64 = 0.0;
    for _ in 0..n_steps(10.0, h) {
        hht.step(&mut osc).unwrap();
        let s = hht.state();
        let e = osc.energy(s.q[0], s.v[0]);
        max_rise = max_rise.max(e - previous);
        max_energy = max_energy.max(e);
        previous = e;
    }
    println!(
        "linear oscillator, α = −0.3, h = 1e-2: E(10 s)/E0 = {:.6}, max per-step rise {max_rise:.2e}, max E/E0 {:.8}",
        previous / e0,
        max_energy / e0
    );
    assert!(previous < e0);
    assert!(
        max_rise <= MAX_STEP_ENERGY_RISE * e0,
        "per-step rise {max_rise:e} of E0 = {e0:e}"
    );
    // Measured max E/E0 = 0.99999978: the state's energy never exceeds the initial one.
    assert!(max_energy < e0, "max E {max_energy:e} ≥ E0 = {e0:e}");
}

// ---------------------------------------------------------------------------------------------
// Stiff spring: the diagonal Newton terms
// ---------------------------------------------------------------------------------------------

fn stiff() -> Oscillator {
    Oscillator {
        mass_kg: 1e-3,
        stiffness: 1e6,
        damping: 0.0,
    }
}

#[test]
fn stiff_spring_converges_with_diagonal_terms() {
    /// Linear problem + exact diagonal Jacobian: Newton converges in one correction, a second
    /// confirms; allow one more.
    const MAX_ITERATIONS_PER_STEP: usize = 3;
    let mut sys = stiff();
    let hht = simulate(&mut sys, HhtSettings::default(), &[0.1], &[0.0], 1.0);
    let st = hht.stats();
    println!(
        "stiff spring with diagonal terms: {} steps, {} iterations (max {} per step), {} factorisations, {} refreshes, q(1) = {:.3e}",
        st.steps, st.newton_iterations, st.max_iterations_in_a_step, st.factorisations, st.refreshes, hht.state().q[0]
    );
    assert!(st.max_iterations_in_a_step <= MAX_ITERATIONS_PER_STEP);
    assert_eq!(st.refreshes, 0);
    assert!(hht.state().q[0].abs() <= 0.1, "stable");
}

#[test]
fn stiff_spring_fails_without_diagonal_terms() {
    let mut sys = stiff();
    // The fixed step reports the failure at once.
    let settings = HhtSettings {
        newton_diagonal_terms: false,
        ..HhtSettings::default()
    };
    let mut hht =
        HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&[0.1]), &dvec(&[0.0])).unwrap();
    let err = hht.step(&mut sys).unwrap_err();
    println!("stiff spring without diagonal terms: {err}");
    match err {
        IntegrateError::NewtonNotConverged { step, t, worst, .. } => {
            assert_eq!(step, 1);
            assert!((t - 1e-3).abs() < 1e-15);
            assert!(matches!(worst, WorstEntry::Coordinate { index: 0, .. }));
        }
        other => panic!("expected NewtonNotConverged, got {other}"),
    }
    assert_eq!(hht.state().step, 0, "state left at t_n on failure");

    // The adaptive step retries a failed sub-step with half its size: the same step succeeds as
    // sub-steps, and says so.
    let retry = HhtSettings {
        newton_diagonal_terms: false,
        newton_matrix: crate::integrate::NewtonMatrix::Diagonal,
        step_control: crate::integrate::StepControl::Adaptive,
        ..HhtSettings::default()
    };
    let mut sys = stiff();
    let mut hht = HhtIntegrator::new(&mut sys, retry, 0.0, &dvec(&[0.1]), &dvec(&[0.0])).unwrap();
    hht.step(&mut sys).expect("halving rescues the step");
    let st = hht.stats();
    println!(
        "without diagonal terms, halving: {} failed attempts, {} sub-steps, smallest {:.3e} s",
        st.step_failures, st.substeps, st.smallest_step_s
    );
    assert!(st.step_failures > 0 && st.substeps > 1);
    assert!(!hht.control().last_step_plain);
    assert!((hht.state().t - 1e-3).abs() < 1e-15, "ends on the grid");
}

/// A moderately stiff spring that plain modified Newton still handles, but at a cost: count the
/// iterations with and without the diagonal terms.
#[test]
fn moderate_spring_needs_more_iterations_without_diagonal_terms() {
    let moderate = || Oscillator {
        mass_kg: 1e-3,
        stiffness: 1e3,
        damping: 0.05,
    };
    let mut counts = Vec::new();
    for diagonal in [true, false] {
        let settings = HhtSettings {
            newton_diagonal_terms: diagonal,
            max_newton_iterations: 50,
            ..HhtSettings::default()
        };
        let mut sys = moderate();
        let hht = simulate(&mut sys, settings, &[0.1], &[0.0], 0.5);
        let st = hht.stats();
        println!(
            "spring k = 1e3 on 1e-3 kg, diagonal terms {diagonal}: {:.2} iterations/step (max {})",
            st.newton_iterations as f64 / st.steps as f64,
            st.max_iterations_in_a_step
        );
        counts.push(st.newton_iterations);
    }
    assert!(counts[1] >= 2 * counts[0], "{counts:?}");
}

// ---------------------------------------------------------------------------------------------
// Constraints: Cartesian pendulum, prescribed motion
// ---------------------------------------------------------------------------------------------

const PENDULUM_THETA0: f64 = 1.0;

fn pendulum_start() -> ([f64; 2], [f64; 2]) {
    let l = 1.0;
    (
        [l * PENDULUM_THETA0.sin(), -l * PENDULUM_THETA0.cos()],
        [0.0, 0.0],
    )
}

/// Errors at `duration` of one Cartesian-pendulum run: (position, velocity, λ) against the RK4
/// reference in θ, plus the run's statistics.
fn pendulum_errors(
    h: f64,
    projection: bool,
    feedback: bool,
    duration: f64,
) -> ([f64; 3], HhtStats) {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let [theta, theta_dot] = sys.reference(PENDULUM_THETA0, duration);
    let l = sys.length_m;
    let (x, y) = (l * theta.sin(), -l * theta.cos());
    let (vx, vy) = (l * theta.cos() * theta_dot, l * theta.sin() * theta_dot);
    let lambda = sys.lambda(theta, theta_dot);
    let (q0, v0) = pendulum_start();
    let settings = HhtSettings {
        velocity_projection: projection,
        ..tight_settings(-0.1, h)
    };
    let mut hht = HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&q0), &dvec(&v0)).unwrap();
    hht.set_projection_feedback(feedback);
    for _ in 0..n_steps(duration, h) {
        hht.step(&mut sys).unwrap();
    }
    let s = hht.state();
    let errors = [
        ((s.q[0] - x).powi(2) + (s.q[1] - y).powi(2)).sqrt(),
        ((s.v[0] - vx).powi(2) + (s.v[1] - vy).powi(2)).sqrt(),
        (s.lambda[0] - lambda).abs(),
    ];
    (errors, *hht.stats())
}

#[test]
fn cartesian_pendulum_second_order_with_closed_constraint() {
    for projection in [true, false] {
        let mut errors = [Vec::new(), Vec::new(), Vec::new()];
        for h in ORDER_STEPS {
            let (e, st) = pendulum_errors(h, projection, false, 1.0);
            for k in 0..3 {
                errors[k].push(e[k]);
            }
            println!(
                "pendulum projection={projection} h = {h}: max|Φ| = {:.2e}, max|Φ_q q̇| = {:.2e} (unprojected {:.2e}), it/step {:.2}, max it {}, rounding-limited steps {}",
                st.max_constraint_violation,
                st.max_velocity_violation,
                st.max_velocity_violation_unprojected,
                st.newton_iterations as f64 / st.steps as f64,
                st.max_iterations_in_a_step,
                st.rounding_limited_steps
            );
            assert!(st.max_constraint_violation <= MAX_CONSTRAINT_VIOLATION);
            if projection {
                assert!(st.max_velocity_violation <= MAX_PROJECTED_VELOCITY_VIOLATION);
            }
        }
        for (name, e) in ["position", "velocity", "λ"].iter().zip(errors.iter()) {
            let r = ratios(e);
            let e_sci = sci(e);
            println!(
                "pendulum projection={projection}: {name} errors at 1 s {e_sci}, ratios {r:.3?}"
            );
            for ratio in r {
                assert!(
                    ratio >= MIN_SECOND_ORDER_RATIO,
                    "projection={projection} {name}: ratio {ratio}"
                );
            }
        }
    }
}

/// Regression pin: feeding the projected velocity back into the generalized-α recursion (the
/// textbook post-step projection) keeps positions second order but makes λ first order — the reason
/// the integrator projects only the reported velocity.
#[test]
fn projection_feedback_makes_multipliers_first_order() {
    let mut pos = Vec::new();
    let mut lam = Vec::new();
    for h in ORDER_STEPS {
        let (e, _) = pendulum_errors(h, true, true, 1.0);
        pos.push(e[0]);
        lam.push(e[2]);
    }
    let (rp, rl) = (ratios(&pos), ratios(&lam));
    let (pos_sci, lam_sci) = (sci(&pos), sci(&lam));
    println!("projection fed back: position errors {pos_sci} ratios {rp:.3?}; λ errors {lam_sci} ratios {rl:.3?}");
    assert!(rp.iter().all(|r| *r >= MIN_SECOND_ORDER_RATIO));
    assert!(rl.iter().all(|r| *r < MAX_FIRST_ORDER_RATIO));
}

#[test]
fn prescribed_motion_gives_known_multiplier() {
    let duration = 2.0;
    let make = || Prescribed {
        mass_kg: 2.0,
        stiffness: 5.0,
        damping: 0.3,
    };
    let lambda_scale = (0..=200)
        .map(|i| make().exact_lambda(i as f64 * 0.005).abs())
        .fold(0.0, f64::max);
    let qdd_scale = Prescribed::OMEGA * Prescribed::OMEGA;
    let mut errors_qdd = Vec::new();
    let mut errors_lambda = Vec::new();
    for h in [1e-3, 5e-4, 2.5e-4] {
        let mut sys = make();
        // Deliberately inconsistent start: the projection must put q, q̇ on the drive.
        let mut hht = HhtIntegrator::new(
            &mut sys,
            tight_settings(-0.2, h),
            0.0,
            &dvec(&[0.3]),
            &dvec(&[0.0]),
        )
        .unwrap();
        // Max relative errors over the second second (after the O(h) start transient of a_0 = q̈_0).
        let (mut eq, mut el): (f64, f64) = (0.0, 0.0);
        for _ in 0..n_steps(duration, h) {
            hht.step(&mut sys).unwrap();
            let s = hht.state();
            if s.t >= 1.0 {
                eq = eq.max((s.qdd[0] - Prescribed::exact_qdd(s.t)).abs() / qdd_scale);
                el = el.max((s.lambda[0] - sys.exact_lambda(s.t)).abs() / lambda_scale);
            }
        }
        println!(
            "prescribed α = −0.2, h = {h}: max over [1, 2] s of relative q̈ error {eq:.3e}, relative λ error {el:.3e}, max|Φ| {:.1e}, start iterations {}",
            hht.stats().max_constraint_violation,
            hht.stats().start_projection_iterations
        );
        errors_qdd.push(eq);
        errors_lambda.push(el);
    }
    let (rq, rl) = (ratios(&errors_qdd), ratios(&errors_lambda));
    println!("prescribed: q̈ ratios {rq:.3?}, λ ratios {rl:.3?}");
    for ratio in rq.iter().chain(rl.iter()) {
        assert!(*ratio >= MIN_SECOND_ORDER_RATIO, "ratio {ratio}");
    }
}

/// Default settings on a constrained system across step sizes: no Newton failure down to h = 1e-5,
/// where `Δλ`'s rounding floor (~eps/(β'h²)) approaches the multiplier tolerance.
#[test]
fn constrained_defaults_converge_from_large_to_tiny_steps() {
    for h in [1e-2, 1e-3, 1e-4, 1e-5] {
        let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
        let (q0, v0) = pendulum_start();
        let settings = HhtSettings {
            step_s: h,
            ..HhtSettings::default()
        };
        let hht = simulate(&mut sys, settings, &q0, &v0, 2000.0 * h);
        let st = hht.stats();
        println!(
            "pendulum defaults h = {h:.0e}: 2000 steps, {:.2} it/step (max {}), refreshes {}, rounding-limited steps {}, max|Φ| {:.1e}",
            st.newton_iterations as f64 / st.steps as f64,
            st.max_iterations_in_a_step,
            st.refreshes,
            st.rounding_limited_steps,
            st.max_constraint_violation
        );
        assert!(st.max_constraint_violation <= MAX_CONSTRAINT_VIOLATION);
    }
}

// ---------------------------------------------------------------------------------------------
// Conditioning of the iteration matrix
// ---------------------------------------------------------------------------------------------

fn condition_number(a: &DMatrix<f64>) -> f64 {
    let sv = a.clone().singular_values();
    sv.max() / sv.min()
}

#[test]
fn scaled_iteration_matrix_stays_well_conditioned() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, _) = pendulum_start();
    let q = dvec(&q0);
    let v = dvec(&[0.5 * PENDULUM_THETA0.cos(), 0.5 * PENDULUM_THETA0.sin()]);
    let mut previous_unscaled = None;
    for exponent in 2..=6 {
        let h = 10f64.powi(-exponent);
        let settings = HhtSettings {
            step_s: h,
            ..HhtSettings::default()
        };
        let scaled = condition_number(
            &iteration_matrix(
                &mut sys,
                &settings,
                0.0,
                &q,
                &v,
                ConstraintRowScaling::Scaled,
            )
            .unwrap(),
        );
        let unscaled = condition_number(
            &iteration_matrix(
                &mut sys,
                &settings,
                0.0,
                &q,
                &v,
                ConstraintRowScaling::Unscaled,
            )
            .unwrap(),
        );
        println!("h = {h:.0e}: cond scaled {scaled:.3e}, unscaled {unscaled:.3e}");
        assert!(scaled < MAX_SCALED_CONDITION);
        if let Some(prev) = previous_unscaled {
            let growth = unscaled / prev;
            assert!(
                (UNSCALED_DECADE_GROWTH.0..UNSCALED_DECADE_GROWTH.1).contains(&growth),
                "growth per decade {growth}"
            );
        }
        previous_unscaled = Some(unscaled);
    }
}

// ---------------------------------------------------------------------------------------------
// Consistent start
// ---------------------------------------------------------------------------------------------

#[test]
fn consistent_start_projects_positions_velocities_and_solves_multipliers() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    // Off the circle, with a velocity that has a radial component.
    let q0 = dvec(&[0.9, -0.6]);
    let v0 = dvec(&[0.3, 0.4]);
    let start = consistent_start(&mut sys, 0.0, &q0, &v0).unwrap();
    let r = (start.q[0].powi(2) + start.q[1].powi(2)).sqrt();
    let radial_v = (start.q[0] * start.v[0] + start.q[1] * start.v[1]) / r;
    // Exact multiplier at the projected state: λ = m (|v|² − g y)/(2L²).
    let v2 = start.v.norm_squared();
    let lambda = (v2 - 9.81 * start.q[1]) / 2.0;
    println!(
        "consistent start: {} Gauss–Newton iterations, |Φ| {:.1e} → {:.1e}, radial v {radial_v:.1e}, λ {:.12} vs {lambda:.12}",
        start.projection_iterations, start.initial_violation, start.final_violation, start.lambda[0]
    );
    assert!(start.final_violation <= START_CONSTRAINT_TOL);
    assert!(radial_v.abs() < 1e-14);
    assert!((start.lambda[0] - lambda).abs() < 1e-12);
}

#[test]
fn redundant_rows_are_reported_not_solved() {
    let mut sys = CartesianPendulum::new(PendulumVariant::DuplicatedRow);
    let (q0, v0) = pendulum_start();
    let err = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&q0),
        &dvec(&v0),
    )
    .unwrap_err();
    println!("{err}");
    assert!(
        matches!(err, IntegrateError::RedundantConstraints { .. }),
        "{err}"
    );
}

#[test]
fn impossible_closure_is_reported() {
    let mut sys = CartesianPendulum::new(PendulumVariant::CannotClose);
    let (q0, v0) = pendulum_start();
    let err = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&q0),
        &dvec(&v0),
    )
    .unwrap_err();
    println!("{err}");
    assert!(matches!(err, IntegrateError::CannotClose { .. }), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Settings
// ---------------------------------------------------------------------------------------------

#[test]
fn alpha_zero_with_constraints_is_refused() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, v0) = pendulum_start();
    let settings = HhtSettings {
        alpha: 0.0,
        ..HhtSettings::default()
    };
    let err = HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&q0), &dvec(&v0)).unwrap_err();
    println!("{err}");
    assert!(matches!(
        err,
        IntegrateError::AlphaZeroWithConstraints { n_constraints: 1 }
    ));
    // Without constraints α = 0 is fine.
    assert!(settings.validate(0).is_ok());
}

#[test]
fn bad_settings_are_errors() {
    let base = HhtSettings::default();
    let bad = [
        HhtSettings { alpha: 0.1, ..base },
        HhtSettings {
            alpha: -0.34,
            ..base
        },
        HhtSettings {
            alpha: f64::NAN,
            ..base
        },
        HhtSettings {
            step_s: 0.0,
            ..base
        },
        HhtSettings {
            step_s: -1e-3,
            ..base
        },
        HhtSettings {
            step_s: f64::INFINITY,
            ..base
        },
        HhtSettings {
            step_s: f64::NAN,
            ..base
        },
        HhtSettings {
            reltol: 0.0,
            ..base
        },
        HhtSettings {
            abstol_position: -1.0,
            ..base
        },
        HhtSettings {
            abstol_multiplier: f64::NAN,
            ..base
        },
        HhtSettings {
            max_newton_iterations: 0,
            ..base
        },
    ];
    for s in bad {
        let err = s.validate(0).unwrap_err();
        println!("{err}");
    }
    assert!(HhtSettings {
        alpha: ALPHA_MIN,
        ..base
    }
    .validate(3)
    .is_ok());
    let c = base.validate(0).unwrap();
    assert!((c.gamma - 0.6).abs() < 1e-15 && (c.beta - 0.3025).abs() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Failures, manifold, allocation, restart
// ---------------------------------------------------------------------------------------------

#[test]
fn nan_forces_are_reported_with_time_and_step() {
    let mut sys = Scalar {
        nan_after_s: 0.0505,
        ..Scalar::new()
    };
    let mut hht = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&[SCALAR_Q0]),
        &dvec(&[SCALAR_V0]),
    )
    .unwrap();
    let err = (0..100)
        .find_map(|_| hht.step(&mut sys).err())
        .expect("fails");
    println!("{err}");
    match err {
        IntegrateError::NonFinite {
            step,
            quantity,
            index,
            ..
        } => {
            assert_eq!((step, quantity, index), (51, "forces", 0));
        }
        other => panic!("expected NonFinite, got {other}"),
    }
}

#[test]
fn manifold_update_matches_vector_update() {
    /// Same arithmetic up to the rotation's rounding (and atan2): a few rounding units per step.
    const SAME_TRAJECTORY: f64 = 1e-11;
    let theta0: f64 = 0.7;
    let settings = HhtSettings::default();
    let mut rotor = Rotor;
    let mut angle = AngleRotor;
    let a = simulate(
        &mut rotor,
        settings,
        &[theta0.cos(), theta0.sin()],
        &[0.2],
        2.0,
    );
    let b = simulate(&mut angle, settings, &[theta0], &[0.2], 2.0);
    let theta_a = a.state().q[1].atan2(a.state().q[0]);
    let d = (theta_a - b.state().q[0]).abs();
    println!(
        "manifold vs vector update after 2 s: |Δθ| = {d:.2e}, |q| − 1 = {:.1e}",
        a.state().q.norm() - 1.0
    );
    assert!(d < SAME_TRAJECTORY);
    assert!((a.state().v[0] - b.state().v[0]).abs() < SAME_TRAJECTORY);
}

#[test]
fn restart_reuses_workspace_and_reproduces_trajectory() {
    let mut sys = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, v0) = pendulum_start();
    let settings = HhtSettings::default();
    let mut hht = HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&q0), &dvec(&v0)).unwrap();
    for _ in 0..300 {
        hht.step(&mut sys).unwrap();
    }
    let first = hht.state().clone();
    hht.restart(&mut sys, 0.0, &dvec(&q0), &dvec(&v0)).unwrap();
    assert_eq!(hht.stats().steps, 0);
    for _ in 0..300 {
        hht.step(&mut sys).unwrap();
    }
    assert_eq!(&first, hht.state(), "bit-identical (determinism)");
}

#[test]
fn dimension_mismatch_is_an_error() {
    let mut sys = Scalar::new();
    let err = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&[1.0, 2.0]),
        &dvec(&[0.0]),
    )
    .unwrap_err();
    assert!(
        matches!(err, IntegrateError::DimensionMismatch { what: "q0", .. }),
        "{err}"
    );
    let mut hht = HhtIntegrator::new(
        &mut sys,
        HhtSettings::default(),
        0.0,
        &dvec(&[1.0]),
        &dvec(&[0.0]),
    )
    .unwrap();
    let mut other = CartesianPendulum::new(PendulumVariant::Plain);
    let err = hht.step(&mut other).unwrap_err();
    assert!(
        matches!(err, IntegrateError::DimensionMismatch { .. }),
        "{err}"
    );
}

pub(crate) mod alloc_counter {
    //! A global allocator that counts allocations per thread, to prove that `step` allocates
    //! nothing.
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
    }

    pub struct CountingAllocator;

    fn count() {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
    }

    // SAFETY: forwards to the system allocator unchanged; counting touches only a thread-local
    // `Cell<usize>` (no allocation, no destructor).
    unsafe impl GlobalAlloc for CountingAllocator {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            count();
            unsafe { System.alloc(layout) }
        }
        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            count();
            unsafe { System.alloc_zeroed(layout) }
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            count();
            unsafe { System.realloc(ptr, layout, new_size) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            unsafe { System.dealloc(ptr, layout) }
        }
    }

    #[global_allocator]
    static GLOBAL: CountingAllocator = CountingAllocator;

    /// Allocations made by this thread so far.
    pub fn allocations() -> usize {
        ALLOCATIONS.with(|c| c.get())
    }
}

#[test]
fn steps_allocate_nothing() {
    let mut scalar = Scalar::new();
    let mut hht = HhtIntegrator::new(
        &mut scalar,
        HhtSettings::default(),
        0.0,
        &dvec(&[SCALAR_Q0]),
        &dvec(&[SCALAR_V0]),
    )
    .unwrap();
    let before = alloc_counter::allocations();
    for _ in 0..200 {
        hht.step(&mut scalar).unwrap();
    }
    let tree = alloc_counter::allocations() - before;

    let mut pendulum = CartesianPendulum::new(PendulumVariant::Plain);
    let (q0, v0) = pendulum_start();
    let mut hht = HhtIntegrator::new(
        &mut pendulum,
        HhtSettings::default(),
        0.0,
        &dvec(&q0),
        &dvec(&v0),
    )
    .unwrap();
    let before = alloc_counter::allocations();
    for _ in 0..200 {
        hht.step(&mut pendulum).unwrap();
    }
    let constrained = alloc_counter::allocations() - before;
    println!("allocations in 200 steps: tree {tree}, constrained with projection {constrained}");
    assert_eq!((tree, constrained), (0, 0));
}

/// A tolerance no step can meet makes the adaptive step sub-step down to its floor; the attempts
/// within one grid step are capped, and the error says what happened.
#[test]
fn sub_step_attempts_per_grid_step_are_bounded() {
    let mut sys = Oscillator {
        mass_kg: 1.0,
        stiffness: 4.0,
        damping: 0.0,
    };
    let settings = HhtSettings {
        step_control: crate::integrate::StepControl::Adaptive,
        tolerance: 1e-300,
        ..HhtSettings::default()
    };
    let mut hht =
        HhtIntegrator::new(&mut sys, settings, 0.0, &dvec(&[1.0]), &dvec(&[0.0])).unwrap();
    let err = hht.step(&mut sys).unwrap_err();
    println!("{err}");
    assert!(
        matches!(err, IntegrateError::TooManySubsteps { attempts, .. } if attempts == crate::integrate::MAX_ATTEMPTS_PER_STEP)
    );
    assert!(err
        .to_string()
        .contains("smaller step or a looser tolerance"));
}

// ---------------------------------------------------------------------------------------------
// Reusing the Newton matrix across steps (opt-in)
// ---------------------------------------------------------------------------------------------

/// Largest difference of the ur5's positions (rad) after 0.5 s of its own scene between the reused
/// and the fresh Newton matrix: both are converged to the position tolerance (1e-10 per step), so
/// over 500 steps they may part by a few hundred times that, not more.
const REUSE_MAX_POSITION_DIFFERENCE: f64 = 1e-7;

/// The ur5 of the shipped robots with its scene (springs and dampers on the joints, no rows).
fn shipped_ur5() -> (crate::simulate::RobotSystem, crate::scene::Scene) {
    shipped_scene("ur5")
}

#[test]
fn reused_newton_matrix_saves_factorisations_at_the_newton_tolerance() {
    let (mut system, scene) = shipped_ur5();
    let (q0, v0) = (dvec(&scene.initial_q), dvec(&scene.initial_v));
    let fresh = crate::simulate::hht_settings(&scene);
    assert!(!fresh.reuse_newton_matrix, "the reuse is opt-in");
    let reuse = HhtSettings {
        reuse_newton_matrix: true,
        ..fresh
    };
    let mut run = |settings: HhtSettings| {
        let mut hht = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
        for _ in 0..500 {
            hht.step(&mut system).expect("step");
        }
        (hht.state().q.clone(), *hht.stats())
    };
    let (q_fresh, s_fresh) = run(fresh);
    let (q_reuse, s_reuse) = run(reuse);
    let difference = (&q_reuse - &q_fresh).amax();
    println!(
        "ur5 0.5 s: fresh {} factorisations, {} iterations; reused {} factorisations, {} iterations; max |Δq| {difference:.2e} rad",
        s_fresh.factorisations, s_fresh.newton_iterations, s_reuse.factorisations, s_reuse.newton_iterations
    );
    assert_eq!(s_fresh.factorisations, 500);
    assert!(s_reuse.factorisations < s_fresh.factorisations);
    assert!(difference > 0.0 && difference <= REUSE_MAX_POSITION_DIFFERENCE);
}

/// The stored factorisation travels with the trajectory: a trajectory swapped out for another one
/// and back continues bitwise as if it had never left (a study's samples do not depend on which
/// samples a thread advanced in between).
#[test]
fn reused_newton_matrix_travels_with_the_trajectory() {
    let (mut system, scene) = shipped_ur5();
    let settings = HhtSettings {
        reuse_newton_matrix: true,
        ..crate::simulate::hht_settings(&scene)
    };
    let (q0, v0) = (dvec(&scene.initial_q), dvec(&scene.initial_v));
    let mut other_q0 = q0.clone();
    other_q0[1] += 0.3;
    let mut alone = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
    for _ in 0..200 {
        alone.step(&mut system).expect("step");
    }
    let mut shared = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
    let mut other = HhtIntegrator::new(&mut system, settings, 0.0, &other_q0, &v0)
        .expect("start")
        .trajectory();
    for _ in 0..100 {
        shared.step(&mut system).expect("step");
    }
    shared.swap_trajectory(&mut other).expect("same dimensions");
    for _ in 0..37 {
        shared.step(&mut system).expect("step");
    }
    shared.swap_trajectory(&mut other).expect("same dimensions");
    for _ in 0..100 {
        shared.step(&mut system).expect("step");
    }
    // Vacuous unless some steps reused the matrix.
    assert!(alone.stats().factorisations < 200);
    assert_eq!(shared.state(), alone.state());
    assert_eq!(shared.stats().factorisations, alone.stats().factorisations);
}

/// A shipped robot in its own scene's environment, for runs of the integrator alone.
fn shipped_scene(dir: &str) -> (crate::simulate::RobotSystem, crate::scene::Scene) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots")
        .join(dir);
    let model = crate::model::Model::from_urdf_file(
        &root.join(format!("{dir}.urdf")),
        crate::model::LoadOptions::default(),
    )
    .expect("robot loads");
    let (file, _) = crate::scene::read_sidecar(&root.join(format!("{dir}.uncertainty.toml")))
        .expect("sidecar reads");
    let scene =
        crate::scene::Scene::resolve(&file, &model, dir, crate::scene::SceneOverrides::default())
            .expect("scene resolves");
    (
        crate::simulate::RobotSystem::new(model, scene.environment(), &scene),
        scene,
    )
}

/// How much tighter the reference runs of the first-correction test converge.
const TIGHT_NEWTON_FACTOR: f64 = 1e-3;

/// A step accepted after its first correction by the last step's contraction (docs/step-control.md
/// §2, "Accepting the first correction") is within the Newton tolerance: over 1 s of the shipped
/// ur5, double pendulum, four-bar and slider-crank scenes, the positions stay within one step's
/// position tolerance (`reltol · max|q| + abstol_position`) of a run converged 1000× tighter, while
/// the acceptance saves iterations. (Since the predictor chooses its order per entry, the double
/// pendulum's first correction is within tolerance at every step and the rule is never asked; the
/// loop scenes and the ur5 still use it.)
#[test]
fn first_corrections_accepted_by_the_carried_contraction_stay_within_the_tolerance() {
    let mut scenes_using_the_rule = 0;
    for dir in ["ur5", "double_pendulum", "four_bar", "slider_crank"] {
        let (mut system, scene) = shipped_scene(dir);
        let (q0, v0) = (dvec(&scene.initial_q), dvec(&scene.initial_v));
        let settings = crate::simulate::hht_settings(&scene);
        let tight = HhtSettings {
            reltol: settings.reltol * TIGHT_NEWTON_FACTOR,
            abstol_position: settings.abstol_position * TIGHT_NEWTON_FACTOR,
            abstol_multiplier: settings.abstol_multiplier * TIGHT_NEWTON_FACTOR,
            accept_by_carried_contraction: false,
            ..settings
        };
        let mut run = HhtIntegrator::new(&mut system, settings, 0.0, &q0, &v0).expect("start");
        let mut reference = HhtIntegrator::new(&mut system, tight, 0.0, &q0, &v0).expect("start");
        let (mut max_difference, mut max_q): (f64, f64) = (0.0, 0.0);
        for _ in 0..1000 {
            run.step(&mut system).expect("step");
            reference.step(&mut system).expect("step");
            max_difference = max_difference.max((&run.state().q - &reference.state().q).amax());
            max_q = max_q.max(reference.state().q.amax());
        }
        let one_step_tolerance = settings.reltol * max_q + settings.abstol_position;
        let stats = run.stats();
        println!(
            "{dir}: {} Newton iterations in 1000 steps, {} accepted by the carried contraction; max |Δq| {max_difference:.2e} against one step's tolerance {one_step_tolerance:.2e}",
            stats.newton_iterations, stats.carried_rate_acceptances
        );
        if stats.carried_rate_acceptances > 0 {
            scenes_using_the_rule += 1;
        }
        // The reference must not depend on the rule under test.
        assert_eq!(
            reference.stats().carried_rate_acceptances,
            0,
            "{dir}: the tight reference accepted a first correction by the carried contraction"
        );
        assert!(
            max_difference <= one_step_tolerance,
            "{dir}: {max_difference:e} > {one_step_tolerance:e}"
        );
    }
    assert!(
        scenes_using_the_rule >= 3,
        "only {scenes_using_the_rule} of the four scenes accepted a first correction by the carried contraction"
    );
}
