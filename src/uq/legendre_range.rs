//! The exact range of a univariate Legendre series `q(ξ) = Σ_{n≤k} c_n P_n(ξ)` on [−1, 1]
//! (docs/high-dimension.md §7b): the extremes are at ±1 or at real roots of `q'` inside.
//!
//! Degrees ≤ 2 use closed forms. Higher degrees convert to monomial form and isolate the roots of
//! `q'` from those of `q''`, which are isolated from those of `q'''`, and so on down from the
//! linear `q^{(k−1)}`: between consecutive roots of `q^{(j+1)}` the function `q^{(j)}` is monotone,
//! so it has at most one root there, found by bisection to the last bit. `q` is stationary at its
//! critical points, so the values there are exact up to rounding. A series whose linear
//! coefficient outweighs what the others can add to the slope is monotone, and its range is its
//! values at ±1 without the cascade (`monotone_with_margin`).
//!
//! Does not: bound multivariate polynomials (see [`crate::uq::box_optimize`]).

use crate::uq::basis::legendre_values;

/// Bisection halves a bracket of width ≤ 2 this often: below the spacing of doubles near ±1.
const BISECTION_STEPS: usize = 64;

/// `(min, max)` of `Σ_n coef[n] P_n(ξ)` over ξ ∈ [−1, 1].
///
/// ```
/// use ribbon::uq::legendre_range::legendre_series_range;
/// // ξ + ξ² = 1/3 + P_1 + 2/3 P_2: range [−1/4, 2].
/// let (lo, hi) = legendre_series_range(&[1.0 / 3.0, 1.0, 2.0 / 3.0]);
/// assert!((lo + 0.25).abs() < 1e-15 && (hi - 2.0).abs() < 1e-15);
/// ```
pub fn legendre_series_range(coef: &[f64]) -> (f64, f64) {
    let Some(k) = coef.iter().rposition(|&c| c != 0.0) else {
        return (0.0, 0.0);
    };
    let coef = &coef[..=k];
    match coef.len() {
        1 => (coef[0], coef[0]),
        2 => (coef[0] - coef[1].abs(), coef[0] + coef[1].abs()),
        3 => {
            // c0 + c1 ξ + c2 (3ξ² − 1)/2: endpoints and the vertex −c1 / (3 c2).
            let (c0, c1, c2) = (coef[0], coef[1], coef[2]);
            let at = |x: f64| c0 + c1 * x + c2 * (1.5 * x * x - 0.5);
            let (a, b) = (at(-1.0), at(1.0));
            let (mut lo, mut hi) = (a.min(b), a.max(b));
            let vertex = -c1 / (3.0 * c2);
            if vertex.abs() < 1.0 {
                let v = at(vertex);
                lo = lo.min(v);
                hi = hi.max(v);
            }
            (lo, hi)
        }
        _ => general_range(coef),
    }
}

/// The range of a series of degree ≥ 3 ([`general_range`]), without isolating the roots of `q'`
/// when `q` is monotone with margin ([`monotone_with_margin`]): then its values at ±1 are its
/// range, as the cascade of bisections would find too (issue 40: nine in ten univariate series of
/// the README's scaling rows are, and their bisections were half of the outer bound).
fn general_range(coef: &[f64]) -> (f64, f64) {
    if monotone_with_margin(coef) {
        let mut values = vec![0.0; coef.len()];
        let (a, b) = (
            series_value(coef, -1.0, &mut values),
            series_value(coef, 1.0, &mut values),
        );
        return (a.min(b), a.max(b));
    }
    range_from_critical_points(coef)
}

/// Whether `q' = c₁ + Σ_{n≥2} c_n P_n'` stays away from 0 on [−1, 1] by far more than rounding:
/// `|P_n'| ≤ P_n'(1) = n(n+1)/2` there, so `|q' − c₁| ≤ Σ_{n≥2} |c_n| n(n+1)/2 =: r`, and
/// `|c₁| > 2r` keeps `|q'| ≥ |c₁|/2`. The rounding of `q'` in monomial form (Horner's, from the
/// coefficients [`to_monomial`] gives, whose magnitudes sum to at most a few thousand times
/// `Σ |c_n|` up to degree 12) is below 1e-9 of `|c₁|`, so no bracket of the cascade sees `q'`
/// change sign and it finds no critical point inside: the range is the values at ±1.
fn monotone_with_margin(coef: &[f64]) -> bool {
    let rest: f64 = coef
        .iter()
        .enumerate()
        .skip(2)
        .map(|(n, c)| c.abs() * (n * (n + 1)) as f64 / 2.0)
        .sum();
    coef.get(1).is_some_and(|c1| c1.abs() > 2.0 * rest)
}

/// `Σ_n coef[n] P_n(x)`, with `values` (as long as `coef`) for the `P_n(x)`.
fn series_value(coef: &[f64], x: f64, values: &mut [f64]) -> f64 {
    legendre_values(x, values);
    coef.iter()
        .zip(values.iter())
        .map(|(c, p)| c * p)
        .sum::<f64>()
}

/// The range from the values at ±1 and at the critical points inside, isolated by the cascade of
/// bisections (module documentation).
fn range_from_critical_points(coef: &[f64]) -> (f64, f64) {
    let k = coef.len() - 1;
    let monomial = to_monomial(coef);
    // derivatives[j] = coefficients of q^{(j)} (monomial).
    let mut derivatives = vec![monomial];
    for j in 1..k {
        let prev = &derivatives[j - 1];
        let next: Vec<f64> = (1..prev.len()).map(|i| i as f64 * prev[i]).collect();
        derivatives.push(next);
    }
    // Roots of the linear q^{(k−1)}, then upward.
    let mut roots: Vec<f64> = Vec::new();
    {
        let lin = &derivatives[k - 1];
        if lin[1] != 0.0 {
            let x = -lin[0] / lin[1];
            if x > -1.0 && x < 1.0 {
                roots.push(x);
            }
        }
    }
    for j in (1..k - 1).rev() {
        let p = &derivatives[j];
        let mut edges = Vec::with_capacity(roots.len() + 2);
        edges.push(-1.0);
        edges.extend_from_slice(&roots);
        edges.push(1.0);
        let mut next = Vec::with_capacity(edges.len());
        for w in edges.windows(2) {
            if let Some(x) = bisect(p, w[0], w[1]) {
                next.push(x);
            }
        }
        roots = next;
    }
    let mut values = vec![0.0; k + 1];
    let mut eval = |x: f64| series_value(coef, x, &mut values);
    let (a, b) = (eval(-1.0), eval(1.0));
    let (mut lo, mut hi) = (a.min(b), a.max(b));
    for &x in &roots {
        let v = eval(x);
        lo = lo.min(v);
        hi = hi.max(v);
    }
    (lo, hi)
}

/// A root of the monotone `p` in the open interval (a, b), if its sign changes there.
fn bisect(p: &[f64], a: f64, b: f64) -> Option<f64> {
    let horner = |x: f64| p.iter().rev().fold(0.0, |acc, &c| acc * x + c);
    let (fa, fb) = (horner(a), horner(b));
    if fa == 0.0 || fb == 0.0 || (fa > 0.0) == (fb > 0.0) {
        // No sign change (or a root exactly at an edge, which is a candidate already).
        return None;
    }
    let (mut lo, mut hi) = (a, b);
    let rising = fb > 0.0;
    for _ in 0..BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if (horner(mid) > 0.0) == rising {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// Monomial coefficients of `Σ c_n P_n`, from `P_{n+1} = ((2n+1) ξ P_n − n P_{n−1}) / (n+1)`.
fn to_monomial(coef: &[f64]) -> Vec<f64> {
    let k = coef.len() - 1;
    let mut out = vec![0.0; k + 1];
    let mut prev = vec![0.0; k + 1];
    let mut cur = vec![0.0; k + 1];
    cur[0] = 1.0; // P_0
    for (n, &c) in coef.iter().enumerate() {
        for (o, &p) in out.iter_mut().zip(&cur) {
            *o += c * p;
        }
        if n == k {
            break;
        }
        let nf = n as f64;
        let mut next = vec![0.0; k + 1];
        for i in 0..=n {
            next[i + 1] += (2.0 * nf + 1.0) * cur[i] / (nf + 1.0);
            next[i] -= nf * prev[i] / (nf + 1.0);
        }
        prev = std::mem::replace(&mut cur, next);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// A series monotone with margin gets the range the cascade of bisections gives, bit for bit,
    /// from its values at ±1 alone; one just inside the margin's reach still gets the cascade.
    #[test]
    fn a_monotone_series_skips_the_cascade_with_the_same_bits() {
        let mut rng = SplitMix64::new(40);
        let mut skipped = 0;
        for k in 3..=12 {
            for _ in 0..400 {
                let mut coef: Vec<f64> = (0..=k).map(|_| rng.uniform(-1.0, 1.0)).collect();
                // Shrink the curvature so that about half of the series are monotone with margin.
                let shrink = rng.uniform(0.0, 0.3) / (k * k) as f64;
                coef.iter_mut().skip(2).for_each(|c| *c *= shrink);
                let cascade = range_from_critical_points(&coef);
                let got = legendre_series_range(&coef);
                assert_eq!(
                    (got.0.to_bits(), got.1.to_bits()),
                    (cascade.0.to_bits(), cascade.1.to_bits()),
                    "k={k} {coef:?}"
                );
                skipped += usize::from(monotone_with_margin(&coef));
            }
        }
        assert!(
            skipped > 1000 && skipped < 3800,
            "{skipped} of 4000 skipped"
        );
        // ξ³ − 3ξ = 2/5 P₃ − 12/5 P₁: stationary at ±1, where the margin fails (12/5 < 2 · 6 · 2/5).
        assert!(!monotone_with_margin(&[0.0, -2.4, 0.0, 0.4]));
        let (lo, hi) = legendre_series_range(&[0.0, -2.4, 0.0, 0.4]);
        assert!((lo + 2.0).abs() < 1e-15 && (hi - 2.0).abs() < 1e-15);
    }

    #[test]
    fn matches_dense_sampling() {
        let mut rng = SplitMix64::new(4);
        let mut p = vec![0.0; 9];
        for k in 0..=8 {
            for _ in 0..40 {
                let coef: Vec<f64> = (0..=k).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let (lo, hi) = legendre_series_range(&coef);
                let (mut slo, mut shi) = (f64::INFINITY, f64::NEG_INFINITY);
                for i in 0..=20_000 {
                    legendre_values(-1.0 + 2.0 * i as f64 / 20_000.0, &mut p[..=k]);
                    let v: f64 = coef.iter().zip(&p).map(|(c, p)| c * p).sum();
                    slo = slo.min(v);
                    shi = shi.max(v);
                }
                // Exact range contains the samples (up to rounding) and is within the sampling
                // error (spacing 1e-4, slope ≤ k²·Σ|c| ⇒ ≲ 1e-6 near a stationary point).
                assert!(lo <= slo + 1e-14 && hi >= shi - 1e-14, "k={k}");
                assert!(
                    slo - lo < 1e-6 && hi - shi < 1e-6,
                    "k={k}: {lo} {slo} {hi} {shi}"
                );
            }
        }
        assert_eq!(legendre_series_range(&[]), (0.0, 0.0));
        assert_eq!(legendre_series_range(&[2.0, 0.0, 0.0, 0.0]), (2.0, 2.0));
        assert_eq!(legendre_series_range(&[0.0, 0.0]), (0.0, 0.0));
        // P_4: min −3/7 at the interior critical points, max 1 at the ends.
        let (lo, hi) = legendre_series_range(&[0.0, 0.0, 0.0, 0.0, 1.0]);
        assert!((lo + 3.0 / 7.0).abs() < 1e-15 && hi == 1.0);
    }
}
