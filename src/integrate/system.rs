//! The contract between the integrator and a mechanical system: [`DaeSystem`].
//!
//! The integrator sees the system only through this trait — no robot types, no effects, no scene. A
//! robot model implements it once (CRBA for `M`, RNEA for the bias, the scene's effects for `Q`, the
//! loop closures and drives for `Φ`).
//!
//! Equations (index-3 DAE, joint coordinates):
//!
//! ```text
//! M(q) q̈ + Φ_q(q, t)ᵀ λ = Q(t, q, q̇)        (nv rows)
//!              Φ(q, t) = 0                   (m rows)
//! ```
//!
//! Conventions:
//! - `q` has `nq` entries, velocities and accelerations `nv` (`nq ≠ nv` for a quaternion floating
//!   base). Every derivative "with respect to q" is taken along the tangent space: `Φ(q ⊕ δ) ≈ Φ(q) +
//!   Φ_q δ` with `δ` of dimension `nv` and `⊕` = [`DaeSystem::integrate_position`].
//! - `Q` is the right-hand side: generalised applied forces minus the bias `C(q, q̇) q̇ + g(q)`.
//! - `λ` has the sign fixed by `M q̈ + Φ_qᵀ λ = Q`: a drive row `Φ = q_j − f(t)` gives `λ = −τ`.
//! - Each method overwrites its `out` argument(s) entirely; sizes are checked by the integrator before
//!   the call, so implementations may index without checks.
//! - Methods return `Result`: report an invalid state (e.g. a singular configuration or a NaN the
//!   system detects itself) as an error rather than panicking. The integrator also checks every output
//!   for NaN/Inf itself.

use nalgebra::{DMatrix, DVector};

use super::error::SystemError;

/// A multibody system `M(q) q̈ + Φ_qᵀ λ = Q(t, q, q̇)`, `Φ(q, t) = 0`, as the HHT-I3 integrator needs it.
///
/// Required methods: [`nq`](Self::nq), [`nv`](Self::nv), [`mass_matrix`](Self::mass_matrix),
/// [`forces`](Self::forces). A tree (no constraints) needs nothing else. A system with constraint
/// rows also implements [`n_constraints`](Self::n_constraints), [`constraints`](Self::constraints),
/// [`constraint_jacobian`](Self::constraint_jacobian),
/// [`constraint_acceleration_bias`](Self::constraint_acceleration_bias) and, when a row depends on
/// time explicitly (drives), [`constraint_time_derivative`](Self::constraint_time_derivative).
///
/// Methods take `&mut self` so that an implementation can keep its work buffers (a Pinocchio-style
/// `Data`) inside. Within one Newton iteration the integrator evaluates everything it needs at one
/// `(t, q, q̇)` consecutively (mass matrix and Jacobian first, then residual terms), so caching the
/// kinematics of the last `q` is effective.
pub trait DaeSystem {
    /// Number of position coordinates `nq` (length of `q`).
    fn nq(&self) -> usize;

    /// Number of velocity coordinates `nv` (length of `q̇`, `q̈`, `Q`; size of `M`).
    fn nv(&self) -> usize;

    /// Number of constraint rows `m` (length of `Φ` and `λ`). Default 0 (a tree): then the integrator
    /// never calls a constraint method and allocates no constraint storage.
    fn n_constraints(&self) -> usize {
        0
    }

    /// `out = q ⊕ dq`: the configuration reached from `q` by the tangent increment `dq`.
    ///
    /// - `q`: dim `nq`; `dq`: dim `nv`; `out`: dim `nq`, overwritten.
    ///
    /// Default: vector addition, valid when `nq == nv`. A floating base (quaternion) overrides it with
    /// the exponential map on SE(3)/SO(3) and renormalises the quaternion.
    fn integrate_position(
        &self,
        q: &DVector<f64>,
        dq: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        if q.len() != dq.len() || out.len() != q.len() {
            return Err(format!(
                "default integrate_position needs nq == nv (got q {}, dq {}, out {}); a system with \
                 nq != nv must implement integrate_position",
                q.len(),
                dq.len(),
                out.len()
            )
            .into());
        }
        for i in 0..q.len() {
            out[i] = q[i] + dq[i];
        }
        Ok(())
    }

    /// Magnitude of each velocity coordinate's position, for the error weights of the Newton test
    /// (`ewt_i = 1 / (reltol · scale_i + abstol)`).
    ///
    /// - `q`: dim `nq`; `out`: dim `nv`, overwritten with values ≥ 0.
    ///
    /// Default: `|q_i|` when `nq == nv`, otherwise 0 (absolute tolerance only). A floating base may
    /// return `|x|, |y|, |z|` for its translation and 0 for its rotation.
    fn position_scale(&self, q: &DVector<f64>, out: &mut DVector<f64>) {
        if q.len() == out.len() {
            for i in 0..q.len() {
                out[i] = q[i].abs();
            }
        } else {
            out.fill(0.0);
        }
    }

    /// The joint-space mass matrix `M(q)` (symmetric positive definite).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: `nv × nv`, overwritten (both triangles).
    fn mass_matrix(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError>;

    /// The right-hand side `Q(t, q, q̇)` = generalised applied forces − `(C(q, q̇) q̇ + g(q))`.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `out`: dim `nv`, overwritten.
    fn forces(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError>;

    /// Whether [`dynamics_residual`](Self::dynamics_residual) is implemented. Default `false`.
    ///
    /// When `true`, the Newton residual uses it (one inverse-dynamics pass, e.g. RNEA, O(nv)) instead
    /// of `mass_matrix` + `forces` (CRBA, O(nv²)); `M` is then only evaluated when the iteration matrix
    /// is factorised.
    fn provides_dynamics_residual(&self) -> bool {
        false
    }

    /// `out = M(q) q̈ − Q(t, q, q̇)` (the inverse-dynamics residual, without the constraint forces).
    /// Only called when [`provides_dynamics_residual`](Self::provides_dynamics_residual) is `true`.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `qdd`: dim `nv`; `out`: dim `nv`, overwritten.
    fn dynamics_residual(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v, qdd, out);
        Err("dynamics_residual is not implemented by this system".into())
    }

    /// The cheap diagonal parts of `−∂Q/∂q` and `−∂Q/∂q̇`: per velocity coordinate, the stiffness
    /// `k_j ≥ 0` of springs (and penalty limits) and the damping `c_j ≥ 0` of dampers acting on that
    /// coordinate alone. The modified Newton matrix adds `β'h² k_j + γ'h c_j` to `M_jj`; without them a
    /// stiff spring on a light link makes the iteration diverge.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`;
    /// - `stiffness_out`: dim `nv`, overwritten, N·m/rad or N/m;
    /// - `damping_out`: dim `nv`, overwritten, N·m·s/rad or N·s/m.
    ///
    /// Default: zeros (no springs or dampers).
    fn newton_diagonal(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        stiffness_out: &mut DVector<f64>,
        damping_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v);
        stiffness_out.fill(0.0);
        damping_out.fill(0.0);
        Ok(())
    }

    /// The constraint values `Φ(q, t)`.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: dim `m`, overwritten (m or rad, per row).
    ///
    /// Default: nothing to do for `m = 0`; an error if a system declares rows without implementing it.
    fn constraints(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q);
        if out.is_empty() {
            Ok(())
        } else {
            Err("constraints() is not implemented but n_constraints() > 0".into())
        }
    }

    /// The constraint Jacobian `Φ_q` along the tangent space (`Φ(q ⊕ δ) ≈ Φ + Φ_q δ`).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: `m × nv`, overwritten.
    fn constraint_jacobian(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q);
        if out.is_empty() {
            Ok(())
        } else {
            Err("constraint_jacobian() is not implemented but n_constraints() > 0".into())
        }
    }

    /// The explicit time derivative `Φ_t(q, t)` (rheonomic rows such as drives; velocity level:
    /// `Φ̇ = Φ_q q̇ + Φ_t`).
    ///
    /// - `t`: time, s; `q`: dim `nq`; `out`: dim `m`, overwritten.
    ///
    /// Default: zeros (scleronomic constraints).
    fn constraint_time_derivative(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q);
        out.fill(0.0);
        Ok(())
    }

    /// The acceleration-level right-hand side `Φ_q q̈ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt`, used once for
    /// the consistent initial acceleration and multipliers.
    ///
    /// - `t`: time, s; `q`: dim `nq`; `v`: dim `nv`; `out`: dim `m`, overwritten.
    fn constraint_acceleration_bias(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let _ = (t, q, v);
        if out.is_empty() {
            Ok(())
        } else {
            Err("constraint_acceleration_bias() is not implemented but n_constraints() > 0".into())
        }
    }
}
