//! In-place Cholesky factorisation `A = L Lᵀ` of small dense symmetric positive-definite matrices,
//! without allocation (nalgebra's `Cholesky` takes its matrix by value and allocates).

use nalgebra::{DMatrix, DVector};

/// Smallest pivot accepted, relative to the largest diagonal entry: below it the matrix is treated as
/// singular (a coordinate that moves no inertia), not factorised into garbage.
pub const RELATIVE_PIVOT_TOLERANCE: f64 = 1e-13;

/// Factorises the symmetric matrix `a` in place: on success its lower triangle holds `L` (the strict
/// upper triangle is left as it was). On failure returns the index of the failing pivot and its
/// value.
pub fn cholesky_factor_in_place(a: &mut DMatrix<f64>) -> Result<(), (usize, f64)> {
    let n = a.nrows();
    let scale = (0..n).map(|i| a[(i, i)].abs()).fold(0.0, f64::max);
    let threshold = RELATIVE_PIVOT_TOLERANCE * scale.max(f64::MIN_POSITIVE);
    for j in 0..n {
        let mut pivot = a[(j, j)];
        for k in 0..j {
            pivot -= a[(j, k)] * a[(j, k)];
        }
        if pivot.is_nan() || pivot <= threshold {
            return Err((j, pivot));
        }
        let diagonal = pivot.sqrt();
        a[(j, j)] = diagonal;
        for i in j + 1..n {
            let mut value = a[(i, j)];
            for k in 0..j {
                value -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = value / diagonal;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ x = b` in place (`b` becomes `x`), with `L` in the lower triangle of `factor`.
pub fn cholesky_solve_in_place(factor: &DMatrix<f64>, b: &mut DVector<f64>) {
    let n = factor.nrows();
    for i in 0..n {
        let mut value = b[i];
        for k in 0..i {
            value -= factor[(i, k)] * b[k];
        }
        b[i] = value / factor[(i, i)];
    }
    for i in (0..n).rev() {
        let mut value = b[i];
        for k in i + 1..n {
            value -= factor[(k, i)] * b[k];
        }
        b[i] = value / factor[(i, i)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_spd_system_and_rejects_singular() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0]);
        let x = DVector::from_row_slice(&[1.0, -2.0, 0.5]);
        let mut b = &a * &x;
        let mut factor = a.clone();
        cholesky_factor_in_place(&mut factor).unwrap();
        cholesky_solve_in_place(&factor, &mut b);
        assert!((b - x).amax() < 1e-14);
        let mut singular = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        assert_eq!(cholesky_factor_in_place(&mut singular).unwrap_err().0, 1);
    }
}
