//! Which family of orthogonal polynomials a surrogate is expanded in: the name alone, which the
//! error type can carry without depending on the polynomials. Their values, derivatives and
//! quadrature rules are `basis.rs`'s (`impl Family` there).

/// A family of orthogonal polynomials on [-1, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// `P_0 = 1`, `P_1 = ξ`, `(n+1) P_{n+1} = (2n+1) ξ P_n − n P_{n−1}`; orthogonal with weight 1;
    /// fitted on Gauss–Legendre nodes.
    Legendre,
    /// `T_0 = 1`, `T_1 = ξ`, `T_{n+1} = 2ξ T_n − T_{n−1}` (`T_n(cos θ) = cos nθ`); orthogonal with
    /// weight 1/√(1−ξ²); fitted on Gauss–Chebyshev nodes (docs/method.md §4).
    Chebyshev,
}
