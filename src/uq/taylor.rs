//! First-order Taylor inclusion about the box centre (docs/method.md §4, the classic baseline the paper
//! argues against), with derivatives from central finite differences of model runs:
//!
//! `∂y/∂ξ_r ≈ (y(c + h e_r) − y(c − h e_r)) / (2h)`,   bound `y(c) ± Σ_r |∂y/∂ξ_r|`.
//!
//! **Label: [`BoundKind::Approximate`].** This is the exact range of the linearisation, not an
//! enclosure of the response (curvature can push the response outside it, e.g. ξ + ξ² reaches 2
//! but the bound stops at 1) nor an inner bound (it can exceed the response's range: for
//! ξ + ξ² it goes down to −1, the response only to −0.25). Its error estimate is the size of the
//! dropped diagonal second-order terms, `Σ_r ½ |∂²y/∂ξ_r²|`, from the same runs.
//!
//! Does not: second-order Taylor or mixed derivatives (they would need more runs).

use crate::uq::bounds::{Bound, BoundKind, ErrorEstimate};
use crate::uq::error::UqError;

/// The 2d + 1 model runs of a central-difference stencil in standard coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaylorStencil {
    dim: usize,
    step: f64,
}

impl TaylorStencil {
    /// A stencil for `dim` parameters with step `step` ∈ (0, 1] in ξ units (`h = 1` puts the runs
    /// on the faces of the box; smaller h gives derivatives at the centre, larger h secants).
    pub fn new(dim: usize, step: f64) -> Result<TaylorStencil, UqError> {
        if dim == 0 {
            return Err(UqError::ZeroDimension);
        }
        check_step(step)?;
        Ok(TaylorStencil { dim, step })
    }

    /// Number of runs: 2d + 1.
    pub fn n_points(&self) -> usize {
        2 * self.dim + 1
    }

    /// The runs, `(2d + 1) × d` row-major: the centre, then `+h e_1`, `−h e_1`, `+h e_2`, `−h e_2`, …
    pub fn points(&self) -> Vec<f64> {
        let d = self.dim;
        let mut out = vec![0.0; self.n_points() * d];
        for r in 0..d {
            out[(1 + 2 * r) * d + r] = self.step;
            out[(2 + 2 * r) * d + r] = -self.step;
        }
        out
    }

    /// Bounds for many outputs: `values` is `(2d + 1) × n_outputs` row-major (run-major, as in
    /// [`crate::uq::Projector::fit`]), runs in [`TaylorStencil::points`] order.
    pub fn bounds(&self, values: &[f64], n_outputs: usize) -> Result<Vec<Bound>, UqError> {
        let n = self.n_points();
        if n_outputs == 0 {
            return Err(UqError::Empty {
                what: "taylor: outputs",
            });
        }
        if values.len() != n * n_outputs {
            return Err(UqError::WrongLength {
                what: "taylor: values ((2d + 1) × n_outputs)",
                expected: n * n_outputs,
                got: values.len(),
            });
        }
        let mut plus = vec![0.0; self.dim];
        let mut minus = vec![0.0; self.dim];
        (0..n_outputs)
            .map(|o| {
                for r in 0..self.dim {
                    plus[r] = values[(1 + 2 * r) * n_outputs + o];
                    minus[r] = values[(2 + 2 * r) * n_outputs + o];
                }
                taylor_first_order(values[o], &plus, &minus, self.step)
            })
            .collect()
    }

    /// Where output `output`'s linearisation `y(c) + Σ_r g_r ξ_r` takes its minimum and maximum
    /// over the box: the vertices `−sign(g)` and `sign(g)` (a coordinate whose slope is exactly 0
    /// stays at the centre), `(argmin, argmax)`, each of length d. `values` as in
    /// [`TaylorStencil::bounds`]; the a-posteriori check runs the true model there.
    pub fn linear_extremisers(
        &self,
        values: &[f64],
        n_outputs: usize,
        output: usize,
    ) -> (Vec<f64>, Vec<f64>) {
        let slope_sign = |r: usize| {
            let plus = values[(1 + 2 * r) * n_outputs + output];
            let minus = values[(2 + 2 * r) * n_outputs + output];
            let slope = plus - minus;
            if slope > 0.0 {
                1.0
            } else if slope < 0.0 {
                -1.0
            } else {
                0.0
            }
        };
        let argmax: Vec<f64> = (0..self.dim).map(slope_sign).collect();
        // `0 − x`, not `−x`: a flat coordinate stays at +0, not −0.
        let argmin = argmax.iter().map(|&x| 0.0 - x).collect();
        (argmin, argmax)
    }
}

fn check_step(step: f64) -> Result<(), UqError> {
    if !(step > 0.0 && step <= 1.0) {
        return Err(UqError::InvalidStep { step });
    }
    Ok(())
}

/// First-order Taylor bound from the centre value and the runs at `c ± h e_r` (`plus[r]`,
/// `minus[r]`, one per parameter). Kind [`BoundKind::Approximate`] (module doc).
///
/// ```
/// use ribbon::uq::{taylor_first_order, BoundKind};
/// // y = ξ + ξ²: y(0) = 0, y(±½) = ¾, −¼ ⇒ y'(0) = 1, y'' = 2.
/// let b = taylor_first_order(0.0, &[0.75], &[-0.25], 0.5)?;
/// assert_eq!((b.lower, b.upper, b.kind), (-1.0, 1.0, BoundKind::Approximate));
/// assert_eq!(b.error.top_order, 1.0); // ½ |y''|
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
///
/// Errors: `plus` and `minus` of different lengths or empty, a step outside (0, 1], a non-finite
/// value.
pub fn taylor_first_order(
    centre: f64,
    plus: &[f64],
    minus: &[f64],
    step: f64,
) -> Result<Bound, UqError> {
    check_step(step)?;
    if plus.is_empty() {
        return Err(UqError::Empty {
            what: "taylor: plus runs",
        });
    }
    if minus.len() != plus.len() {
        return Err(UqError::WrongLength {
            what: "taylor: minus runs",
            expected: plus.len(),
            got: minus.len(),
        });
    }
    let all = std::iter::once(&centre).chain(plus).chain(minus);
    if let Some((index, &value)) = all.enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(UqError::NonFinite {
            what: "taylor: values (centre, plus…, minus…)",
            index,
            value,
        });
    }
    let (mut radius, mut curvature) = (0.0, 0.0);
    for (&p, &m) in plus.iter().zip(minus) {
        radius += ((p - m) / (2.0 * step)).abs();
        curvature += 0.5 * ((p + m - 2.0 * centre) / (step * step)).abs();
    }
    Ok(Bound {
        lower: centre - radius,
        upper: centre + radius,
        kind: BoundKind::Approximate,
        error: ErrorEstimate {
            top_order: curvature,
            misfit: None,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Finite differences of quadratics are exact up to rounding.
    const TOL: f64 = 1e-14;

    #[test]
    fn worked_example_is_neither_inner_nor_outer() {
        let y = |x: f64| x + x * x;
        let stencil = TaylorStencil::new(1, 1.0).unwrap();
        let values: Vec<f64> = stencil.points().iter().map(|&x| y(x)).collect();
        let b = stencil.bounds(&values, 1).unwrap()[0];
        assert!((b.lower + 1.0).abs() < TOL && (b.upper - 1.0).abs() < TOL);
        // true range [−0.25, 2]: lower bound below it, upper bound inside it.
        assert!(b.lower < -0.25 && b.upper < 2.0);
        assert!((b.error.top_order - 1.0).abs() < TOL);
    }

    #[test]
    fn linear_function_is_exact_in_several_dimensions() {
        // y = 1 + 2ξ1 − 3ξ2 + 0.5ξ3 over [-1,1]³: [1 − 5.5, 1 + 5.5]; two outputs (second = −y).
        let stencil = TaylorStencil::new(3, 0.1).unwrap();
        let pts = stencil.points();
        let mut values = Vec::new();
        for x in pts.chunks_exact(3) {
            let y = 1.0 + 2.0 * x[0] - 3.0 * x[1] + 0.5 * x[2];
            values.extend([y, -y]);
        }
        let b = stencil.bounds(&values, 2).unwrap();
        assert!((b[0].lower + 4.5).abs() < 1e-13 && (b[0].upper - 6.5).abs() < 1e-13);
        assert!((b[1].lower + 6.5).abs() < 1e-13 && (b[1].upper - 4.5).abs() < 1e-13);
        assert!(b[0].error.top_order < 1e-10);
    }

    #[test]
    fn the_linearisations_extremes_are_at_the_sign_vertices_of_its_slopes() {
        // y = 1 + 2ξ1 − 3ξ2 + 0·ξ3 over [-1,1]³: largest at (1, −1, 0), smallest at (−1, 1, 0);
        // the second output (−y) the other way round.
        let stencil = TaylorStencil::new(3, 0.1).unwrap();
        let mut values = Vec::new();
        for x in stencil.points().chunks_exact(3) {
            let y = 1.0 + 2.0 * x[0] - 3.0 * x[1];
            values.extend([y, -y]);
        }
        let (argmin, argmax) = stencil.linear_extremisers(&values, 2, 0);
        assert_eq!(
            (argmin, argmax),
            (vec![-1.0, 1.0, 0.0], vec![1.0, -1.0, 0.0])
        );
        let (argmin, argmax) = stencil.linear_extremisers(&values, 2, 1);
        assert_eq!(
            (argmin, argmax),
            (vec![1.0, -1.0, 0.0], vec![-1.0, 1.0, 0.0])
        );
    }

    #[test]
    fn refuses_bad_input() {
        assert!(matches!(
            TaylorStencil::new(2, 0.0),
            Err(UqError::InvalidStep { .. })
        ));
        assert!(TaylorStencil::new(2, 1.5).is_err());
        assert!(TaylorStencil::new(0, 0.5).is_err());
        assert!(taylor_first_order(0.0, &[1.0], &[1.0, 2.0], 0.5).is_err());
        assert!(matches!(
            taylor_first_order(0.0, &[f64::NAN], &[1.0], 0.5),
            Err(UqError::NonFinite { index: 1, .. })
        ));
        let s = TaylorStencil::new(1, 0.5).unwrap();
        assert!(s.bounds(&[0.0; 4], 1).is_err());
    }
}
