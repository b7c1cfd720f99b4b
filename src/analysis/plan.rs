//! Where the model is run: sample points ξ in [-1, 1]^d for each method.
//!
//! - surrogate methods: the tensor Gauss grid of `order + 1` points per dimension (the design's
//!   row-major order, ξ_1 slowest);
//! - `taylor`: the centre, then `±h e_r` for each parameter ([`TAYLOR_STEP`]);
//! - `scan`: a uniform grid of `N` points per dimension, endpoints included;
//! - `monte-carlo`: `N` uniform random points from a seeded generator (splitmix64), so runs repeat.

use super::sparse::SparseDesign;
use super::Method;
use crate::uq::{Design, TaylorStencil, Truncation, UqError};
use std::sync::Arc;

/// Central-difference step of the Taylor baseline, in standard coordinates: small enough that the
/// second-order terms of smooth responses do not bias the slope (error ~h²/6 · f'''), large enough
/// that Newton-tolerance noise (~1e-10) divided by 2h stays below 1e-8.
pub const TAYLOR_STEP: f64 = 1e-2;

/// Largest number of model runs a plan may ask for (the machine's memory, and common sense): a
/// 21^d scan is refused above this, with the count in the message.
pub const MAX_RUNS: usize = 2_000_000;

/// The sample points of a study.
#[derive(Clone, Debug)]
pub enum Plan {
    /// A surrogate's design (tensor Gauss grid).
    Surrogate(Design),
    /// The Taylor stencil.
    Taylor(TaylorStencil),
    /// A uniform grid of this many points per dimension.
    Grid(usize),
    /// A sparse design (Leja sparse grid or Sobol' regression).
    Sparse(Arc<SparseDesign>),
    /// This many random points from this seed.
    Random {
        /// Number of points.
        samples: usize,
        /// Seed.
        seed: u64,
    },
}

/// A small, fast, seedable generator (splitmix64, Steele et al. 2014): uniform `u64`s.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next `u64`.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A uniform number in [-1, 1] (53 random bits).
    pub fn next_symmetric(&mut self) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        2.0 * unit - 1.0
    }
}

/// Point `index` of the grid of `counts[j]` evenly spaced points per dimension over [-1, 1], both
/// ends included (0 where a count is 1), row-major with the first dimension slowest: the scan's
/// grid (`counts` all equal) and a scanned element's (docs/method.md §12).
pub fn grid_point(counts: &[usize], index: usize) -> Vec<f64> {
    let mut point = vec![0.0; counts.len()];
    let mut rest = index;
    for (x, &n) in point.iter_mut().zip(counts).rev() {
        let i = rest % n;
        rest /= n;
        *x = if n <= 1 {
            0.0
        } else {
            -1.0 + 2.0 * i as f64 / (n - 1) as f64
        };
    }
    point
}

impl Plan {
    /// The plan of `method` for `dim` parameters.
    pub fn new(
        method: Method,
        dim: usize,
        order: usize,
        truncation: Truncation,
        grid: usize,
        samples: usize,
        seed: u64,
    ) -> Result<Plan, UqError> {
        Ok(match method {
            Method::Taylor => Plan::Taylor(TaylorStencil::new(dim, TAYLOR_STEP)?),
            Method::Scan => Plan::Grid(grid),
            Method::MonteCarlo => Plan::Random { samples, seed },
            surrogate => {
                let family = surrogate.family().ok_or(UqError::ZeroDimension)?;
                Plan::Surrogate(Design::new(family, dim, order, truncation)?)
            }
        })
    }

    /// Number of model runs (without the nominal run), or `None` if it overflows.
    pub fn runs(&self, dim: usize) -> Option<usize> {
        match self {
            Plan::Surrogate(design) => Some(design.n_points()),
            Plan::Taylor(stencil) => Some(stencil.n_points()),
            Plan::Grid(n) => n.checked_pow(u32::try_from(dim).ok()?),
            Plan::Random { samples, .. } => Some(*samples),
            Plan::Sparse(design) => Some(design.n_points()),
        }
    }

    /// The sample points, row-major (`runs × dim`).
    pub fn points(&self, dim: usize) -> Vec<f64> {
        match self {
            Plan::Surrogate(design) => design.points(),
            Plan::Sparse(design) => design.points().to_vec(),
            Plan::Taylor(stencil) => stencil.points(),
            Plan::Grid(n) => {
                let counts = vec![*n; dim];
                (0..self.runs(dim).unwrap_or(0))
                    .flat_map(|index| grid_point(&counts, index))
                    .collect()
            }
            Plan::Random { samples, seed } => {
                let mut generator = SplitMix64::new(*seed);
                (0..samples * dim)
                    .map(|_| generator.next_symmetric())
                    .collect()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_includes_endpoints_and_centre() {
        let plan = Plan::Grid(3);
        let points = plan.points(2);
        assert_eq!(points.len(), 18);
        assert_eq!(&points[..4], &[-1.0, -1.0, -1.0, 0.0]);
        assert_eq!(&points[8..10], &[0.0, 0.0]);
        assert_eq!(&points[16..], &[1.0, 1.0]);
    }

    #[test]
    fn random_points_repeat_with_the_seed_and_stay_in_the_box() {
        let a = Plan::Random {
            samples: 100,
            seed: 7,
        }
        .points(3);
        let b = Plan::Random {
            samples: 100,
            seed: 7,
        }
        .points(3);
        let c = Plan::Random {
            samples: 100,
            seed: 8,
        }
        .points(3);
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|x| (-1.0..=1.0).contains(x)));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        assert!(mean.abs() < 0.15, "mean {mean}");
    }
}
