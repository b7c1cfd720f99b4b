//! The time the bounding workers spend per phase (fit, inner and outer bound, Sobol' indices),
//! summed over the threads, and its reading as the report's `PhaseSeconds`.
//!
//! Does not: time the simulation or the phases of a study (`phase.rs`, `report.rs`).

use super::report::PhaseSeconds;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Nanoseconds the workers spent fitting, bounding (inner, outer) and computing Sobol' indices,
/// summed over the threads.
#[derive(Debug, Default)]
pub(super) struct BoundClock {
    fit: AtomicU64,
    inner: AtomicU64,
    outer: AtomicU64,
    sobol: AtomicU64,
}

/// Which phase a [`BoundClock`] reading belongs to.
#[derive(Clone, Copy)]
pub(super) enum BoundPhase {
    Fit,
    Inner,
    Outer,
    Sobol,
}

impl BoundClock {
    /// Adds the time since `since` to `phase` and returns now (the next phase's start).
    pub(super) fn lap(&self, phase: BoundPhase, since: Instant) -> Instant {
        let now = Instant::now();
        let nanos = u64::try_from(now.duration_since(since).as_nanos()).unwrap_or(u64::MAX);
        let counter = match phase {
            BoundPhase::Fit => &self.fit,
            BoundPhase::Inner => &self.inner,
            BoundPhase::Outer => &self.outer,
            BoundPhase::Sobol => &self.sobol,
        };
        counter.fetch_add(nanos, Ordering::Relaxed);
        now
    }

    pub(super) fn seconds(&self) -> PhaseSeconds {
        let seconds = |counter: &AtomicU64| counter.load(Ordering::Relaxed) as f64 * 1e-9;
        PhaseSeconds {
            fit: seconds(&self.fit),
            inner_bound: seconds(&self.inner),
            outer_bound: seconds(&self.outer),
            sobol_indices: seconds(&self.sobol),
            ..PhaseSeconds::default()
        }
    }
}
