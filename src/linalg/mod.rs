//! Small dense linear algebra shared by the dynamics, the integrator and the bound optimisers:
//! in-place factorisations on caller-owned storage, so that hot loops allocate nothing.
//!
//! What it does not hold: the integrator's solver with its breakdown report
//! (`integrate::dense_solver`, built on [`cholesky`] and [`lu`]) and the blocked Householder QR of
//! the regression designs (`uq::householder`).

pub mod cholesky;
pub mod lu;

/// Largest `n` for which the factorisations and solves here run a kernel compiled for that size:
/// the same operations in the same order as for any other `n` (so the same bits), with the loop
/// bounds known to the compiler, which unrolls them and drops the index checks. The dynamics and
/// Newton matrices of the robots we ship are 6 to 14 rows; on the example-robot-data ur5 the 6 × 6
/// Cholesky factorisation went from 691 to 419 instructions and its solve from 538 to 156 (per
/// sample and step of a lock-step study under callgrind, benches/README.md).
pub const FIXED_SIZE_UP_TO: usize = 16;

/// `return body` with the const `SIZE` (the caller's name for it) equal to `n` when `n` is in
/// `1..=`[`FIXED_SIZE_UP_TO`]; otherwise nothing: `return_for_fixed_size!(n, N => kernel::<N>(…))`.
/// The one list of the sizes that the factorisations and solves here and the batched ones
/// (`dynamics::batch::cholesky`) compile for.
macro_rules! return_for_fixed_size {
    ($n:expr, $size:ident => $body:expr) => {
        $crate::linalg::return_for_fixed_size!(
            @sizes $n, $size, $body, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16
        )
    };
    (@sizes $n:expr, $size:ident, $body:expr, $($fixed:literal)*) => {
        match $n {
            $($fixed => {
                const $size: usize = $fixed;
                return $body;
            })*
            _ => {}
        }
    };
}
pub(crate) use return_for_fixed_size;
