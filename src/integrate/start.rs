//! Consistent initial state (docs/method.md §5, "Consistent start"):
//!
//! ```text
//! (t0, q0, q̇0) => project q onto Φ(q, t0) = 0          (Gauss–Newton, least-norm steps, backtracking)
//!              => project q̇ onto Φ_q q̇ + Φ_t = 0       (least-norm)
//!              => solve [M Φ_qᵀ; Φ_q 0] [q̈0; λ0] = [Q; −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt]
//! ```
//!
//! Runs once per trajectory, so it may allocate (an SVD of `Φ_q` detects redundant rows before any
//! singular solve). Each sample of a study is projected with its own parameters.

use nalgebra::{DMatrix, DVector, SVD};

use super::dense_solver::{DenseSolver, FactorKind};
use super::error::IntegrateError;
use super::eval::{self, At};
use super::system::DaeSystem;

/// `Φ_q` rows count as dependent when its smallest singular value is below this fraction of its
/// largest. Genuinely redundant rows give ~1e-16 (rounding); a mechanism merely near a singular
/// configuration keeps ratios of 1e-3..1e-6, far above.
pub const REDUNDANT_ROW_RELATIVE_SV: f64 = 1e-10;

/// The initial positions are accepted as closed when `max |Φ_j| ≤` this (m or rad): a few hundred
/// rounding units of a metre-sized mechanism, far below any modelling accuracy, and reachable in a
/// handful of Gauss–Newton steps.
pub const START_CONSTRAINT_TOL: f64 = 1e-12;

/// Gauss–Newton iterations allowed to close the constraints. Converges quadratically from any
/// reasonable start, so needing more means the loop cannot close.
pub const START_MAX_ITERATIONS: usize = 50;

/// Step halvings allowed in one Gauss–Newton iteration before giving up (a step 2⁻³⁰ of the
/// least-norm step that still does not reduce ‖Φ‖ means a local minimum of ‖Φ‖ with Φ ≠ 0).
const START_MAX_HALVINGS: usize = 30;

/// The consistent initial state returned by [`consistent_start`].
#[derive(Debug, Clone, PartialEq)]
pub struct ConsistentStart {
    /// Positions on `Φ = 0`, dim `nq`.
    pub q: DVector<f64>,
    /// Velocities on `Φ_q q̇ + Φ_t = 0`, dim `nv`.
    pub v: DVector<f64>,
    /// Accelerations satisfying the equations of motion and the acceleration-level constraints, dim `nv`.
    pub qdd: DVector<f64>,
    /// Multipliers, dim `m` (sign: `M q̈ + Φ_qᵀ λ = Q`).
    pub lambda: DVector<f64>,
    /// Gauss–Newton iterations used to close the constraints (0 when already closed or `m = 0`).
    pub projection_iterations: usize,
    /// `max |Φ_j|` of the given `q0` before projection.
    pub initial_violation: f64,
    /// `max |Φ_j|` after projection.
    pub final_violation: f64,
}

/// Makes `(q0, v0)` consistent with the constraints at `t0` and computes `q̈0`, `λ0`.
///
/// - `q0`: dim `nq`; `v0`: dim `nv`.
///
/// Errors: [`IntegrateError::CannotClose`] if Gauss–Newton does not reach `START_CONSTRAINT_TOL`;
/// [`IntegrateError::RedundantConstraints`] if `Φ_q` is rank deficient;
/// [`IntegrateError::SingularMatrix`] if `M` (or the saddle-point matrix) is singular;
/// [`IntegrateError::NonFinite`] / [`IntegrateError::System`] from the system's outputs.
pub fn consistent_start<S: DaeSystem + ?Sized>(
    sys: &mut S,
    t0: f64,
    q0: &DVector<f64>,
    v0: &DVector<f64>,
) -> Result<ConsistentStart, IntegrateError> {
    let (nq, nv, m) = (sys.nq(), sys.nv(), eval::n_constraints(sys));
    eval::check_position_update(sys)?;
    if q0.len() != nq {
        return Err(IntegrateError::DimensionMismatch {
            what: "q0",
            expected: nq,
            got: q0.len(),
        });
    }
    if v0.len() != nv {
        return Err(IntegrateError::DimensionMismatch {
            what: "v0",
            expected: nv,
            got: v0.len(),
        });
    }
    let at = At { t: t0, step: 0 };
    at.check_finite("q0", q0.as_slice())?;
    at.check_finite("v0", v0.as_slice())?;
    if !t0.is_finite() {
        return Err(IntegrateError::NonFinite {
            t: t0,
            step: 0,
            quantity: "t0",
            index: 0,
        });
    }

    let mut q = q0.clone();
    let mut v = v0.clone();
    let mut phi = DVector::zeros(m);
    let mut phi_q = DMatrix::zeros(m, nv);
    let mut projection_iterations = 0;
    let mut initial_violation = 0.0;
    let mut final_violation = 0.0;

    if m > 0 {
        // (q0) => q on Φ = 0: least-norm Gauss–Newton steps δ = −Φ_q⁺ Φ, halved until ‖Φ‖ decreases.
        eval::constraints(sys, at, &q, &mut phi)?;
        initial_violation = phi.amax();
        let mut trial_q = q.clone();
        let mut trial_phi = phi.clone();
        let mut dq = DVector::zeros(nv);
        let mut step_dq = DVector::zeros(nv);
        while phi.amax() > START_CONSTRAINT_TOL {
            if projection_iterations == START_MAX_ITERATIONS {
                return Err(cannot_close(t0, projection_iterations, &phi));
            }
            projection_iterations += 1;
            eval::constraint_jacobian(sys, at, &q, &mut phi_q)?;
            let svd = checked_svd(&phi_q, t0)?;
            dq.copy_from(&least_norm_solve(&svd, &phi));
            dq.neg_mut();
            let norm = phi.norm();
            let mut scale = 1.0;
            let mut accepted = false;
            for _ in 0..=START_MAX_HALVINGS {
                step_dq.copy_from(&dq);
                step_dq *= scale;
                eval::integrate_position(sys, at, &q, &step_dq, &mut trial_q)?;
                eval::constraints(sys, at, &trial_q, &mut trial_phi)?;
                if trial_phi.norm() < norm {
                    accepted = true;
                    break;
                }
                scale *= 0.5;
            }
            if !accepted {
                return Err(cannot_close(t0, projection_iterations, &phi));
            }
            q.copy_from(&trial_q);
            phi.copy_from(&trial_phi);
        }
        final_violation = phi.amax();

        // (q, q̇0) => q̇ on Φ_q q̇ + Φ_t = 0: q̇ −= Φ_q⁺ (Φ_q q̇ + Φ_t).
        eval::constraint_jacobian(sys, at, &q, &mut phi_q)?;
        let svd = checked_svd(&phi_q, t0)?;
        let mut velocity_residual = DVector::zeros(m);
        eval::constraint_time_derivative(sys, at, &q, &mut velocity_residual)?;
        velocity_residual.gemv(1.0, &phi_q, &v, 1.0);
        v -= least_norm_solve(&svd, &velocity_residual);
    }

    // (q, q̇) => (q̈0, λ0): [M Φ_qᵀ; Φ_q 0] [q̈0; λ0] = [Q; bias].
    let mut mass = DMatrix::zeros(nv, nv);
    eval::mass_matrix(sys, at, &q, &mut mass)?;
    let mut rhs = DVector::zeros(nv + m);
    let mut q_force = DVector::zeros(nv);
    eval::forces(sys, at, &q, &v, &mut q_force)?;
    rhs.rows_mut(0, nv).copy_from(&q_force);
    if m > 0 {
        let mut bias = DVector::zeros(m);
        eval::constraint_acceleration_bias(sys, at, &q, &v, &mut bias)?;
        rhs.rows_mut(nv, m).copy_from(&bias);
    }
    let kind = if m == 0 {
        FactorKind::Cholesky
    } else {
        FactorKind::SaddlePoint { constraint_rows: m }
    };
    let mut solver = DenseSolver::new(nv + m, kind);
    solver
        .factor_blocks(&mass, None, &phi_q)
        .map_err(|b| IntegrateError::SingularMatrix {
            t: t0,
            step: 0,
            matrix: if m == 0 {
                "mass matrix (initial acceleration)"
            } else {
                "saddle-point matrix [M Φ_qᵀ; Φ_q 0] (initial acceleration)"
            },
            index: b.index,
            pivot_relative: b.pivot_relative,
        })?;
    solver.solve_in_place(&mut rhs);
    at.check_finite("initial acceleration", rhs.as_slice())?;
    Ok(ConsistentStart {
        q,
        v,
        qdd: rhs.rows(0, nv).into_owned(),
        lambda: rhs.rows(nv, m).into_owned(),
        projection_iterations,
        initial_violation,
        final_violation,
    })
}

fn cannot_close(t: f64, iterations: usize, phi: &DVector<f64>) -> IntegrateError {
    IntegrateError::CannotClose {
        t,
        iterations,
        violation: phi.amax(),
        worst_row: phi.iamax(),
        tolerance: START_CONSTRAINT_TOL,
    }
}

/// SVD of `Φ_q` (m × nv), refusing rank-deficient Jacobians (redundant rows) with a clear error.
pub(crate) fn checked_svd(
    phi_q: &DMatrix<f64>,
    t: f64,
) -> Result<SVD<f64, nalgebra::Dyn, nalgebra::Dyn>, IntegrateError> {
    let m = phi_q.nrows();
    let too_few_columns = phi_q.ncols() < m;
    let svd = SVD::new(phi_q.clone(), true, true);
    let largest = svd.singular_values.max();
    let (smallest, idx) = if too_few_columns {
        (0.0, 0)
    } else {
        let i = svd.singular_values.imin();
        (svd.singular_values[i], i)
    };
    if too_few_columns || largest == 0.0 || smallest < REDUNDANT_ROW_RELATIVE_SV * largest {
        // The left singular vector of the smallest singular value is the dependent combination of
        // rows: name its dominant row. With more rows than columns the rows are dependent for sure
        // and the thin SVD does not hold that vector: name the last row.
        let row = match (&svd.u, too_few_columns) {
            (Some(u), false) => u.column(idx).iamax(),
            _ => m - 1,
        };
        return Err(IntegrateError::RedundantConstraints {
            t,
            smallest,
            largest,
            tolerance: REDUNDANT_ROW_RELATIVE_SV,
            row,
        });
    }
    Ok(svd)
}

/// Least-norm solution `x = A⁺ b` from a full-row-rank SVD (`checked_svd`).
fn least_norm_solve(
    svd: &SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
    b: &DVector<f64>,
) -> DVector<f64> {
    // Full row rank was checked, so every singular value is well above zero: no truncation needed.
    let u = svd.u.as_ref().expect("SVD computed with U");
    let v_t = svd.v_t.as_ref().expect("SVD computed with Vᵀ");
    let mut coeff = u.tr_mul(b);
    for (c, s) in coeff.iter_mut().zip(svd.singular_values.iter()) {
        *c /= *s;
    }
    v_t.tr_mul(&coeff)
}
