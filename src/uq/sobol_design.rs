//! Low-discrepancy regression designs in [−1, 1]^d: the centre, then caller-chosen points, then
//! an Owen-scrambled Sobol' sequence (docs/high-dimension.md §4).
//!
//! The Sobol' digits come from the `sobol_burley` crate's building blocks (Joe & Kuo direction
//! numbers, 256 dimensions, 2¹⁶ points; Burley's hash-based Owen scrambling): we take its 32-bit
//! integers and map them to doubles ourselves, `u = (n + ½) / 2³²`, `ξ = 2u − 1`, so the design
//! keeps all 32 bits (the crate's own `sample` returns f32) and never lands exactly on a face.
//! One scramble per dimension, derived from the seed: the same seed gives the same design on every
//! machine and thread count.
//!
//! Does not: fit (see [`crate::uq::regression`]).

use sobol_burley::parts::{hash, owen_scramble_rev, sobol_rev};

use crate::uq::error::UqError;

/// Most dimensions the Sobol' generator supports (`sobol_burley::NUM_DIMENSIONS`).
pub const SOBOL_MAX_DIM: usize = sobol_burley::NUM_DIMENSIONS as usize;

/// Most Sobol' points the generator supports (2¹⁶).
pub const SOBOL_MAX_POINTS: usize = 1 << 16;

/// `n_points × dim` row-major points in [−1, 1]^d: row 0 is the centre ξ = 0, rows 1..=k are the k
/// points of `extra` (`k × dim` row-major, each coordinate in [−1, 1]), and the rest are scrambled
/// Sobol' points 0, 1, 2, … (scrambled with `seed`).
///
/// ```
/// let design = ribbon::uq::sobol_design(3, 8, 7, &[1.0, -1.0, 0.5])?;
/// assert_eq!(&design[..6], &[0.0, 0.0, 0.0, 1.0, -1.0, 0.5]);
/// assert!(design[6..].iter().all(|x| x.abs() < 1.0));
/// # Ok::<(), ribbon::uq::UqError>(())
/// ```
///
/// Errors: `dim == 0`; `dim >` [`SOBOL_MAX_DIM`] or more than [`SOBOL_MAX_POINTS`] Sobol' points
/// ([`UqError::DesignTooLarge`]); `extra` not a multiple of `dim`, or not fitting in `n_points − 1`
/// rows ([`UqError::WrongLength`]); a non-finite extra coordinate ([`UqError::NonFinite`]) or one
/// outside [−1, 1] ([`UqError::InvalidInterval`] names the point index and coordinate).
pub fn sobol_design(
    dim: usize,
    n_points: usize,
    seed: u32,
    extra: &[f64],
) -> Result<Vec<f64>, UqError> {
    if dim == 0 {
        return Err(UqError::ZeroDimension);
    }
    if dim > SOBOL_MAX_DIM {
        return Err(UqError::DesignTooLarge {
            what: "Sobol' dimensions",
            got: dim,
            max: SOBOL_MAX_DIM,
        });
    }
    if n_points == 0 {
        return Err(UqError::Empty {
            what: "Sobol' design points",
        });
    }
    let n_extra = extra.len() / dim;
    if !extra.len().is_multiple_of(dim) || 1 + n_extra > n_points {
        return Err(UqError::WrongLength {
            what: "Sobol' design: extra points (k × d, k < n_points)",
            expected: dim * (n_points - 1).min(n_extra),
            got: extra.len(),
        });
    }
    if let Some(index) = extra.iter().position(|v| !v.is_finite()) {
        return Err(UqError::NonFinite {
            what: "Sobol' design: extra points",
            index,
            value: extra[index],
        });
    }
    if let Some(index) = extra.iter().position(|v| v.abs() > 1.0) {
        return Err(UqError::InvalidInterval {
            index,
            lo: extra[index],
            hi: extra[index],
        });
    }
    let n_sobol = n_points - 1 - n_extra;
    if n_sobol > SOBOL_MAX_POINTS {
        return Err(UqError::DesignTooLarge {
            what: "Sobol' points",
            got: n_sobol,
            max: SOBOL_MAX_POINTS,
        });
    }
    let mut points = vec![0.0; n_points * dim];
    points[dim..dim * (1 + n_extra)].copy_from_slice(extra);
    let scrambles: Vec<u32> = (0..dim as u32)
        .map(|r| hash(r.wrapping_mul(0x9E37_79B9) ^ hash(seed)))
        .collect();
    for (i, x) in points[dim * (1 + n_extra)..]
        .chunks_exact_mut(dim)
        .enumerate()
    {
        let index_rev = (i as u32).reverse_bits();
        for (r, (xr, &scramble)) in x.iter_mut().zip(&scrambles).enumerate() {
            let digits = owen_scramble_rev(sobol_rev(index_rev, r as u32), scramble).reverse_bits();
            let u = (digits as f64 + 0.5) / 4_294_967_296.0;
            *xr = 2.0 * u - 1.0;
        }
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_stratified_and_checked() {
        let a = sobol_design(60, 1025, 0, &[]).unwrap();
        let b = sobol_design(60, 1025, 0, &[]).unwrap();
        assert_eq!(a, b);
        let c = sobol_design(60, 1025, 1, &[]).unwrap();
        assert_ne!(a, c);
        assert!(a[..60].iter().all(|&x| x == 0.0));
        // Scrambled Sobol' points 0..1024 are a (t, 10, s)-net: in every dimension each of the
        // 1024 intervals of width 2/1024 holds exactly one point (one-dimensional projections of
        // a Sobol' net are perfectly stratified, and Owen scrambling keeps that).
        for r in 0..60 {
            let mut counts = vec![0; 1024];
            for x in a[60..].chunks_exact(60) {
                let cell = ((x[r] + 1.0) / 2.0 * 1024.0).floor() as usize;
                counts[cell] += 1;
            }
            assert!(counts.iter().all(|&c| c == 1), "dimension {r}");
        }
        // Pairwise: 32 × 32 cells of the first two dimensions each hold one point (t = 0 for
        // Sobol' dimensions 1 and 2).
        let mut counts = vec![0; 1024];
        for x in a[60..].chunks_exact(60) {
            let i = ((x[0] + 1.0) / 2.0 * 32.0).floor() as usize;
            let j = ((x[1] + 1.0) / 2.0 * 32.0).floor() as usize;
            counts[i * 32 + j] += 1;
        }
        assert!(counts.iter().all(|&c| c == 1));
        assert!(sobol_design(0, 3, 0, &[]).is_err());
        assert!(sobol_design(SOBOL_MAX_DIM + 1, 3, 0, &[]).is_err());
        assert!(sobol_design(2, 3, 0, &[0.0, 0.0, 0.0]).is_err());
        assert!(sobol_design(2, 2, 0, &[0.0, 0.0, 0.0, 0.0]).is_err());
        assert!(sobol_design(2, 3, 0, &[0.0, 1.5]).is_err());
        assert!(sobol_design(2, 3, 0, &[0.0, f64::NAN]).is_err());
        assert!(sobol_design(1, SOBOL_MAX_POINTS + 2, 0, &[]).is_err());
    }
}
