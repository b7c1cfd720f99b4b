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

/// `return kernel::<N>(args…)` when `n` is `N` in `1..=`[`FIXED_SIZE_UP_TO`]; otherwise nothing.
macro_rules! return_for_fixed_size {
    ($n:expr, $kernel:ident($($arg:expr),*)) => {
        match $n {
            1 => return $kernel::<1>($($arg),*),
            2 => return $kernel::<2>($($arg),*),
            3 => return $kernel::<3>($($arg),*),
            4 => return $kernel::<4>($($arg),*),
            5 => return $kernel::<5>($($arg),*),
            6 => return $kernel::<6>($($arg),*),
            7 => return $kernel::<7>($($arg),*),
            8 => return $kernel::<8>($($arg),*),
            9 => return $kernel::<9>($($arg),*),
            10 => return $kernel::<10>($($arg),*),
            11 => return $kernel::<11>($($arg),*),
            12 => return $kernel::<12>($($arg),*),
            13 => return $kernel::<13>($($arg),*),
            14 => return $kernel::<14>($($arg),*),
            15 => return $kernel::<15>($($arg),*),
            16 => return $kernel::<16>($($arg),*),
            _ => {}
        }
    };
}
use return_for_fixed_size;
