//! One output's polynomial surrogate `y(ξ) ≈ Σ_i c_i Π_r φ_{i_r}(ξ_r)` on ξ ∈ [-1, 1]^d: its
//! coefficients (stored as a dense `(k+1)^d` tensor, zero outside the truncation), point
//! evaluation, and its error estimate (top-order coefficients, misfit at extra runs).
//!
//! Does not: fit (see [`crate::uq::Projector`]) or bound (see [`crate::uq::bounds`],
//! [`crate::uq::Scanner`]).

use crate::uq::basis::Family;
use crate::uq::design::{Design, Truncation};
use crate::uq::error::UqError;
use crate::uq::projection::CoefficientMatrix;
use crate::uq::sobol_indices::{tensor_sobol_indices_into, SobolIndices};
use crate::uq::tensor_contraction::PointEvaluator;

/// How large the error ignored by a bound may be, in the output's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorEstimate {
    /// Magnitude of the highest retained order: for a surrogate `Σ |c_i|` over terms of
    /// truncation degree k ([`Surrogate::top_order_magnitude`]); for first-order Taylor, the
    /// diagonal second-order terms `Σ_r ½ |∂²f/∂ξ_r²|` that the linearisation drops.
    pub top_order: f64,
    /// Largest `|model − surrogate|` at extra model runs, when the caller made some.
    pub misfit: Option<f64>,
}

impl ErrorEstimate {
    /// The same estimate with a misfit measured at extra runs.
    pub fn with_misfit(self, misfit: f64) -> ErrorEstimate {
        ErrorEstimate {
            misfit: Some(misfit),
            ..self
        }
    }
}

/// A polynomial surrogate of one output.
#[derive(Debug, Clone, PartialEq)]
pub struct Surrogate {
    family: Family,
    dim: usize,
    order: usize,
    truncation: Truncation,
    /// Dense row-major tensor, `(order+1)^dim` entries (term order of [`crate::uq::design`]).
    dense: Vec<f64>,
}

impl Surrogate {
    /// The zero surrogate of `design` (fill it with [`Surrogate::set_from_matrix`] or
    /// [`Surrogate::set_terms`]).
    pub fn zeros(design: &Design) -> Surrogate {
        Surrogate {
            family: design.family(),
            dim: design.dim(),
            order: design.order(),
            truncation: design.truncation(),
            dense: vec![0.0; design.n_dense_terms()],
        }
    }

    /// From coefficients in `design`'s kept-term order (length `design.n_terms()`).
    ///
    /// ```
    /// use ribbon::uq::{Design, Family, Surrogate, Truncation};
    /// // 1/3 + P_1 + 2/3 P_2 = ξ + ξ²
    /// let design = Design::new(Family::Legendre, 1, 2, Truncation::Tensor)?;
    /// let s = Surrogate::from_terms(&design, &[1.0 / 3.0, 1.0, 2.0 / 3.0])?;
    /// assert!((s.eval(&[-0.5])? + 0.25).abs() < 1e-15);
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    pub fn from_terms(design: &Design, coefficients: &[f64]) -> Result<Surrogate, UqError> {
        let mut s = Surrogate::zeros(design);
        s.set_terms(design, coefficients)?;
        Ok(s)
    }

    /// Overwrites the coefficients from `design`'s kept-term order; `design` must match this
    /// surrogate's family, dimension, order and truncation.
    pub fn set_terms(&mut self, design: &Design, coefficients: &[f64]) -> Result<(), UqError> {
        self.check_design(design)?;
        if coefficients.len() != design.n_terms() {
            return Err(UqError::WrongLength {
                what: "surrogate coefficients",
                expected: design.n_terms(),
                got: coefficients.len(),
            });
        }
        self.dense.fill(0.0);
        for (&c, &t) in coefficients.iter().zip(design.dense_positions()) {
            self.dense[t] = c;
        }
        Ok(())
    }

    /// Overwrites the coefficients with output `output` of `matrix` (fitted with `design`).
    pub fn set_from_matrix(
        &mut self,
        design: &Design,
        matrix: &CoefficientMatrix,
        output: usize,
    ) -> Result<(), UqError> {
        self.check_design(design)?;
        if matrix.n_terms() != design.n_terms() {
            return Err(UqError::WrongLength {
                what: "coefficient matrix rows (design terms)",
                expected: design.n_terms(),
                got: matrix.n_terms(),
            });
        }
        let column = matrix.output(output)?;
        if design.truncation() == Truncation::Tensor {
            self.dense.copy_from_slice(column);
        } else {
            self.dense.fill(0.0);
            for (&c, &t) in column.iter().zip(design.dense_positions()) {
                self.dense[t] = c;
            }
        }
        Ok(())
    }

    /// From output `output` of `matrix` (fitted with `design`).
    pub fn from_matrix(
        design: &Design,
        matrix: &CoefficientMatrix,
        output: usize,
    ) -> Result<Surrogate, UqError> {
        let mut s = Surrogate::zeros(design);
        s.set_from_matrix(design, matrix, output)?;
        Ok(s)
    }

    fn check_design(&self, design: &Design) -> Result<(), UqError> {
        if design.family() != self.family
            || design.dim() != self.dim
            || design.order() != self.order
            || design.truncation() != self.truncation
        {
            return Err(UqError::SurrogateMismatch {
                what: "design",
                expected_family: design.family(),
                expected_dim: design.dim(),
                expected_order: design.order(),
                got_family: self.family,
                got_dim: self.dim,
                got_order: self.order,
            });
        }
        Ok(())
    }

    /// Polynomial family.
    pub fn family(&self) -> Family {
        self.family
    }

    /// Number of parameters d.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Order k per dimension.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Truncation the coefficients came from.
    pub fn truncation(&self) -> Truncation {
        self.truncation
    }

    /// Dense coefficient tensor, `(k+1)^d` entries in row-major multi-index order (zeros outside
    /// the truncation). Entry 0 is the constant term `c_0`.
    pub fn dense_coefficients(&self) -> &[f64] {
        &self.dense
    }

    /// Coefficient of multi-index `(i_1, …, i_d)` (0 if a degree exceeds k or the truncation
    /// drops it); `None` if the length is not d.
    pub fn coefficient(&self, multi_index: &[usize]) -> Option<f64> {
        if multi_index.len() != self.dim {
            return None;
        }
        if multi_index.iter().any(|&i| i > self.order) {
            return Some(0.0);
        }
        let m = self.order + 1;
        let t = multi_index.iter().fold(0, |acc, &i| acc * m + i);
        Some(self.dense[t])
    }

    /// The surrogate's value at `xi` (length d, normally in [-1, 1]^d), by sum factorisation.
    pub fn eval(&self, xi: &[f64]) -> Result<f64, UqError> {
        if xi.len() != self.dim {
            return Err(UqError::WrongLength {
                what: "surrogate eval: xi",
                expected: self.dim,
                got: xi.len(),
            });
        }
        Ok(PointEvaluator::new(self.family, self.dim, self.order).value(&self.dense, xi))
    }

    /// Top-order magnitude: `Σ |c_i|` over multi-indices whose truncation degree (max for tensor,
    /// sum for total) equals k. A heuristic for the truncation error: for smooth responses the
    /// coefficients decay geometrically, so the neglected ones are usually no larger.
    pub fn top_order_magnitude(&self) -> f64 {
        top_order_sum(&self.dense, self.order, self.truncation, 0)
    }

    /// Largest `|y − surrogate(ξ)|` over extra model runs: `points` is `n × d` row-major standard
    /// coordinates, `values` the n model values (same order).
    ///
    /// Errors: lengths that disagree, no points, non-finite values.
    pub fn misfit(&self, points: &[f64], values: &[f64]) -> Result<f64, UqError> {
        if values.is_empty() {
            return Err(UqError::Empty {
                what: "misfit: values",
            });
        }
        if points.len() != values.len() * self.dim {
            return Err(UqError::WrongLength {
                what: "misfit: points (n × d)",
                expected: values.len() * self.dim,
                got: points.len(),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(UqError::NonFinite {
                what: "misfit: values",
                index,
                value: values[index],
            });
        }
        let mut ev = PointEvaluator::new(self.family, self.dim, self.order);
        Ok(points
            .chunks_exact(self.dim)
            .zip(values)
            .map(|(xi, y)| (y - ev.value(&self.dense, xi)).abs())
            .fold(0.0, f64::max))
    }

    /// Main and total Sobol' indices per dimension under uniform ξ, from the coefficients
    /// (docs/sobol-indices.md §2–§3; a Chebyshev surrogate is rewritten in the Legendre basis
    /// first). A constant surrogate has every index 0.
    ///
    /// ```
    /// use ribbon::uq::{Design, Family, Surrogate, Truncation};
    /// // y = ξ1 + 2 ξ2: variances 1/3 and 4/3, no interaction.
    /// let design = Design::new(Family::Legendre, 2, 1, Truncation::Tensor)?;
    /// let s = Surrogate::from_terms(&design, &[0.0, 2.0, 1.0, 0.0])?;
    /// let indices = s.sobol_indices()?;
    /// assert!((indices.main[0] - 0.2).abs() < 1e-15 && (indices.total[1] - 0.8).abs() < 1e-15);
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    ///
    /// Errors: an order beyond the quadrature's range (Chebyshev change of basis).
    pub fn sobol_indices(&self) -> Result<SobolIndices, UqError> {
        let mut out = SobolIndices::zeros(self.dim);
        self.sobol_indices_into(&mut out)?;
        Ok(out)
    }

    /// As [`Surrogate::sobol_indices`], overwriting `out` (resized to d).
    pub fn sobol_indices_into(&self, out: &mut SobolIndices) -> Result<(), UqError> {
        tensor_sobol_indices_into(self.family, self.dim, self.order, &self.dense, out)
    }

    /// The error estimate attached to every bound of this surrogate: top-order magnitude, no
    /// misfit (add one with [`ErrorEstimate::with_misfit`]).
    pub fn error_estimate(&self) -> ErrorEstimate {
        ErrorEstimate {
            top_order: self.top_order_magnitude(),
            misfit: None,
        }
    }
}

/// `Σ |c|` over the terms of `block` (a dense sub-tensor, its leading digits already chosen with
/// running truncation degree `degree`) whose final degree is exactly `order`. Recursive over
/// leading digits, so each level costs a slice split rather than a per-term decode.
fn top_order_sum(block: &[f64], order: usize, truncation: Truncation, degree: usize) -> f64 {
    let m = order + 1;
    if block.len() == m {
        // Last digit i: degree max(degree, i) or degree + i.
        return match truncation {
            Truncation::Tensor if degree == order => block.iter().map(|c| c.abs()).sum(),
            Truncation::Tensor => block[order].abs(),
            Truncation::Total => block[order - degree].abs(),
        };
    }
    let len = block.len() / m;
    block
        .chunks_exact(len)
        .enumerate()
        .map(|(i, sub)| {
            let next = match truncation {
                Truncation::Tensor => degree.max(i),
                Truncation::Total => degree + i,
            };
            if next > order {
                0.0
            } else {
                top_order_sum(sub, order, truncation, next)
            }
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn top_order_and_coefficient_lookup() {
        let design = Design::new(Family::Legendre, 2, 2, Truncation::Total).unwrap();
        // kept terms in dense order: (0,0) (0,1) (0,2) (1,0) (1,1) (2,0)
        let s = Surrogate::from_terms(&design, &[1.0, 2.0, -3.0, 4.0, 5.0, -6.0]).unwrap();
        assert_eq!(s.top_order_magnitude(), 3.0 + 5.0 + 6.0);
        assert_eq!(s.coefficient(&[1, 1]), Some(5.0));
        assert_eq!(s.coefficient(&[2, 2]), Some(0.0));
        assert_eq!(s.coefficient(&[1]), None);
        let tensor = Design::new(Family::Legendre, 2, 2, Truncation::Tensor).unwrap();
        let t = Surrogate::from_terms(&tensor, &[1.0; 9]).unwrap();
        // max degree 2: (0,2) (1,2) (2,0) (2,1) (2,2)
        assert_eq!(t.top_order_magnitude(), 5.0);
        assert!(Surrogate::from_terms(&tensor, &[1.0; 8]).is_err());
    }

    #[test]
    fn top_order_matches_definition() {
        use crate::uq::design::for_each_multi_index;
        for truncation in [Truncation::Tensor, Truncation::Total] {
            for (dim, order) in [(1, 0), (1, 3), (2, 2), (3, 4), (4, 3)] {
                let design = Design::new(Family::Chebyshev, dim, order, truncation).unwrap();
                let coef: Vec<f64> = (0..design.n_terms())
                    .map(|t| (t as f64 * 0.37).sin())
                    .collect();
                let s = Surrogate::from_terms(&design, &coef).unwrap();
                let mut want = 0.0;
                for_each_multi_index(order + 1, dim, |t, idx| {
                    if truncation.degree(idx) == order {
                        want += s.dense_coefficients()[t].abs();
                    }
                });
                assert!((s.top_order_magnitude() - want).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn misfit_at_extra_points() {
        let design = Design::new(Family::Legendre, 1, 2, Truncation::Tensor).unwrap();
        let s = Surrogate::from_terms(&design, &[1.0 / 3.0, 1.0, 2.0 / 3.0]).unwrap();
        // y = ξ + ξ² + 0.1 ξ³ is not representable at k = 2: misfit 0.1·|ξ|³ at ξ = ±1 and ±0.5.
        let xs = [-1.0, -0.5, 0.5, 1.0];
        let ys: Vec<f64> = xs.iter().map(|x| x + x * x + 0.1 * x * x * x).collect();
        assert!((s.misfit(&xs, &ys).unwrap() - 0.1).abs() < 1e-15);
        assert!(s.misfit(&xs, &ys[..3]).is_err());
        assert!(s.misfit(&[], &[]).is_err());
        let e = s.error_estimate().with_misfit(0.1);
        assert_eq!(e.misfit, Some(0.1));
        assert!((e.top_order - 2.0 / 3.0).abs() < 1e-15);
    }
}
