//! A [`RobotSystem`]'s joint limits as the integrator's unilateral constraints
//! ([`UnilateralLimits`]): the gaps `g = q − lower`, `g = upper − q` and the impact law
//! (docs/step-control.md §4) that puts a joint on its limit and turns its approach speed into a
//! separation speed, with the resting limits the impulse drives in joining as plastic rows.
//! Does not: enforce limits between impacts (the scene's penalty, `effects/`), or find when a
//! gap closes (the integrator's events).

use super::RobotSystem;
use crate::dynamics::crba;
use crate::integrate::{SystemError, UnilateralLimits};
use nalgebra::{DMatrix, DVector};

impl UnilateralLimits for RobotSystem {
    fn n_events(&self) -> usize {
        self.effects.n_limit_events()
    }

    /// Joint limits as unilateral constraints: `g = q_j − lower` and `g = upper − q_j`.
    fn event_gaps(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        gaps_out: &mut DVector<f64>,
        rates_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.effects.limit_gaps(
            &self.model,
            q.as_slice(),
            v.as_slice(),
            gaps_out.as_mut_slice(),
            rates_out.as_mut_slice(),
        );
        Ok(())
    }

    /// The joint-limit impact law (docs/step-control.md §4): the joint is put on its limit and the
    /// velocity jumps by the impulse that turns the joint's approach speed `−ġ⁻` into a separation
    /// speed `e·(−ġ⁻)` while keeping every constraint row's velocity:
    ///
    /// ```text
    /// [ M    Wᵀ  Φ_qᵀ ] [Δq̇]   [ 0            ]
    /// [ W    0   0    ] [ν  ] = [ −(1 + e) ġ⁻  ]      W = ∂g/∂q (a row ±1 at each joint)
    /// [ Φ_q  0   0    ] [μ  ]   [ 0            ]
    /// ```
    ///
    /// The impulse acts through `M` on the whole mechanism, and can drive another joint that rests
    /// on (or a penalty depth past) its own limit into it, faster than the penalty can stop; such a
    /// limit joins the impact as a plastic row (`ġ⁺ = 0`), and the system is solved again, until no
    /// resting joint is driven in faster than [`crate::integrate::IMPACT_MIN_SPEED`] (at most one
    /// round per limit). Kinetic energy never grows: each row removes the approach speed it
    /// constrains (`−½ (1 − e²) (ġ⁻)² / (w M_c⁻¹ wᵀ) ≤ 0` with one row; `M_c`: `M` restricted to the
    /// constraint-consistent velocities). Allocates (impacts are rare).
    fn apply_impact(
        &mut self,
        _t: f64,
        event: usize,
        q: &mut DVector<f64>,
        v: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let limit = self
            .effects
            .limit_event(&self.model, event)
            .ok_or_else(|| format!("joint-limit event {event} does not exist"))?;
        let approach_rate = limit_sign(limit.side) * v[limit.v_index];
        if approach_rate >= 0.0 {
            // Already separating: nothing to do but keep the joint inside.
            q[limit.q_index] = limit.limit;
            return Ok(());
        }
        let n_events = self.effects.n_limit_events();
        let (mut gaps, mut rates) = (vec![0.0; n_events], vec![0.0; n_events]);
        self.effects.limit_gaps(
            &self.model,
            q.as_slice(),
            v.as_slice(),
            &mut gaps,
            &mut rates,
        );
        let mass = crba(&self.model, &mut self.data, q.as_slice()).clone();
        let (nv, m) = (self.model.nv, self.constraints.len());
        let mut phi_q = DMatrix::zeros(m, nv);
        if m > 0 {
            self.constraints
                .jacobian(&self.model, &mut self.data, q.as_slice(), &mut phi_q);
        }
        // Rows: (the limit, the jump of its rate it imposes). The impacting limit's row must
        // solve; a resting limit whose row would make the system singular (a mimic follower's, a
        // loop's: its motion is already fixed by the others) is left out.
        let mut rows = vec![(limit, -(1.0 + limit.restitution) * approach_rate)];
        let mut jump = impact_velocity_jump(&self.model, &mass, &phi_q, &rows)?;
        let mut excluded = vec![false; n_events];
        for _ in 0..n_events {
            // The resting limit driven in fastest by the current jump, if faster than an impact.
            let mut fastest: Option<(usize, f64)> = None;
            for k in 0..n_events {
                let Some(other) = self.effects.limit_event(&self.model, k) else {
                    continue;
                };
                let already = rows.iter().any(|(row, _)| row.v_index == other.v_index);
                let rate_after = rates[k] + limit_sign(other.side) * jump[other.v_index];
                if gaps[k] <= 0.0
                    && !already
                    && !excluded[k]
                    && rate_after < -crate::integrate::IMPACT_MIN_SPEED
                    && fastest.is_none_or(|(_, r)| rate_after < r)
                {
                    fastest = Some((k, rate_after));
                }
            }
            let Some((k, _)) = fastest else {
                break;
            };
            let Some(other) = self.effects.limit_event(&self.model, k) else {
                break;
            };
            // Plastic: the jump cancels the rate it had before the impact.
            rows.push((other, -rates[k]));
            match impact_velocity_jump(&self.model, &mass, &phi_q, &rows) {
                Ok(with_it) => jump = with_it,
                Err(_) => {
                    rows.pop();
                    excluded[k] = true;
                }
            }
        }
        *v += &jump;
        q[limit.q_index] = limit.limit;
        Ok(())
    }
}

/// The velocity jump `Δq̇` of the impact whose limit rows are `rows` (each: the limit and the
/// jump of its rate `w Δq̇` it imposes), keeping every constraint row's velocity (`Φ_q Δq̇ = 0`).
fn impact_velocity_jump(
    model: &crate::model::Model,
    mass: &DMatrix<f64>,
    phi_q: &DMatrix<f64>,
    rows: &[(crate::effects::LimitEvent, f64)],
) -> Result<DVector<f64>, SystemError> {
    let (nv, m, r) = (mass.nrows(), phi_q.nrows(), rows.len());
    let n = nv + r + m;
    let mut kkt = DMatrix::zeros(n, n);
    kkt.view_mut((0, 0), (nv, nv)).copy_from(mass);
    let mut rhs = DVector::zeros(n);
    for (i, (row, jump)) in rows.iter().enumerate() {
        let sign = limit_sign(row.side);
        kkt[(row.v_index, nv + i)] = sign;
        kkt[(nv + i, row.v_index)] = sign;
        rhs[nv + i] = *jump;
    }
    for c in 0..m {
        for j in 0..nv {
            kkt[(j, nv + r + c)] = phi_q[(c, j)];
            kkt[(nv + r + c, j)] = phi_q[(c, j)];
        }
    }
    let mut solver = crate::integrate::DenseSolver::new(n, crate::integrate::FactorKind::Lu);
    solver.factor(&kkt).map_err(|_| {
        let names: Vec<String> = rows
            .iter()
            .map(|(row, _)| {
                format!(
                    "'{}' at {}",
                    model.description.joints[row.source].name, row.limit
                )
            })
            .collect();
        format!(
            "the impact at the limit of joint {} cannot be resolved (the limits' directions \
             are blocked by the constraint rows or the mass matrix is singular)",
            names.join(" with ")
        )
    })?;
    let mut solution = rhs;
    solver.solve_in_place(&mut solution);
    Ok(solution.rows(0, nv).into_owned())
}

/// `w` of a limit event: `g = q − lower` (+1) or `g = upper − q` (−1).
fn limit_sign(side: crate::effects::LimitSide) -> f64 {
    match side {
        crate::effects::LimitSide::Lower => 1.0,
        crate::effects::LimitSide::Upper => -1.0,
    }
}
