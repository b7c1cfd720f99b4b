//! The bounding methods a study can use, and what kind of bound each gives.

use crate::uq::Family;

/// A method of computing envelopes (design contract names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Legendre surrogate on the tensor Gauss–Legendre grid, bounded by scanning it (inner).
    LegendreScan,
    /// Legendre surrogate bounded by interval arithmetic with exact `P_n` ranges (outer).
    LegendreIa,
    /// Legendre surrogate bounded by its Bernstein form, sharpened by subdivision (outer, within
    /// 1e-6 of the width of the surrogate's range when converged; docs/bernstein.md).
    LegendreBernstein,
    /// Chebyshev surrogate on the Gauss–Chebyshev grid, bounded by scanning it (inner).
    ChebyshevScan,
    /// Chebyshev inclusion function `c_0 ± Σ|c_i|` (outer).
    ChebyshevIa,
    /// First-order Taylor inclusion from central differences (approximate: neither bound).
    Taylor,
    /// The true model on a uniform grid (reference up to grid resolution).
    Scan,
    /// The true model at uniform random points (inner; converges slowly).
    MonteCarlo,
    /// Chosen by the number of parameters (docs/method.md §10): `legendre-scan` on the tensor grid
    /// for d ≤ 4, a Legendre surrogate on a sparse design bounded by multi-start projected
    /// Newton (inner) above. Resolved before a study runs; never a study's method itself.
    Auto,
}

/// Every method with its name, in documentation order.
pub const METHODS: [(&str, Method); 9] = [
    ("auto", Method::Auto),
    ("legendre-scan", Method::LegendreScan),
    ("legendre-ia", Method::LegendreIa),
    ("legendre-bernstein", Method::LegendreBernstein),
    ("chebyshev-scan", Method::ChebyshevScan),
    ("chebyshev-ia", Method::ChebyshevIa),
    ("taylor", Method::Taylor),
    ("scan", Method::Scan),
    ("monte-carlo", Method::MonteCarlo),
];

impl Method {
    /// Parses a method name.
    pub fn parse(name: &str) -> Option<Method> {
        METHODS.iter().find(|(n, _)| *n == name).map(|(_, m)| *m)
    }

    /// The method's name.
    pub fn name(self) -> &'static str {
        METHODS
            .iter()
            .find(|(_, m)| *m == self)
            .map_or("?", |(n, _)| n)
    }

    /// The summary's `bound_kind`: `inner`, `outer`, `reference` or `approximate` (Taylor; an
    /// extension of the contract's list, since first-order Taylor is neither).
    pub fn bound_kind(self) -> &'static str {
        match self {
            Method::LegendreScan | Method::ChebyshevScan | Method::MonteCarlo => "inner",
            Method::LegendreIa | Method::LegendreBernstein | Method::ChebyshevIa => "outer",
            Method::Scan => "reference",
            Method::Taylor => "approximate",
            Method::Auto => "inner",
        }
    }

    /// The polynomial family of a surrogate method.
    pub fn family(self) -> Option<Family> {
        match self {
            Method::LegendreScan
            | Method::LegendreIa
            | Method::LegendreBernstein
            | Method::Auto => Some(Family::Legendre),
            Method::ChebyshevScan | Method::ChebyshevIa => Some(Family::Chebyshev),
            _ => None,
        }
    }

    /// Whether the method scans its surrogate.
    pub fn scans_surrogate(self) -> bool {
        matches!(self, Method::LegendreScan | Method::ChebyshevScan)
    }

    /// Whether the method locates where its surrogate takes its extremes, so that the
    /// a-posteriori check can run the true model there.
    pub fn locates_extremes(self) -> bool {
        self.scans_surrogate()
    }
}
