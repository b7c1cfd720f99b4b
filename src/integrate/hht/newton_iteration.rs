//! One modified-Newton iteration at the current iterate: the dynamics and constraint rows of the
//! residual, the solve with the stored factorisation, the weighted (WRMS) size of the correction
//! and its worst entry, the correction (shortened where the system asks) and the new iterate.

use super::newton_pass::IterationReport;
use super::HhtIntegrator;
use crate::integrate::error::{IntegrateError, WorstEntry};
use crate::integrate::eval::{self, At};
use crate::integrate::system::DaeSystem;

impl HhtIntegrator {
    /// One modified-Newton iteration at the current iterate: residual, solve with the stored
    /// factorisation, correction, convergence measure.
    ///
    /// ```text
    /// r = [ M q̈ + Φ_qᵀ λ − Q ]      J [Δq̈; Δλ] = −r,   q̈ += Δq̈,  λ += Δλ
    ///     [ Φ / (β'h²)       ]
    /// converged ⇔ ‖β'h² Δq̈‖_WRMS < 1 and ‖Δλ‖_WRMS < 1,   ewt_i = 1 / (reltol |x_i| + abstol)
    /// ```
    pub(super) fn newton_iteration<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<IterationReport, IntegrateError> {
        {
            let ws = &mut self.ws;
            // Dynamics rows: M q̈ − Q (+ Φ_qᵀ λ below).
            if let Some(inverse_dynamics) = system.as_inverse_dynamics() {
                // With M fresh, the factorisation just evaluated it at this iterate (the
                // system's last mass_matrix call): its kinematics may be reused.
                let after_mass_matrix = ws.mass_fresh;
                eval::dynamics_residual(
                    inverse_dynamics,
                    at,
                    &ws.q,
                    &ws.v,
                    &ws.qdd,
                    after_mass_matrix,
                    &mut ws.dyn_residual,
                )?;
            } else {
                if !ws.mass_fresh {
                    eval::mass_matrix(system, at, &ws.q, &mut ws.mass)?;
                    ws.mass_fresh = true;
                }
                eval::forces(system, at, &ws.q, &ws.v, &mut ws.forces)?;
                ws.dyn_residual.copy_from(&ws.forces);
                ws.dyn_residual.gemv(1.0, &ws.mass, &ws.qdd, -1.0);
            }
        }
        self.add_constraint_rows(system, at)?;
        self.correct_iterate(system, at)
    }

    /// With constraint rows: `Φ` at the iterate into `ws.phi`, and `Φ_qᵀ λ` added to the dynamics
    /// rows in `ws.dyn_residual` (`Φ_q` evaluated unless fresh). Nothing without rows.
    pub(super) fn add_constraint_rows<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<(), IntegrateError> {
        if self.m == 0 {
            return Ok(());
        }
        let ws = &mut self.ws;
        if !ws.constraints_fresh {
            eval::constraints_and_jacobian(system, at, &ws.q, &mut ws.phi, &mut ws.phi_q)?;
            ws.constraints_fresh = true;
        }
        ws.dyn_residual.gemv_tr(1.0, &ws.phi_q, &ws.lambda, 1.0);
        Ok(())
    }

    /// The rest of a modified-Newton iteration once the dynamics rows of the residual are in
    /// `ws.dyn_residual` (and, with constraint rows, `Φ` in `ws.phi`): solve with the stored
    /// factorisation, the convergence measure, the correction (limited where the system asks) and
    /// the new iterate.
    pub(super) fn correct_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
    ) -> Result<IterationReport, IntegrateError> {
        let residual_inf = self.newton_rhs();
        self.solve_newton_rhs();
        self.apply_newton_correction(system, at, residual_inf)
    }

    /// Solves the Newton system in place of its right-hand side `ws.rhs`, with the stored
    /// factorisation (the full Newton matrix's when it is in use).
    #[inline(always)]
    pub(super) fn solve_newton_rhs(&mut self) {
        if self.ws.use_full {
            self.ws.full_solver.solve_in_place(&mut self.ws.rhs);
        } else {
            self.trajectory
                .newton
                .solver
                .solve_in_place(&mut self.ws.rhs);
        }
    }

    /// The Newton system's right-hand side `−(r, Φ/(β'h²))` into `ws.rhs` (`r` the dynamics rows
    /// in `ws.dyn_residual`); returns its largest magnitude, the residual the report carries.
    #[inline(always)]
    pub(super) fn newton_rhs(&mut self) -> f64 {
        let (nv, m) = (self.nv, self.m);
        let beta_h2 = self.coeffs.beta_h2();
        let ws = &mut self.ws;
        // The largest magnitude by comparison (NaN skipped, as `f64::max` skips it), which
        // compiles to fewer instructions than `max`'s NaN handling.
        let larger = |largest: f64, r: f64| if r.abs() > largest { r.abs() } else { largest };
        let mut residual_inf: f64 = 0.0;
        let rhs = &mut ws.rhs.as_mut_slice()[..nv + m];
        for (x, r) in rhs[..nv].iter_mut().zip(&ws.dyn_residual.as_slice()[..nv]) {
            residual_inf = larger(residual_inf, *r);
            *x = -r;
        }
        for (x, phi) in rhs[nv..].iter_mut().zip(&ws.phi.as_slice()[..m]) {
            let r = phi / beta_h2;
            residual_inf = larger(residual_inf, r);
            *x = -r;
        }
        residual_inf
    }

    /// [`Self::correct_iterate`] after the solve: `ws.rhs` holds the correction `(Δq̈, Δλ)`;
    /// `residual_inf` is [`Self::newton_rhs`]'s.
    #[inline(always)]
    pub(super) fn apply_newton_correction<S: DaeSystem + ?Sized>(
        &mut self,
        system: &mut S,
        at: At,
        residual_inf: f64,
    ) -> Result<IterationReport, IntegrateError> {
        let (nv, m) = (self.nv, self.m);
        let beta_h2 = self.coeffs.beta_h2();
        let ws = &mut self.ws;
        at.check_finite("newton_update", ws.rhs.as_slice())?;

        // Weighted RMS of the position-level correction β'h² Δq̈ and of Δλ, at the iterate before
        // the correction; the worst weighted entry is kept for the failure report.
        // A system whose scale is zero everywhere is not asked for it (and `ws.scale` not read).
        let position_scale = system.as_position_scale();
        let scale_is_zero = position_scale.is_none();
        if let Some(position_scale) = position_scale {
            position_scale.position_scale(&ws.q, &mut ws.scale);
        }
        let reltol = self.settings.reltol;
        // The worst weighted entry over coordinates then rows (index ≥ nv: row index − nv); the
        // first of equal ones.
        let (mut worst_value, mut worst_index) = (-1.0, 0);
        let mut sum_q = 0.0;
        let (rhs, scale) = (&ws.rhs.as_slice()[..nv + m], &ws.scale.as_slice()[..nv]);
        let abstol = self.settings.abstol_position;
        let mut take = |i: usize, ewt: f64| {
            let x = (beta_h2 * rhs[i] * ewt).abs();
            sum_q += x * x;
            if x > worst_value {
                (worst_value, worst_index) = (x, i);
            }
        };
        if scale_is_zero {
            // `1 / (reltol · 0 + abstol)`, bit for bit, once.
            let ewt = 1.0 / abstol;
            for i in 0..nv {
                take(i, ewt);
            }
        } else {
            for (i, scale) in scale.iter().enumerate() {
                take(i, 1.0 / (reltol * scale + abstol));
            }
        }
        let mut sum_l = 0.0;
        for j in 0..m {
            let ewt = 1.0 / (reltol * ws.lambda[j].abs() + self.settings.abstol_multiplier);
            let x = (rhs[nv + j] * ewt).abs();
            sum_l += x * x;
            if x > worst_value {
                (worst_value, worst_index) = (x, nv + j);
            }
        }
        let worst = if worst_index < nv || worst_value < 0.0 {
            WorstEntry::Coordinate {
                index: worst_index,
                weighted_correction: worst_value.max(0.0),
            }
        } else {
            WorstEntry::Constraint {
                index: worst_index - nv,
                weighted_correction: worst_value,
                violation: ws.phi[worst_index - nv],
            }
        };
        let wrms_q = if nv > 0 {
            (sum_q / nv as f64).sqrt()
        } else {
            0.0
        };
        let wrms_l = if m > 0 {
            (sum_l / m as f64).sqrt()
        } else {
            0.0
        };

        if let Some(limit) = system.as_newton_update_limit() {
            // The velocity change of the full correction: Δq̇ = γ'h Δq̈.
            let gamma_h = self.coeffs.gamma_h();
            for i in 0..nv {
                ws.dv_trial[i] = gamma_h * ws.rhs[i];
            }
            let fraction = eval::newton_update_fraction(limit, at, &ws.q, &ws.v, &ws.dv_trial)?;
            if fraction < 1.0 {
                self.trajectory.stats.limited_newton_updates += 1;
                for x in ws.rhs.iter_mut() {
                    *x *= fraction;
                }
            }
        }
        let rhs = ws.rhs.as_slice();
        for (x, dx) in ws.qdd.as_mut_slice().iter_mut().zip(&rhs[..nv]) {
            *x += dx;
        }
        for (x, dx) in ws.lambda.as_mut_slice().iter_mut().zip(&rhs[nv..nv + m]) {
            *x += dx;
        }
        self.update_iterate(system, at)?;
        Ok(IterationReport {
            wrms_position: wrms_q,
            wrms_multiplier: wrms_l,
            residual_inf,
            worst,
        })
    }
}
