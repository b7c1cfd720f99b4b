//! The iterate of an attempt: the predictor that starts it (the step's coefficients, `a_n` rescaled
//! to the attempt's size, the history's extrapolation, the constant-velocity fallback for an
//! unresolved stiff mode; docs/step-control.md §1–§2) and the HHT-α/Newmark update
//! `q̈_{n+1} ↦ (a_{n+1}, q_{n+1}, q̇_{n+1})` that every Newton correction goes through.

use super::HhtIntegrator;
use crate::integrate::error::IntegrateError;
use crate::integrate::eval::{self, At};
use crate::integrate::settings::HhtCoefficients;
use crate::integrate::system::DaeSystem;

/// Largest position change (rad or m) the predictor's acceleration term may make before the
/// constant-velocity predictor replaces it: 0.01 is ~3000× what the shipped robots' predictors move
/// at 1 ms (≤ 3e-6), and a stiff mode that moves a joint by more within one step is not resolved
/// by the step anyway.
pub const PREDICTOR_MAX_ACCELERATION_DISPLACEMENT: f64 = 1e-2;

/// The HHT-α/Newmark update of an iterate ([`HhtIntegrator::update_iterate`]), whose
/// acceleration term the predictor's stiffness check also measures: one owner of the formulas.
#[derive(Clone, Copy)]
pub(super) struct NewmarkUpdate {
    pub(super) h: f64,
    pub(super) alpha: f64,
    pub(super) beta: f64,
    pub(super) gamma: f64,
}

impl NewmarkUpdate {
    /// The update of a step with `coeffs`.
    fn of(coeffs: &HhtCoefficients) -> Self {
        Self {
            h: coeffs.h,
            alpha: coeffs.alpha,
            beta: coeffs.beta,
            gamma: coeffs.gamma,
        }
    }

    /// `a_{n+1} = (1 + α) q̈_{n+1} − α q̈_n`.
    #[inline(always)]
    fn acceleration(self, qdd: f64, qdd_n: f64) -> f64 {
        (1.0 + self.alpha) * qdd - self.alpha * qdd_n
    }

    /// The acceleration part of the position update, `h² [(½ − β) a_n + β a_{n+1}]`.
    #[inline(always)]
    fn acceleration_displacement(self, a_n: f64, a_new: f64) -> f64 {
        let (h, beta) = (self.h, self.beta);
        h * h * ((0.5 - beta) * a_n + beta * a_new)
    }

    /// `W` entries' `(a_{n+1}, Δq, q̇_{n+1})` from `q̈_{n+1}`, `q̈_n`, `a_n` and the Newmark
    /// `q̇_n`, lane by lane over arrays (vector instructions; each lane the operations of one
    /// entry).
    #[inline(always)]
    fn entries<const W: usize>(
        self,
        qdd: [f64; W],
        qdd_n: [f64; W],
        a_n: [f64; W],
        v_n: [f64; W],
    ) -> ([f64; W], [f64; W], [f64; W]) {
        let (h, gamma) = (self.h, self.gamma);
        let (mut a, mut dq, mut v) = ([0.0; W], [0.0; W], [0.0; W]);
        for l in 0..W {
            let a_new = self.acceleration(qdd[l], qdd_n[l]);
            a[l] = a_new;
            dq[l] = h * v_n[l] + self.acceleration_displacement(a_n[l], a_new);
            v[l] = v_n[l] + h * ((1.0 - gamma) * a_n[l] + gamma * a_new);
        }
        (a, dq, v)
    }
}

impl HhtIntegrator {
    /// Sets the coefficients of a step of size `h` and the predictor: `a_n` as this step sees it
    /// (`ws.a_start`) and the first iterate `ws.qdd`, `ws.lambda` (counted in
    /// `stats.stiff_predictions` when the constant-velocity predictor replaces the extrapolation).
    pub(super) fn predict(&mut self, h: f64, by_order: bool) {
        self.coeffs = if h == self.grid_coeffs.h {
            self.grid_coeffs
        } else {
            HhtCoefficients::new(self.grid_coeffs.alpha, h)
        };

        // a_n stands for q̈ at t_n + α h_last (a_n = q̈_n + α (q̈_n − q̈_{n−1})); a step of another
        // size needs it at t_n + α h: rescale its offset from q̈_n, or the variable step loses its
        // second order.
        let ratio = h / self.trajectory.control.h_last;
        if ratio == 1.0 {
            self.ws
                .a_start
                .as_mut_slice()
                .copy_from_slice(self.trajectory.state.a.as_slice());
        } else {
            for ((x, a_n), qdd_n) in self
                .ws
                .a_start
                .as_mut_slice()
                .iter_mut()
                .zip(self.trajectory.state.a.as_slice())
                .zip(self.trajectory.state.qdd.as_slice())
            {
                *x = qdd_n + ratio * (a_n - qdd_n);
            }
        }
        // Predictor (docs/step-control.md §2, hht/predictor.rs): q̈_{n+1} and λ_{n+1} extrapolated
        // through the accepted history, each entry by the order that predicted its last value best
        // on a run of equal steps. The converged result is the same to the Newton tolerance.
        let trajectory = &self.trajectory;
        trajectory.predictor.predict(
            h,
            by_order,
            &trajectory.control,
            (
                trajectory.state.qdd.as_slice(),
                trajectory.state.lambda.as_slice(),
            ),
            self.ws.qdd.as_mut_slice(),
            self.ws.lambda.as_mut_slice(),
        );
        // An unresolved stiff mode (a spring whose period is far below h) makes the extrapolated
        // q̈ meaningless: its position term h²[(½ − β) a_n + β a_{n+1}] can throw the predicted
        // configuration radians away, where no Newton matrix helps. Then predict constant velocity
        // instead (that term zero): q_{n+1} = q_n ⊕ h q̇_n (docs/step-control.md §1–§2).
        let newmark = NewmarkUpdate::of(&self.coeffs);
        // Two entries at a time; the largest is the same in any order (comparisons are exact, NaN
        // skipped as `f64::max` skips it).
        let nv = self.nv;
        let (qdd, qdd_n, a_start) = (
            &self.ws.qdd.as_slice()[..nv],
            &self.trajectory.state.qdd.as_slice()[..nv],
            &self.ws.a_start.as_slice()[..nv],
        );
        let displacement = |qdd: f64, qdd_n: f64, a_n: f64| {
            newmark
                .acceleration_displacement(a_n, newmark.acceleration(qdd, qdd_n))
                .abs()
        };
        let mut largest = [0.0_f64; 2];
        let pairs = nv - nv % 2;
        for i in (0..pairs).step_by(2) {
            for l in 0..2 {
                let d = displacement(qdd[i + l], qdd_n[i + l], a_start[i + l]);
                largest[l] = if d > largest[l] { d } else { largest[l] };
            }
        }
        for i in pairs..nv {
            let d = displacement(qdd[i], qdd_n[i], a_start[i]);
            largest[0] = if d > largest[0] { d } else { largest[0] };
        }
        let acceleration_displacement = largest[0].max(largest[1]);
        if acceleration_displacement > PREDICTOR_MAX_ACCELERATION_DISPLACEMENT {
            self.trajectory.stats.stiff_predictions += 1;
            for ((x, qdd_n), a_n) in self
                .ws
                .qdd
                .as_mut_slice()
                .iter_mut()
                .zip(self.trajectory.state.qdd.as_slice())
                .zip(self.ws.a_start.as_slice())
            {
                let (alpha, beta) = (newmark.alpha, newmark.beta);
                let a = -(0.5 - beta) / beta * a_n;
                *x = (a + alpha * qdd_n) / (1.0 + alpha);
            }
        }
    }

    /// Whether the predictor blends its orders by the history on runs of equal steps
    /// ([`HhtSettings::choose_predictor_order`] and a system whose forces are smooth between steps,
    /// [`DaeSystem::smooth_between_steps`]).
    pub(super) fn predicts_by_order<S: DaeSystem + ?Sized>(&self, system: &S) -> bool {
        self.settings.choose_predictor_order && system.smooth_between_steps()
    }

    /// From the iterate `ws.qdd` (and the state at `t_n`), computes `a_{n+1}`, `q_{n+1}`, `q̇_{n+1}`:
    ///
    /// ```text
    /// a_{n+1} = (1+α) q̈_{n+1} − α q̈_n
    /// q_{n+1} = q_n ⊕ (h q̇_n + h² [(½ − β) a_n + β a_{n+1}])
    /// q̇_{n+1} = q̇_n + h [(1 − γ) a_n + γ a_{n+1}]
    /// ```
    pub(super) fn update_iterate<S: DaeSystem + ?Sized>(
        &mut self,
        system: &S,
        at: At,
    ) -> Result<(), IntegrateError> {
        let newmark = NewmarkUpdate::of(&self.coeffs);
        let s = &self.trajectory.state;
        let v_n = &self.trajectory.v_newmark;
        let ws = &mut self.ws;
        // Over slices of one length (no per-entry bounds checks); the same operations per entry.
        let nv = self.nv;
        let (qdd, qdd_n, a_start) = (
            &ws.qdd.as_slice()[..nv],
            &s.qdd.as_slice()[..nv],
            &ws.a_start.as_slice()[..nv],
        );
        let v_n = &v_n.as_slice()[..nv];
        let (a, dq, v) = (
            &mut ws.a.as_mut_slice()[..nv],
            &mut ws.dq.as_mut_slice()[..nv],
            &mut ws.v.as_mut_slice()[..nv],
        );
        // Two entries at a time (one vector register of the x86-64 baseline), the last alone.
        let pairs = nv - nv % 2;
        let pair = |x: &[f64]| -> [f64; 2] { [x[0], x[1]] };
        for (((a, dq), v), (((qdd, qdd_n), a_start), v_n)) in a[..pairs]
            .chunks_exact_mut(2)
            .zip(dq[..pairs].chunks_exact_mut(2))
            .zip(v[..pairs].chunks_exact_mut(2))
            .zip(
                qdd[..pairs]
                    .chunks_exact(2)
                    .zip(qdd_n[..pairs].chunks_exact(2))
                    .zip(a_start[..pairs].chunks_exact(2))
                    .zip(v_n[..pairs].chunks_exact(2)),
            )
        {
            let (a_new, dq_new, v_new) =
                newmark.entries(pair(qdd), pair(qdd_n), pair(a_start), pair(v_n));
            a.copy_from_slice(&a_new);
            dq.copy_from_slice(&dq_new);
            v.copy_from_slice(&v_new);
        }
        for i in pairs..nv {
            let ([a_new], [dq_new], [v_new]) =
                newmark.entries([qdd[i]], [qdd_n[i]], [a_start[i]], [v_n[i]]);
            (a[i], dq[i], v[i]) = (a_new, dq_new, v_new);
        }
        eval::integrate_position(system, at, &s.q, &ws.dq, &mut ws.q)?;
        ws.mass_fresh = false;
        ws.constraints_fresh = false;
        Ok(())
    }
}
