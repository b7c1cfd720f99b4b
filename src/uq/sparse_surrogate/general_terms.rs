//! The terms of a sparse surrogate with three or more factors (the plan's `general` terms): what
//! each adds to the gradient and to the Hessian. The products that leave out one or two factors
//! are multiplied directly, one factor after another in the term's order starting from 1 — the
//! bits of `Iterator::product` over the same factors, which is how they were computed before.
//! Terms of three and four factors (every general term of a total-degree-4 design) take their
//! table values once into arrays of fixed length, so the loops unroll and no factor is looked up
//! twice; longer terms read the tables per product. On the d = 8 scaling study the Hessian was
//! 30 % of all instructions, ~156 k per evaluation, most of them these loops (issue 40). A
//! term's Hessian is added row by row ([`add_hessian_row`]), so that a block of a few free
//! dimensions can take each term from the rows of those dimensions only (`RowLists`).
//!
//! Does not: the value (`SparseSurrogate::value_unchecked`), the singles, pairs and the bilinear
//! part (`super`).

/// Adds the gradient of `ct · Π_e P(ξ_{dim_e})` to `grad` and returns the term's product
/// `Π_e P(ξ_{dim_e})` ([`product`]'s bits): `idx` the term's table indices, `dims` its factors'
/// dimensions, `v` and `g` the tables of values and first derivatives. Terms of three and four
/// factors read their table entries once for both.
#[inline(always)]
pub(super) fn product_adding_gradient(
    ct: f64,
    idx: &[u32],
    dims: &[u32],
    v: &[f64],
    g: &[f64],
    grad: &mut [f64],
) -> f64 {
    match idx.len() {
        3 => gradient_gathered::<3>(ct, idx, dims, v, g, grad),
        4 => gradient_gathered::<4>(ct, idx, dims, v, g, grad),
        m => {
            gradient(
                ct,
                m,
                |e| v[idx[e] as usize],
                |e| g[idx[e] as usize],
                dims,
                grad,
            );
            product(idx, v)
        }
    }
}

/// The term's product of table values `Π_e v[idx_e]`, multiplied in the term's order starting
/// from 1 (the bits of `Iterator::product`); terms of three and four factors gathered first, so
/// the loop unrolls.
#[inline(always)]
pub(super) fn product(idx: &[u32], v: &[f64]) -> f64 {
    match idx.len() {
        3 => gather::<3>(idx, v).iter().product(),
        4 => gather::<4>(idx, v).iter().product(),
        _ => idx.iter().map(|&i| v[i as usize]).product(),
    }
}

/// Adds the upper triangle of the term's Hessian to `hess` (n × n): `h` the table of second
/// derivatives, `place` the row and column of a dimension in `hess` (`None`: not in it, its
/// entries are skipped), the rest as in [`product_adding_gradient`].
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn add_hessian(
    ct: f64,
    idx: &[u32],
    dims: &[u32],
    v: &[f64],
    g: &[f64],
    h: &[f64],
    hess: &mut [f64],
    n: usize,
    place: impl Fn(usize) -> Option<usize>,
) {
    match idx.len() {
        3 => hessian_gathered::<3>(ct, idx, dims, (v, g, h), hess, n, place),
        4 => hessian_gathered::<4>(ct, idx, dims, (v, g, h), hess, n, place),
        m => {
            let at = |e: usize| {
                let i = idx[e] as usize;
                (v[i], g[i], h[i])
            };
            hessian(ct, m, at, dims, hess, n, place);
        }
    }
}

/// As [`add_hessian`] for factor `a`'s row only (the term seen from one of its dimensions,
/// `RowLists::general`): the same entries of that row, the same bits.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn add_hessian_row(
    ct: f64,
    idx: &[u32],
    dims: &[u32],
    tables: (&[f64], &[f64], &[f64]),
    a: usize,
    hess: &mut [f64],
    n: usize,
    place: impl Fn(usize) -> Option<usize>,
) {
    let (v, g, h) = tables;
    match idx.len() {
        // The factor's place as a constant in each arm, so that the loops over the other
        // factors unroll without tests.
        3 => {
            let gathered = (
                gather::<3>(idx, v),
                gather::<3>(idx, g),
                gather::<3>(idx, h),
            );
            let at = |e: usize| (gathered.0[e], gathered.1[e], gathered.2[e]);
            match a {
                0 => hessian_row(ct, 3, at, dims, 0, hess, n, place),
                1 => hessian_row(ct, 3, at, dims, 1, hess, n, place),
                _ => hessian_row(ct, 3, at, dims, 2, hess, n, place),
            }
        }
        4 => {
            let gathered = (
                gather::<4>(idx, v),
                gather::<4>(idx, g),
                gather::<4>(idx, h),
            );
            let at = |e: usize| (gathered.0[e], gathered.1[e], gathered.2[e]);
            match a {
                0 => hessian_row(ct, 4, at, dims, 0, hess, n, place),
                1 => hessian_row(ct, 4, at, dims, 1, hess, n, place),
                2 => hessian_row(ct, 4, at, dims, 2, hess, n, place),
                _ => hessian_row(ct, 4, at, dims, 3, hess, n, place),
            }
        }
        m => {
            let at = |e: usize| {
                let i = idx[e] as usize;
                (v[i], g[i], h[i])
            };
            hessian_row(ct, m, at, dims, a, hess, n, place);
        }
    }
}

/// [`gradient`] of a term of `M` factors from its table values gathered once; returns their
/// product.
#[inline(always)]
fn gradient_gathered<const M: usize>(
    ct: f64,
    idx: &[u32],
    dims: &[u32],
    v: &[f64],
    g: &[f64],
    grad: &mut [f64],
) -> f64 {
    let (values, firsts) = (gather::<M>(idx, v), gather::<M>(idx, g));
    gradient(ct, M, |e| values[e], |e| firsts[e], dims, grad);
    values.iter().product()
}

/// [`hessian`] of a term of `M` factors from its table values (`tables`: values, first and
/// second derivatives) gathered once.
#[inline(always)]
fn hessian_gathered<const M: usize>(
    ct: f64,
    idx: &[u32],
    dims: &[u32],
    tables: (&[f64], &[f64], &[f64]),
    hess: &mut [f64],
    n: usize,
    place: impl Fn(usize) -> Option<usize>,
) {
    let (values, firsts, seconds) = (
        gather::<M>(idx, tables.0),
        gather::<M>(idx, tables.1),
        gather::<M>(idx, tables.2),
    );
    let at = |e: usize| (values[e], firsts[e], seconds[e]);
    hessian(ct, M, at, dims, hess, n, place);
}

/// The `M` table entries of a term.
#[inline(always)]
fn gather<const M: usize>(idx: &[u32], table: &[f64]) -> [f64; M] {
    std::array::from_fn(|e| table[idx[e] as usize])
}

/// `Π_{e ∉ {a, b}} value(e)` over the `m` factors (`a == b`: leaving out one), multiplied one by
/// one in order starting from 1.
#[inline(always)]
fn product_leaving_out(m: usize, value: impl Fn(usize) -> f64, a: usize, b: usize) -> f64 {
    let mut product = 1.0;
    for e in 0..m {
        if e != a && e != b {
            product *= value(e);
        }
    }
    product
}

#[inline(always)]
fn gradient(
    ct: f64,
    m: usize,
    value: impl Fn(usize) -> f64,
    first: impl Fn(usize) -> f64,
    dims: &[u32],
    grad: &mut [f64],
) {
    for (a, &dim) in dims.iter().enumerate().take(m) {
        let others = product_leaving_out(m, &value, a, a);
        grad[dim as usize] += ct * first(a) * others;
    }
}

/// `at(e)` = (value, first, second derivative) of factor `e`; entries of dimensions that `place`
/// leaves out are neither computed nor written (the others' sums are unchanged).
#[inline(always)]
fn hessian(
    ct: f64,
    m: usize,
    at: impl Fn(usize) -> (f64, f64, f64),
    dims: &[u32],
    hess: &mut [f64],
    n: usize,
    place: impl Fn(usize) -> Option<usize>,
) {
    for a in 0..m {
        hessian_row(ct, m, &at, dims, a, hess, n, &place);
    }
}

/// What factor `a`'s row of the block gets from the term: the diagonal entry and the entries
/// with the later factors (upper triangle), as [`hessian`] adds them for that factor.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn hessian_row(
    ct: f64,
    m: usize,
    at: impl Fn(usize) -> (f64, f64, f64),
    dims: &[u32],
    a: usize,
    hess: &mut [f64],
    n: usize,
    place: impl Fn(usize) -> Option<usize>,
) {
    let value = |e: usize| at(e).0;
    let Some(pa) = place(dims[a] as usize) else {
        return;
    };
    let (_, first_a, second_a) = at(a);
    let others = product_leaving_out(m, value, a, a);
    hess[pa * n + pa] += ct * second_a * others;
    for (b, &dim_b) in dims.iter().enumerate().take(m).skip(a + 1) {
        let Some(pb) = place(dim_b as usize) else {
            continue;
        };
        let rest = product_leaving_out(m, value, a, b);
        hess[pa * n + pb] += ct * first_a * at(b).1 * rest;
    }
}
