//! The map between a physical interval `[lo, hi]` and the standard variable ξ ∈ [-1, 1]:
//! `x = c + r ξ` with midpoint `c = (lo + hi)/2` and radius `r = (hi − lo)/2` (docs/method.md §1), one
//! per parameter ([`IntervalMap`]) or for a whole box ([`ParameterBox`]).
//!
//! Does not: know parameter names or units; callers keep those beside the box.

use crate::uq::error::UqError;

/// One parameter's interval, as midpoint and radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntervalMap {
    /// Midpoint `c = (lo + hi)/2`, in the parameter's unit.
    pub centre: f64,
    /// Radius `r = (hi − lo)/2 ≥ 0`, in the parameter's unit.
    pub radius: f64,
}

impl IntervalMap {
    /// The map of `[lo, hi]`; `lo == hi` (a degenerate interval, r = 0) is allowed.
    ///
    /// ```
    /// use ribbon::uq::IntervalMap;
    /// let mass_kg = IntervalMap::new(2.1, 2.5).unwrap();
    /// assert!((mass_kg.x_from_xi(-1.0) - 2.1).abs() < 1e-15);
    /// assert!((mass_kg.x_from_xi(0.0) - 2.3).abs() < 1e-15);
    /// assert!((mass_kg.xi_from_x(2.5) - 1.0).abs() < 1e-14);
    /// ```
    pub fn new(lo: f64, hi: f64) -> Result<IntervalMap, UqError> {
        Self::checked(0, lo, hi)
    }

    fn checked(index: usize, lo: f64, hi: f64) -> Result<IntervalMap, UqError> {
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(UqError::InvalidInterval { index, lo, hi });
        }
        Ok(IntervalMap {
            centre: 0.5 * (lo + hi),
            radius: 0.5 * (hi - lo),
        })
    }

    /// Lower end `c − r`.
    pub fn lo(&self) -> f64 {
        self.centre - self.radius
    }

    /// Upper end `c + r`.
    pub fn hi(&self) -> f64 {
        self.centre + self.radius
    }

    /// `x = c + r ξ`.
    pub fn x_from_xi(&self, xi: f64) -> f64 {
        self.centre + self.radius * xi
    }

    /// `ξ = (x − c)/r`; 0 for a degenerate interval (r = 0).
    pub fn xi_from_x(&self, x: f64) -> f64 {
        if self.radius == 0.0 {
            0.0
        } else {
            (x - self.centre) / self.radius
        }
    }
}

/// A box of d interval parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterBox {
    maps: Vec<IntervalMap>,
}

impl ParameterBox {
    /// From `(lo, hi)` pairs, one per parameter.
    ///
    /// Errors: an empty list ([`UqError::ZeroDimension`]); an interval with a non-finite end or
    /// `lo > hi` ([`UqError::InvalidInterval`], naming its index).
    pub fn new(bounds: &[(f64, f64)]) -> Result<ParameterBox, UqError> {
        if bounds.is_empty() {
            return Err(UqError::ZeroDimension);
        }
        let maps = bounds
            .iter()
            .enumerate()
            .map(|(i, &(lo, hi))| IntervalMap::checked(i, lo, hi))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ParameterBox { maps })
    }

    /// Number of parameters d.
    pub fn dim(&self) -> usize {
        self.maps.len()
    }

    /// The per-parameter maps.
    pub fn maps(&self) -> &[IntervalMap] {
        &self.maps
    }

    /// `x_r = c_r + r_r ξ_r` for every parameter; `xi` and `x` have length d.
    pub fn x_from_xi(&self, xi: &[f64], x: &mut [f64]) -> Result<(), UqError> {
        self.check("x_from_xi: xi", xi.len())?;
        self.check("x_from_xi: x", x.len())?;
        for ((x, &xi), map) in x.iter_mut().zip(xi).zip(&self.maps) {
            *x = map.x_from_xi(xi);
        }
        Ok(())
    }

    /// `ξ_r = (x_r − c_r)/r_r` for every parameter; `x` and `xi` have length d.
    pub fn xi_from_x(&self, x: &[f64], xi: &mut [f64]) -> Result<(), UqError> {
        self.check("xi_from_x: x", x.len())?;
        self.check("xi_from_x: xi", xi.len())?;
        for ((xi, &x), map) in xi.iter_mut().zip(x).zip(&self.maps) {
            *xi = map.xi_from_x(x);
        }
        Ok(())
    }

    /// Maps a row-major `n × d` matrix of standard points (e.g. [`crate::uq::Design::points`]) to
    /// physical values, same layout.
    pub fn x_from_xi_rows(&self, xi_rows: &[f64]) -> Result<Vec<f64>, UqError> {
        let d = self.dim();
        if !xi_rows.len().is_multiple_of(d) {
            return Err(UqError::WrongLength {
                what: "x_from_xi_rows: rows of d standard coordinates",
                expected: xi_rows.len() / d * d,
                got: xi_rows.len(),
            });
        }
        Ok(xi_rows
            .chunks_exact(d)
            .flat_map(|row| row.iter().zip(&self.maps).map(|(&xi, m)| m.x_from_xi(xi)))
            .collect())
    }

    fn check(&self, what: &'static str, len: usize) -> Result<(), UqError> {
        if len != self.dim() {
            return Err(UqError::WrongLength {
                what,
                expected: self.dim(),
                got: len,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_ends() {
        let b = ParameterBox::new(&[(1.0, 3.0), (-0.5, -0.5), (-2.0, 6.0)]).unwrap();
        let mut x = [0.0; 3];
        b.x_from_xi(&[-1.0, 0.3, 1.0], &mut x).unwrap();
        assert_eq!(x, [1.0, -0.5, 6.0]);
        let mut xi = [0.0; 3];
        b.xi_from_x(&[2.0, -0.5, 4.0], &mut xi).unwrap();
        assert_eq!(xi, [0.0, 0.0, 0.5]);
        let rows = b.x_from_xi_rows(&[0.0, 0.0, 0.0, 1.0, 1.0, -1.0]).unwrap();
        assert_eq!(rows, vec![2.0, -0.5, 2.0, 3.0, -0.5, -2.0]);
    }

    #[test]
    fn refuses_bad_intervals() {
        assert_eq!(
            ParameterBox::new(&[(0.0, 1.0), (2.0, 1.0)]),
            Err(UqError::InvalidInterval {
                index: 1,
                lo: 2.0,
                hi: 1.0
            })
        );
        assert!(IntervalMap::new(f64::NAN, 1.0).is_err());
        assert_eq!(ParameterBox::new(&[]), Err(UqError::ZeroDimension));
        let b = ParameterBox::new(&[(0.0, 1.0)]).unwrap();
        assert!(b.x_from_xi(&[0.0, 0.0], &mut [0.0]).is_err());
    }
}
