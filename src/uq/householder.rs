//! Blocked Householder QR of a tall matrix and the explicit least-squares map built from it
//! (docs/high-dimension.md §4). nalgebra's QR is unblocked: on a 3800 × 1891 matrix it took 11.7 s
//! and forming Q another 10.3 s on this machine; blocking the reflectors (compact WY form,
//! `H_1 ⋯ H_b = I − V T Vᵀ`, Schreiber & Van Loan 1989) moves almost all the work into
//! matrix products (`gemm` → `matrixmultiply`).
//!
//! Steps, for `A` (n × m, n ≥ m, column-major):
//! 1. [`qr_in_place`]: panels of [`PANEL`] columns; each panel is factored column by column
//!    (`H = I − τ v vᵀ`, `v_0 = 1`, `H x = β e_1`, LAPACK's `dlarfg` convention), its `T` is formed
//!    (`T_{0:i, i} = −τ_i T_{0:i,0:i} V_{:,0:i}ᵀ v_i`, `T_ii = τ_i`), and the trailing columns are
//!    updated as `A₂ ← A₂ − V Tᵀ (Vᵀ A₂)`. R ends in the upper triangle, the v's below it.
//! 2. [`form_q`]: the thin `Q₁` (n × m) by applying the panels to `[I; 0]` in reverse order.
//! 3. [`right_solve_upper_transposed`]: `Y = Q₁ R⁻ᵀ` (so `Yᵀ = R⁻¹ Q₁ᵀ` is the pseudo-inverse),
//!    blocked from the last column.
//!
//! Does not: choose points or terms (see [`crate::uq::regression`]).

use nalgebra::{DMatrix, DMatrixViewMut};

/// Columns per panel: large enough that the trailing updates are matrix products with an inner
/// dimension of 48, small enough that the column-by-column panel work (`n · PANEL` per column)
/// stays a small share.
const PANEL: usize = 48;

/// Factors `a` (n × m, n ≥ m) in place: R in the upper triangle, Householder vectors (unit
/// diagonal implied) below it. Returns the m reflector scalars τ.
pub(crate) fn qr_in_place(a: &mut DMatrix<f64>) -> Vec<f64> {
    let (n, m) = a.shape();
    debug_assert!(n >= m);
    let mut tau = vec![0.0; m];
    let mut j = 0;
    while j < m {
        let nb = PANEL.min(m - j);
        factor_panel(a, j, nb, &mut tau[j..j + nb]);
        if j + nb < m {
            let v = panel_vectors(a, j, nb);
            let t = block_t(&v, &tau[j..j + nb]);
            // A₂ ← A₂ − V Tᵀ (Vᵀ A₂) on rows j.., columns j+nb..
            let mut a2 = a.view_mut((j, j + nb), (n - j, m - j - nb));
            apply_block(&v, &t.transpose(), &mut a2);
        }
        j += nb;
    }
    tau
}

/// The thin Q₁ (n × m) of a factorisation from [`qr_in_place`].
pub(crate) fn form_q(factored: &DMatrix<f64>, tau: &[f64]) -> DMatrix<f64> {
    let (n, m) = factored.shape();
    let mut q = DMatrix::zeros(n, m);
    for i in 0..m {
        q[(i, i)] = 1.0;
    }
    let starts: Vec<usize> = (0..m).step_by(PANEL).collect();
    for &j in starts.iter().rev() {
        let nb = PANEL.min(m - j);
        let v = panel_vectors(factored, j, nb);
        let t = block_t(&v, &tau[j..j + nb]);
        // Columns < j of Q are still zero in rows ≥ j: only Q[j.., j..] changes.
        let mut q2 = q.view_mut((j, j), (n - j, m - j));
        apply_block(&v, &t, &mut q2);
    }
    q
}

/// Overwrites `y` (n × m) with `y R⁻ᵀ`, R the upper triangle of `factored` (m × m block): the
/// solution Z of `Z Rᵀ = y`, column i = `(y_i − Σ_{j>i} R_ij Z_j) / R_ii`, blocked from the right.
pub(crate) fn right_solve_upper_transposed(factored: &DMatrix<f64>, y: &mut DMatrix<f64>) {
    let m = factored.ncols();
    let n = y.nrows();
    let starts: Vec<usize> = (0..m).step_by(PANEL).collect();
    for &i0 in starts.iter().rev() {
        let i1 = (i0 + PANEL).min(m);
        if i1 < m {
            // Y[:, i0..i1] −= Y[:, i1..m] · R[i0..i1, i1..m]ᵀ.
            let r_block_t = factored.view((i0, i1), (i1 - i0, m - i1)).transpose();
            let (left, right) = y.columns_range_pair_mut(i0..i1, i1..m);
            let mut left = left;
            left.gemm(-1.0, &right, &r_block_t, 1.0);
        }
        let data = y.as_mut_slice();
        for i in (i0..i1).rev() {
            let (head, tail) = data.split_at_mut((i + 1) * n);
            let yi = &mut head[i * n..];
            for j in i + 1..i1 {
                let r = factored[(i, j)];
                if r != 0.0 {
                    let yj = &tail[(j - i - 1) * n..(j - i) * n];
                    for (a, &b) in yi.iter_mut().zip(yj) {
                        *a -= r * b;
                    }
                }
            }
            let d = factored[(i, i)];
            yi.iter_mut().for_each(|v| *v /= d);
        }
    }
}

/// Unblocked Householder on columns j..j+nb, rows j.., updating only the panel's own columns.
fn factor_panel(a: &mut DMatrix<f64>, j: usize, nb: usize, tau: &mut [f64]) {
    let n = a.nrows();
    let data = a.as_mut_slice();
    for c in j..j + nb {
        // Column-major: column c is data[c·n .. (c+1)·n].
        let (head, tail) = data.split_at_mut((c + 1) * n);
        let col = &mut head[c * n + c..];
        let (beta, t) = householder(col);
        tau[c - j] = t;
        if t != 0.0 {
            let v = &col[1..];
            for q in 0..(j + nb - c - 1) {
                let target = &mut tail[q * n + c..(q + 1) * n];
                // w = vᵀ a[c.., q] with v_0 = 1.
                let w = target[0] + v.iter().zip(&target[1..]).map(|(a, b)| a * b).sum::<f64>();
                let s = t * w;
                target[0] -= s;
                for (x, &vi) in target[1..].iter_mut().zip(v) {
                    *x -= s * vi;
                }
            }
        }
        col[0] = beta;
    }
}

/// LAPACK `dlarfg` on `x` (the column below and including the diagonal): on return `x[1..]`
/// holds v (with `v_0 = 1` implied); returns `(β, τ)`. τ = 0 (H = I) when `x[1..]` is zero.
fn householder(x: &mut [f64]) -> (f64, f64) {
    let alpha = x[0];
    let sigma: f64 = x[1..].iter().map(|v| v * v).sum();
    if sigma == 0.0 {
        return (alpha, 0.0);
    }
    let norm = (alpha * alpha + sigma).sqrt();
    let beta = if alpha >= 0.0 { -norm } else { norm };
    let tau = (beta - alpha) / beta;
    let scale = 1.0 / (alpha - beta);
    x[1..].iter_mut().for_each(|v| *v *= scale);
    (beta, tau)
}

/// The panel's Householder vectors as an explicit (n−j) × nb matrix (unit diagonal, zeros above).
fn panel_vectors(a: &DMatrix<f64>, j: usize, nb: usize) -> DMatrix<f64> {
    let n = a.nrows();
    let mut v = DMatrix::zeros(n - j, nb);
    for c in 0..nb {
        v[(c, c)] = 1.0;
        for i in c + 1..n - j {
            v[(i, c)] = a[(j + i, j + c)];
        }
    }
    v
}

/// The upper triangular T of the compact WY form `H_1 ⋯ H_nb = I − V T Vᵀ` (LAPACK `dlarft`,
/// forward, columnwise).
fn block_t(v: &DMatrix<f64>, tau: &[f64]) -> DMatrix<f64> {
    let nb = tau.len();
    let mut t = DMatrix::zeros(nb, nb);
    let mut z = vec![0.0; nb];
    for i in 0..nb {
        t[(i, i)] = tau[i];
        if i == 0 || tau[i] == 0.0 {
            continue;
        }
        // z = V_{:,0:i}ᵀ v_i (v_i is zero above row i).
        for (c, zc) in z.iter_mut().enumerate().take(i) {
            *zc = v
                .column(c)
                .rows_range(i..)
                .dot(&v.column(i).rows_range(i..));
        }
        // T_{0:i, i} = −τ_i T_{0:i, 0:i} z.
        for r in 0..i {
            let s: f64 = (r..i).map(|c| t[(r, c)] * z[c]).sum();
            t[(r, i)] = -tau[i] * s;
        }
    }
    t
}

/// `b ← b − V (M (Vᵀ b))` for an nb × nb `m` (Tᵀ to apply Qᵀ, T to apply Q).
fn apply_block(v: &DMatrix<f64>, m: &DMatrix<f64>, b: &mut DMatrixViewMut<'_, f64>) {
    let nb = v.ncols();
    let v_t = v.transpose();
    let mut w = DMatrix::zeros(nb, b.ncols());
    w.gemm(1.0, &v_t, &*b, 0.0);
    let mw = m * &w;
    b.gemm(-1.0, v, &mw, 1.0);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// Householder QR is backward stable: residuals of O(n · ε · ‖A‖).
    const TOL: f64 = 1e-12;

    #[test]
    fn factorisation_reproduces_the_matrix_and_q_is_orthonormal() {
        let mut rng = SplitMix64::new(21);
        for (n, m) in [(5, 5), (7, 3), (130, 100), (300, 97), (1, 1)] {
            let a = DMatrix::from_fn(n, m, |_, _| rng.uniform(-1.0, 1.0));
            let mut f = a.clone();
            let tau = qr_in_place(&mut f);
            let q = form_q(&f, &tau);
            let r = f.rows(0, m).upper_triangle();
            let back = &q * &r;
            assert!((back - &a).amax() < TOL, "A = QR, {n}×{m}");
            let qtq = q.transpose() * &q;
            assert!((qtq - DMatrix::identity(m, m)).amax() < TOL, "QᵀQ, {n}×{m}");
            // Yᵀ = R⁻¹ Q₁ᵀ is the pseudo-inverse: Yᵀ A = I.
            let mut y = q.clone();
            right_solve_upper_transposed(&f, &mut y);
            let pinv_a = y.transpose() * &a;
            assert!(
                (pinv_a - DMatrix::identity(m, m)).amax() < 1e-10,
                "pinv, {n}×{m}"
            );
        }
    }

    #[test]
    fn zero_columns_below_the_diagonal_give_identity_reflectors() {
        // An upper triangular matrix needs no reflection: τ = 0, R = A.
        let a = DMatrix::from_row_slice(3, 2, &[2.0, 1.0, 0.0, 3.0, 0.0, 0.0]);
        let mut f = a.clone();
        let tau = qr_in_place(&mut f);
        assert_eq!(tau, vec![0.0, 0.0]);
        assert_eq!(f, a);
    }
}
