//! Fitting: from model values at the tensor Gauss design to expansion coefficients, for many
//! outputs at once, as a precomputed linear map applied by sum factorisation (one 1-D transform per
//! dimension), never as a loop of scalar fits.
//!
//! Layouts:
//! - **values** (input): `n_points × n_outputs` row-major, row `p` = every output of model run `p`
//!   (design point order of [`crate::uq::design`]), i.e. `values[p · n_outputs + o]`. This is what
//!   a batch of runs naturally produces, and it lets each 1-D transform run as long contiguous axpy
//!   loops over outputs.
//! - **coefficients** ([`CoefficientMatrix`], output): output-major, `data[o · n_terms + t]` for
//!   kept term `t` of the design, so each output's coefficients are one contiguous slice
//!   ([`CoefficientMatrix::output`]), which is what bounding one output at a time reads.
//!
//! Does not: bound or evaluate anything (see [`crate::uq::Surrogate`]).

use crate::uq::basis::Family;
use crate::uq::design::Design;
use crate::uq::error::UqError;
use crate::uq::quadrature;
use crate::uq::tensor_contraction::apply_axis;

/// Outputs transformed together: bounds the work buffers to `m^d × CHUNK` doubles (cache-sized for
/// d ≤ 4, k ≤ 4) while keeping the axpy loops at least `CHUNK` long.
const OUTPUT_CHUNK: usize = 64;

/// Expansion coefficients of many outputs, output-major (module doc): `data[o · n_terms + t]`.
#[derive(Debug, Clone, PartialEq)]
pub struct CoefficientMatrix {
    n_terms: usize,
    n_outputs: usize,
    data: Vec<f64>,
}

impl CoefficientMatrix {
    /// A zero matrix.
    pub fn zeros(n_terms: usize, n_outputs: usize) -> CoefficientMatrix {
        CoefficientMatrix {
            n_terms,
            n_outputs,
            data: vec![0.0; n_terms * n_outputs],
        }
    }

    /// Number of kept terms of the design (coefficients per output).
    pub fn n_terms(&self) -> usize {
        self.n_terms
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.n_outputs
    }

    /// All coefficients, output-major: `data[o · n_terms + t]`.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// Coefficient of term `t` for output `o`, if both are in range.
    pub fn get(&self, term: usize, output: usize) -> Option<f64> {
        if term < self.n_terms && output < self.n_outputs {
            Some(self.data[output * self.n_terms + term])
        } else {
            None
        }
    }

    /// Output `o`'s coefficients, one per kept term of the design (design term order).
    pub fn output(&self, output: usize) -> Result<&[f64], UqError> {
        if output >= self.n_outputs {
            return Err(UqError::IndexOutOfRange {
                what: "coefficient matrix output",
                index: output,
                len: self.n_outputs,
            });
        }
        Ok(&self.data[output * self.n_terms..(output + 1) * self.n_terms])
    }
}

/// The fitting map of one design: a constant description, shareable across threads.
#[derive(Debug, Clone, PartialEq)]
pub struct Projector {
    design: Design,
    /// 1-D transforms `A` (m × m, row-major): `coef_i = Σ_j A[i, j] · y(ξ_j)`; one for every
    /// dimension, or one per dimension for a design on its own nodes ([`Design::axis_nodes`]).
    transforms: Vec<Vec<f64>>,
}

/// Largest entry of the inverse Vandermonde matrix of a design's own 1-D nodes
/// ([`Design::with_axis_nodes`]) that the projector accepts: the 1-D interpolation's coefficients
/// are at most this many times the values' size. Gauss–Legendre nodes at k = 4 give ≈ 4.6 (the
/// degree-4 coefficient of a unit spike); nodes this far past them interpolate badly.
pub const MAX_NODAL_TRANSFORM_ENTRY: f64 = 50.0;

impl Projector {
    /// Precomputes the 1-D transform of `design`'s family (`m = k + 1`):
    ///
    /// - Legendre (docs/method.md §2): `A[i, j] = (2i + 1)/2 · w_j · P_i(ξ_j)`, Gauss–Legendre `(ξ_j, w_j)`.
    ///   With m = k + 1 the discrete orthogonality is exact: the projection is the interpolant at the
    ///   Gauss nodes.
    /// - Chebyshev (docs/method.md §4): `A[i, j] = (2/m) cos(i θ_j)`, halved for `i = 0`, so that the
    ///   tensor product carries ½ per zero index and the surrogate is `Σ c_i Π_r T_{i_r}`.
    /// - A Legendre design on its own nodes: `A = V⁻¹`, `V[j, i] = P_i(ξ_j)`, per dimension — the
    ///   interpolant at those nodes (docs/method.md §12, "Nested elements").
    ///
    /// The d-dimensional map is `A ⊗ … ⊗ A`, applied one dimension at a time.
    ///
    /// Errors: a design on its own nodes whose inverse Vandermonde matrix is singular or has an
    /// entry above [`MAX_NODAL_TRANSFORM_ENTRY`] ([`UqError::BadNodes`]).
    pub fn new(design: Design) -> Result<Projector, UqError> {
        let m = design.points_per_dim();
        if !design.has_gauss_nodes() {
            let transforms = (0..design.dim())
                .map(|r| nodal_transform(design.axis_nodes(r), r))
                .collect::<Result<Vec<_>, _>>()?;
            return Ok(Projector { design, transforms });
        }
        let mut transform = vec![0.0; m * m];
        match design.family() {
            Family::Legendre => {
                let rule = quadrature::gauss_legendre(m)?;
                let mut p = vec![0.0; m];
                for (j, (&x, &w)) in rule.nodes().iter().zip(rule.weights()).enumerate() {
                    Family::Legendre.values(x, &mut p);
                    for (i, &pi) in p.iter().enumerate() {
                        transform[i * m + j] = (2 * i + 1) as f64 / 2.0 * w * pi;
                    }
                }
            }
            Family::Chebyshev => {
                let theta = quadrature::chebyshev_angles(m)?;
                for (j, &t) in theta.iter().enumerate() {
                    for i in 0..m {
                        let half = if i == 0 { 0.5 } else { 1.0 };
                        transform[i * m + j] = half * 2.0 / m as f64 * (i as f64 * t).cos();
                    }
                }
            }
        }
        Ok(Projector {
            design,
            transforms: vec![transform],
        })
    }

    /// The design this projector fits.
    pub fn design(&self) -> &Design {
        &self.design
    }

    /// Fits every output: `values` is `n_points × n_outputs` row-major (module doc). Returns the
    /// coefficient matrix (output-major, `n_terms` coefficients per output).
    ///
    /// Errors: wrong `values` length, `n_outputs == 0`, a non-finite value (its flat index).
    ///
    /// ```
    /// use ribbon::uq::{Design, Family, Projector, Truncation};
    /// // y = ξ + ξ² on the 3-point Gauss–Legendre grid: 1/3 + P_1 + 2/3 P_2 (docs/method.md §3).
    /// let projector = Projector::new(Design::new(Family::Legendre, 1, 2, Truncation::Tensor)?)?;
    /// let values: Vec<f64> = projector.design().points().iter().map(|x| x + x * x).collect();
    /// let coef = projector.fit(&values, 1)?;
    /// let expected = [1.0 / 3.0, 1.0, 2.0 / 3.0];
    /// for (c, e) in coef.as_slice().iter().zip(expected) {
    ///     assert!((c - e).abs() < 1e-15);
    /// }
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    pub fn fit(&self, values: &[f64], n_outputs: usize) -> Result<CoefficientMatrix, UqError> {
        let mut out = CoefficientMatrix::zeros(self.design.n_terms(), n_outputs);
        self.fit_into(values, n_outputs, &mut out)?;
        Ok(out)
    }

    /// As [`Projector::fit`], overwriting `out` (resized as needed) to reuse its allocation.
    pub fn fit_into(
        &self,
        values: &[f64],
        n_outputs: usize,
        out: &mut CoefficientMatrix,
    ) -> Result<(), UqError> {
        let n_points = self.design.n_points();
        if n_outputs == 0 {
            return Err(UqError::Empty {
                what: "fit: outputs",
            });
        }
        if values.len() != n_points * n_outputs {
            return Err(UqError::WrongLength {
                what: "fit: values (n_points × n_outputs)",
                expected: n_points * n_outputs,
                got: values.len(),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(UqError::NonFinite {
                what: "fit: values",
                index,
                value: values[index],
            });
        }
        let n_terms = self.design.n_terms();
        out.n_terms = n_terms;
        out.n_outputs = n_outputs;
        out.data.resize(n_terms * n_outputs, 0.0);

        let (m, d) = (self.design.points_per_dim(), self.design.dim());
        let chunk = OUTPUT_CHUNK.min(n_outputs);
        let mut a = vec![0.0; n_points * chunk];
        let mut b = vec![0.0; n_points * chunk];
        let kept = self.design.dense_positions();
        for o0 in (0..n_outputs).step_by(chunk) {
            let c = chunk.min(n_outputs - o0);
            let (mut a, mut b) = (&mut a[..n_points * c], &mut b[..n_points * c]);
            for (dst, src) in a.chunks_exact_mut(c).zip(values.chunks_exact(n_outputs)) {
                dst.copy_from_slice(&src[o0..o0 + c]);
            }
            // Tensor of shape (m, …, m, c); transform axis r: outer = m^r, inner = m^{d−1−r}·c.
            for r in 0..d {
                let outer = m.pow(r as u32);
                let inner = m.pow((d - 1 - r) as u32) * c;
                let transform = &self.transforms[r.min(self.transforms.len() - 1)];
                apply_axis(a, outer, m, inner, transform, m, b);
                std::mem::swap(&mut a, &mut b);
            }
            // Transpose the chunk (dense term × output) into output-major kept terms.
            let block = &mut out.data[o0 * n_terms..(o0 + c) * n_terms];
            for (t, &dense) in kept.iter().enumerate() {
                let src = &a[dense * c..(dense + 1) * c];
                for (o, &v) in src.iter().enumerate() {
                    block[o * n_terms + t] = v;
                }
            }
        }
        Ok(())
    }
}

/// The inverse of the Legendre Vandermonde matrix `V[j, i] = P_i(nodes[j])` (row-major m × m):
/// the interpolation transform of a design's own nodes along `dimension`.
fn nodal_transform(nodes: &[f64], dimension: usize) -> Result<Vec<f64>, UqError> {
    let m = nodes.len();
    let bad = UqError::BadNodes {
        dimension,
        expected: m,
        got: m,
    };
    let mut p = vec![0.0; m];
    let vandermonde = nalgebra::DMatrix::from_fn(m, m, |j, i| {
        Family::Legendre.values(nodes[j], &mut p);
        p[i]
    });
    let inverse = vandermonde.try_inverse().ok_or(bad.clone())?;
    let mut transform = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            transform[i * m + j] = inverse[(i, j)];
        }
    }
    if transform
        .iter()
        .any(|a| !a.is_finite() || a.abs() > MAX_NODAL_TRANSFORM_ENTRY)
    {
        return Err(bad);
    }
    Ok(transform)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::design::{for_each_multi_index, Truncation};
    use crate::uq::surrogate::Surrogate;

    /// Reproduction is exact in exact arithmetic; in floating point the fit and evaluation of
    /// O(1)-coefficient polynomials of degree ≤ 6 in 4 variables lose a few hundred ulp at most.
    const REPRODUCTION_TOL: f64 = 1e-12;

    /// A random polynomial in monomial form `Σ a_e Π ξ_r^{e_r}` over the exponents kept by the
    /// truncation, fitted from its values at the design, must evaluate like the polynomial at random
    /// points (independent of the basis code: the data come from monomials).
    fn check_reproduction(family: Family, dim: usize, order: usize, truncation: Truncation) {
        let mut rng = SplitMix64::new(0x5EED ^ ((dim * 100 + order) as u64));
        let design = Design::new(family, dim, order, truncation).unwrap();
        let mut exponents = Vec::new();
        for_each_multi_index(order + 1, dim, |_, e| {
            if truncation.degree(e) <= order {
                exponents.push(e.to_vec());
            }
        });
        // Three outputs at once, each its own random polynomial.
        let n_out = 3;
        let coef: Vec<Vec<f64>> = (0..n_out)
            .map(|_| exponents.iter().map(|_| rng.uniform(-1.0, 1.0)).collect())
            .collect();
        let poly = |o: usize, x: &[f64]| -> f64 {
            exponents
                .iter()
                .zip(&coef[o])
                .map(|(e, a)| {
                    a * e
                        .iter()
                        .zip(x)
                        .map(|(&k, &x)| x.powi(k as i32))
                        .product::<f64>()
                })
                .sum()
        };
        let mut values = Vec::new();
        for x in design.points().chunks_exact(dim) {
            values.extend((0..n_out).map(|o| poly(o, x)));
        }
        let projector = Projector::new(design.clone()).unwrap();
        let fitted = projector.fit(&values, n_out).unwrap();
        assert_eq!(fitted.n_terms(), design.n_terms());
        assert!(fitted.output(n_out).is_err());
        assert_eq!(fitted.get(0, 2), Some(fitted.output(2).unwrap()[0]));
        let scale: f64 = coef.iter().flatten().map(|a| a.abs()).sum();
        for o in 0..n_out {
            let s = Surrogate::from_matrix(&design, &fitted, o).unwrap();
            for _ in 0..20 {
                let x: Vec<f64> = (0..dim).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let err = (s.eval(&x).unwrap() - poly(o, &x)).abs();
                assert!(
                    err < REPRODUCTION_TOL * scale.max(1.0),
                    "{family:?} {truncation:?} d={dim} k={order}: error {err}"
                );
            }
        }
    }

    #[test]
    fn legendre_reproduces_tensor_and_total_degree_polynomials() {
        for dim in 1..=4 {
            for order in 0..=6 {
                if dim == 4 && order > 5 {
                    continue;
                }
                check_reproduction(Family::Legendre, dim, order, Truncation::Tensor);
                check_reproduction(Family::Legendre, dim, order, Truncation::Total);
            }
        }
    }

    #[test]
    fn chebyshev_reproduces_tensor_and_total_degree_polynomials() {
        for dim in 1..=4 {
            for order in 0..=6 {
                if dim == 4 && order > 5 {
                    continue;
                }
                check_reproduction(Family::Chebyshev, dim, order, Truncation::Tensor);
                check_reproduction(Family::Chebyshev, dim, order, Truncation::Total);
            }
        }
    }

    #[test]
    fn reproduces_basis_coefficients_at_high_order() {
        // Coefficient-space check up to k = 39 (40 Gauss points) in 1-D and k = 12 in 2-D: data
        // generated from random basis coefficients come back unchanged.
        let mut rng = SplitMix64::new(7);
        for family in [Family::Legendre, Family::Chebyshev] {
            for (dim, order) in [(1, 39), (1, 20), (2, 12), (3, 6)] {
                let design = Design::new(family, dim, order, Truncation::Tensor).unwrap();
                let coef: Vec<f64> = (0..design.n_terms())
                    .map(|_| rng.uniform(-1.0, 1.0))
                    .collect();
                let s = Surrogate::from_terms(&design, &coef).unwrap();
                let values: Vec<f64> = design
                    .points()
                    .chunks_exact(dim)
                    .map(|x| s.eval(x).unwrap())
                    .collect();
                let fitted = Projector::new(design.clone())
                    .unwrap()
                    .fit(&values, 1)
                    .unwrap();
                for (a, b) in fitted.as_slice().iter().zip(&coef) {
                    assert!(
                        (a - b).abs() < REPRODUCTION_TOL,
                        "{family:?} d={dim} k={order}"
                    );
                }
            }
        }
    }

    #[test]
    fn worked_example_coefficients() {
        // ξ + ξ² = 1/3 + P_1 + 2/3 P_2 = 1/2 + T_1 + 1/2 T_2 (docs/method.md §3).
        for (family, expected) in [
            (Family::Legendre, [1.0 / 3.0, 1.0, 2.0 / 3.0]),
            (Family::Chebyshev, [0.5, 1.0, 0.5]),
        ] {
            let p = Projector::new(Design::new(family, 1, 2, Truncation::Tensor).unwrap()).unwrap();
            let values: Vec<f64> = p.design().points().iter().map(|x| x + x * x).collect();
            let c = p.fit(&values, 1).unwrap();
            for (a, b) in c.as_slice().iter().zip(expected) {
                assert!((a - b).abs() < 1e-15, "{family:?}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn chunked_outputs_match_single_fits() {
        // 150 outputs cross the 64-output chunk boundary twice.
        let design = Design::new(Family::Legendre, 2, 3, Truncation::Total).unwrap();
        let p = Projector::new(design.clone()).unwrap();
        let n_out = 150;
        let mut rng = SplitMix64::new(11);
        let values: Vec<f64> = (0..design.n_points() * n_out)
            .map(|_| rng.uniform(-1.0, 1.0))
            .collect();
        let all = p.fit(&values, n_out).unwrap();
        for o in [0, 63, 64, 127, 128, 149] {
            let single: Vec<f64> = values.iter().skip(o).step_by(n_out).copied().collect();
            let one = p.fit(&single, 1).unwrap();
            for (a, b) in one.as_slice().iter().zip(all.output(o).unwrap()) {
                // Same arithmetic up to the grouping of a 2-term sum.
                assert!((a - b).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn refuses_bad_values() {
        let p = Projector::new(Design::new(Family::Legendre, 2, 1, Truncation::Tensor).unwrap())
            .unwrap();
        assert!(matches!(
            p.fit(&[0.0; 7], 2),
            Err(UqError::WrongLength {
                expected: 8,
                got: 7,
                ..
            })
        ));
        assert!(matches!(
            p.fit(&[0.0, 1.0, f64::NAN, 0.0], 1),
            Err(UqError::NonFinite { index: 2, .. })
        ));
        assert!(matches!(p.fit(&[], 0), Err(UqError::Empty { .. })));
    }
}
