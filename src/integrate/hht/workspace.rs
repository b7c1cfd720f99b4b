//! The preallocated buffers of one integrator ([`Workspace`]): every vector and matrix a step
//! writes, sized at construction, so that a step allocates nothing; and the flags that say which
//! of them hold values at the current Newton iterate.

use crate::integrate::dense_solver::{DenseSolver, FactorKind};
use nalgebra::{DMatrix, DVector};

/// Preallocated buffers of one integrator (sizes `nq`, `nv`, `m`, `n = nv + m`).
#[derive(Debug, Clone)]
pub(super) struct Workspace {
    /// Current Newton iterate q̈_{n+1}, dim nv.
    pub(super) qdd: DVector<f64>,
    /// Current Newton iterate λ_{n+1}, dim m.
    pub(super) lambda: DVector<f64>,
    /// a_{n+1}(q̈), dim nv.
    pub(super) a: DVector<f64>,
    /// q_{n+1}(q̈), dim nq.
    pub(super) q: DVector<f64>,
    /// q̇_{n+1}(q̈), dim nv.
    pub(super) v: DVector<f64>,
    /// Tangent increment h q̇_n + h²[(½−β) a_n + β a_{n+1}], dim nv.
    pub(super) dq: DVector<f64>,
    /// M, nv × nv.
    pub(super) mass: DMatrix<f64>,
    /// Q, dim nv.
    pub(super) forces: DVector<f64>,
    /// M q̈ + Φ_qᵀλ − Q, dim nv.
    pub(super) dyn_residual: DVector<f64>,
    /// Diagonal stiffness k_j, dim nv.
    pub(super) stiffness: DVector<f64>,
    /// Diagonal damping c_j, dim nv.
    pub(super) damping: DVector<f64>,
    /// Position magnitudes for error weights, dim nv.
    pub(super) scale: DVector<f64>,
    /// Φ, dim m.
    pub(super) phi: DVector<f64>,
    /// Φ_q, m × nv.
    pub(super) phi_q: DMatrix<f64>,
    /// Φ_t then Φ_q q̇ + Φ_t, dim m.
    pub(super) phi_dot: DVector<f64>,
    /// Assembled iteration (or projection) matrix, n × n.
    pub(super) matrix: DMatrix<f64>,
    /// Right-hand side, then solution, dim n.
    pub(super) rhs: DVector<f64>,
    /// `a_n` as the attempted step sees it, dim nv: `a_n` itself for a step of the last size, else
    /// rescaled to the new size (`q̈_n + (h/h_last)(a_n − q̈_n)`, docs/step-control.md §3).
    pub(super) a_start: DVector<f64>,
    /// The Newton matrix's diagonal terms `β'h² k_j + γ'h c_j`, dim nv.
    pub(super) newton_diagonal: DVector<f64>,
    /// Full stiffness `∂r/∂q`, nv × nv.
    pub(super) stiffness_full: DMatrix<f64>,
    /// Full damping `∂r/∂q̇`, nv × nv.
    pub(super) damping_full: DMatrix<f64>,
    /// LU factorisation of the full Newton matrix (not symmetric).
    pub(super) full_solver: DenseSolver,
    /// The current Newton factorisation is the full one (`full_solver`), not `solver`.
    pub(super) use_full: bool,
    /// Gaps and rates of the unilateral limits at the start and at the end of a step, dim n_events.
    pub(super) gaps_start: DVector<f64>,
    pub(super) rates_start: DVector<f64>,
    pub(super) gaps_end: DVector<f64>,
    pub(super) rates_end: DVector<f64>,
    /// The state an impact law rewrites, dims nq and nv.
    pub(super) impact_q: DVector<f64>,
    pub(super) impact_v: DVector<f64>,
    /// The velocity change of a full Newton correction, `γ'h Δq̈`, dim nv.
    pub(super) dv_trial: DVector<f64>,
    /// `mass` holds M at the current iterate.
    pub(super) mass_fresh: bool,
    /// `mass` holds M at the accepted `q_{n+1}`, handed in for the velocity projection (a plain
    /// step driven from outside, `hht/plain.rs`).
    pub(super) projection_mass_given: bool,
    /// `phi` and `phi_q` hold `Φ` and `Φ_q` at the current iterate (set where they are
    /// evaluated there, cleared where the iterate moves or they are evaluated elsewhere).
    pub(super) constraints_fresh: bool,
}

impl Workspace {
    pub(super) fn new(nq: usize, nv: usize, m: usize, n_events: usize) -> Self {
        let n = nv + m;
        Self {
            qdd: DVector::zeros(nv),
            lambda: DVector::zeros(m),
            a: DVector::zeros(nv),
            q: DVector::zeros(nq),
            v: DVector::zeros(nv),
            dq: DVector::zeros(nv),
            mass: DMatrix::zeros(nv, nv),
            forces: DVector::zeros(nv),
            dyn_residual: DVector::zeros(nv),
            stiffness: DVector::zeros(nv),
            damping: DVector::zeros(nv),
            scale: DVector::zeros(nv),
            phi: DVector::zeros(m),
            phi_q: DMatrix::zeros(m, nv),
            phi_dot: DVector::zeros(m),
            matrix: DMatrix::zeros(n, n),
            rhs: DVector::zeros(n),
            a_start: DVector::zeros(nv),
            newton_diagonal: DVector::zeros(nv),
            stiffness_full: DMatrix::zeros(nv, nv),
            damping_full: DMatrix::zeros(nv, nv),
            full_solver: DenseSolver::new(n, FactorKind::Lu),
            use_full: false,
            gaps_start: DVector::zeros(n_events),
            rates_start: DVector::zeros(n_events),
            gaps_end: DVector::zeros(n_events),
            rates_end: DVector::zeros(n_events),
            impact_q: DVector::zeros(nq),
            impact_v: DVector::zeros(nv),
            dv_trial: DVector::zeros(nv),
            mass_fresh: false,
            projection_mass_given: false,
            constraints_fresh: false,
        }
    }
}
