//! [`HhtSettings`]: every option of the integrator, with its default, range and reason; and the
//! derived Newmark coefficients [`HhtCoefficients`].

use super::error::IntegrateError;

/// Options of the HHT-I3 integrator. Build with `HhtSettings::default()` and override fields.
///
/// Validated by [`HhtSettings::validate`] (called by the integrator's constructor).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HhtSettings {
    /// HHT `α`, range `[−1/3, 0]`, default `−0.1`. `0` = trapezoidal rule (no numerical damping),
    /// `−1/3` = most high-frequency damping. With constraint rows `|α|` must be at least
    /// [`ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS`] (`α ≤ −0.05`). Sets `γ = ½ − α`, `β = (1 − α)²/4`.
    pub alpha: f64,
    /// Fixed step `h`, s, finite and `> 0`, default `1e-3`. Shared by every sample of a study so that
    /// trajectories stay smooth in the parameters.
    pub step_s: f64,
    /// Relative tolerance of the Newton test, `> 0`, default `1e-6`: error weight
    /// `ewt_i = 1 / (reltol · |x_i| + abstol)`, converged when the weighted RMS norm of the
    /// correction is `< 1`.
    pub reltol: f64,
    /// Absolute tolerance on the position-level correction `β'h² Δq̈`, m or rad, `> 0`, default
    /// `1e-10`: well below the ~1e-6 discretisation error of a 1 ms step, so that Newton noise does not
    /// roughen the parameter-to-trajectory map the surrogates fit.
    pub abstol_position: f64,
    /// Absolute tolerance on the multiplier correction `Δλ`, N or N·m, `> 0`, default `1e-8`.
    pub abstol_multiplier: f64,
    /// Newton iterations per pass, `≥ 1`, default `10`. A pass that does not converge is followed by
    /// one refresh of the iteration matrix at the current iterate and a second pass; then the step
    /// fails with [`IntegrateError::NewtonNotConverged`].
    pub max_newton_iterations: usize,
    /// Post-step projection of the reported `q̇` onto `Φ_q q̇ + Φ_t = 0` (default `true`), by
    /// `[M Φ_qᵀ; Φ_q 0][Δq̇; μ] = [0; −(Φ_q q̇ + Φ_t)]`, with `Φ_q` at `q_{n+1}` and `M` there or the
    /// Newton matrix's ([`HhtSettings::projection_keeps_newton_mass`]). Only meaningful with
    /// constraint rows; without
    /// it the velocity-level constraint of the reported velocity is off by O(h²) (bounded, no drift
    /// growth: plain I3 enforces only `Φ = 0`).
    ///
    /// The projection changes what [`HhtState::v`](super::HhtState::v) reports, **not** the velocity
    /// the recursion carries: generalized-α's velocity carries an O(h²) offset that keeps `q̈` and `λ`
    /// second order, and resetting it every step pushes an O(h) error into `a`, `q̈` and `λ`.
    /// Measured on the Cartesian pendulum (α = −0.1, t = 1 s, h = 2e-3 → 5e-4): with the projected
    /// velocity fed back, λ errors 2.4e-3 → 6.0e-4 (ratio 2.0); kept out of the recursion, 1.4e-5 →
    /// 9.2e-7 (ratio 4.0). Positions are second order either way. So a step may leave it out when
    /// nothing reads the state before the next one ([`ReportedVelocity::Skipped`](super::ReportedVelocity)).
    pub velocity_projection: bool,
    /// Let the velocity projection use the `M` of the Newton matrix the step converged with when
    /// that matrix was `M` alone, refactorising only the rows at `q_{n+1}` (default `true`;
    /// docs/method.md §5, "Velocity drift"): the panda's step 40 209 → 28 458 instructions. The
    /// projected velocity then depends on where the iteration started (the predictor), by far
    /// less than the Newton tolerance; off, the metric is `M(q_{n+1})`, a function of the state
    /// alone, as difference quotients and the forward sensitivities' derivative of the projection
    /// need (the four-bar's velocity sensitivities differ by 3e-5 relative otherwise).
    pub projection_keeps_newton_mass: bool,
    /// Add the diagonal spring and damper terms `β'h² k_j + γ'h c_j` of
    /// [`NewtonDiagonal::newton_diagonal`](super::NewtonDiagonal::newton_diagonal) to the iteration matrix
    /// (default `true`). Turning it off only serves to measure what the terms buy: a stiff spring on
    /// a light link then diverges.
    pub newton_diagonal_terms: bool,
    /// Which matrix Newton iterates with (default [`NewtonMatrix::Diagonal`]; docs/step-control.md §1).
    pub newton_matrix: NewtonMatrix,
    /// How the step is chosen (default [`StepControl::Fixed`]; docs/step-control.md §3).
    pub step_control: StepControl,
    /// Local error tolerance of [`StepControl::Adaptive`], rad or m per step, finite and `> 0`,
    /// default [`DEFAULT_STEP_TOLERANCE`]: a sub-step is rejected when the weighted RMS of its
    /// estimated position error `|β − 1/6| h² |q̈_{n+1} − q̈_n|` exceeds it. Unused by the fixed step.
    pub tolerance: f64,
    /// The smallest sub-step is `h / 2^k`, `k = 0..=`[`MAX_STEP_HALVINGS`], default
    /// [`DEFAULT_STEP_HALVINGS`]: the floor of the adaptive step's sub-steps (and of its retries of
    /// a failed sub-step, by halving) and of the short steps that locate an impact (both modes).
    pub max_step_halvings: u32,
    /// Keep a trajectory's Newton factorisation from step to step while Newton contracts fast
    /// (default `false`, opt-in; docs/method.md §5, "Reusing the Newton matrix"): a step refactorises only
    /// when the step size changed, the last step contracted slower than
    /// [`NEWTON_REUSE_MAX_RATE`], the old matrix fails to converge, or after a restart or an impact.
    /// Systems without constraint rows only: with rows an old `Φ_q` leaves `Φ` at the position
    /// tolerance after convergence instead of at rounding (1.4e-9 m against ≤ 1e-10 m with a fresh
    /// matrix, Cartesian pendulum at h = 1e-2), and the drift bound of the tests is rounding.
    /// Off, every step factorises at its predictor. Results differ between the two by the Newton
    /// tolerance only, but that is the point of the default: a reused matrix accepts an iterate
    /// anywhere below the tolerance where a fresh one overshoots it by far, so the Newton noise
    /// across the samples of a study grows, and with it the surrogate's misfit (double pendulum's
    /// a-posteriori check: 9e-8 → 1.0e-5 of the envelope width, over the 1e-5 that
    /// `tests/analysis.rs` accepts as smooth). Worth it for single trajectories; not yet for studies.
    pub reuse_newton_matrix: bool,
    /// Accept a step's first Newton correction when the contraction the last step measured says
    /// the iterate is within tolerance (default `true`; docs/step-control.md §2, "Accepting the
    /// first correction"; [`CARRIED_RATE_FLOOR`](super::CARRIED_RATE_FLOOR),
    /// [`CARRIED_RATE_SAFETY`](super::CARRIED_RATE_SAFETY)). Saves 10–45 % of the Newton
    /// iterations of the shipped studies at the cost of iterates nearer the tolerance (the double
    /// pendulum study's a-posteriori check misfit 1.0e-8 → 4.4e-7 of the envelope width at 1 s);
    /// off for runs that must converge to rounding (references, difference quotients).
    pub accept_by_carried_contraction: bool,
    /// On a run of equal steps, extrapolate every entry of `q̈` and `λ` by the polynomials of
    /// orders 0 to [`PREDICTOR_MAX_ORDER`](super::PREDICTOR_MAX_ORDER), weighted by how well each
    /// predicted the entry's last value (default `true`; docs/step-control.md §2). Off: `q̈`
    /// quadratically where its history is smooth and `λ` linearly. The better start lets Newton
    /// stop after fewer corrections, nearer its tolerance, so off for runs that must converge to
    /// rounding (references, difference quotients): on the four-bar, the central differences of
    /// whole runs at a step of 0.01 in ξ moved 3e-6 away from the direct derivatives of the
    /// velocities with it on (3.3e-7 with it off).
    pub choose_predictor_order: bool,
}

/// Which matrix the Newton iteration of a step factorises (docs/step-control.md §1).
///
/// Every effect (springs, dampers, friction, limits) acts on its own joint, so its exact Jacobian
/// is diagonal and already in [`NewtonMatrix::Diagonal`]; what the full matrix adds is the
/// configuration and velocity dependence of the rigid-body terms (`∂(M q̈)/∂q`, Coriolis) and of
/// loop closures (`∂(Φ_qᵀλ)/∂q`). Measured on a double pendulum with an elbow spring of 1e6–1e9
/// N·m/rad displaced 0.01–0.5 rad at h = 1 ms (`tests/stability.rs`), the full matrix never
/// converged where the diagonal one failed (what fixed those was the predictor, §2), so the
/// default stays the cheap one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NewtonMatrix {
    /// Modified Newton with `M`, `Φ_q` and the effects' diagonal terms; a refresh recomputes the same
    /// matrix at the current iterate. The default.
    #[default]
    Diagonal,
    /// The diagonal matrix first; when it fails, the refresh factorises the full matrix
    /// `M + β'h² K_t + γ'h D_t` from [`DaeSystem::as_residual_jacobians`](super::DaeSystem::as_residual_jacobians)
    /// (when the system provides it) and keeps using it for [`FULL_NEWTON_HOLD_STEPS`] steps.
    /// Costs nothing on steps the diagonal matrix converges.
    Auto,
    /// The full matrix at every step (when the system provides it; else the diagonal one).
    Full,
}

/// How the integrator chooses its step (docs/step-control.md §3). Either way every call of
/// [`HhtIntegrator::step`](super::HhtIntegrator::step) ends exactly on the grid `t0 + n h`, so records
/// and the lock-step study engine see the same time grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StepControl {
    /// One step of `h` per grid interval, and a Newton failure is reported (with the joint and the
    /// advice of a smaller step). Only an impact with a unilateral limit is located inside the
    /// interval. The default: every sample of a study takes the same steps, which keeps
    /// trajectories smooth in the parameters, and a step too long for the dynamics is said, not
    /// silently repaired in some samples only.
    #[default]
    Fixed,
    /// Sub-steps of the grid interval chosen by a local error estimate against
    /// [`HhtSettings::tolerance`]: rejected and shrunk when over it, grown (up to `h`) after easy
    /// steps, halved on Newton failure, shortened to locate impacts.
    Adaptive,
}

/// Default [`HhtSettings::tolerance`], rad or m per step: 1e-5 leaves the shipped robots' scenes at
/// the grid step of 1 ms (their largest error measures there: ur5 0.28, double pendulum 0.014,
/// four-bar 0.47, slider-crank 0.0012, in units of 1e-5), so the adaptive step costs what the
/// fixed one does on smooth motion (0.7–3.0 % more instructions, docs/step-control.md §5) and
/// sub-steps where the motion is not smooth (impacts, stiff transients). At 1e-6 the four-bar
/// already sub-steps (4117 sub-steps for 2000 steps, 2.4× the instructions).
pub const DEFAULT_STEP_TOLERANCE: f64 = 1e-5;

/// Default [`HhtSettings::max_step_halvings`]: sub-steps down to `h / 2^20` ≈ `h · 1e-6` (a scene
/// lowers it so that no sub-step falls below `MIN_STEP_S` = 1 ns).
pub const DEFAULT_STEP_HALVINGS: u32 = 20;

/// Largest accepted [`HhtSettings::max_step_halvings`]: below `h / 2^20` a sub-step resolves
/// nothing a rigid model has (and a grid interval would need a million of them).
pub const MAX_STEP_HALVINGS: u32 = 20;

/// Steps that keep the full Newton matrix after the diagonal one failed ([`NewtonMatrix::Auto`]):
/// a stiff phase (a spring driven hard, a contact) lasts many steps, and retrying the cheap matrix on
/// each of them would pay a failed pass every step; after the hold the cheap matrix is tried again.
pub const FULL_NEWTON_HOLD_STEPS: u32 = 50;

/// Slowest contraction `ρ = ‖Δ_k‖/‖Δ_{k−1}‖` of a step's Newton iteration after which the next step
/// still reuses the factorisation ([`HhtSettings::reuse_newton_matrix`]); a reused matrix that
/// contracts slower than this within a step is dropped at once and the step refactorises at its
/// current iterate. On the shipped arms an iteration (RNEA, solve, test) and a refactorisation
/// (CRBA, assembly, Cholesky or LU) cost about the same (≈ 9 000 instructions each on the ur5), so
/// a refactorisation pays when it saves one iteration. Measured in instructions per step of the
/// benches' 1 s falls (benches/README.md, 2026-11-23) for thresholds 0.02, 0.05, 0.1, 0.2, 0.3,
/// 0.5: the fast-spinning ur5 is cheapest at 0.02 and already worse than no reuse at 0.05 (its
/// fresh matrix contracts at ρ ≈ 0.02–0.05, the Coriolis terms the modified matrix leaves out);
/// the example-robot-data ur5 gains 30–32 % at every threshold, the panda 2–7 %.
pub const NEWTON_REUSE_MAX_RATE: f64 = 0.02;

impl Default for HhtSettings {
    fn default() -> Self {
        Self {
            alpha: -0.1,
            step_s: 1e-3,
            reltol: 1e-6,
            abstol_position: 1e-10,
            abstol_multiplier: 1e-8,
            max_newton_iterations: 10,
            velocity_projection: true,
            projection_keeps_newton_mass: true,
            newton_diagonal_terms: true,
            newton_matrix: NewtonMatrix::Diagonal,
            step_control: StepControl::Fixed,
            tolerance: DEFAULT_STEP_TOLERANCE,
            max_step_halvings: DEFAULT_STEP_HALVINGS,
            reuse_newton_matrix: false,
            accept_by_carried_contraction: true,
            choose_predictor_order: true,
        }
    }
}

/// The lower end of the HHT range of `α`.
pub const ALPHA_MIN: f64 = -1.0 / 3.0;

/// Smallest `|α|` accepted when the system has constraint rows: `α` in `(−0.05, 0]` is refused.
///
/// The consistent start leaves an O(h) transient in `q̈` and `λ` that shrinks by `(1+α)/(1−α)` per
/// step (docs/method.md §5): at `α = −0.05` ten-fold in 23 steps, at `α = −1e-3` only after 1150
/// steps, at `α → 0` never. Measured with `ribbon simulate` on the shipped slider-crank (drive
/// effort and loop forces) and four-bar (loop forces) over 1 s, against a run at `h = 1e-5`, as the
/// largest error over all record times relative to the largest |value|:
///
/// | α | slider-crank h = 1e-3 | four-bar h = 1e-3 | slider-crank h = 2e-3 | four-bar h = 2e-3 |
/// |---|---|---|---|---|
/// | −1e-9 | 0.39 | 9.99 | | |
/// | −1e-3 | 0.072 | 1.53 | 0.14 | 3.9 |
/// | −0.01 | 7.3e-3 | 0.015 | 0.015 | 0.031 |
/// | −0.02 | 3.7e-3 | 7.6e-3 | 7.5e-3 | 0.015 |
/// | −0.05 | 1.6e-3 | 3.4e-3 | 3.2e-3 | 6.7e-3 |
/// | −0.1 (default) | 6.7e-4 | 1.4e-3 | 1.9e-3 | 5.1e-3 |
///
/// From −0.05 on the error is within 2.4× of the default's at every step measured (also at
/// h = 1e-4: 2.2e-5 and 1.4e-5, equal to the default's); at −0.02 it is 4–5.5×, at −0.01 8–25×,
/// and closer to 0 the constraint forces are wrong by up to ten times their size. Positions are
/// unaffected (the error is in `q̈` and `λ`). Without constraint rows every `α` in `[−1/3, 0]` is
/// accurate.
pub const ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS: f64 = 0.05;

/// Why an HHT `α` is refused by [`check_alpha`]; each caller words the message for its input (the
/// integrator's [`IntegrateError`], the scene's flag or sidecar key).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlphaRefusal {
    /// NaN, infinite, or outside `[ALPHA_MIN, 0]` = `[−1/3, 0]`.
    OutsideRange,
    /// `α = 0` with constraint rows: the trapezoidal member does not converge in `q̈` and `λ`.
    ZeroWithConstraints,
    /// `α` in `(−ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS, 0)` with constraint rows.
    TooCloseToZeroWithConstraints,
}

/// The one check of the HHT `α` for a system with `n_constraints` constraint rows: in `[−1/3, 0]`
/// (docs/method.md §5), and with constraint rows at most `−`[`ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS`].
/// With `n_constraints = 0` only the range is checked.
pub fn check_alpha(alpha: f64, n_constraints: usize) -> Result<(), AlphaRefusal> {
    if !alpha.is_finite() || !(ALPHA_MIN..=0.0).contains(&alpha) {
        return Err(AlphaRefusal::OutsideRange);
    }
    if alpha == 0.0 && n_constraints > 0 {
        return Err(AlphaRefusal::ZeroWithConstraints);
    }
    if alpha > -ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS && n_constraints > 0 {
        return Err(AlphaRefusal::TooCloseToZeroWithConstraints);
    }
    Ok(())
}

/// Coefficients derived from `α` and `h` (docs/method.md §5, Arnold–Brüls generalized-α with
/// `α_m = 0`, `α_f = −α`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HhtCoefficients {
    /// `α` ∈ [−1/3, 0].
    pub alpha: f64,
    /// `γ = ½ − α`.
    pub gamma: f64,
    /// `β = (1 − α)² / 4`.
    pub beta: f64,
    /// `β' = (1 + α) β` = `∂q_{n+1}/∂q̈_{n+1} / h²`.
    pub beta_prime: f64,
    /// `γ' = (1 + α) γ` = `∂q̇_{n+1}/∂q̈_{n+1} / h`.
    pub gamma_prime: f64,
    /// Step `h`, s.
    pub h: f64,
}

impl HhtCoefficients {
    /// Coefficients for `alpha` and step `h` (not validated; see [`HhtSettings::validate`]).
    pub fn new(alpha: f64, h: f64) -> Self {
        let gamma = 0.5 - alpha;
        let beta = 0.25 * (1.0 - alpha) * (1.0 - alpha);
        Self {
            alpha,
            gamma,
            beta,
            beta_prime: (1.0 + alpha) * beta,
            gamma_prime: (1.0 + alpha) * gamma,
            h,
        }
    }

    /// `β' h²`: derivative of `q_{n+1}` with respect to `q̈_{n+1}`.
    pub fn beta_h2(&self) -> f64 {
        self.beta_prime * self.h * self.h
    }

    /// `γ' h`: derivative of `q̇_{n+1}` with respect to `q̈_{n+1}`.
    pub fn gamma_h(&self) -> f64 {
        self.gamma_prime * self.h
    }
}

impl HhtSettings {
    /// Checks every field for a system with `n_constraints` rows and returns the derived coefficients.
    ///
    /// Errors: `α ∉ [−1/3, 0]` or NaN → [`IntegrateError::InvalidAlpha`]; `α = 0` with
    /// constraints → [`IntegrateError::AlphaZeroWithConstraints`]; `α` in
    /// `(−`[`ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS`]`, 0)` with constraints →
    /// [`IntegrateError::AlphaTooCloseToZero`]; `h ≤ 0` or not finite →
    /// [`IntegrateError::InvalidStep`]; a non-positive tolerance or zero iterations →
    /// [`IntegrateError::InvalidSetting`].
    pub fn validate(&self, n_constraints: usize) -> Result<HhtCoefficients, IntegrateError> {
        let alpha = self.alpha;
        check_alpha(alpha, n_constraints).map_err(|refusal| match refusal {
            AlphaRefusal::OutsideRange => IntegrateError::InvalidAlpha { alpha },
            AlphaRefusal::ZeroWithConstraints => {
                IntegrateError::AlphaZeroWithConstraints { n_constraints }
            }
            AlphaRefusal::TooCloseToZeroWithConstraints => IntegrateError::AlphaTooCloseToZero {
                alpha,
                limit: -ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS,
                n_constraints,
            },
        })?;
        if !self.step_s.is_finite() || self.step_s <= 0.0 {
            return Err(IntegrateError::InvalidStep {
                step_s: self.step_s,
            });
        }
        for (name, value) in [
            ("reltol", self.reltol),
            ("abstol_position", self.abstol_position),
            ("abstol_multiplier", self.abstol_multiplier),
            ("tolerance", self.tolerance),
        ] {
            if !value.is_finite() || value <= 0.0 {
                return Err(IntegrateError::InvalidSetting {
                    name,
                    value,
                    reason: "must be finite and > 0",
                });
            }
        }
        if self.max_newton_iterations == 0 {
            return Err(IntegrateError::InvalidSetting {
                name: "max_newton_iterations",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        if self.max_step_halvings > MAX_STEP_HALVINGS {
            return Err(IntegrateError::InvalidSetting {
                name: "max_step_halvings",
                value: f64::from(self.max_step_halvings),
                reason: "must be at most 20 (sub-steps down to h / 2^20)",
            });
        }
        Ok(HhtCoefficients::new(alpha, self.step_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_range_and_the_constraint_rows_limit() {
        for alpha in [ALPHA_MIN, -0.1, -ALPHA_MIN_MAGNITUDE_WITH_CONSTRAINTS] {
            assert_eq!(check_alpha(alpha, 3), Ok(()), "{alpha}");
        }
        for alpha in [-0.34, 0.2, f64::NAN, f64::NEG_INFINITY] {
            assert_eq!(
                check_alpha(alpha, 0),
                Err(AlphaRefusal::OutsideRange),
                "{alpha}"
            );
        }
        assert_eq!(check_alpha(0.0, 0), Ok(()));
        assert_eq!(check_alpha(-1e-9, 0), Ok(()));
        assert_eq!(check_alpha(0.0, 1), Err(AlphaRefusal::ZeroWithConstraints));
        assert_eq!(
            check_alpha(-0.049, 1),
            Err(AlphaRefusal::TooCloseToZeroWithConstraints)
        );
    }
}
