//! Small dense linear algebra shared by the dynamics, the integrator and the bound optimisers:
//! in-place factorisations on caller-owned storage, so that hot loops allocate nothing.
//!
//! What it does not hold: the integrator's LU / Cholesky solver with its breakdown report
//! (`integrate::linalg`, built on [`cholesky`]) and the blocked Householder QR of the regression
//! designs (`uq::householder`).

pub mod cholesky;
