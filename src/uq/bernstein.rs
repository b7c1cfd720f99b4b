//! An outer bound of a tensor surrogate's range from its Bernstein form, sharpened by subdivision
//! (docs/bernstein.md): beside interval arithmetic (outer, often wide) and scanning (inner), a
//! bound that contains the surrogate's range and whose gap to attained values is measured, not
//! guessed.
//!
//! On `u = (ξ + 1)/2 ∈ [0, 1]^d` a polynomial of degree ≤ k per dimension is
//! `p = Σ_i b_i Π_r B_{i_r,k}(u_r)` with the Bernstein polynomials `B_{i,k} = C(k,i) u^i (1−u)^{k−i}`.
//! They are non-negative and sum to one, so `min b ≤ p ≤ max b` on the box; the corner coefficients
//! are the values at the corners. Splitting a box in half (de Casteljau) gives the coefficients of
//! both halves, whose range enclosures converge to the true range quadratically in the box width.
//! Branch and bound on the smallest lower bound (then on the largest upper bound) stops when the
//! enclosure is within a tolerance of the best corner value, or after a budget of boxes.
//!
//! Floating point: the conversion and splitting are in round-to-nearest; the outer bound is widened
//! by a rounding allowance ([`ROUNDING_ALLOWANCE_ULPS`]) so that it stays outside in practice. It
//! is an outer bound of the **surrogate** — like every bound here, not of the true model.
//!
//! Does not: bound sparse surrogates (the tensor of `(k+1)^d` coefficients is the point of the
//! method; see [`crate::uq::BoxOptimizer`] for high d).

use crate::uq::basis::Family;
use crate::uq::error::UqError;
use crate::uq::sobol_indices::chebyshev_to_legendre;
use crate::uq::surrogate::Surrogate;

/// Largest order per dimension: the Bernstein coefficients of `P_n` are `±C(n, i)`, and past
/// this the enclosure of a high-order term is so loose (`C(24, 12) ≈ 2.7e6` times the term's size)
/// that subdivision cannot recover it within a box budget.
pub const BERNSTEIN_MAX_ORDER: usize = 24;

/// The outer bound is widened by this many units of roundoff of the largest Bernstein coefficient
/// magnitude, times `(d + 1)(k + 1)` (the depth of the sums and splittings each coefficient went
/// through): a generous allowance for round-to-nearest, not a proof.
pub const ROUNDING_ALLOWANCE_ULPS: f64 = 8.0;

/// When to stop subdividing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BernsteinOptions {
    /// Stop when the enclosure is within this fraction of the first enclosure's width of the best
    /// attained value (each side separately).
    pub relative_tolerance: f64,
    /// Most boxes split per side (the bound is still outer when the budget stops it, just wider).
    pub max_splits: usize,
}

impl Default for BernsteinOptions {
    /// 1e-6 of the width, 400 splits per side.
    fn default() -> Self {
        BernsteinOptions {
            relative_tolerance: 1e-6,
            max_splits: 400,
        }
    }
}

/// An outer bound of a surrogate's range and the best attained values found on the way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BernsteinBound {
    /// Outer lower bound: ≤ the surrogate everywhere on the box.
    pub lower: f64,
    /// Outer upper bound.
    pub upper: f64,
    /// The smallest surrogate value found (at a corner of a sub-box): an inner lower bound.
    pub attained_lower: f64,
    /// The largest surrogate value found.
    pub attained_upper: f64,
    /// Boxes split, both sides together.
    pub splits: usize,
    /// Whether both sides met the tolerance within the budget.
    pub converged: bool,
}

impl BernsteinBound {
    /// The largest distance between the outer bound and the attained values (either side): how
    /// much the surrogate's true range is still unknown.
    pub fn gap(&self) -> f64 {
        (self.attained_lower - self.lower).max(self.upper - self.attained_upper)
    }
}

/// `b[n][i]` (row-major `(k+1) × (k+1)`): the degree-k Bernstein coefficients on `u ∈ [0, 1]` of
/// `P_n(2u − 1)`. In degree n they are `(−1)^{n+i} C(n, i)` (docs/bernstein.md §2); degree
/// elevation to k takes convex combinations, so no cancellation enters.
///
/// Errors: `order >` [`BERNSTEIN_MAX_ORDER`].
pub fn legendre_in_bernstein(order: usize) -> Result<Vec<f64>, UqError> {
    if order > BERNSTEIN_MAX_ORDER {
        return Err(UqError::DesignTooLarge {
            what: "Bernstein form: order",
            got: order,
            max: BERNSTEIN_MAX_ORDER,
        });
    }
    let m = order + 1;
    let mut matrix = vec![0.0; m * m];
    let mut row = vec![0.0; m];
    for n in 0..m {
        // Degree n: (−1)^{n+i} C(n, i).
        let mut binomial = 1.0;
        for (i, b) in row.iter_mut().enumerate().take(n + 1) {
            *b = if (n + i) % 2 == 0 {
                binomial
            } else {
                -binomial
            };
            binomial = binomial * (n - i) as f64 / (i + 1) as f64;
        }
        // Elevate n → k: b'_i = (i/(m'+1)) b_{i−1} + (1 − i/(m'+1)) b_i, degree m' → m' + 1.
        for degree in n..order {
            let next = degree + 1;
            row[next] = row[degree];
            for i in (1..next).rev() {
                let t = i as f64 / next as f64;
                row[i] = t * row[i - 1] + (1.0 - t) * row[i];
            }
        }
        matrix[n * m..(n + 1) * m].copy_from_slice(&row);
    }
    Ok(matrix)
}

/// Applies a `(k+1) × (k+1)` change of basis `a[n][i]` (old index n → new index i) along every
/// dimension of a dense row-major tensor.
fn change_basis(dim: usize, m: usize, a: &[f64], tensor: &mut Vec<f64>) {
    let mut next = vec![0.0; tensor.len()];
    for r in 0..dim {
        let inner = m.pow((dim - 1 - r) as u32);
        next.fill(0.0);
        for (block_in, block_out) in tensor
            .chunks_exact(m * inner)
            .zip(next.chunks_exact_mut(m * inner))
        {
            for n in 0..m {
                let source = &block_in[n * inner..(n + 1) * inner];
                for i in 0..m {
                    let coefficient = a[n * m + i];
                    if coefficient == 0.0 {
                        continue;
                    }
                    for (o, s) in block_out[i * inner..(i + 1) * inner].iter_mut().zip(source) {
                        *o += coefficient * s;
                    }
                }
            }
        }
        std::mem::swap(tensor, &mut next);
    }
}

/// One sub-box in the branch and bound: its Bernstein coefficients (of the sign-adjusted
/// polynomial: we always minimise), their minimum, and how often each dimension was halved.
struct SubBox {
    coefficients: Vec<f64>,
    lower: f64,
    splits: Vec<u32>,
}

/// Bounds tensor surrogates by their Bernstein form; keeps the change-of-basis matrix of one order.
#[derive(Clone, Debug)]
pub struct BernsteinBounder {
    options: BernsteinOptions,
    order: Option<usize>,
    legendre_to_bernstein: Vec<f64>,
}

impl Default for BernsteinBounder {
    /// A bounder with [`BernsteinOptions::default`].
    fn default() -> Self {
        BernsteinBounder {
            options: BernsteinOptions::default(),
            order: None,
            legendre_to_bernstein: Vec::new(),
        }
    }
}

impl BernsteinBounder {
    /// A bounder with `options`.
    ///
    /// Errors: a tolerance that is not finite and ≥ 0 ([`UqError::InvalidInterval`]).
    pub fn new(options: BernsteinOptions) -> Result<BernsteinBounder, UqError> {
        if !(options.relative_tolerance.is_finite() && options.relative_tolerance >= 0.0) {
            return Err(UqError::InvalidInterval {
                index: 0,
                lo: options.relative_tolerance,
                hi: options.relative_tolerance,
            });
        }
        Ok(BernsteinBounder {
            options,
            order: None,
            legendre_to_bernstein: Vec::new(),
        })
    }

    /// The Bernstein coefficients of `surrogate` on `u ∈ [0, 1]^d` (dense, row-major, degree k per
    /// dimension).
    ///
    /// Errors: an order beyond [`BERNSTEIN_MAX_ORDER`].
    pub fn bernstein_coefficients(&mut self, surrogate: &Surrogate) -> Result<Vec<f64>, UqError> {
        let (dim, order) = (surrogate.dim(), surrogate.order());
        if self.order != Some(order) {
            self.legendre_to_bernstein = legendre_in_bernstein(order)?;
            self.order = Some(order);
        }
        let mut tensor = match surrogate.family() {
            Family::Legendre => surrogate.dense_coefficients().to_vec(),
            Family::Chebyshev => chebyshev_to_legendre(dim, order, surrogate.dense_coefficients())?,
        };
        change_basis(dim, order + 1, &self.legendre_to_bernstein, &mut tensor);
        Ok(tensor)
    }

    /// An outer bound of `surrogate`'s range on [−1, 1]^d, with the attained values found
    /// (docs/bernstein.md §3).
    ///
    /// ```
    /// use ribbon::uq::{BernsteinBounder, BernsteinOptions, Design, Family, Surrogate, Truncation};
    /// // ξ² − ξ/2 = 1/3 − ½ P_1 + ⅔ P_2: range [−1/16, 3/2].
    /// let design = Design::new(Family::Legendre, 1, 2, Truncation::Tensor)?;
    /// let s = Surrogate::from_terms(&design, &[1.0 / 3.0, -0.5, 2.0 / 3.0])?;
    /// let b = BernsteinBounder::new(BernsteinOptions::default())?.bound(&s)?;
    /// assert!(b.lower <= -1.0 / 16.0 && b.lower > -1.0 / 16.0 - 1e-5);
    /// assert!(b.upper >= 1.5 && b.upper < 1.5 + 1e-12);
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    ///
    /// Errors: an order beyond [`BERNSTEIN_MAX_ORDER`].
    pub fn bound(&mut self, surrogate: &Surrogate) -> Result<BernsteinBound, UqError> {
        let (dim, order) = (surrogate.dim(), surrogate.order());
        let root = self.bernstein_coefficients(surrogate)?;
        let scale = root.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
        let allowance =
            ROUNDING_ALLOWANCE_ULPS * f64::EPSILON * scale * ((dim + 1) * (order + 1)) as f64;
        let (lo, hi) = min_max(&root);
        let tolerance = self.options.relative_tolerance * (hi - lo);
        let (lower, attained_lower, splits_min, converged_min) =
            minimise(root.clone(), dim, order, tolerance, self.options.max_splits);
        let negated: Vec<f64> = root.iter().map(|b| -b).collect();
        let (neg_upper, neg_attained, splits_max, converged_max) =
            minimise(negated, dim, order, tolerance, self.options.max_splits);
        Ok(BernsteinBound {
            lower: lower - allowance,
            upper: -neg_upper + allowance,
            attained_lower,
            attained_upper: -neg_attained,
            splits: splits_min + splits_max,
            converged: converged_min && converged_max,
        })
    }
}

fn min_max(values: &[f64]) -> (f64, f64) {
    values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// The smallest corner coefficient (a value of the polynomial at a corner of the box).
fn best_corner(coefficients: &[f64], dim: usize, order: usize) -> f64 {
    let m = order + 1;
    let mut best = f64::INFINITY;
    for mask in 0..(1usize << dim) {
        let mut index = 0;
        for r in 0..dim {
            let digit = if mask >> (dim - 1 - r) & 1 == 1 {
                order
            } else {
                0
            };
            index = index * m + digit;
        }
        best = best.min(coefficients[index]);
    }
    best
}

/// Halves a box along dimension `r` (de Casteljau at ½ on every fibre along r): returns the
/// coefficients of the lower and upper halves.
fn split(coefficients: &[f64], dim: usize, order: usize, r: usize) -> (Vec<f64>, Vec<f64>) {
    let m = order + 1;
    let inner = m.pow((dim - 1 - r) as u32);
    let mut left = vec![0.0; coefficients.len()];
    let mut right = vec![0.0; coefficients.len()];
    let mut fibre = vec![0.0; m];
    for (block, (block_left, block_right)) in coefficients.chunks_exact(m * inner).zip(
        left.chunks_exact_mut(m * inner)
            .zip(right.chunks_exact_mut(m * inner)),
    ) {
        for offset in 0..inner {
            for (i, f) in fibre.iter_mut().enumerate() {
                *f = block[i * inner + offset];
            }
            // Level j of de Casteljau: fibre[0..m−j]; its first entry belongs to the left half
            // (index j), its last to the right half (index k − j).
            for j in 0..m {
                block_left[j * inner + offset] = fibre[0];
                block_right[(order - j) * inner + offset] = fibre[order - j];
                for i in 0..order - j {
                    fibre[i] = 0.5 * (fibre[i] + fibre[i + 1]);
                }
            }
        }
    }
    (left, right)
}

/// Branch and bound for the minimum of the polynomial with Bernstein coefficients `root`: returns
/// (outer lower bound, best attained value, splits, converged).
fn minimise(
    root: Vec<f64>,
    dim: usize,
    order: usize,
    tolerance: f64,
    max_splits: usize,
) -> (f64, f64, usize, bool) {
    let mut best = best_corner(&root, dim, order);
    let lower = min_max(&root).0;
    // Lowest lower bound of the boxes dropped because they could not improve on `best` by more
    // than the tolerance.
    let mut dropped_floor = f64::INFINITY;
    let mut live = vec![SubBox {
        coefficients: root,
        lower,
        splits: vec![0; dim],
    }];
    let mut splits = 0;
    let mut converged = false;
    loop {
        // Drop the boxes that cannot improve on `best` by more than the tolerance.
        live.retain(|b| {
            if b.lower >= best - tolerance {
                dropped_floor = dropped_floor.min(b.lower);
                false
            } else {
                true
            }
        });
        let Some(index) = live
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.lower.total_cmp(&b.1.lower))
            .map(|(i, _)| i)
        else {
            converged = true;
            break;
        };
        if splits >= max_splits {
            break;
        }
        let sub = live.swap_remove(index);
        // Halve the dimension halved least so far (ties: the first).
        let r = (0..dim).min_by_key(|&r| (sub.splits[r], r)).unwrap_or(0);
        let (left, right) = split(&sub.coefficients, dim, order, r);
        splits += 1;
        for coefficients in [left, right] {
            best = best.min(best_corner(&coefficients, dim, order));
            let mut child_splits = sub.splits.clone();
            child_splits[r] += 1;
            live.push(SubBox {
                lower: min_max(&coefficients).0,
                coefficients,
                splits: child_splits,
            });
        }
    }
    let live_floor = live.iter().fold(f64::INFINITY, |a, b| a.min(b.lower));
    (
        best.min(live_floor).min(dropped_floor),
        best,
        splits,
        converged,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::bounds::{interval_bound, RangeMode};
    use crate::uq::design::{Design, Truncation};
    use crate::uq::projection::Projector;
    use crate::uq::scan::{ScanOptions, Scanner};

    /// Tolerance of the tests against exact ranges: the bounder's own (1e-6 of the width) plus
    /// rounding.
    const RANGE_TOL: f64 = 2e-6;

    fn fit(family: Family, dim: usize, order: usize, f: impl Fn(&[f64]) -> f64) -> Surrogate {
        let design = Design::new(family, dim, order, Truncation::Tensor).unwrap();
        let projector = Projector::new(design.clone()).unwrap();
        let values: Vec<f64> = design.points().chunks_exact(dim).map(&f).collect();
        let matrix = projector.fit(&values, 1).unwrap();
        Surrogate::from_matrix(&design, &matrix, 0).unwrap()
    }

    #[test]
    fn bernstein_form_reproduces_the_polynomial() {
        let mut rng = SplitMix64::new(5);
        for family in [Family::Legendre, Family::Chebyshev] {
            let design = Design::new(family, 2, 5, Truncation::Tensor).unwrap();
            let c: Vec<f64> = (0..design.n_terms())
                .map(|_| rng.uniform(-1.0, 1.0))
                .collect();
            let s = Surrogate::from_terms(&design, &c).unwrap();
            let b = BernsteinBounder::new(BernsteinOptions::default())
                .unwrap()
                .bernstein_coefficients(&s)
                .unwrap();
            for xi in [[-0.3, 0.8], [1.0, -1.0], [0.0, 0.25]] {
                let u: Vec<f64> = xi.iter().map(|x| 0.5 * (x + 1.0)).collect();
                let basis = |u: f64, i: usize| {
                    let binomial = (0..i).fold(1.0, |a, j| a * (5 - j) as f64 / (j + 1) as f64);
                    binomial * u.powi(i as i32) * (1.0 - u).powi((5 - i) as i32)
                };
                let mut value = 0.0;
                for i in 0..6 {
                    for j in 0..6 {
                        value += b[i * 6 + j] * basis(u[0], i) * basis(u[1], j);
                    }
                }
                assert!(
                    (value - s.eval(&xi).unwrap()).abs() < 1e-13,
                    "{family:?} {xi:?}"
                );
            }
        }
        assert!(legendre_in_bernstein(BERNSTEIN_MAX_ORDER + 1).is_err());
    }

    #[test]
    fn known_polynomials_get_their_exact_ranges() {
        type Case = (&'static str, usize, usize, fn(&[f64]) -> f64, f64, f64);
        let cases: [Case; 5] = [
            // Interior minimum −1/16 at ξ = ¼; maximum 3/2 at ξ = −1.
            (
                "ξ² − ξ/2",
                1,
                2,
                |x| x[0] * x[0] - 0.5 * x[0],
                -1.0 / 16.0,
                1.5,
            ),
            // A saddle: range [−1, 1] at the corners.
            ("ξ1 ξ2", 2, 1, |x| x[0] * x[1], -1.0, 1.0),
            // Interior minimum 0 at (0.3, −0.2); maximum at (−1, 1): 1.69 + 2·1.44.
            (
                "(ξ1 − 0.3)² + 2(ξ2 + 0.2)²",
                2,
                2,
                |x| (x[0] - 0.3).powi(2) + 2.0 * (x[1] + 0.2).powi(2),
                0.0,
                1.69 + 2.0 * 1.44,
            ),
            // T_4 = 8ξ⁴ − 8ξ² + 1: range [−1, 1], minima at ξ = ±1/√2 inside.
            (
                "T_4(ξ1) + ξ2³",
                2,
                4,
                |x| 8.0 * x[0].powi(4) - 8.0 * x[0] * x[0] + 1.0 + x[1].powi(3),
                -2.0,
                2.0,
            ),
            // (ξ1² − ½)(ξ2² − ½) ∈ [−¼, ¼] and ξ3 + 2 ∈ [1, 3]: min −¾ at (±1, 0, 1), max ¾ at
            // (0, 0, 1) and (±1, ±1, 1).
            (
                "(ξ1² − ½)(ξ2² − ½)(ξ3 + 2)",
                3,
                2,
                |x| (x[0] * x[0] - 0.5) * (x[1] * x[1] - 0.5) * (x[2] + 2.0),
                -0.75,
                0.75,
            ),
        ];
        for (name, dim, order, f, lo, hi) in cases {
            for family in [Family::Legendre, Family::Chebyshev] {
                let s = fit(family, dim, order, f);
                let mut bounder = BernsteinBounder::new(BernsteinOptions::default()).unwrap();
                let b = bounder.bound(&s).unwrap();
                let width = hi - lo;
                assert!(
                    b.lower <= lo && b.upper >= hi,
                    "{name} {family:?}: [{}, {}] does not contain [{lo}, {hi}]",
                    b.lower,
                    b.upper
                );
                assert!(
                    lo - b.lower < RANGE_TOL * width && b.upper - hi < RANGE_TOL * width,
                    "{name} {family:?}: [{}, {}] vs [{lo}, {hi}]",
                    b.lower,
                    b.upper
                );
                assert!(b.attained_lower >= lo - 1e-12 && b.attained_upper <= hi + 1e-12);
                assert!(
                    b.converged && b.gap() <= RANGE_TOL * width,
                    "{name}: gap {}",
                    b.gap()
                );
                // Never looser than interval arithmetic with exact P_n ranges.
                if family == Family::Legendre {
                    let ia = interval_bound(&s, RangeMode::Exact).unwrap();
                    assert!(b.lower >= ia.lower - 1e-12 && b.upper <= ia.upper + 1e-12);
                }
            }
        }
    }

    #[test]
    fn random_surrogates_contain_the_scan_and_close_on_it() {
        let mut rng = SplitMix64::new(17);
        for (dim, order) in [(1, 6), (2, 4), (3, 3), (4, 2)] {
            let design = Design::new(Family::Legendre, dim, order, Truncation::Tensor).unwrap();
            // Decaying coefficients, like a fitted smooth response.
            let mut digits = vec![0usize; dim];
            let c: Vec<f64> = (0..design.n_terms())
                .map(|t| {
                    design.multi_index_into(t, &mut digits).unwrap();
                    let degree: usize = digits.iter().sum();
                    rng.uniform(-1.0, 1.0) * 0.5_f64.powi(degree as i32)
                })
                .collect();
            let s = Surrogate::from_terms(&design, &c).unwrap();
            let b = BernsteinBounder::new(BernsteinOptions::default())
                .unwrap()
                .bound(&s)
                .unwrap();
            let mut scanner =
                Scanner::new(Family::Legendre, dim, order, ScanOptions::for_dim(dim)).unwrap();
            let scan = scanner.scan(&s).unwrap().bound;
            let width = scan.upper - scan.lower;
            assert!(b.lower <= scan.lower && b.upper >= scan.upper, "d {dim}");
            let gap = (scan.lower - b.lower).max(b.upper - scan.upper);
            assert!(
                gap < 1e-5 * width,
                "d {dim}: gap to the scan {gap} of {width}"
            );
            let ia = interval_bound(&s, RangeMode::Exact).unwrap();
            assert!(ia.upper - ia.lower >= b.upper - b.lower - 1e-12);
        }
    }

    #[test]
    fn a_spent_budget_still_gives_an_outer_bound() {
        let s = fit(Family::Legendre, 2, 8, |x| {
            (3.0 * x[0]).sin() * (2.0 * x[1]).cos()
        });
        let options = BernsteinOptions {
            relative_tolerance: 0.0,
            max_splits: 3,
        };
        let b = BernsteinBounder::new(options).unwrap().bound(&s).unwrap();
        assert!(!b.converged);
        assert_eq!(b.splits, 6);
        let mut scanner = Scanner::new(Family::Legendre, 2, 8, ScanOptions::for_dim(2)).unwrap();
        let scan = scanner.scan(&s).unwrap().bound;
        assert!(b.lower <= scan.lower && b.upper >= scan.upper);
        assert!(b.attained_lower >= scan.lower - 1e-12 && b.attained_upper <= scan.upper + 1e-12);
        assert!(BernsteinBounder::new(BernsteinOptions {
            relative_tolerance: f64::NAN,
            max_splits: 1
        })
        .is_err());
    }
}
