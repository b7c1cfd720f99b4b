//! Checked calls into a [`DaeSystem`]: each wrapper maps the system's error to
//! [`IntegrateError::System`] with the time, step and method name, and checks the output for NaN/Inf
//! where it arises ([`IntegrateError::NonFinite`]), both through one helper ([`At::checked`]). Allocation-free on the success path.

use nalgebra::{DMatrix, DVector};

use super::dense_solver::{all_finite, first_non_finite};
use super::error::IntegrateError;
use super::system::{
    Constraints, DaeState, DaeSystem, InverseDynamics, NewtonCoupling, NewtonUpdateLimit,
    Parameters, ResidualJacobians,
};

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

/// `stiffness (nv), damping (nv)` = diagonal spring and damper terms, when the system has them
/// ([`DaeSystem::as_newton_diagonal`]); returns whether it has (without, both are left as they are).
pub(crate) fn newton_diagonal<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    v: &DVector<f64>,
    stiffness: &mut DVector<f64>,
    damping: &mut DVector<f64>,
) -> Result<bool, IntegrateError> {
    let Some(terms) = sys.as_newton_diagonal() else {
        return Ok(false);
    };
    let result = terms.newton_diagonal(at.t, q, v, stiffness, damping);
    at.checked(
        "newton_diagonal",
        result,
        "newton_diagonal.stiffness",
        stiffness.as_slice(),
    )?;
    at.check_finite("newton_diagonal.damping", damping.as_slice())?;
    Ok(true)
}

/// The coupling terms of [`NewtonCoupling::newton_coupling`], checked finite.
pub(crate) fn newton_coupling(
    sys: &mut dyn NewtonCoupling,
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

/// Number of constraint rows `m` of `sys` (0 without [`DaeSystem::as_constraints`]).
pub(crate) fn n_constraints<S: DaeSystem + ?Sized>(sys: &mut S) -> usize {
    sys.as_constraints().map_or(0, |rows| rows.n_constraints())
}

/// Number of unilateral limits of `sys` (0 without [`DaeSystem::as_unilateral_limits`]).
pub(crate) fn n_events<S: DaeSystem + ?Sized>(sys: &mut S) -> usize {
    sys.as_unilateral_limits()
        .map_or(0, |limits| limits.n_events())
}

/// Number of parameters `P` of `sys` (0 without [`DaeSystem::as_parameters`]).
pub(crate) fn n_parameters<S: DaeSystem + ?Sized>(sys: &mut S) -> usize {
    sys.as_parameters().map_or(0, |p| p.n_parameters())
}

/// The error of a system whose capability hook answers `None` after the integrator was sized by
/// its earlier answer (`hook` named): a system's capabilities must not change during a run.
#[cold]
#[inline(never)]
pub(crate) fn capability_withdrawn(
    at: At,
    call: &'static str,
    hook: &'static str,
) -> IntegrateError {
    IntegrateError::System {
        t: at.t,
        step: at.step,
        call,
        source: format!(
            "{hook}() returned None, but the integrator was sized by an earlier answer that was \
             Some; a system's capabilities must not change during a run"
        )
        .into(),
    }
}

/// The system's [`Constraints`] for `call`, which writes `rows` entries: with no rows to write a
/// system without constraints has nothing to do (`Ok(None)`).
#[inline]
fn constraint_rows_for<'a, S: DaeSystem + ?Sized>(
    sys: &'a mut S,
    at: At,
    call: &'static str,
    rows: usize,
) -> Result<Option<&'a mut dyn Constraints>, IntegrateError> {
    match sys.as_constraints() {
        Some(constraints) => Ok(Some(constraints)),
        None if rows == 0 => Ok(None),
        None => Err(capability_withdrawn(at, call, "as_constraints")),
    }
}

/// `out (m) = Φ(q, t)`.
pub(crate) fn constraints<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let Some(rows) = constraint_rows_for(sys, at, "constraints", out.len())? else {
        return Ok(());
    };
    let result = rows.constraints(at.t, q, out);
    at.checked("constraints", result, "constraints", out.as_slice())
}

/// `out (m × nv) = Φ_q(q, t)`.
pub(crate) fn constraint_jacobian<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let Some(rows) = constraint_rows_for(sys, at, "constraint_jacobian", out.nrows())? else {
        return Ok(());
    };
    let result = rows.constraint_jacobian(at.t, q, out);
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
    let Some(rows) = constraint_rows_for(sys, at, "constraints_and_jacobian", phi.len())? else {
        return Ok(());
    };
    let result = rows.constraints_and_jacobian(at.t, q, phi, phi_q);
    at.checked(
        "constraints_and_jacobian",
        result,
        "constraints",
        phi.as_slice(),
    )?;
    at.check_finite("constraint_jacobian", phi_q.as_slice())
}

/// Whether `sys` has no row that depends on time explicitly
/// ([`Constraints::constraints_are_scleronomic`]; a system without constraints has none).
pub(crate) fn constraints_are_scleronomic<S: DaeSystem + ?Sized>(sys: &mut S) -> bool {
    sys.as_constraints()
        .is_none_or(|rows| rows.constraints_are_scleronomic())
}

/// `out (m) = Φ_t(q, t)`.
pub(crate) fn constraint_time_derivative<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    q: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let Some(rows) = constraint_rows_for(sys, at, "constraint_time_derivative", out.len())? else {
        return Ok(());
    };
    let result = rows.constraint_time_derivative(at.t, q, out);
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
    let Some(rows) = constraint_rows_for(sys, at, "constraint_acceleration_bias", out.len())?
    else {
        return Ok(());
    };
    let result = rows.constraint_acceleration_bias(at.t, q, v, out);
    at.checked(
        "constraint_acceleration_bias",
        result,
        "constraint_acceleration_bias",
        out.as_slice(),
    )
}

/// `out (nq) = q ⊕ dq`: the system's [`PositionGroup`], or `q + dq` without one. Always inlined:
/// it runs at every Newton iterate (an outlined call cost ~1 % of a ur5 step's instructions).
#[inline(always)]
pub(crate) fn integrate_position<S: DaeSystem + ?Sized>(
    sys: &S,
    at: At,
    q: &DVector<f64>,
    dq: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = match sys.as_position_group() {
        Some(group) => group.integrate_position(q, dq, out),
        None => add_positions(q, dq, out),
    };
    at.checked(
        "integrate_position",
        result,
        "integrate_position",
        out.as_slice(),
    )
}

/// `out = q + dq`, the position update of a system without a [`PositionGroup`] (`nq == nv`,
/// checked by [`check_position_update`] before a run; checked here too, as an error).
#[inline(always)]
fn add_positions(
    q: &DVector<f64>,
    dq: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), super::error::SystemError> {
    if q.len() != dq.len() || out.len() != q.len() {
        return Err(addition_needs_equal_lengths(q.len(), dq.len(), out.len()));
    }
    for ((x, q), dq) in out
        .as_mut_slice()
        .iter_mut()
        .zip(q.as_slice())
        .zip(dq.as_slice())
    {
        *x = q + dq;
    }
    Ok(())
}

/// The error of `q + dq` with `nq != nv` (a system that needs a [`PositionGroup`]).
#[cold]
#[inline(never)]
fn addition_needs_equal_lengths(q: usize, dq: usize, out: usize) -> super::error::SystemError {
    format!(
        "q ⊕ dq without a position group needs nq == nv (got q {q}, dq {dq}, out {out}); a system \
         with nq != nv must return its PositionGroup from as_position_group"
    )
    .into()
}

/// `out (nv) = q1 ⊖ q0`: the system's [`PositionGroup`], or `q1 − q0` without one.
pub(crate) fn difference_position<S: DaeSystem + ?Sized>(
    sys: &S,
    at: At,
    q0: &DVector<f64>,
    q1: &DVector<f64>,
    out: &mut DVector<f64>,
) -> Result<(), IntegrateError> {
    let result = match sys.as_position_group() {
        Some(group) => group.difference_position(q0, q1, out),
        None if q0.len() == out.len() && q1.len() == out.len() => {
            for i in 0..out.len() {
                out[i] = q1[i] - q0[i];
            }
            Ok(())
        }
        None => Err(format!(
            "q1 ⊖ q0 without a position group needs nq == nv (got q0 {}, q1 {}, out {})",
            q0.len(),
            q1.len(),
            out.len()
        )
        .into()),
    };
    result.map_err(at.system_error("difference_position"))
}

/// A system without a [`PositionGroup`] updates positions by addition, which needs `nq == nv`:
/// an error naming the mismatch otherwise (before a run, instead of at its first step).
pub(crate) fn check_position_update<S: DaeSystem + ?Sized>(sys: &S) -> Result<(), IntegrateError> {
    if sys.as_position_group().is_none() && sys.nq() != sys.nv() {
        return Err(IntegrateError::DimensionMismatch {
            what: "nq of a system without a position group (q ⊕ dq = q + dq needs nq == nv)",
            expected: sys.nv(),
            got: sys.nq(),
        });
    }
    Ok(())
}

/// Checks the system's declared dimensions against the sizes the caller holds.
pub(crate) fn check_dimensions<S: DaeSystem + ?Sized>(
    sys: &mut S,
    nq: usize,
    nv: usize,
    m: usize,
) -> Result<(), IntegrateError> {
    for (what, expected, got) in [
        ("system nq", nq, sys.nq()),
        ("system nv", nv, sys.nv()),
        ("system n_constraints", m, n_constraints(sys)),
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
pub(crate) fn residual_jacobians(
    sys: &mut dyn ResidualJacobians,
    at: At,
    state: &DaeState<'_>,
    stiffness: &mut DMatrix<f64>,
    damping: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    let result = sys.residual_jacobians(state, stiffness, damping);
    at.checked(
        "residual_jacobians",
        result,
        "residual_jacobians.stiffness",
        stiffness.as_slice(),
    )?;
    at.check_finite("residual_jacobians.damping", damping.as_slice())
}

/// The system's [`Parameters`] for `call` (which the caller makes only with `P > 0`).
pub(crate) fn parameters<'a, S: DaeSystem + ?Sized>(
    sys: &'a mut S,
    at: At,
    call: &'static str,
) -> Result<&'a mut dyn Parameters, IntegrateError> {
    sys.as_parameters()
        .ok_or_else(|| capability_withdrawn(at, call, "as_parameters"))
}

/// `dynamics_out (nv × P) = ∂r/∂p`, `constraints_out (m × P) = ∂Φ/∂p` at `state`
/// ([`Parameters::parameter_jacobians`]); without parameters there is no column to write. The
/// caller checks what it reads for NaN/Inf.
pub(crate) fn parameter_jacobians<S: DaeSystem + ?Sized>(
    sys: &mut S,
    at: At,
    state: &DaeState<'_>,
    dynamics_out: &mut DMatrix<f64>,
    constraints_out: &mut DMatrix<f64>,
) -> Result<(), IntegrateError> {
    match sys.as_parameters() {
        Some(parameters) => parameters
            .parameter_jacobians(state, dynamics_out, constraints_out)
            .map_err(at.system_error("parameter_jacobians")),
        None if dynamics_out.ncols() == 0 && constraints_out.ncols() == 0 => Ok(()),
        None => Err(capability_withdrawn(
            at,
            "parameter_jacobians",
            "as_parameters",
        )),
    }
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
    let limits = sys
        .as_unilateral_limits()
        .ok_or_else(|| capability_withdrawn(at, "event_gaps", "as_unilateral_limits"))?;
    let result = limits.event_gaps(at.t, q, v, gaps, rates);
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
    let limits = sys
        .as_unilateral_limits()
        .ok_or_else(|| capability_withdrawn(at, "apply_impact", "as_unilateral_limits"))?;
    let result = limits.apply_impact(at.t, event, q, v);
    at.checked("apply_impact", result, "apply_impact.q", q.as_slice())?;
    at.check_finite("apply_impact.v", v.as_slice())
}

/// The fraction of a Newton correction to apply ([`NewtonUpdateLimit::newton_update_fraction`]),
/// checked to lie in `(0, 1]`: anything else (NaN included) is an error of the system, not a
/// reason to stall.
pub(crate) fn newton_update_fraction(
    sys: &mut dyn NewtonUpdateLimit,
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
