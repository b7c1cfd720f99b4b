//! Small dense factorisations done in place in preallocated storage, so that a time step allocates
//! nothing (nalgebra's `LU::new` / `Cholesky::new` take their matrix by value).
//!
//! Sizes here are `nv + m ≤ ~50`: a plain right-looking LU with partial pivoting and a plain
//! Cholesky (the crate's ones, [`crate::linalg::lu`] and [`crate::linalg::cholesky`]) are as fast
//! as anything for these sizes and keep the workspace explicit.

use nalgebra::{DMatrix, DVector};

use crate::linalg::{cholesky, lu};

/// A pivot smaller than this fraction of the matrix's largest entry (for a Cholesky factorisation:
/// its largest diagonal entry, the same for the positive-definite matrices it accepts) means
/// "singular to working precision". A matrix that close to singular (condition ≳ 1e13) leaves no correct digits at the
/// Newton tolerances we use, and dependent constraint rows give pivots at the 1e-16 rounding level,
/// well below it.
pub const SINGULAR_PIVOT_RELATIVE: f64 = 1e-13;

/// Where a factorisation broke down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Breakdown {
    /// Elimination step (row) at which the pivot was too small.
    pub index: usize,
    /// |pivot| / max |entry| (for Cholesky: the diagonal before its square root, relative).
    pub pivot_relative: f64,
}

/// Which factorisation a [`DenseSolver`] uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FactorKind {
    /// LU with partial pivoting: general square matrices (the full Newton matrix, impacts).
    Lu,
    /// Cholesky `L Lᵀ`: symmetric positive definite matrices (the Newton matrix of a tree).
    Cholesky,
    /// A symmetric saddle-point matrix `[A Bᵀ; B 0]` whose last `constraint_rows` rows are `B`
    /// (the Newton matrix, the velocity projection and the consistent start with constraint rows):
    /// factorised through `A`'s Cholesky factor and the Schur complement `B A⁻¹ Bᵀ`
    /// (docs/method.md §5, "Solving the saddle-point system"); by LU when `A` is not positive
    /// definite.
    SaddlePoint {
        /// `m`, the rows of `B`.
        constraint_rows: usize,
    },
}

/// An `n × n` factorisation held in preallocated storage.
#[derive(Debug, Clone)]
pub(crate) struct DenseSolver {
    factors: DMatrix<f64>,
    pivots: Vec<usize>,
    kind: FactorKind,
    /// [`FactorKind::SaddlePoint`]: `A`'s Cholesky factor `L` (`nv²`, column-major), `Y = L⁻¹ Bᵀ`
    /// (`nv · m`, column `r` for row `r` of `B`) and the Schur complement's factor `L_S` (`m²`);
    /// empty for the other kinds.
    blocks: Vec<f64>,
    /// [`FactorKind::SaddlePoint`]: the last factorisation is an LU of the whole matrix in
    /// `factors` (`A` was not positive definite).
    whole_by_lu: bool,
    /// [`FactorKind::SaddlePoint`]: `blocks` hold the Cholesky factor of the `A` that
    /// [`DenseSolver::factor_blocks`] was last handed without a diagonal, or with a zero one
    /// (`A` = its `mass`), so [`DenseSolver::refactor_constraint_rows`] can keep it.
    holds_mass_factor: bool,
}

impl DenseSolver {
    /// Storage for `n × n` systems (the only allocation).
    pub fn new(n: usize, kind: FactorKind) -> Self {
        let blocks = match kind {
            FactorKind::SaddlePoint { constraint_rows: m } => {
                assert!(
                    m <= n,
                    "DenseSolver: {m} constraint rows in a {n} × {n} matrix"
                );
                vec![0.0; (n - m) * (n - m) + (n - m) * m + m * m]
            }
            FactorKind::Lu | FactorKind::Cholesky => Vec::new(),
        };
        Self {
            factors: DMatrix::zeros(n, n),
            pivots: vec![0; n],
            kind,
            blocks,
            whole_by_lu: false,
            holds_mass_factor: false,
        }
    }

    /// Which factorisation it makes.
    pub fn kind(&self) -> FactorKind {
        self.kind
    }

    /// The dimension `n` of the systems it solves.
    pub fn dimension(&self) -> usize {
        self.factors.nrows()
    }

    /// Factorises `a` (dimension `n × n`; only the lower triangle is read for Cholesky), overwriting
    /// the stored factors. Allocation-free.
    pub fn factor(&mut self, a: &DMatrix<f64>) -> Result<(), Breakdown> {
        assert_eq!(
            self.factors.shape(),
            a.shape(),
            "DenseSolver::factor: the matrix has the solver's dimension"
        );
        self.holds_mass_factor = false;
        let whole = a.as_slice();
        let scale = max_abs(whole);
        match self.kind {
            FactorKind::SaddlePoint { constraint_rows: m } => {
                let n = a.nrows();
                let nv = n - m;
                for (column, source) in self.blocks[..nv * nv]
                    .chunks_exact_mut(nv)
                    .zip(whole.chunks_exact(n))
                {
                    column.copy_from_slice(&source[..nv]);
                }
                // Row r of B is row nv + r of the matrix.
                let regular = self.factor_saddle_point(scale, m, |r, j| whole[j * n + nv + r]);
                if regular == SaddlePointFactor::ByLu {
                    self.factors.as_mut_slice().copy_from_slice(whole);
                }
                self.finish_saddle_point(regular, scale)
            }
            FactorKind::Cholesky => {
                self.factors.as_mut_slice().copy_from_slice(whole);
                self.factor_whole(largest_diagonal_entry(whole, a.nrows()))
            }
            FactorKind::Lu => {
                self.factors.as_mut_slice().copy_from_slice(whole);
                self.factor_whole(scale)
            }
        }
    }

    /// [`DenseSolver::factor`] of the saddle-point matrix `[A Bᵀ; B 0]` with
    /// `A = mass + diag(diagonal)` (`nv × nv`; `diagonal` of dim `nv` or none) and `B` (`m × nv`,
    /// `m` = the constraint rows of a [`FactorKind::SaddlePoint`] solver, 0 for the others), given
    /// by its blocks: the same bits as assembling the matrix and calling `factor`, without the
    /// assembly (a [`FactorKind::SaddlePoint`] solver never needs the whole matrix unless `A` is
    /// not positive definite). Allocation-free.
    pub fn factor_blocks(
        &mut self,
        mass: &DMatrix<f64>,
        diagonal: Option<&[f64]>,
        b: &DMatrix<f64>,
    ) -> Result<(), Breakdown> {
        let (nv, m) = (mass.nrows(), b.nrows());
        assert!(
            mass.is_square() && nv + m == self.dimension() && (m == 0 || b.ncols() == nv),
            "DenseSolver::factor_blocks: the blocks fit the solver's dimension"
        );
        let write_a = |out: &mut [f64], stride: usize| {
            if stride == nv {
                out[..nv * nv].copy_from_slice(mass.as_slice());
            } else {
                for (column, source) in out.chunks_mut(stride).zip(mass.as_slice().chunks_exact(nv))
                {
                    column[..nv].copy_from_slice(source);
                }
            }
            if let Some(diagonal) = diagonal {
                for (j, d) in diagonal.iter().enumerate() {
                    out[j * stride + j] += d;
                }
            }
        };
        self.holds_mass_factor = false;
        match self.kind {
            FactorKind::SaddlePoint { constraint_rows } => {
                assert_eq!(
                    constraint_rows, m,
                    "DenseSolver::factor_blocks: B has the solver's constraint rows"
                );
                write_a(&mut self.blocks[..nv * nv], nv);
                let scale = max_abs(&self.blocks[..nv * nv]).max(max_abs(b.as_slice()));
                let regular = self.factor_saddle_point(scale, m, |r, j| b[(r, j)]);
                if regular == SaddlePointFactor::ByLu {
                    let n = nv + m;
                    let whole = self.factors.as_mut_slice();
                    write_a(whole, n);
                    assemble_constraint_blocks(whole, n, b, 1.0);
                }
                let factorised = self.finish_saddle_point(regular, scale);
                // `mass + 0` is `mass`, bit for bit (its diagonal is positive once factorised).
                let unshifted = diagonal.is_none_or(|d| d.iter().all(|x| *x == 0.0));
                self.holds_mass_factor = unshifted && factorised.is_ok();
                factorised
            }
            FactorKind::Lu | FactorKind::Cholesky => {
                let n = nv + m;
                let whole = self.factors.as_mut_slice();
                write_a(whole, n);
                if m > 0 {
                    assemble_constraint_blocks(whole, n, b, 1.0);
                }
                let scale = if self.kind == FactorKind::Cholesky {
                    largest_diagonal_entry(whole, n)
                } else {
                    max_abs(whole)
                };
                self.factor_whole(scale)
            }
        }
    }

    /// The smallest pivot a [`FactorKind::Cholesky`] factorisation accepts of a matrix whose
    /// largest diagonal entry in magnitude (NaN entries counted as 0) is `largest`
    /// ([`largest_diagonal_entry`]), as
    /// [`DenseSolver::factor_blocks`] decides it: [`SINGULAR_PIVOT_RELATIVE`] times `largest`;
    /// `None` for a zero matrix, which it refuses outright.
    pub fn cholesky_min_pivot(largest: f64) -> Option<f64> {
        (largest != 0.0).then_some(SINGULAR_PIVOT_RELATIVE * largest)
    }

    /// Stores a Cholesky factorisation made elsewhere — the lock-step's batched factorisation
    /// (`dynamics::batch::cholesky_factor_with_min_pivots`) of the matrix [`DenseSolver::factor_blocks`]
    /// would have factorised, with [`DenseSolver::cholesky_min_pivot`]'s threshold — as if
    /// `factor_blocks` had made it: `write` fills in the `n × n` column-major result (lower
    /// triangle `L`, the strict upper triangle the matrix's). Only for the
    /// [`FactorKind::Cholesky`] kind.
    pub fn install_cholesky_factor(&mut self, write: impl FnOnce(&mut [f64])) {
        assert_eq!(
            self.kind,
            FactorKind::Cholesky,
            "DenseSolver::install_cholesky_factor: a Cholesky solver"
        );
        write(self.factors.as_mut_slice());
        self.holds_mass_factor = false;
    }

    /// Whether the last factorisation was [`DenseSolver::factor_blocks`]'s of `[M Bᵀ; B 0]`
    /// without a diagonal (or with a zero one), by the Schur complement: then
    /// [`DenseSolver::refactor_constraint_rows`] can keep `M`'s factor.
    pub fn holds_mass_factor(&self) -> bool {
        self.holds_mass_factor
    }

    /// Refactorises `[M Bᵀ; B 0]` for new constraint rows `b` (`m × nv`), keeping the Cholesky
    /// factor of the `M` that the last [`DenseSolver::factor_blocks`] was handed (only when
    /// [`DenseSolver::holds_mass_factor`]): `Y = L⁻¹ Bᵀ` and the Schur complement's factor
    /// only, `m` triangular solves and an `m × m` Cholesky instead of `M`'s. The same bits as
    /// `factor_blocks` with that `M`, no diagonal and `b`. On a breakdown (dependent rows) the
    /// factor of `M` stays and the caller factorises afresh.
    pub fn refactor_constraint_rows(&mut self, b: &DMatrix<f64>) -> Result<(), Breakdown> {
        let FactorKind::SaddlePoint { constraint_rows: m } = self.kind else {
            panic!("DenseSolver::refactor_constraint_rows: a saddle-point solver");
        };
        assert!(
            self.holds_mass_factor,
            "DenseSolver::refactor_constraint_rows: after factor_blocks without a diagonal"
        );
        assert_eq!(
            b.shape(),
            (m, self.dimension() - m),
            "DenseSolver::refactor_constraint_rows: B has the solver's constraint rows"
        );
        match self.factor_schur_complement(m, |r, j| b[(r, j)]) {
            SaddlePointFactor::DependentRows(breakdown) => Err(breakdown),
            _ => Ok(()),
        }
    }

    /// LU or Cholesky of the whole matrix in `factors` (per the kind; LU for a saddle-point
    /// solver), `scale` its largest entry (for the Cholesky kind its largest diagonal entry).
    fn factor_whole(&mut self, scale: f64) -> Result<(), Breakdown> {
        if scale == 0.0 && self.dimension() > 0 {
            return Err(Breakdown {
                index: 0,
                pivot_relative: 0.0,
            });
        }
        match self.kind {
            FactorKind::Cholesky => self.factor_cholesky(scale),
            FactorKind::Lu | FactorKind::SaddlePoint { .. } => self.factor_lu(scale),
        }
    }

    /// With `A` (`nv × nv`) in the first block of `blocks`: `A = L Lᵀ` (pivots refused below
    /// [`SINGULAR_PIVOT_RELATIVE`] × `scale`, the largest entry of the whole matrix, as for the
    /// LU), `Y = L⁻¹ Bᵀ` (`b_entry(r, j)` = `B_rj`), `S = Yᵀ Y = L_S L_Sᵀ` (pivots
    /// refused below [`SINGULAR_PIVOT_RELATIVE`] × S's largest diagonal entry: dependent rows of
    /// `B`). An `A` that is not positive definite (a coordinate that moves no inertia but is held
    /// by a constraint row) can leave the saddle-point matrix regular: then the caller puts the
    /// whole matrix in `factors` for [`DenseSolver::finish_saddle_point`] to factorise by LU.
    fn factor_saddle_point(
        &mut self,
        scale: f64,
        m: usize,
        b_entry: impl Fn(usize, usize) -> f64,
    ) -> SaddlePointFactor {
        let nv = self.dimension() - m;
        let l = &mut self.blocks[..nv * nv];
        if scale == 0.0
            || cholesky::factor_in_place(l, nv, SINGULAR_PIVOT_RELATIVE * scale).is_err()
        {
            return SaddlePointFactor::ByLu;
        }
        self.factor_schur_complement(m, b_entry)
    }

    /// The second half of [`DenseSolver::factor_saddle_point`], with `A`'s factor `L` in
    /// `blocks`: `Y = L⁻¹ Bᵀ` and the Cholesky factor of the Schur complement `YᵀY`.
    fn factor_schur_complement(
        &mut self,
        m: usize,
        b_entry: impl Fn(usize, usize) -> f64,
    ) -> SaddlePointFactor {
        let nv = self.dimension() - m;
        let (l, rest) = self.blocks.split_at_mut(nv * nv);
        let (y, s) = rest.split_at_mut(nv * m);
        for (r, column) in y.chunks_exact_mut(nv.max(1)).take(m).enumerate() {
            for (j, entry) in column.iter_mut().enumerate() {
                *entry = b_entry(r, j);
            }
            cholesky::forward_substitute(l, nv, column);
        }
        let mut largest_diagonal = 0.0_f64;
        for c in 0..m {
            for r in c..m {
                s[c * m + r] = dot(&y[r * nv..(r + 1) * nv], &y[c * nv..(c + 1) * nv]);
            }
            largest_diagonal = largest_diagonal.max(s[c * m + c]);
        }
        match cholesky::factor_in_place(s, m, SINGULAR_PIVOT_RELATIVE * largest_diagonal) {
            Ok(()) => SaddlePointFactor::BySchurComplement,
            Err(failure) => SaddlePointFactor::DependentRows(Breakdown {
                index: nv + failure.index,
                pivot_relative: if largest_diagonal > 0.0 {
                    failure.pivot / largest_diagonal
                } else {
                    0.0
                },
            }),
        }
    }

    /// Ends a saddle-point factorisation: the LU of the whole matrix (then in `factors`) when
    /// `A` was not positive definite.
    fn finish_saddle_point(
        &mut self,
        factor: SaddlePointFactor,
        scale: f64,
    ) -> Result<(), Breakdown> {
        self.whole_by_lu = factor == SaddlePointFactor::ByLu;
        match factor {
            SaddlePointFactor::BySchurComplement => Ok(()),
            SaddlePointFactor::ByLu => self.factor_whole(scale),
            SaddlePointFactor::DependentRows(breakdown) => Err(breakdown),
        }
    }

    fn factor_lu(&mut self, scale: f64) -> Result<(), Breakdown> {
        let n = self.factors.nrows();
        lu::factor_in_place(
            self.factors.as_mut_slice(),
            n,
            &mut self.pivots,
            SINGULAR_PIVOT_RELATIVE * scale,
        )
        .map_err(|failure| Breakdown {
            index: failure.index,
            pivot_relative: failure.magnitude / scale,
        })
    }

    fn factor_cholesky(&mut self, scale: f64) -> Result<(), Breakdown> {
        let n = self.factors.nrows();
        // `factor_whole` refused a zero matrix already.
        let min_pivot = Self::cholesky_min_pivot(scale).unwrap_or(0.0);
        cholesky::factor_in_place(self.factors.as_mut_slice(), n, min_pivot).map_err(|failure| {
            Breakdown {
                index: failure.index,
                pivot_relative: failure.pivot / scale,
            }
        })
    }

    /// Solves `A x = b` in place (`b` of dimension `n`, overwritten with `x`) with the last successful
    /// factorisation. Allocation-free.
    #[inline]
    pub fn solve_in_place(&self, b: &mut DVector<f64>) {
        // The Cholesky factor (a matrix without constraint rows) at the call site; the other
        // kinds out of line.
        if self.kind == FactorKind::Cholesky {
            let a = &self.factors;
            cholesky::solve_in_place(a.as_slice(), a.nrows(), b.as_mut_slice());
        } else {
            self.solve_other_in_place(b);
        }
    }

    /// [`Self::solve_in_place`] with an LU or saddle-point factorisation.
    #[inline(never)]
    fn solve_other_in_place(&self, b: &mut DVector<f64>) {
        let a = &self.factors;
        let n = a.nrows();
        match self.kind {
            FactorKind::Lu => lu::solve_in_place(a.as_slice(), n, &self.pivots, b.as_mut_slice()),
            FactorKind::Cholesky => cholesky::solve_in_place(a.as_slice(), n, b.as_mut_slice()),
            FactorKind::SaddlePoint { .. } if self.whole_by_lu => {
                lu::solve_in_place(a.as_slice(), n, &self.pivots, b.as_mut_slice())
            }
            FactorKind::SaddlePoint { constraint_rows: m } => {
                self.solve_saddle_point(m, b.as_mut_slice())
            }
        }
    }

    /// `[A Bᵀ; B 0] [x; λ] = [f; g]`: `z = L⁻¹ f`, `S λ = Yᵀ z − g`, `x = L⁻ᵀ (z − Y λ)`, in place.
    fn solve_saddle_point(&self, m: usize, b: &mut [f64]) {
        let nv = b.len() - m;
        let (l, rest) = self.blocks.split_at(nv * nv);
        let (y, s) = rest.split_at(nv * m);
        let (f, g) = b.split_at_mut(nv);
        cholesky::forward_substitute(l, nv, f);
        for (r, g_r) in g.iter_mut().enumerate() {
            *g_r = dot(&y[r * nv..(r + 1) * nv], f) - *g_r;
        }
        cholesky::solve_in_place(s, m, g);
        for (r, &lambda_r) in g.iter().enumerate() {
            for (f_i, &y_ir) in f.iter_mut().zip(&y[r * nv..(r + 1) * nv]) {
                *f_i -= y_ir * lambda_r;
            }
        }
        cholesky::backward_substitute(l, nv, f);
    }
}

/// How a saddle-point factorisation went.
#[derive(Debug, Clone, Copy, PartialEq)]
enum SaddlePointFactor {
    /// `A`'s Cholesky factor and the Schur complement's are stored.
    BySchurComplement,
    /// `A` is not positive definite: the whole matrix is to be factorised by LU.
    ByLu,
    /// The Schur complement is singular: `B`'s rows are dependent.
    DependentRows(Breakdown),
}

/// Writes `row_factor · B` (`B` of `m × nv`) into the last `m` rows and `Bᵀ` into the last `m`
/// columns of the column-major `n × n` `whole`, and zeros its last `m × m` block: the constraint
/// blocks of every saddle-point matrix the integrator assembles (`row_factor` 1 but for the
/// unscaled diagnostic matrix, docs/method.md §5).
pub(crate) fn assemble_constraint_blocks(
    whole: &mut [f64],
    n: usize,
    b: &DMatrix<f64>,
    row_factor: f64,
) {
    let (m, nv) = (b.nrows(), n - b.nrows());
    for j in 0..nv {
        for r in 0..m {
            whole[j * n + nv + r] = row_factor * b[(r, j)];
        }
    }
    for r in 0..m {
        let column = &mut whole[(nv + r) * n..(nv + r + 1) * n];
        for (i, entry) in column[..nv].iter_mut().enumerate() {
            *entry = b[(r, i)];
        }
        column[nv..].fill(0.0);
    }
}

/// `Σ aᵢ bᵢ`, summed in increasing `i`.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |sum, (x, y)| sum + x * y)
}

/// From this length on, [`first_non_finite`] tests four lanes at once (a 14 × 14 mass matrix: 1.4 %
/// fewer instructions per HHT step of the quadruped); below it, one chain (the 4-lane setup cost
/// more than it saved on the ur5's 6-vectors).
const LANE_TEST_FROM: usize = 32;

/// [`first_non_finite`] entry by entry in one pass without early exit.
#[inline]
fn first_non_finite_by_entry(x: &[f64]) -> Option<usize> {
    let all_finite = x.iter().fold(true, |finite, v| finite & v.is_finite());
    if all_finite {
        None
    } else {
        x.iter().position(|v| !v.is_finite())
    }
}

/// Whether every entry of `x` is finite: `v − v` is 0 for a finite entry and NaN for NaN or ±∞, so
/// sums of those in two lanes (one vector register of the x86-64 baseline) are both 0 exactly when
/// every entry is finite. Long slices take four lanes ([`first_non_finite`]).
#[inline]
#[allow(clippy::eq_op)] // `v − v` is the test itself.
pub(crate) fn all_finite(x: &[f64]) -> bool {
    if x.len() >= LANE_TEST_FROM {
        return first_non_finite_by_lanes(x).is_none();
    }
    let mut lanes = [0.0_f64; 2];
    let mut pairs = x.chunks_exact(2);
    for pair in &mut pairs {
        lanes[0] += pair[0] - pair[0];
        lanes[1] += pair[1] - pair[1];
    }
    for v in pairs.remainder() {
        lanes[0] += v - v;
    }
    lanes[0] == 0.0 && lanes[1] == 0.0
}

/// Index of the first non-finite entry (column-major for matrices), if any. The common case, every
/// entry finite, is one pass with no early exit; the index is searched for only when there is one.
#[inline]
pub(crate) fn first_non_finite(x: &[f64]) -> Option<usize> {
    if x.len() < LANE_TEST_FROM {
        first_non_finite_by_entry(x)
    } else {
        first_non_finite_by_lanes(x)
    }
}

/// [`first_non_finite`] for long slices, four lanes at once.
#[inline(never)]
#[allow(clippy::eq_op)] // `v − v` is the test itself: 0 for a finite `v`, NaN otherwise.
fn first_non_finite_by_lanes(x: &[f64]) -> Option<usize> {
    // `v − v` is 0 for a finite entry and NaN for NaN or ±∞: sums of those in four lanes are NaN
    // exactly when an entry is not finite.
    let mut lanes = [0.0_f64; 4];
    let mut chunks = x.chunks_exact(4);
    for chunk in &mut chunks {
        for (lane, v) in lanes.iter_mut().zip(chunk) {
            *lane += v - v;
        }
    }
    for v in chunks.remainder() {
        lanes[0] += v - v;
    }
    let all_finite = lanes.iter().all(|lane| *lane == 0.0);
    if all_finite {
        None
    } else {
        x.iter().position(|v| !v.is_finite())
    }
}

/// The largest `|a_jj|` of the `n × n` column-major `a` over the diagonal entries that are not NaN
/// (0 for none): the scale of a Cholesky factorisation's pivot test. Of a positive semi-definite
/// matrix it is the largest entry (`|a_ij| ≤ √(a_ii a_jj)`), read from `n` entries instead of
/// `n²`; a matrix that is not positive definite has a pivot at or below zero, refused at any
/// scale.
pub(crate) fn largest_diagonal_entry(a: &[f64], n: usize) -> f64 {
    let mut largest = 0.0_f64;
    for j in 0..n {
        let magnitude = a[j * n + j].abs();
        if magnitude > largest {
            largest = magnitude;
        }
    }
    largest
}

/// `max |x_i|` over the entries that are not NaN (0 for none): the same value as folding with
/// `f64::max`, which skips NaN, but in four independent accumulators (a maximum is exact, so the
/// order does not matter) rather than one chain of dependent comparisons.
fn max_abs(x: &[f64]) -> f64 {
    let magnitude = |v: f64| {
        let a = v.abs();
        if a.is_nan() {
            0.0
        } else {
            a
        }
    };
    let mut lanes = [0.0_f64; 4];
    let mut chunks = x.chunks_exact(4);
    for chunk in &mut chunks {
        for (lane, v) in lanes.iter_mut().zip(chunk) {
            let a = magnitude(*v);
            if a > *lane {
                *lane = a;
            }
        }
    }
    for v in chunks.remainder() {
        let a = magnitude(*v);
        if a > lanes[0] {
            lanes[0] = a;
        }
    }
    lanes.iter().fold(0.0, |acc: f64, lane| acc.max(*lane))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// Agreement of an in-place solve with nalgebra's own LU on a well-conditioned matrix.
    const SOLVE_TOL: f64 = 1e-12;

    /// The Cholesky kind scales its pivot test by the largest diagonal entry: of a positive
    /// semi-definite matrix that is its largest entry, so the threshold is the whole matrix's
    /// (`|a_ij| ≤ √(a_ii a_jj)`), here on Gram matrices of 1 to 16 rows, one singular.
    #[test]
    fn the_largest_diagonal_entry_of_a_semi_definite_matrix_is_its_largest_entry() {
        let mut random = SplitMix64::new(41);
        for n in 1..=16 {
            let rank = if n == 9 { 4 } else { n };
            let j = DMatrix::from_fn(rank, n, |_, _| random.uniform(-2.0, 2.0));
            let a = j.transpose() * j;
            assert_eq!(
                largest_diagonal_entry(a.as_slice(), n),
                max_abs(a.as_slice()),
                "n {n}"
            );
        }
        let mut nan = DMatrix::<f64>::identity(3, 3) * 2.0;
        nan[(1, 1)] = f64::NAN;
        assert_eq!(largest_diagonal_entry(nan.as_slice(), 3), 2.0);
        assert_eq!(largest_diagonal_entry(&[], 0), 0.0);
    }

    /// `max_abs` equals the `f64::max` fold it replaced, bit for bit, NaN and infinities included,
    /// for every length around the four accumulators' chunk.
    #[test]
    fn max_abs_equals_the_sequential_fold() {
        let values = [
            0.5,
            -3.25,
            f64::NAN,
            1e-300,
            -0.0,
            7.0,
            f64::INFINITY,
            -1e308,
            2.0,
            -7.5,
            f64::NAN,
        ];
        for len in 0..=values.len() {
            for start in 0..(values.len() - len).min(3) + 1 {
                let x = &values[start..start + len];
                let sequential = x.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
                assert_eq!(max_abs(x).to_bits(), sequential.to_bits(), "{x:?}");
            }
        }
        assert_eq!(max_abs(&[f64::NAN, f64::NAN]), 0.0);
        let finite = [1.0, -9.5, 3.0, 2.0, 0.1];
        assert_eq!(max_abs(&finite), 9.5);
        assert_eq!(first_non_finite(&finite), None);
        assert_eq!(
            first_non_finite(&[1.0, 2.0, f64::NEG_INFINITY, f64::NAN]),
            Some(2)
        );
    }

    /// Every length on both sides of `LANE_TEST_FROM`, a NaN or an infinity at every position.
    #[test]
    fn the_first_non_finite_entry_is_found_at_every_length_and_position() {
        for len in 0..LANE_TEST_FROM * 2 + 3 {
            let finite: Vec<f64> = (0..len).map(|i| (i as f64 - 7.0) * 1e300).collect();
            assert_eq!(first_non_finite(&finite), None, "len {len}");
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                for position in 0..len {
                    let mut x = finite.clone();
                    x[position] = bad;
                    x[len - 1] = if position == len - 1 { bad } else { f64::NAN };
                    assert_eq!(first_non_finite(&x), Some(position), "len {len}, {bad}");
                }
            }
        }
    }

    #[test]
    fn lu_and_cholesky_solve_small_systems() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let b = DVector::from_column_slice(&[1.0, -2.0, 0.5]);
        let expected = a.clone().lu().solve(&b).expect("invertible");
        for kind in [FactorKind::Lu, FactorKind::Cholesky] {
            let mut s = DenseSolver::new(3, kind);
            s.factor(&a).expect("regular");
            let mut x = b.clone();
            s.solve_in_place(&mut x);
            assert!((x - &expected).amax() < SOLVE_TOL, "{kind:?}");
        }
        // A saddle-point matrix needs the pivoting.
        let k = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 1.0, 0.0, 2.0, 1.0, 1.0, 1.0, 0.0]);
        let mut s = DenseSolver::new(3, FactorKind::Lu);
        s.factor(&k).expect("regular");
        let mut x = b.clone();
        s.solve_in_place(&mut x);
        assert!((&k * x - &b).amax() < SOLVE_TOL);
    }

    /// A deterministic stream in `[-0.5, 0.5)`.
    fn stream(seed: u64) -> impl FnMut() -> f64 {
        let mut generator = SplitMix64::new(seed);
        move || generator.uniform(-0.5, 0.5)
    }

    /// `(M, d, B)`: `M` symmetric positive definite (`nv × nv`), a positive diagonal `d`, and `B`
    /// (`m × nv`) of full row rank.
    fn blocks(nv: usize, m: usize, seed: u64) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
        let mut next = stream(seed);
        let r = DMatrix::from_fn(nv, nv, |_, _| next());
        let mass = &r * r.transpose() + DMatrix::identity(nv, nv) * 0.5;
        let diagonal = DVector::from_fn(nv, |_, _| next() + 0.5);
        let b = DMatrix::from_fn(m, nv, |_, _| next());
        (mass, diagonal, b)
    }

    /// `[M + diag(d), Bᵀ; B, 0]`, as the integrator assembles it.
    fn assembled(
        mass: &DMatrix<f64>,
        diagonal: Option<&DVector<f64>>,
        b: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        let (nv, m) = (mass.nrows(), b.nrows());
        let mut k = DMatrix::zeros(nv + m, nv + m);
        k.view_mut((0, 0), (nv, nv)).copy_from(mass);
        if let Some(d) = diagonal {
            for j in 0..nv {
                k[(j, j)] += d[j];
            }
        }
        k.view_mut((nv, 0), (m, nv)).copy_from(b);
        k.view_mut((0, nv), (nv, m)).copy_from(&b.transpose());
        k
    }

    /// The Schur-complement solve agrees with LU of the whole matrix to rounding, and the
    /// unassembled entry point gives the assembled one's bits, for every kind.
    #[test]
    fn saddle_point_solves_agree_with_lu_and_the_blocks_with_the_assembled_matrix() {
        for (nv, m) in [(1, 1), (3, 2), (6, 1), (9, 1), (14, 5), (20, 3)] {
            let (mass, diagonal, b) = blocks(nv, m, 0x51_7cc1_b727_220a + nv as u64);
            let k = assembled(&mass, Some(&diagonal), &b);
            let rhs = DVector::from_fn(nv + m, |i, _| (i as f64 * 0.7).sin());
            let mut by_lu = DenseSolver::new(nv + m, FactorKind::Lu);
            by_lu.factor(&k).expect("regular");
            let mut expected = rhs.clone();
            by_lu.solve_in_place(&mut expected);

            let kind = FactorKind::SaddlePoint { constraint_rows: m };
            let mut whole = DenseSolver::new(nv + m, kind);
            whole.factor(&k).expect("regular");
            assert!(!whole.whole_by_lu);
            let mut x = rhs.clone();
            whole.solve_in_place(&mut x);
            assert!((&x - &expected).amax() < SOLVE_TOL, "nv {nv}, m {m}");
            assert!((&k * &x - &rhs).amax() < SOLVE_TOL, "nv {nv}, m {m}");

            for kind in [kind, FactorKind::Lu] {
                let mut from_blocks = DenseSolver::new(nv + m, kind);
                from_blocks
                    .factor_blocks(&mass, Some(diagonal.as_slice()), &b)
                    .expect("regular");
                let mut y = rhs.clone();
                from_blocks.solve_in_place(&mut y);
                let mut reference = DenseSolver::new(nv + m, kind);
                reference.factor(&k).expect("regular");
                let mut z = rhs.clone();
                reference.solve_in_place(&mut z);
                assert_eq!(y.as_slice(), z.as_slice(), "{kind:?}, nv {nv}");
            }
        }
        // A tree (no rows): the Cholesky kind from its blocks, with and without the diagonal.
        let (mass, diagonal, b) = blocks(6, 0, 7);
        for d in [Some(&diagonal), None] {
            let mut from_blocks = DenseSolver::new(6, FactorKind::Cholesky);
            from_blocks
                .factor_blocks(&mass, d.map(|d| d.as_slice()), &b)
                .expect("positive definite");
            let mut reference = DenseSolver::new(6, FactorKind::Cholesky);
            reference
                .factor(&assembled(&mass, d, &b))
                .expect("positive definite");
            assert_eq!(from_blocks.factors.as_slice(), reference.factors.as_slice());
        }
    }

    /// Refactorising only the rows keeps `M`'s factor and gives `factor_blocks`'s bits for the new
    /// rows; it is offered only after `factor_blocks` of `M` alone (or with a zero diagonal), and a
    /// breakdown (dependent rows) leaves the caller to factorise afresh.
    #[test]
    fn refactoring_the_rows_keeps_the_factor_of_m_and_the_bits_of_a_fresh_factorisation() {
        for (nv, m) in [(1, 1), (6, 1), (7, 2), (14, 5)] {
            let (mass, diagonal, b) = blocks(nv, m, 0x2f_41a9_03d1 + nv as u64);
            let (_, _, new_rows) = blocks(nv, m, 0x77_0b3e_5c19 + nv as u64);
            let kind = FactorKind::SaddlePoint { constraint_rows: m };
            let rhs = DVector::from_fn(nv + m, |i, _| (i as f64 * 1.3).cos());
            let zero = DVector::zeros(nv);
            for d in [None, Some(&zero)] {
                let mut kept = DenseSolver::new(nv + m, kind);
                kept.factor_blocks(&mass, d.map(|d| d.as_slice()), &b)
                    .expect("regular");
                assert!(kept.holds_mass_factor(), "nv {nv}, m {m}");
                kept.refactor_constraint_rows(&new_rows).expect("regular");
                let mut fresh = DenseSolver::new(nv + m, kind);
                fresh
                    .factor_blocks(&mass, None, &new_rows)
                    .expect("regular");
                assert_eq!(kept.blocks, fresh.blocks, "nv {nv}, m {m}");
                let (mut x, mut y) = (rhs.clone(), rhs.clone());
                kept.solve_in_place(&mut x);
                fresh.solve_in_place(&mut y);
                assert_eq!(x.as_slice(), y.as_slice(), "nv {nv}, m {m}");
            }
            // A non-zero diagonal, or a whole matrix: M's factor is not what the blocks hold.
            let mut shifted = DenseSolver::new(nv + m, kind);
            shifted
                .factor_blocks(&mass, Some(diagonal.as_slice()), &b)
                .expect("regular");
            assert!(!shifted.holds_mass_factor());
            let mut whole = DenseSolver::new(nv + m, kind);
            whole.factor(&assembled(&mass, None, &b)).expect("regular");
            assert!(!whole.holds_mass_factor());
        }
        // Two copies of one row: refused, M's factor kept for the next attempt.
        let (mass, _, row) = blocks(4, 2, 5);
        let kind = FactorKind::SaddlePoint { constraint_rows: 2 };
        let mut s = DenseSolver::new(6, kind);
        s.factor_blocks(&mass, None, &row).expect("regular");
        let doubled = DMatrix::from_fn(2, 4, |_, j| row[(0, j)]);
        let failure = s.refactor_constraint_rows(&doubled).unwrap_err();
        assert_eq!(failure.index, 5);
        assert!(s.holds_mass_factor());
        s.refactor_constraint_rows(&row).expect("regular");
    }

    /// A coordinate with no inertia held by a constraint row: `A` is singular but the
    /// saddle-point matrix is not, and is factorised whole by LU; dependent rows are named.
    #[test]
    fn a_singular_block_falls_back_to_lu_and_dependent_rows_are_named() {
        // A = diag(2, 0); the row B = [0, 1] holds the second coordinate.
        let mass = DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 0.0]);
        let b = DMatrix::from_row_slice(1, 2, &[0.0, 1.0]);
        let k = assembled(&mass, None, &b);
        let rhs = DVector::from_column_slice(&[1.0, 3.0, 0.5]);
        let expected = k.clone().lu().solve(&rhs).expect("regular");
        let kind = FactorKind::SaddlePoint { constraint_rows: 1 };
        for from_blocks in [false, true] {
            let mut s = DenseSolver::new(3, kind);
            if from_blocks {
                s.factor_blocks(&mass, None, &b).expect("regular");
            } else {
                s.factor(&k).expect("regular");
            }
            assert!(s.whole_by_lu);
            let mut x = rhs.clone();
            s.solve_in_place(&mut x);
            assert!((&x - &expected).amax() < SOLVE_TOL, "{x}");
        }

        // Two copies of one row: the Schur complement's second pivot vanishes.
        let (mass, _, row) = blocks(4, 1, 11);
        let b = DMatrix::from_fn(2, 4, |_, j| row[(0, j)]);
        let mut s = DenseSolver::new(6, FactorKind::SaddlePoint { constraint_rows: 2 });
        let failure = s.factor_blocks(&mass, None, &b).unwrap_err();
        assert_eq!(failure.index, 5);
        assert!(failure.pivot_relative < SINGULAR_PIVOT_RELATIVE);
    }

    #[test]
    fn singular_matrices_are_reported() {
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        let mut s = DenseSolver::new(2, FactorKind::Lu);
        let e = s.factor(&a).unwrap_err();
        assert_eq!(e.index, 1);
        let mut c = DenseSolver::new(2, FactorKind::Cholesky);
        assert!(c.factor(&a).is_err());
    }
}
