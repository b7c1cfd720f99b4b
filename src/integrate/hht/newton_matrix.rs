//! The Newton iteration matrix (docs/method.md §5): its assembly from `M`, the diagonal
//! spring/damper terms, the coupling terms and `Φ_q` ([`assemble_iteration_matrix`]), its
//! factorisation at the current iterate (diagonal or full, docs/step-control.md §1–§2), and the
//! same matrix for diagnostics ([`iteration_matrix`]).

use super::HhtIntegrator;
use crate::integrate::dense_solver::assemble_constraint_blocks;
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::settings::HhtSettings;
use crate::integrate::system::{DaeState, DaeSystem};
use nalgebra::{DMatrix, DVector};

/// Which form of the constraint rows [`iteration_matrix`] returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConstraintRowScaling {
    /// Rows `[Φ_q 0]` with right-hand side `−Φ/(β'h²)`: what the integrator factorises. Condition
    /// number bounded as `h → 0`.
    Scaled,
    /// Rows `[β'h² Φ_q 0]` with right-hand side `−Φ` (the plain derivative of `Φ(q(q̈))`). Condition
    /// number grows like `h⁻²`.
    Unscaled,
}

/// Assembles the Newton iteration matrix of docs/method.md §5 into `out` (`(nv + m) × (nv + m)`).
///
/// The Newton system for the unknowns `(q̈_{n+1}, λ_{n+1})`, with `β' = (1+α)β`, `γ' = (1+α)γ`:
///
/// ```text
/// [ M + β'h² K_t − γ'h C_t    Φ_qᵀ ] [Δq̈]      [ M q̈ + Φ_qᵀλ − Q ]
/// [ c · Φ_q                   0    ] [Δλ ]  = − [ c · Φ / (β'h²)    ]
///
/// K_t = ∂(M q̈ + Φ_qᵀλ − Q)/∂q,  C_t = ∂Q/∂q̇
/// ```
///
/// Modified Newton keeps only `M` and the diagonal spring/damper parts of `K_t` and `C_t`: a spring
/// `Q_j = −k_j q_j` gives `K_t,jj = +k_j`, a damper `Q_j = −c_j q̇_j` gives `C_t,jj = −c_j`, so the
/// diagonal gets `+β'h² k_j + γ'h c_j`.
///
/// The constraint rows are written with `c = 1` (`constraint_row_factor = 1`): that is the plain
/// derivative of `Φ(q(q̈))` (`Φ_q β'h²`) divided by `β'h²`, which keeps the condition number bounded
/// as `h → 0`. `constraint_row_factor = β'h²` gives the unscaled rows (condition ∝ h⁻²), exposed only
/// for [`iteration_matrix`]. With `beta_h2 = gamma_h = 0` and no diagonal this is the saddle-point
/// matrix `[M Φ_qᵀ; Φ_q 0]` of the consistent start and the velocity projection.
///
/// - `mass`: `nv × nv`; `diagonal`: `(stiffness, damping)`, each dim `nv` (`None` = no diagonal
///   terms); `phi_q`: `m × nv`; `out`: overwritten.
pub(crate) fn assemble_iteration_matrix(
    mass: &DMatrix<f64>,
    diagonal: Option<(&DVector<f64>, &DVector<f64>)>,
    phi_q: &DMatrix<f64>,
    beta_h2: f64,
    gamma_h: f64,
    constraint_row_factor: f64,
    out: &mut DMatrix<f64>,
) {
    let nv = mass.nrows();
    let m = phi_q.nrows();
    let n = nv + m;
    debug_assert_eq!((out.nrows(), out.ncols()), (n, n));
    // Column by column in the column-major storage: M's columns over the first nv rows, the
    // (scaled) constraint rows below them; Φ_qᵀ in the last m columns over a zero block.
    let mass = mass.as_slice();
    let out = out.as_mut_slice();
    for j in 0..nv {
        out[j * n..j * n + nv].copy_from_slice(&mass[j * nv..(j + 1) * nv]);
    }
    assemble_constraint_blocks(out, n, phi_q, constraint_row_factor);
    if let Some((k, c)) = diagonal {
        for j in 0..nv {
            out[j * n + j] += beta_h2 * k[j] + gamma_h * c[j];
        }
    }
}

/// The iteration matrix the integrator would factorise at `(t, q, v)`, for diagnostics (condition
/// numbers). Allocates.
///
/// - `t`: s; `q`: dim `nq`; `v`: dim `nv`; returns `(nv + m) × (nv + m)`.
/// - `scaling`: [`ConstraintRowScaling::Scaled`] is what [`HhtIntegrator`] uses.
///
/// Errors: settings errors, dimension mismatches, system errors and non-finite outputs.
pub fn iteration_matrix<S: DaeSystem + ?Sized>(
    system: &mut S,
    settings: &HhtSettings,
    t: f64,
    q: &DVector<f64>,
    v: &DVector<f64>,
    scaling: ConstraintRowScaling,
) -> Result<DMatrix<f64>, IntegrateError> {
    let (nq, nv, m) = (system.nq(), system.nv(), eval::n_constraints(system));
    let coeffs = settings.validate(m)?;
    if q.len() != nq {
        return Err(IntegrateError::DimensionMismatch {
            what: "q",
            expected: nq,
            got: q.len(),
        });
    }
    if v.len() != nv {
        return Err(IntegrateError::DimensionMismatch {
            what: "v",
            expected: nv,
            got: v.len(),
        });
    }
    let at = At { t, step: 0 };
    let mut mass = DMatrix::zeros(nv, nv);
    eval::mass_matrix(system, at, q, &mut mass)?;
    let mut stiffness = DVector::zeros(nv);
    let mut damping = DVector::zeros(nv);
    if settings.newton_diagonal_terms {
        // Without terms the zeros stay (the same bits as adding none).
        eval::newton_diagonal(system, at, q, v, &mut stiffness, &mut damping)?;
    }
    let mut phi_q = DMatrix::zeros(m, nv);
    if m > 0 {
        eval::constraint_jacobian(system, at, q, &mut phi_q)?;
    }
    let factor = match scaling {
        ConstraintRowScaling::Scaled => 1.0,
        ConstraintRowScaling::Unscaled => coeffs.beta_h2(),
    };
    let mut out = DMatrix::zeros(nv + m, nv + m);
    assemble_iteration_matrix(
        &mass,
        Some((&stiffness, &damping)),
        &phi_q,
        coeffs.beta_h2(),
        coeffs.gamma_h(),
        factor,
        &mut out,
    );
    Ok(out)
}

impl HhtIntegrator {
    /// Evaluates `M`, the diagonal spring/damper terms and `Φ_q` at the current iterate and factorises
    /// the iteration matrix (see [`assemble_iteration_matrix`]).
    pub(super) fn factorise_at_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        full: bool,
    ) -> Result<(), IntegrateError> {
        if full {
            return self.factorise_full_at_iterate(system, at);
        }
        eval::mass_matrix(system, at, &self.ws.q, &mut self.ws.mass)?;
        self.factorise_diagonal(system, at)
    }

    /// Factorises the diagonal Newton matrix `[M + β'h² K + γ'h C, Φ_qᵀ; Φ_q, 0]` (plus the
    /// contacts' coupling) at the current iterate, with `M` already in `ws.mass`: evaluates the
    /// diagonal spring/damper terms and `Φ`, `Φ_q` there (see [`assemble_iteration_matrix`]).
    pub(super) fn factorise_diagonal<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        self.ws.use_full = false;
        let has_diagonal = self.evaluate_newton_diagonal(system, at)?;
        self.constraint_rows_at_iterate(system, at)?;
        let ws = &mut self.ws;
        let (beta_h2, gamma_h) = (self.coeffs.beta_h2(), self.coeffs.gamma_h());
        let solver = &mut self.trajectory.newton.solver;
        let coupling = if self.settings.newton_diagonal_terms {
            system.as_newton_coupling()
        } else {
            None
        };
        let factorised = if let Some(coupling) = coupling {
            assemble_iteration_matrix(
                &ws.mass,
                has_diagonal.then_some((&ws.stiffness, &ws.damping)),
                &ws.phi_q,
                beta_h2,
                gamma_h,
                1.0,
                &mut ws.matrix,
            );
            // Forces that couple joints (contacts): their Jacobians beside the diagonal ones,
            // in the buffers of the full matrix (unused on this path).
            eval::newton_coupling(
                coupling,
                at,
                &ws.q,
                &ws.v,
                &mut ws.stiffness_full,
                &mut ws.damping_full,
            )?;
            for c in 0..self.nv {
                for r in 0..self.nv {
                    ws.matrix[(r, c)] +=
                        beta_h2 * ws.stiffness_full[(r, c)] + gamma_h * ws.damping_full[(r, c)];
                }
            }
            solver.factor(&ws.matrix)
        } else {
            // The matrix of docs/method.md §5 from its blocks, unassembled (the same bits).
            let diagonal = has_diagonal.then_some(ws.newton_diagonal.as_slice());
            solver.factor_blocks(&ws.mass, diagonal, &ws.phi_q)
        };
        factorised.map_err(|b| IntegrateError::SingularMatrix {
            t: at.t,
            step: at.step,
            matrix: "Newton iteration matrix",
            index: b.index,
            pivot_relative: b.pivot_relative,
        })?;
        ws.mass_fresh = true;
        self.trajectory.stats.factorisations += 1;
        Ok(())
    }

    /// With constraint rows, `Φ` and `Φ_q` at the current iterate in one pass of the kinematics
    /// (`ws.phi`, `ws.phi_q`): a factorisation needs `Φ_q`, and the iteration that follows at this
    /// iterate reads both (`add_constraint_rows`).
    pub(super) fn constraint_rows_at_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        if self.m > 0 {
            let ws = &mut self.ws;
            eval::constraints_and_jacobian(system, at, &ws.q, &mut ws.phi, &mut ws.phi_q)?;
        }
        self.ws.constraints_fresh = true;
        Ok(())
    }

    /// With [`HhtSettings::newton_diagonal_terms`]: the spring/damper terms at the current iterate
    /// (`ws.stiffness`, `ws.damping`) and the Newton matrix's diagonal `β'h² k + γ'h c` from them
    /// (`ws.newton_diagonal`); returns whether there is one.
    pub(super) fn evaluate_newton_diagonal<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<bool, IntegrateError> {
        if !self.settings.newton_diagonal_terms {
            return Ok(false);
        }
        let ws = &mut self.ws;
        if !eval::newton_diagonal(system, at, &ws.q, &ws.v, &mut ws.stiffness, &mut ws.damping)? {
            // No terms: `stiffness` and `damping` are left as they are, and nothing reads them.
            return Ok(false);
        }
        let (beta_h2, gamma_h) = (self.coeffs.beta_h2(), self.coeffs.gamma_h());
        for ((d, k), c) in ws
            .newton_diagonal
            .as_mut_slice()
            .iter_mut()
            .zip(ws.stiffness.as_slice())
            .zip(ws.damping.as_slice())
        {
            *d = beta_h2 * k + gamma_h * c;
        }
        Ok(true)
    }

    /// Evaluates `M`, the full residual Jacobians and `Φ`, `Φ_q` at the current iterate and
    /// factorises the full Newton matrix `[M + β'h² K_t + γ'h D_t, Φ_qᵀ; Φ_q, 0]` (LU;
    /// docs/step-control.md §1–§2).
    pub(super) fn factorise_full_at_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        let nv = self.nv;
        let (beta_h2, gamma_h) = (self.coeffs.beta_h2(), self.coeffs.gamma_h());
        let ws = &mut self.ws;
        ws.use_full = true;
        eval::mass_matrix(system, at, &ws.q, &mut ws.mass)?;
        let Some(jacobians) = system.as_residual_jacobians() else {
            // `attempt` asks for the full matrix only of a system that has the Jacobians.
            return Err(IntegrateError::System {
                t: at.t,
                step: at.step,
                call: "residual_jacobians",
                source: "the full Newton matrix needs DaeSystem::as_residual_jacobians".into(),
            });
        };
        let state = DaeState {
            t: at.t,
            q: &ws.q,
            v: &ws.v,
            qdd: &ws.qdd,
            lambda: &ws.lambda,
        };
        eval::residual_jacobians(
            jacobians,
            at,
            &state,
            &mut ws.stiffness_full,
            &mut ws.damping_full,
        )?;
        self.constraint_rows_at_iterate(system, at)?;
        let ws = &mut self.ws;
        assemble_iteration_matrix(&ws.mass, None, &ws.phi_q, 0.0, 0.0, 1.0, &mut ws.matrix);
        for c in 0..nv {
            for r in 0..nv {
                ws.matrix[(r, c)] +=
                    beta_h2 * ws.stiffness_full[(r, c)] + gamma_h * ws.damping_full[(r, c)];
            }
        }
        ws.full_solver
            .factor(&ws.matrix)
            .map_err(|b| IntegrateError::SingularMatrix {
                t: at.t,
                step: at.step,
                matrix: "full Newton iteration matrix",
                index: b.index,
                pivot_relative: b.pivot_relative,
            })?;
        ws.mass_fresh = true;
        self.trajectory.stats.factorisations += 1;
        self.trajectory.stats.full_factorisations += 1;
        Ok(())
    }
}
