//! Local refinement of a surrogate extremum inside the box [-1, 1]^d: projected Newton with
//! Levenberg damping and a monotone backtracking line search, from a start point (a grid point of
//! the scan). Every accepted step lowers the objective, so the result is an attained value of the
//! surrogate no worse than the start (what keeps the scan an inner bound).
//!
//! Per iteration (objective `φ = σ·y`, σ = +1 for the minimum, −1 for the maximum):
//! 1. active set: coordinates on a face whose gradient points out of the box stay fixed;
//! 2. on the free coordinates solve `(H_ff + μI) Δ = −g_f` (μ = 0 if `H_ff` is positive definite,
//!    else the smallest of 1e-12·s, 1e-11·s, … that makes Cholesky succeed, s = scale of H);
//! 3. try `x_t = clamp(x + tΔ)`, t = 1, ½, ¼, …, until `φ(x_t) ≤ φ(x) + 1e-4 · gᵀ(x_t − x)` and
//!    `φ(x_t) < φ(x)`; stop when the full step is below [`STEP_TOL`] or promises less than the
//!    rounding of φ, when no t works, or after the iteration cap.
//!
//! Does not: choose start points (see [`crate::uq::scan`]).

use crate::linalg::cholesky;
use crate::uq::tensor_contraction::PointEvaluator;

/// Newton stops once the accepted step is this small in every coordinate: the extremum is then
/// located to ~1e-12 and its value (stationary there) to ~1e-24 relative.
pub const STEP_TOL: f64 = 1e-12;

/// Armijo sufficient-decrease constant (standard choice).
const ARMIJO: f64 = 1e-4;

/// Backtracking halvings before giving up on a direction (t ≥ 2⁻³⁰ ≈ 1e-9): a Newton direction
/// needing a smaller step is not a useful direction.
const MAX_HALVINGS: usize = 30;

/// Relative Levenberg shift tried first when the Hessian is not positive definite.
const FIRST_SHIFT: f64 = 1e-12;

/// Work buffers for [`refine`], sized for one dimension d.
#[derive(Debug, Clone)]
pub(crate) struct RefineWorkspace {
    grad: Vec<f64>,
    hess: Vec<f64>,
    free: Vec<usize>,
    reduced: Vec<f64>,
    step: Vec<f64>,
    trial: Vec<f64>,
}

impl RefineWorkspace {
    pub(crate) fn new(dim: usize) -> RefineWorkspace {
        RefineWorkspace {
            grad: vec![0.0; dim],
            hess: vec![0.0; dim * dim],
            free: Vec::with_capacity(dim),
            reduced: vec![0.0; dim * dim],
            step: vec![0.0; dim],
            trial: vec![0.0; dim],
        }
    }
}

/// Refines a local minimum of `sign · y(ξ)` from `x` (in [-1, 1]^d, overwritten with the best
/// point found); returns `y` there (unsigned). `coef` is the dense coefficient tensor.
pub(crate) fn refine(
    ev: &mut PointEvaluator,
    coef: &[f64],
    sign: f64,
    x: &mut [f64],
    max_iterations: usize,
    ws: &mut RefineWorkspace,
) -> f64 {
    let d = x.len();
    let mut f = sign * ev.value_grad_hess(coef, x, &mut ws.grad, &mut ws.hess);
    for _ in 0..max_iterations {
        for (g, h) in ws.grad.iter_mut().zip(ws.hess.chunks_exact_mut(d)) {
            *g *= sign;
            h.iter_mut().for_each(|v| *v *= sign);
        }
        ws.free.clear();
        ws.free.extend((0..d).filter(|&r| {
            let g = ws.grad[r];
            !((x[r] <= -1.0 && g > 0.0) || (x[r] >= 1.0 && g < 0.0))
        }));
        let nf = ws.free.len();
        if nf == 0 || ws.free.iter().all(|&r| ws.grad[r] == 0.0) {
            break;
        }
        // Newton direction on the free coordinates, Levenberg-shifted until positive definite.
        let scale = ws
            .free
            .iter()
            .map(|&r| ws.hess[r * d + r].abs())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let mut shift = 0.0;
        loop {
            for (a, &r) in ws.free.iter().enumerate() {
                for (b, &s) in ws.free.iter().enumerate() {
                    ws.reduced[b * nf + a] = ws.hess[r * d + s] + if a == b { shift } else { 0.0 };
                }
            }
            if cholesky::factor_in_place(
                &mut ws.reduced[..nf * nf],
                nf,
                cholesky::ANY_POSITIVE_PIVOT,
            )
            .is_ok()
            {
                break;
            }
            shift = if shift == 0.0 {
                FIRST_SHIFT * scale
            } else {
                shift * 10.0
            };
            if !shift.is_finite() {
                return sign * f;
            }
        }
        for (a, &r) in ws.free.iter().enumerate() {
            ws.step[a] = -ws.grad[r];
        }
        cholesky::solve_in_place(&ws.reduced[..nf * nf], nf, &mut ws.step[..nf]);

        // Converged: the full projected step is negligible, or its predicted decrease is below the
        // rounding of φ (a line search could then only chase noise).
        let mut full_move = 0.0_f64;
        let mut full_decrease = 0.0;
        for (a, &r) in ws.free.iter().enumerate() {
            let delta = (x[r] + ws.step[a]).clamp(-1.0, 1.0) - x[r];
            full_move = full_move.max(delta.abs());
            full_decrease -= ws.grad[r] * delta;
        }
        if full_move <= STEP_TOL || full_decrease <= f64::EPSILON * f.abs() {
            break;
        }

        // Projected backtracking line search.
        let mut t = 1.0;
        let mut accepted = false;
        let mut moved = 0.0_f64;
        for _ in 0..=MAX_HALVINGS {
            ws.trial.copy_from_slice(x);
            for (a, &r) in ws.free.iter().enumerate() {
                ws.trial[r] = (x[r] + t * ws.step[a]).clamp(-1.0, 1.0);
            }
            let predicted: f64 = ws
                .free
                .iter()
                .map(|&r| ws.grad[r] * (ws.trial[r] - x[r]))
                .sum();
            let f_trial = sign * ev.value(coef, &ws.trial);
            if f_trial < f && f_trial <= f + ARMIJO * predicted {
                moved = ws
                    .free
                    .iter()
                    .map(|&r| (ws.trial[r] - x[r]).abs())
                    .fold(0.0, f64::max);
                accepted = true;
                break;
            }
            t *= 0.5;
        }
        if !accepted {
            break;
        }
        x.copy_from_slice(&ws.trial);
        f = sign * ev.value_grad_hess(coef, x, &mut ws.grad, &mut ws.hess);
        if moved <= STEP_TOL {
            break;
        }
    }
    sign * f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uq::basis::Family;
    use crate::uq::design::{Design, Truncation};
    use crate::uq::projection::Projector;
    use crate::uq::surrogate::Surrogate;

    /// Newton converges quadratically; the value at a stationary point is exact to rounding.
    const VALUE_TOL: f64 = 1e-13;

    fn fitted(dim: usize, order: usize, f: impl Fn(&[f64]) -> f64) -> Surrogate {
        let design = Design::new(Family::Legendre, dim, order, Truncation::Tensor).unwrap();
        let values: Vec<f64> = design.points().chunks_exact(dim).map(f).collect();
        let p = Projector::new(design).unwrap();
        let c = p.fit(&values, 1).unwrap();
        Surrogate::from_matrix(p.design(), &c, 0).unwrap()
    }

    #[test]
    fn finds_interior_and_boundary_extrema() {
        // (ξ1 − 0.3)² + 2(ξ2 + 0.45)² − ξ1 ξ2 / 4: convex quadratic, interior minimum; maximum at a
        // corner.
        let f = |x: &[f64]| (x[0] - 0.3).powi(2) + 2.0 * (x[1] + 0.45).powi(2) - 0.25 * x[0] * x[1];
        let s = fitted(2, 2, f);
        let mut ev = PointEvaluator::new(Family::Legendre, 2, 2);
        let mut ws = RefineWorkspace::new(2);
        // ∇ = 0: 2(x − 0.3) − y/4 = 0, 4(y + 0.45) − x/4 = 0.
        let det = 2.0 * 4.0 - 0.0625;
        let (bx, by) = (0.6, -1.8);
        let x_star = (bx * 4.0 - (-0.25) * by) / det;
        let y_star = (2.0 * by - (-0.25) * bx) / det;
        let mut x = [1.0, 1.0];
        let v = refine(&mut ev, s.dense_coefficients(), 1.0, &mut x, 50, &mut ws);
        assert!((x[0] - x_star).abs() < 1e-10 && (x[1] - y_star).abs() < 1e-10);
        assert!((v - f(&[x_star, y_star])).abs() < VALUE_TOL);
        let mut x = [0.2, 0.3];
        let v = refine(&mut ev, s.dense_coefficients(), -1.0, &mut x, 50, &mut ws);
        let corners = [[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]];
        let best = corners.iter().map(|c| f(c)).fold(f64::MIN, f64::max);
        assert!((v - best).abs() < VALUE_TOL, "{v} vs {best}");
    }
}
