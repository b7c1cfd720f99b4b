//! Checked calls into a [`DaeSystem`]: each wrapper maps the system's error to
//! [`IntegrateError::System`] with the time, step and method name, and checks the output for NaN/Inf
//! where it arises ([`IntegrateError::NonFinite`]), both through one helper ([`At::checked`]). Allocation-free on the success path.

use nalgebra::{DMatrix, DVector};

use super::dense_solver::{all_finite, first_non_finite};
use super::error::IntegrateError;
use super::system::{DaeSystem, InverseDynamics, ResidualJacobians};

/// Where an evaluation happens: time and step number (0 = consistent start).
#[derive(Debug, Clone, Copy)]
pub(crate) struct At {
    /// Time, s.
    pub t: f64,
    /// Step number (0 = consistent start).
    pub step: u64,
}

impl At {
    pub fn system_error(
        self,
        call: &'static str,
    ) -> impl FnOnce(super::error::SystemError) -> IntegrateError {
        move |source| IntegrateError::System {
            t: self.t,
            step: self.step,
            call,
            source,
        }
    }

    /// The result of the system's method `call` with its output checked where it arises: the
    /// system's error as [`IntegrateError::System`] naming `call`, then `output` as
    /// [`Self::check_finite`] under `quantity` (a method with a second output checks it after
    /// this, with `check_finite`). Always inlined: each wrapper compiles to what its two lines were.
    #[inline(always)]
    pub fn checked(
        self,
        call: &'static str,
        result: Result<(), super::error::SystemError>,
        quantity: &'static str,
        output: &[f64],
    ) -> Result<(), IntegrateError> {
        result.map_err(self.system_error(call))?;
        self.check_finite(quantity, output)
    }

    /// `Err(NonFinite)` naming `quantity` if any entry of `x` is NaN or infinite.
    /// Inlined test, out-of-line report: the common case is a short loop at the call site.
    #[inline]
    pub fn check_finite(self, quantity: &'static str, x: &[f64]) -> Result<(), IntegrateError> {
        if all_finite(x) {
            Ok(())
        } else {
            self.non_finite(quantity, x)
        }
    }

    /// The [`IntegrateError::NonFinite`] of `x`, which holds a NaN or infinite entry.
    #[cold]
    #[inline(never)]
    fn non_finite(self, quantity: &'static str, x: &[f64]) -> Result<(), IntegrateError> {
        Err(IntegrateError::NonFinite {
            t: self.t,
            step: self.step,
            quantity,
            index: first_non_finite(x).unwrap_or(0),
        })
    }
}

/// `out (nv × nv) = M(q)`.
pub(crate) fn mass_matrix<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.mass_matrix(at.t, q, out);
    at.checked("mass_matrix", result, "mass_matrix", out.as_slice())
}

/// `out (nv) = Q(t, q, v)`.
pub(crate) fn forces<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.forces(at.t, q, v, out);
    at.checked("forces", result, "forces", out.as_slice())
}

/// `out (nv) = M q̈ − Q` through the system's inverse dynamics. `after_mass_matrix`: `q` is the
/// configuration of the system's last `mass_matrix` call (the first residual after a
/// factorisation at the same iterate), whose kinematics the system may reuse
/// ([`InverseDynamics::dynamics_residual_after_mass_matrix`]). Inlined into the Newton iteration,
/// as the generic wrappers are.
#[inline]
pub(crate) fn dynamics_residual(
    sys: &mut dyn InverseDynamics,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    qdd: &DVector<f64>,
    after_mass_matrix: bool,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = if after_mass_matrix {
        sys.dynamics_residual_after_mass_matrix(at.t, q, v, qdd, out)
    } else {
        sys.dynamics_residual(at.t, q, v, qdd, out)
    };
    at.checked(
        "dynamics_residual",
        result,
        "dynamics_residual",
        out.as_slice(),
    )
}

/// `stiffness (nv), damping (nv)` = diagonal spring and damper terms.
pub(crate) fn newton_diagonal<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    stiffness: &mut DVector<f64>,
    damping: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.newton_diagonal(at.t, q, v, stiffness, damping);
    at.checked(
        "newton_diagonal",
        result,
        "newton_diagonal.stiffness",
        stiffness.as_slice(),
    )?;
    at.check_finite("newton_diagonal.damping", damping.as_slice())
}

/// The coupling terms of [`DaeSystem::newton_coupling`], checked finite.
pub(crate) fn newton_coupling<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    stiffness: &mut DMatrix<f64>,
    damping: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.newton_coupling(at.t, q, v, stiffness, damping);
    at.checked(
        "newton_coupling",
        result,
        "newton_coupling.stiffness",
        stiffness.as_slice(),
    )?;
    at.check_finite("newton_coupling.damping", damping.as_slice())
}

/// `out (m) = Φ(q, t)`.
pub(crate) fn constraints<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.constraints(at.t, q, out);
    at.checked("constraints", result, "constraints", out.as_slice())
}

/// `out (m × nv) = Φ_q(q, t)`.
pub(crate) fn constraint_jacobian<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.constraint_jacobian(at.t, q, out);
    at.checked(
        "constraint_jacobian",
        result,
        "constraint_jacobian",
        out.as_slice(),
    )
}

/// `phi (m) = Φ(q, t)` and `phi_q (m × nv) = Φ_q(q, t)` in one call (the same bits as
/// [`constraints`] then [`constraint_jacobian`]).
pub(crate) fn constraints_and_jacobian<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    phi: &mut DVector<f64>,
    phi_q: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.constraints_and_jacobian(at.t, q, phi, phi_q);
    at.checked(
        "constraints_and_jacobian",
        result,
        "constraints",
        phi.as_slice(),
    )?;
    at.check_finite("constraint_jacobian", phi_q.as_slice())
}

/// `out (m) = Φ_t(q, t)`.
pub(crate) fn constraint_time_derivative<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.constraint_time_derivative(at.t, q, out);
    at.checked(
        "constraint_time_derivative",
        result,
        "constraint_time_derivative",
        out.as_slice(),
    )
}

/// `out (m) = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt`.
pub(crate) fn constraint_acceleration_bias<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.constraint_acceleration_bias(at.t, q, v, out);
    at.checked(
        "constraint_acceleration_bias",
        result,
        "constraint_acceleration_bias",
        out.as_slice(),
    )
}

/// `out (nq) = q ⊕ dq`.
#[inline]
pub(crate) fn integrate_position<S: DaeSystem + ?Sized>(
    sys: &S,
    at: At,
    q: &DVector<f64>,
    dq: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.integrate_position(q, dq, out);
    at.checked(
        "integrate_position",
        result,
        "integrate_position",
        out.as_slice(),
    )
}

/// Checks the system's declared dimensions against the sizes the caller holds.
pub(crate) fn check_dimensions<S: DaeSystem + ?Sized>(
    sys: &S,
    nq: usize,
    nv: usize,
    m: usize,
) -> Result<(), IntegrateError> {
    for (what, expected, got) in [
        ("system nq", nq, sys.nq()),
        ("system nv", nv, sys.nv()),
        ("system n_constraints", m, sys.n_constraints()),
    ] {
        if expected != got {
            return Err(IntegrateError::DimensionMismatch {
                what,
                expected,
                got,
            });
        }
    }
    Ok(())
}

/// `stiffness (nv × nv) = ∂r/∂q`, `damping (nv × nv) = ∂r/∂q̇` of `r = M q̈ + Φ_qᵀλ − Q`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn residual_jacobians(
    sys: &mut dyn ResidualJacobians,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    qdd: &DVector<f64>,
    lambda: &DVector<f64>,
    stiffness: &mut DMatrix<f64>,
    damping: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.residual_jacobians(at.t, q, v, qdd, lambda, stiffness, damping);
    at.checked(
        "residual_jacobians",
        result,
        "residual_jacobians.stiffness",
        stiffness.as_slice(),
    )?;
    at.check_finite("residual_jacobians.damping", damping.as_slice())
}

/// `gaps (n_events) = g(q)`, `rates (n_events) = ġ(q, v)` of the unilateral limits.
pub(crate) fn event_gaps<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    gaps: &mut DVector<f64>,
    rates: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.event_gaps(at.t, q, v, gaps, rates);
    at.checked("event_gaps", result, "event_gaps", gaps.as_slice())?;
    at.check_finite("event_gaps.rates", rates.as_slice())
}

/// The impact law of limit `event` at `(q, v)` (both overwritten).
pub(crate) fn apply_impact<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    event: usize,
    q: &mut DVector<f64>,
    v: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.apply_impact(at.t, event, q, v);
    at.checked("apply_impact", result, "apply_impact.q", q.as_slice())?;
    at.check_finite("apply_impact.v", v.as_slice())
}

/// The fraction of a Newton correction to apply ([`DaeSystem::newton_update_fraction`]), checked to
/// lie in `(0, 1]`: anything else (NaN included) is an error of the system, not a reason to stall.
pub(crate) fn newton_update_fraction<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    dv: &DVector<f64>,
) -> Result<f64, IntegrateError> {
    let fraction = sys
        .newton_update_fraction(at.t, q, v, dv)
        .map_err(at.system_error("newton_update_fraction"))?;
    if fraction > 0.0 && fraction <= 1.0 {
        Ok(fraction)
    } else {
        Err(IntegrateError::System {
            t: at.t,
            step: at.step,
            call: "newton_update_fraction",
            source: format!("returned {fraction}, outside (0, 1]").into(),
        })
    }
}
