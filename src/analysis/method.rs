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

    /// Whether the a-posteriori check (docs/method.md §7) runs after the method: every method
    /// whose envelope rests on a surrogate or on `taylor`'s linearisation locates where that
    /// approximation takes its extremes, so that the true model can be run there. `scan` and
    /// `monte-carlo` are made of true runs only: there is nothing to check.
    pub fn is_checked(self) -> bool {
        self.family().is_some() || self == Method::Taylor
    }

    /// How the check measures a miss of this method's envelope ([`CheckMisfit`]).
    pub fn check_misfit(self) -> CheckMisfit {
        match self.bound_kind() {
            "outer" | "approximate" => CheckMisfit::Excess,
            _ => CheckMisfit::Prediction,
        }
    }
}

/// What the a-posteriori check counts as a miss at a checked point (docs/method.md §7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckMisfit {
    /// `|true − predicted|` at the surrogate's predicted extremes: an inner bound (a scan of the
    /// surrogate) claims to reach the true extremes, so any difference there counts.
    Prediction,
    /// How far a true value lies outside the envelope as it was before the check widened it
    /// (0 inside): an outer bound (interval arithmetic, Bernstein, Chebyshev inclusion) or
    /// `taylor`'s linearised range may be loose without being wrong, but a true run outside it
    /// breaks it.
    Excess,
}
