//! Scanning a surrogate (docs/method.md §3b): evaluate it on a uniform grid of `N` points per dimension
//! (odd, endpoints included, so the centre is on it), take min / max, then refine locally from the
//! best few grid points with projected Newton (`refine.rs`). The result is an **inner**
//! bound of the surrogate's range: every number in it is a value the surrogate attains.
//!
//! Grid evaluation is by sum factorisation: the coefficient tensor (shape `m^d`, m = k + 1) is
//! multiplied by the `N × m` basis matrix along one axis at a time, last axis first, so the largest
//! stage (`N^d · m` multiply-adds) runs as axpys over contiguous `N^{d−1}`-long slices. Cost per
//! output ≈ `m (N^d + m N^{d−1} + …)`: for d = 4, k = 4, N = 11 about 1.3e5 multiply-adds.
//!
//! Start points: discrete local minima (no smaller value among the 2d axis neighbours) whose value
//! lies within [`CANDIDATE_BAND`] of the grid range above the grid minimum, best first, at most
//! [`ScanOptions::max_starts`]; the same for maxima.
//!
//! Does not: scan the true model (that is the reference method, run by the caller).

use crate::uq::basis::{Family, MAX_ORDER};
use crate::uq::bounds::{Bound, BoundKind};
use crate::uq::design::{checked_grid_size, decode_multi_index, MAX_TENSOR_SIZE};
use crate::uq::error::UqError;
use crate::uq::refine::{refine, RefineWorkspace};
use crate::uq::surrogate::Surrogate;
use crate::uq::tensor_contraction::{apply_axis, PointEvaluator};

/// Grid points per dimension by default for d ≤ 2 (docs/method.md §3b: odd so that ξ = 0 and the
/// midpoints ±½ are on it; 21 catches the ξ + ξ² minimum at −½ exactly).
pub const DEFAULT_POINTS_LOW_DIM: usize = 21;

/// Grid points per dimension by default for d ≥ 3: 21^d grows too fast (21^4 ≈ 1.9e5 points per
/// output); with refinement, 11 finds the same extrema on smooth surrogates.
pub const DEFAULT_POINTS_HIGH_DIM: usize = 11;

/// A grid local extremum is a refinement start if it is within this fraction of the grid range of
/// the grid extremum: generous against the grid's discretisation error (≈ h²/8 · |y''|, about 4 %
/// of the range for `cos 4ξ` at N = 11), so a basin whose grid value is slightly worse but whose
/// true extremum is better still gets refined.
pub const CANDIDATE_BAND: f64 = 0.1;

/// Grid values examined together when looking for refinement starts (a multiple of the 4-lane
/// min / max; large enough to amortise the block test, small enough to skip most of the grid).
const BLOCK: usize = 32;

/// Options of a surrogate scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScanOptions {
    /// Grid points per dimension, odd ≥ 3, endpoints included. Default: [`DEFAULT_POINTS_LOW_DIM`]
    /// for d ≤ 2, [`DEFAULT_POINTS_HIGH_DIM`] for d ≥ 3 ([`ScanOptions::for_dim`]).
    pub points_per_dim: usize,
    /// Refinement starts per extremum (0 = grid only). Default 3: the grid's best basin plus two
    /// runners-up in case the grid misjudged which basin is best.
    pub max_starts: usize,
    /// Newton iterations per start. Default 30 (quadratic convergence needs 3–6 from a grid point).
    pub max_newton_iterations: usize,
}

impl ScanOptions {
    /// The default options for `dim` parameters (grid size by the rule above).
    pub fn for_dim(dim: usize) -> ScanOptions {
        ScanOptions {
            points_per_dim: if dim <= 2 {
                DEFAULT_POINTS_LOW_DIM
            } else {
                DEFAULT_POINTS_HIGH_DIM
            },
            ..ScanOptions::default()
        }
    }
}

impl Default for ScanOptions {
    /// 21 points per dimension, 3 starts, 30 Newton iterations.
    fn default() -> ScanOptions {
        ScanOptions {
            points_per_dim: DEFAULT_POINTS_LOW_DIM,
            max_starts: 3,
            max_newton_iterations: 30,
        }
    }
}

/// The result of scanning one surrogate.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanOutcome {
    /// Inner bound of the surrogate's range (after refinement).
    pub bound: Bound,
    /// Smallest grid value (before refinement).
    pub grid_lower: f64,
    /// Largest grid value (before refinement).
    pub grid_upper: f64,
    /// Where the surrogate takes `bound.lower` (standard coordinates, length d): a good place for
    /// an extra model run to check the surrogate.
    pub argmin: Vec<f64>,
    /// Where the surrogate takes `bound.upper`.
    pub argmax: Vec<f64>,
}

/// Scans surrogates of one family, dimension and order: precomputed grid basis plus work buffers
/// (reuse one per thread).
#[derive(Debug, Clone)]
pub struct Scanner {
    family: Family,
    dim: usize,
    order: usize,
    options: ScanOptions,
    /// 1-D grid coordinates, ascending, exactly −1, 0, 1 at the ends and centre.
    grid: Vec<f64>,
    /// `N × m` row-major: `basis[a·m + j] = φ_j(grid[a])`.
    basis: Vec<f64>,
    stage_a: Vec<f64>,
    stage_b: Vec<f64>,
    /// Grid values, `N^d`, row-major (ξ_1 slowest).
    values: Vec<f64>,
    evaluator: PointEvaluator,
    refine_ws: RefineWorkspace,
    /// Grid strides: `strides[r] = N^{d−1−r}`.
    strides: Vec<usize>,
    starts_min: Vec<(f64, usize)>,
    starts_max: Vec<(f64, usize)>,
    index: Vec<usize>,
    point: Vec<f64>,
}

/// Largest number of points of a scan grid (and of its intermediate tensors): 2²² ≈ 4.2 M, i.e.
/// three work buffers of 32 MiB. d = 6 at N = 11 is 1.8 M.
pub const MAX_SCAN_POINTS: usize = MAX_TENSOR_SIZE;

impl Scanner {
    /// A scanner for surrogates of `family`, `dim` parameters, order `order`.
    ///
    /// Errors: `dim == 0`, `order > MAX_ORDER`, an even or < 3 grid size, a grid (or intermediate
    /// tensor) larger than [`MAX_SCAN_POINTS`].
    pub fn new(
        family: Family,
        dim: usize,
        order: usize,
        options: ScanOptions,
    ) -> Result<Scanner, UqError> {
        if dim == 0 {
            return Err(UqError::ZeroDimension);
        }
        if order > MAX_ORDER {
            return Err(UqError::OrderTooLarge {
                order,
                max: MAX_ORDER,
            });
        }
        let n = options.points_per_dim;
        if n < 3 || n.is_multiple_of(2) {
            return Err(UqError::InvalidScanGrid { points: n });
        }
        let m = order + 1;
        let n_values = checked_grid_size("scan grid", n, dim, MAX_SCAN_POINTS)?;
        // Intermediate tensors after contracting the last d − r axes: m^r · N^{d−r}.
        let mut stage_len = 0;
        for r in 1..dim {
            let a = checked_grid_size("scan stage", m, r, MAX_SCAN_POINTS)?;
            let b = checked_grid_size("scan stage", n, dim - r, MAX_SCAN_POINTS)?;
            stage_len = a
                .checked_mul(b)
                .filter(|&s| s <= MAX_SCAN_POINTS)
                .ok_or(UqError::GridTooLarge {
                    what: "scan stage",
                    per_dim: m.max(n),
                    dim,
                    max: MAX_SCAN_POINTS,
                })?
                .max(stage_len);
        }
        let half = (n - 1) as f64;
        let grid: Vec<f64> = (0..n).map(|a| (2.0 * a as f64 - half) / half).collect();
        let mut basis = vec![0.0; n * m];
        for (row, &x) in basis.chunks_exact_mut(m).zip(&grid) {
            family.values(x, row);
        }
        Ok(Scanner {
            family,
            dim,
            order,
            options,
            grid,
            basis,
            stage_a: vec![0.0; stage_len],
            stage_b: vec![0.0; stage_len],
            values: vec![0.0; n_values],
            evaluator: PointEvaluator::new(family, dim, order),
            refine_ws: RefineWorkspace::new(dim),
            strides: (0..dim).map(|r| n.pow((dim - 1 - r) as u32)).collect(),
            starts_min: Vec::with_capacity(options.max_starts + 1),
            starts_max: Vec::with_capacity(options.max_starts + 1),
            index: vec![0; dim],
            point: vec![0.0; dim],
        })
    }

    /// The options this scanner was built with.
    pub fn options(&self) -> &ScanOptions {
        &self.options
    }

    /// The 1-D grid coordinates (ascending, N points from −1 to 1).
    pub fn grid(&self) -> &[f64] {
        &self.grid
    }

    /// Grid values of the last scanned surrogate: `N^d`, row-major (ξ_1 slowest).
    pub fn grid_values(&self) -> &[f64] {
        &self.values
    }

    /// Scans `surrogate` (which must match the scanner's family, dimension and order): grid, then
    /// refinement. Kind [`BoundKind::Inner`], error estimate of the surrogate.
    ///
    /// ```
    /// use ribbon::uq::{Design, Family, ScanOptions, Scanner, Surrogate, Truncation};
    /// // ξ + ξ² = 1/3 + P_1 + 2/3 P_2 has range [−0.25, 2] (docs/method.md §3).
    /// let design = Design::new(Family::Legendre, 1, 2, Truncation::Tensor)?;
    /// let s = Surrogate::from_terms(&design, &[1.0 / 3.0, 1.0, 2.0 / 3.0])?;
    /// let mut scanner = Scanner::new(Family::Legendre, 1, 2, ScanOptions::for_dim(1))?;
    /// let out = scanner.scan(&s)?;
    /// assert!((out.bound.lower + 0.25).abs() < 1e-12 && (out.bound.upper - 2.0).abs() < 1e-12);
    /// assert!((out.argmin[0] + 0.5).abs() < 1e-9);
    /// # Ok::<(), ribbon::uq::UqError>(())
    /// ```
    pub fn scan(&mut self, surrogate: &Surrogate) -> Result<ScanOutcome, UqError> {
        if surrogate.family() != self.family
            || surrogate.dim() != self.dim
            || surrogate.order() != self.order
        {
            return Err(UqError::SurrogateMismatch {
                what: "scanner",
                expected_family: self.family,
                expected_dim: self.dim,
                expected_order: self.order,
                got_family: surrogate.family(),
                got_dim: surrogate.dim(),
                got_order: surrogate.order(),
            });
        }
        let coef = surrogate.dense_coefficients();
        self.evaluate_grid(coef);
        let (grid_lower, grid_upper) = min_max(&self.values);

        let mut argmin = vec![0.0; self.dim];
        let mut argmax = vec![0.0; self.dim];
        self.collect_starts(grid_lower, grid_upper);
        let lower = self.refine_extremum(coef, 1.0, grid_lower, &mut argmin);
        let upper = self.refine_extremum(coef, -1.0, grid_upper, &mut argmax);
        Ok(ScanOutcome {
            bound: Bound {
                lower,
                upper,
                kind: BoundKind::Inner,
                error: surrogate.error_estimate(),
            },
            grid_lower,
            grid_upper,
            argmin,
            argmax,
        })
    }

    /// Fills `self.values` with the surrogate on the grid by sum factorisation.
    fn evaluate_grid(&mut self, coef: &[f64]) {
        let (d, m, n) = (self.dim, self.order + 1, self.options.points_per_dim);
        if d == 1 {
            apply_axis(coef, 1, m, 1, &self.basis, n, &mut self.values);
            return;
        }
        // Contract axis r = d−1, …, 0: shape m^r × m × N^{d−1−r} → m^r × N × N^{d−1−r}.
        let mut input_is_a = false;
        for r in (0..d).rev() {
            let outer = m.pow(r as u32);
            let inner = n.pow((d - 1 - r) as u32);
            let in_len = outer * m * inner;
            let out_len = outer * n * inner;
            let (input, output): (&[f64], &mut [f64]) = if r == d - 1 {
                (coef, &mut self.stage_a[..out_len])
            } else if r == 0 {
                let src = if input_is_a {
                    &self.stage_a
                } else {
                    &self.stage_b
                };
                (&src[..in_len], &mut self.values[..])
            } else if input_is_a {
                (&self.stage_a[..in_len], &mut self.stage_b[..out_len])
            } else {
                (&self.stage_b[..in_len], &mut self.stage_a[..out_len])
            };
            apply_axis(input, outer, m, inner, &self.basis, n, output);
            input_is_a = if r == d - 1 { true } else { !input_is_a };
        }
    }

    /// Fills `starts_min` / `starts_max` with (signed value, grid index) of the best discrete local
    /// minima of `y` / of `−y` within the candidate band, best first.
    ///
    /// One pass over the grid in blocks of [`BLOCK`] contiguous values: a branch-free min / max
    /// (independent lanes, vectorisable) skips blocks that miss both bands; in the others a point
    /// must beat the band and its two neighbours along the last axis before the other axes are
    /// looked at. Most of the grid costs about one vector compare per point.
    fn collect_starts(&mut self, grid_lower: f64, grid_upper: f64) {
        let (d, n) = (self.dim, self.options.points_per_dim);
        let band = CANDIDATE_BAND * (grid_upper - grid_lower);
        let (cut_low, cut_high) = (grid_lower + band, grid_upper - band);
        let keep = self.options.max_starts.max(1);
        let values = &self.values;
        let strides = &self.strides;
        let index = &mut self.index;
        self.starts_min.clear();
        self.starts_max.clear();
        let mut lists = [(1.0, &mut self.starts_min), (-1.0, &mut self.starts_max)];
        for (block_number, block) in values.chunks(BLOCK).enumerate() {
            let (block_min, block_max) = min_max(block);
            if block_min > cut_low && block_max < cut_high {
                continue;
            }
            let base = block_number * BLOCK;
            for (sign, list) in lists.iter_mut() {
                let sign = *sign;
                let (block_best, cutoff) = if sign > 0.0 {
                    (block_min, cut_low)
                } else {
                    (-block_max, -cut_high)
                };
                if block_best > cutoff {
                    continue;
                }
                let mut j = base % n; // position along the last axis
                for (offset, &v) in block.iter().enumerate() {
                    let p = base + offset;
                    let s = sign * v;
                    let reject = s > cutoff
                        || (list.len() == keep && s >= list[keep - 1].0)
                        || (j > 0 && sign * values[p - 1] < s)
                        || (j + 1 < n && sign * values[p + 1] < s);
                    j = if j + 1 == n { 0 } else { j + 1 };
                    if reject {
                        continue;
                    }
                    decode_multi_index(p, n, index);
                    let is_local = (0..d - 1).all(|r| {
                        let (i, stride) = (index[r], strides[r]);
                        (i == 0 || sign * values[p - stride] >= s)
                            && (i + 1 == n || sign * values[p + stride] >= s)
                    });
                    if is_local {
                        let pos = list.partition_point(|&(q, _)| q <= s);
                        list.insert(pos, (s, p));
                        list.truncate(keep);
                    }
                }
            }
        }
    }

    /// Best value of `sign · y` after refining from the collected starts (`sign` = +1: minimum,
    /// −1: maximum); writes its location into `at`. Returns the unsigned value.
    fn refine_extremum(&mut self, coef: &[f64], sign: f64, grid_best: f64, at: &mut [f64]) -> f64 {
        let mut starts = std::mem::take(if sign > 0.0 {
            &mut self.starts_min
        } else {
            &mut self.starts_max
        });
        // The grid's best point is a discrete local extremum, so `starts` is never empty.
        let mut best = sign * grid_best;
        if let Some(&(_, p)) = starts.first() {
            self.grid_point(p, at);
        }
        let mut x = std::mem::take(&mut self.point);
        for &(_, p) in starts.iter().take(self.options.max_starts) {
            self.grid_point(p, &mut x);
            let y = refine(
                &mut self.evaluator,
                coef,
                sign,
                &mut x,
                self.options.max_newton_iterations,
                &mut self.refine_ws,
            );
            if sign * y < best {
                best = sign * y;
                at.copy_from_slice(&x);
            }
        }
        self.point = x;
        starts.clear();
        if sign > 0.0 {
            self.starts_min = starts;
        } else {
            self.starts_max = starts;
        }
        sign * best
    }

    fn grid_point(&mut self, p: usize, x: &mut [f64]) {
        decode_multi_index(p, self.options.points_per_dim, &mut self.index);
        for (x, &i) in x.iter_mut().zip(&self.index) {
            *x = self.grid[i];
        }
    }
}

/// `(min, max)` of a non-empty slice, in 4 independent lanes (vectorisable).
fn min_max(v: &[f64]) -> (f64, f64) {
    let mut lo = [f64::INFINITY; 4];
    let mut hi = [f64::NEG_INFINITY; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for l in 0..4 {
            lo[l] = if c[l] < lo[l] { c[l] } else { lo[l] };
            hi[l] = if c[l] > hi[l] { c[l] } else { hi[l] };
        }
    }
    for &x in rest {
        lo[0] = lo[0].min(x);
        hi[0] = hi[0].max(x);
    }
    (
        lo.iter().copied().fold(f64::INFINITY, f64::min),
        hi.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;
    use crate::uq::bounds::{chebyshev_inclusion, interval_bound, RangeMode};
    use crate::uq::design::{Design, Truncation};
    use crate::uq::projection::Projector;

    /// Interval arithmetic on exactly representable coefficients: a few ulp.
    const IA_TOL: f64 = 1e-12;
    /// Scan after Newton refinement (the brief's requirement for the worked example).
    const SCAN_TOL: f64 = 1e-9;

    fn fit(
        family: Family,
        dim: usize,
        order: usize,
        truncation: Truncation,
        f: &dyn Fn(&[f64]) -> f64,
    ) -> Surrogate {
        let design = Design::new(family, dim, order, truncation).unwrap();
        let values: Vec<f64> = design.points().chunks_exact(dim).map(f).collect();
        let p = Projector::new(design).unwrap();
        let c = p.fit(&values, 1).unwrap();
        Surrogate::from_matrix(p.design(), &c, 0).unwrap()
    }

    /// Brute-force min / max of a surrogate on a dense uniform grid.
    fn dense_range(s: &Surrogate, per_dim: usize) -> (f64, f64) {
        let d = s.dim();
        let total = per_dim.pow(d as u32);
        let mut idx = vec![0; d];
        let mut x = vec![0.0; d];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut ev = PointEvaluator::new(s.family(), d, s.order());
        for p in 0..total {
            decode_multi_index(p, per_dim, &mut idx);
            for (x, &i) in x.iter_mut().zip(&idx) {
                *x = -1.0 + 2.0 * i as f64 / (per_dim - 1) as f64;
            }
            let v = ev.value(s.dense_coefficients(), &x);
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (lo, hi)
    }

    #[test]
    fn worked_example_every_method() {
        let y = |x: &[f64]| x[0] + x[0] * x[0];
        // Legendre: 1/3 + P_1 + 2/3 P_2.
        let s = fit(Family::Legendre, 1, 2, Truncation::Tensor, &y);
        let crude = interval_bound(&s, RangeMode::Crude).unwrap();
        assert!((crude.lower + 4.0 / 3.0).abs() < IA_TOL && (crude.upper - 2.0).abs() < IA_TOL);
        let exact = interval_bound(&s, RangeMode::Exact).unwrap();
        assert!((exact.lower + 1.0).abs() < IA_TOL && (exact.upper - 2.0).abs() < IA_TOL);
        assert_eq!(exact.kind, BoundKind::Outer);
        for points in [21, 11, 3] {
            let opts = ScanOptions {
                points_per_dim: points,
                ..ScanOptions::default()
            };
            let out = Scanner::new(Family::Legendre, 1, 2, opts)
                .unwrap()
                .scan(&s)
                .unwrap();
            assert!((out.bound.lower + 0.25).abs() < SCAN_TOL, "N = {points}");
            assert!((out.bound.upper - 2.0).abs() < SCAN_TOL);
            assert_eq!(out.bound.kind, BoundKind::Inner);
        }
        // Grid only: 21 points hit ξ = −½ exactly; 11 points do not (−0.24 at ξ = −0.4 or −0.6).
        let grid_only = |points| {
            let opts = ScanOptions {
                points_per_dim: points,
                max_starts: 0,
                ..ScanOptions::default()
            };
            let mut sc = Scanner::new(Family::Legendre, 1, 2, opts).unwrap();
            sc.scan(&s).unwrap().bound.lower
        };
        assert!((grid_only(21) + 0.25).abs() < 1e-15);
        assert!((grid_only(11) + 0.24).abs() < 1e-15);

        // Chebyshev: 1/2 + T_1 + 1/2 T_2.
        let c = fit(Family::Chebyshev, 1, 2, Truncation::Tensor, &y);
        let inc = chebyshev_inclusion(&c).unwrap();
        assert!((inc.lower + 1.0).abs() < IA_TOL && (inc.upper - 2.0).abs() < IA_TOL);
        let out = Scanner::new(Family::Chebyshev, 1, 2, ScanOptions::for_dim(1))
            .unwrap()
            .scan(&c)
            .unwrap();
        assert!(
            (out.bound.lower + 0.25).abs() < SCAN_TOL && (out.bound.upper - 2.0).abs() < SCAN_TOL
        );
    }

    /// `cos(0.8ξ1 + 0.3)·cos(0.6ξ2 − 0.2)·cos(0.5ξ3 + 0.1)`. Each factor's argument range contains
    /// 0 and stays inside (−π/2, π/2): factor ranges [cos 1.1, 1], [cos 0.8, 1], [cos 0.6, 1], all
    /// positive, so the product's range is [cos 1.1 · cos 0.8 · cos 0.6, 1]; the maximum is interior
    /// (ξ = (−0.375, 1/3, −0.2)), the minimum at the corner (1, −1, 1).
    fn cos_product(x: &[f64]) -> f64 {
        (0.8 * x[0] + 0.3).cos() * (0.6 * x[1] - 0.2).cos() * (0.5 * x[2] + 0.1).cos()
    }

    #[test]
    fn smooth_three_parameter_function_known_range() {
        /// At k = 8 (tensor) the surrogate error is ~1e-9 (measured: 8e-10), far below this.
        const RANGE_TOL: f64 = 1e-6;
        let true_range = (1.1f64.cos() * 0.8f64.cos() * 0.6f64.cos(), 1.0);
        for family in [Family::Legendre, Family::Chebyshev] {
            for truncation in [Truncation::Tensor, Truncation::Total] {
                let s = fit(family, 3, 8, truncation, &cos_product);
                // Total degree 8 drops mixed terms such as P_3 P_3 P_3 (measured error 7e-6 at the
                // corner): there the bound must be within the surrogate's own error estimate.
                let tol = match truncation {
                    Truncation::Tensor => RANGE_TOL,
                    Truncation::Total => s.error_estimate().top_order,
                };
                for points in [11, 21, 5] {
                    let opts = ScanOptions {
                        points_per_dim: points,
                        ..ScanOptions::for_dim(3)
                    };
                    let out = Scanner::new(family, 3, 8, opts).unwrap().scan(&s).unwrap();
                    let b = out.bound;
                    assert!(
                        (b.lower - true_range.0).abs() < tol
                            && (b.upper - true_range.1).abs() < tol,
                        "{family:?} {truncation:?} N={points}: [{}, {}]",
                        b.lower,
                        b.upper
                    );
                    let at_max = [-0.375, 1.0 / 3.0, -0.2];
                    for (a, e) in out.argmax.iter().zip(at_max) {
                        assert!((a - e).abs() < 1e-3, "{:?}", out.argmax);
                    }
                    assert_eq!(out.argmin, vec![1.0, -1.0, 1.0]);
                }
                for mode in [RangeMode::Crude, RangeMode::Exact] {
                    let ia = interval_bound(&s, mode).unwrap();
                    assert!(ia.lower <= true_range.0 && ia.upper >= true_range.1);
                }
            }
        }
    }

    #[test]
    fn refinement_matches_dense_scan_with_several_basins() {
        // Several local minima and maxima of similar depth; 2-D, k = 12.
        let f =
            |x: &[f64]| (3.0 * x[0]).sin() * (2.5 * x[1] + 0.3).sin() + 0.05 * x[0] - 0.02 * x[1];
        for family in [Family::Legendre, Family::Chebyshev] {
            let s = fit(family, 2, 12, Truncation::Tensor, &f);
            let (lo, hi) = dense_range(&s, 2001);
            for points in [21, 11, 7] {
                let opts = ScanOptions {
                    points_per_dim: points,
                    ..ScanOptions::default()
                };
                let b = Scanner::new(family, 2, 12, opts)
                    .unwrap()
                    .scan(&s)
                    .unwrap()
                    .bound;
                // The refined scan must be at least as good as the dense grid, and the dense grid
                // (spacing 1e-3) is within ~|y''| h²/8 ≈ 2e-6 of the true surrogate extremum.
                assert!(b.lower <= lo + 1e-14 && b.lower > lo - 1e-5, "N={points}");
                assert!(b.upper >= hi - 1e-14 && b.upper < hi + 1e-5, "N={points}");
            }
        }
    }

    #[test]
    fn four_parameter_scan_matches_dense_scan() {
        let mut rng = SplitMix64::new(42);
        for _ in 0..3 {
            let a: Vec<f64> = (0..4).map(|_| rng.uniform(0.5, 1.5)).collect();
            let b: Vec<f64> = (0..4).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let f = |x: &[f64]| {
                (a[0] * x[0] + b[0]).sin() * (a[1] * x[1] + b[1]).cos()
                    + (a[2] * x[2] * x[3] + b[2]).sin()
                    + b[3] * x[3] * x[3]
            };
            for truncation in [Truncation::Tensor, Truncation::Total] {
                let s = fit(Family::Legendre, 4, 4, truncation, &f);
                let (lo, hi) = dense_range(&s, 41);
                let b = Scanner::new(Family::Legendre, 4, 4, ScanOptions::for_dim(4))
                    .unwrap()
                    .scan(&s)
                    .unwrap()
                    .bound;
                // Dense spacing 0.05 ⇒ its error ≲ 1e-3; the refined scan must not be worse.
                assert!(
                    b.lower <= lo + 1e-14 && b.lower > lo - 2e-3,
                    "{b:?} vs {lo}"
                );
                assert!(
                    b.upper >= hi - 1e-14 && b.upper < hi + 2e-3,
                    "{b:?} vs {hi}"
                );
            }
        }
    }

    #[test]
    fn scanner_refuses_mismatch_and_bad_grids() {
        assert!(matches!(
            Scanner::new(
                Family::Legendre,
                2,
                4,
                ScanOptions {
                    points_per_dim: 20,
                    ..Default::default()
                }
            ),
            Err(UqError::InvalidScanGrid { points: 20 })
        ));
        assert!(matches!(
            Scanner::new(
                Family::Legendre,
                8,
                4,
                ScanOptions {
                    points_per_dim: 21,
                    ..Default::default()
                }
            ),
            Err(UqError::GridTooLarge { .. })
        ));
        let s = fit(Family::Chebyshev, 2, 3, Truncation::Tensor, &|x| x[0]);
        let mut sc = Scanner::new(Family::Legendre, 2, 3, ScanOptions::default()).unwrap();
        assert!(matches!(
            sc.scan(&s),
            Err(UqError::SurrogateMismatch { .. })
        ));
    }

    #[test]
    fn constant_surrogate_scans_to_its_value() {
        let s = fit(Family::Legendre, 3, 2, Truncation::Tensor, &|_| 2.5);
        let out = Scanner::new(Family::Legendre, 3, 2, ScanOptions::for_dim(3))
            .unwrap()
            .scan(&s)
            .unwrap();
        assert!((out.bound.lower - 2.5).abs() < 1e-14 && (out.bound.upper - 2.5).abs() < 1e-14);
    }
}
