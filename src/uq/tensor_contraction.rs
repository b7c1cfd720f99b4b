//! Sum-factorisation kernels: apply a small matrix along one axis of a row-major tensor, and
//! evaluate a dense tensor-product expansion (value, gradient, Hessian) at one point by contracting
//! one dimension at a time.
//!
//! Cost of evaluating `Σ_t c_t Π_r φ_{t_r}(ξ_r)` with `m^d` terms: `m^d + m^{d−1} + … ≈ m^d` multiply-adds
//! (instead of `d · m^d` for a term-by-term loop); the gradient and Hessian together cost about
//! `3 m^d`. Does not: know about designs, truncation or outputs.

use crate::uq::basis::Family;

/// `out[o, i, s] = Σ_j a[i, j] · inp[o, j, s]`: applies the `p × n` row-major matrix `a` along the
/// middle axis of `inp` (shape `outer × n × inner`), writing `out` (shape `outer × p × inner`).
///
/// The inner loops run over contiguous `inner`-long slices (vectorisable axpy).
pub(crate) fn apply_axis(
    inp: &[f64],
    outer: usize,
    n: usize,
    inner: usize,
    a: &[f64],
    p: usize,
    out: &mut [f64],
) {
    debug_assert_eq!(inp.len(), outer * n * inner);
    debug_assert_eq!(out.len(), outer * p * inner);
    debug_assert_eq!(a.len(), p * n);
    if inner == 1 {
        for (x, y) in inp.chunks_exact(n).zip(out.chunks_exact_mut(p)) {
            for (yi, row) in y.iter_mut().zip(a.chunks_exact(n)) {
                *yi = row.iter().zip(x).map(|(a, x)| a * x).sum();
            }
        }
        return;
    }
    for (x, y) in inp
        .chunks_exact(n * inner)
        .zip(out.chunks_exact_mut(p * inner))
    {
        for (yi, row) in y.chunks_exact_mut(inner).zip(a.chunks_exact(n)) {
            combine_slices(row, x, inner, yi);
        }
    }
}

/// `y = Σ_j w[j] · x[j·len .. (j+1)·len]`, four input slices per pass to cut stores.
#[inline]
pub(crate) fn combine_slices(w: &[f64], x: &[f64], len: usize, y: &mut [f64]) {
    let n = w.len();
    // First pass initialises y with up to four slices (m = k + 1 = 5 at k = 4: two passes in all).
    let j = match n {
        1 => {
            let w0 = w[0];
            for (y, a) in y.iter_mut().zip(&x[..len]) {
                *y = w0 * a;
            }
            1
        }
        2 => {
            let (x0, x1) = x[..2 * len].split_at(len);
            let (w0, w1) = (w[0], w[1]);
            for ((y, a), b) in y.iter_mut().zip(x0).zip(x1) {
                *y = w0 * a + w1 * b;
            }
            2
        }
        3 => {
            let (x0, rest) = x[..3 * len].split_at(len);
            let (x1, x2) = rest.split_at(len);
            let (w0, w1, w2) = (w[0], w[1], w[2]);
            for (((y, a), b), c) in y.iter_mut().zip(x0).zip(x1).zip(x2) {
                *y = w0 * a + w1 * b + w2 * c;
            }
            3
        }
        _ => {
            let (x0, rest) = x[..4 * len].split_at(len);
            let (x1, rest) = rest.split_at(len);
            let (x2, x3) = rest.split_at(len);
            let (w0, w1, w2, w3) = (w[0], w[1], w[2], w[3]);
            for ((((y, a), b), c), d) in y.iter_mut().zip(x0).zip(x1).zip(x2).zip(x3) {
                *y = (w0 * a + w1 * b) + (w2 * c + w3 * d);
            }
            4
        }
    };
    let mut j = j;
    while j + 4 <= n {
        let xs = &x[j * len..(j + 4) * len];
        let (x0, rest) = xs.split_at(len);
        let (x1, rest) = rest.split_at(len);
        let (x2, x3) = rest.split_at(len);
        let (w0, w1, w2, w3) = (w[j], w[j + 1], w[j + 2], w[j + 3]);
        for ((((y, a), b), c), d) in y.iter_mut().zip(x0).zip(x1).zip(x2).zip(x3) {
            *y += (w0 * a + w1 * b) + (w2 * c + w3 * d);
        }
        j += 4;
    }
    while j + 2 <= n {
        let (x0, x1) = (&x[j * len..(j + 1) * len], &x[(j + 1) * len..(j + 2) * len]);
        let (w0, w1) = (w[j], w[j + 1]);
        for ((y, a), b) in y.iter_mut().zip(x0).zip(x1) {
            *y += w0 * a + w1 * b;
        }
        j += 2;
    }
    if j < n {
        let w0 = w[j];
        for (y, a) in y.iter_mut().zip(&x[j * len..(j + 1) * len]) {
            *y += w0 * a;
        }
    }
}

/// Evaluates dense expansions `Σ_t c_t Π_r φ_{t_r}(ξ_r)` (dense row-major term order, `m = k + 1`
/// per dimension) at single points, reusing its buffers: a work buffer, not a description.
#[derive(Debug, Clone)]
pub(crate) struct PointEvaluator {
    family: Family,
    dim: usize,
    m: usize,
    /// `basis[(q·dim + r)·m + i] = φ_i^{(q)}(ξ_r)`, q = derivative order 0..=2.
    basis: Vec<f64>,
    /// Level r holds the tensor after contracting axes 0..=r: `m^{d−1−r}` entries.
    scratch: Vec<f64>,
}

/// Value, gradient and Hessian of an expansion at a point.
struct Derivatives<'a> {
    value: f64,
    grad: &'a mut [f64],
    /// Row-major d × d.
    hess: &'a mut [f64],
}

impl PointEvaluator {
    pub(crate) fn new(family: Family, dim: usize, order: usize) -> PointEvaluator {
        let m = order + 1;
        let scratch_len: usize = (0..dim).map(|r| m.pow((dim - 1 - r) as u32)).sum();
        PointEvaluator {
            family,
            dim,
            m,
            basis: vec![0.0; 3 * dim * m],
            scratch: vec![0.0; scratch_len],
        }
    }

    fn load_basis(&mut self, xi: &[f64], derivatives: bool) {
        let (d, m) = (self.dim, self.m);
        let (v, rest) = self.basis.split_at_mut(d * m);
        let (d1, d2) = rest.split_at_mut(d * m);
        for (r, &x) in xi.iter().enumerate() {
            let s = r * m..(r + 1) * m;
            if derivatives {
                self.family.values_and_derivatives(
                    x,
                    &mut v[s.clone()],
                    &mut d1[s.clone()],
                    &mut d2[s],
                );
            } else {
                self.family.values(x, &mut v[s]);
            }
        }
    }

    /// The expansion's value at `xi` (length dim); `coef` has `m^d` dense entries.
    pub(crate) fn value(&mut self, coef: &[f64], xi: &[f64]) -> f64 {
        self.load_basis(xi, false);
        let mut tmp_g = [0.0; 0];
        let mut tmp_h = [0.0; 0];
        let mut out = Derivatives {
            value: 0.0,
            grad: &mut tmp_g,
            hess: &mut tmp_h,
        };
        let mut pattern = [(0usize, 0u8); 2];
        recurse(
            coef,
            0,
            0,
            self.dim,
            self.m,
            &self.basis,
            &mut self.scratch,
            &mut pattern,
            0,
            &mut out,
        );
        out.value
    }

    /// Value, gradient (`grad`, length dim) and Hessian (`hess`, row-major dim × dim) at `xi`.
    pub(crate) fn value_grad_hess(
        &mut self,
        coef: &[f64],
        xi: &[f64],
        grad: &mut [f64],
        hess: &mut [f64],
    ) -> f64 {
        self.load_basis(xi, true);
        let mut out = Derivatives {
            value: 0.0,
            grad,
            hess,
        };
        let mut pattern = [(0usize, 0u8); 2];
        recurse(
            coef,
            0,
            2,
            self.dim,
            self.m,
            &self.basis,
            &mut self.scratch,
            &mut pattern,
            0,
            &mut out,
        );
        out.value
    }
}

/// Contracts axis `level` of `input` (shape `m^{d−level}`) with φ^{(q)}(ξ_level) for every
/// derivative order q ≤ `budget`, recursing on the rest; a leaf (level = d) is one entry of the
/// value / gradient / Hessian, identified by the non-zero derivative orders in `pattern`.
#[allow(clippy::too_many_arguments)]
fn recurse(
    input: &[f64],
    level: usize,
    budget: u8,
    dim: usize,
    m: usize,
    basis: &[f64],
    scratch: &mut [f64],
    pattern: &mut [(usize, u8); 2],
    n_pattern: usize,
    out: &mut Derivatives<'_>,
) {
    if level == dim {
        let v = input[0];
        match (n_pattern, pattern[0], pattern[1]) {
            (0, _, _) => out.value = v,
            (1, (r, 1), _) => out.grad[r] = v,
            (1, (r, _), _) => out.hess[r * dim + r] = v,
            (_, (r, _), (s, _)) => {
                out.hess[r * dim + s] = v;
                out.hess[s * dim + r] = v;
            }
        }
        return;
    }
    let len = input.len() / m;
    let (buf, rest) = scratch.split_at_mut(len);
    for q in 0..=budget {
        let b = &basis[(q as usize * dim + level) * m..][..m];
        combine_slices(b, input, len, buf);
        let n_next = if q > 0 {
            pattern[n_pattern] = (level, q);
            n_pattern + 1
        } else {
            n_pattern
        };
        recurse(
            buf,
            level + 1,
            budget - q,
            dim,
            m,
            basis,
            rest,
            pattern,
            n_next,
            out,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small sums of O(1) products: a few ulp.
    const TOL: f64 = 1e-13;

    fn brute_force(family: Family, dim: usize, m: usize, coef: &[f64], xi: &[f64]) -> f64 {
        let mut phi = vec![vec![0.0; m]; dim];
        for r in 0..dim {
            family.values(xi[r], &mut phi[r]);
        }
        let mut idx = vec![0; dim];
        coef.iter()
            .enumerate()
            .map(|(t, c)| {
                crate::uq::design::decode_multi_index(t, m, &mut idx);
                c * idx
                    .iter()
                    .enumerate()
                    .map(|(r, &i)| phi[r][i])
                    .product::<f64>()
            })
            .sum()
    }

    #[test]
    fn apply_axis_matches_definition() {
        let (outer, n, inner, p) = (3, 5, 4, 7);
        let inp: Vec<f64> = (0..outer * n * inner).map(|i| (i as f64).sin()).collect();
        let a: Vec<f64> = (0..p * n).map(|i| (i as f64 * 0.7).cos()).collect();
        for inner in [1, inner] {
            let inp = &inp[..outer * n * inner];
            let mut out = vec![0.0; outer * p * inner];
            apply_axis(inp, outer, n, inner, &a, p, &mut out);
            for o in 0..outer {
                for i in 0..p {
                    for s in 0..inner {
                        let want: f64 = (0..n)
                            .map(|j| a[i * n + j] * inp[(o * n + j) * inner + s])
                            .sum();
                        assert!((out[(o * p + i) * inner + s] - want).abs() < TOL);
                    }
                }
            }
        }
        // Every tail length of combine_slices.
        for n in 1..=9 {
            let x: Vec<f64> = (0..n * 3).map(|i| i as f64).collect();
            let w: Vec<f64> = (0..n).map(|j| 1.0 + j as f64).collect();
            let mut y = [0.0; 3];
            combine_slices(&w, &x, 3, &mut y);
            for (s, ys) in y.iter().enumerate() {
                let want: f64 = (0..n).map(|j| w[j] * x[j * 3 + s]).sum();
                assert!((ys - want).abs() < TOL);
            }
        }
    }

    #[test]
    fn value_gradient_hessian_match_brute_force() {
        const H: f64 = 1e-5;
        // Central differences of a degree-3 polynomial in ξ with O(1) coefficients.
        const FD_TOL: f64 = 1e-6;
        for family in [Family::Legendre, Family::Chebyshev] {
            for dim in 1..=4 {
                let m: usize = 4;
                let coef: Vec<f64> = (0..m.pow(dim as u32))
                    .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.5)
                    .collect();
                let xi: Vec<f64> = (0..dim).map(|r| 0.9 - 0.45 * r as f64).collect();
                let mut ev = PointEvaluator::new(family, dim, m - 1);
                let v = ev.value(&coef, &xi);
                assert!((v - brute_force(family, dim, m, &coef, &xi)).abs() < TOL);
                let mut g = vec![0.0; dim];
                let mut h = vec![0.0; dim * dim];
                let v2 = ev.value_grad_hess(&coef, &xi, &mut g, &mut h);
                assert!((v - v2).abs() < TOL);
                for r in 0..dim {
                    let mut xp = xi.clone();
                    let mut xm = xi.clone();
                    xp[r] += H;
                    xm[r] -= H;
                    let fd = (brute_force(family, dim, m, &coef, &xp)
                        - brute_force(family, dim, m, &coef, &xm))
                        / (2.0 * H);
                    assert!((fd - g[r]).abs() < FD_TOL, "{family:?} d={dim} r={r}");
                    let mut gp = vec![0.0; dim];
                    let mut gm = vec![0.0; dim];
                    let mut scratch = vec![0.0; dim * dim];
                    ev.value_grad_hess(&coef, &xp, &mut gp, &mut scratch);
                    ev.value_grad_hess(&coef, &xm, &mut gm, &mut scratch);
                    for s in 0..dim {
                        let fd = (gp[s] - gm[s]) / (2.0 * H);
                        assert!((fd - h[r * dim + s]).abs() < FD_TOL, "hess {r} {s}");
                    }
                }
            }
        }
    }
}
