//! How big a run may be, checked before it starts, so that a hopeless setting is refused with the
//! numbers instead of running "forever" or aborting on an allocation: the step count
//! ([`MAX_STEPS`], [`MIN_STEP_S`]), the memory a command keeps ([`MEMORY_BUDGET_BYTES`],
//! [`Scene::check_memory`]), the dense matrices of a robot's dynamics ([`check_dense_matrices`])
//! and the worker threads ([`MAX_THREADS`], [`check_threads`]).
//!
//! The study engine can call the same checks: [`Scene::record_count`] and [`Scene::check_memory`]
//! with its own footprint, and [`check_threads`] on its thread count.

use super::{Scene, SceneError};
use crate::model::Model;

/// Most integrator steps of one run. At the ~2–6 µs a step of a robot arm takes (README "Speed"),
/// 1e9 steps are one to two hours for a single run — and a study makes tens to thousands of runs.
/// A run that needs more steps has a step far below what its dynamics need, or a duration nobody
/// waits for.
pub const MAX_STEPS: u64 = 1_000_000_000;

/// Smallest step, s — a judgement, not a measurement: a nanosecond resolves dynamics up to hundreds
/// of MHz, far beyond any rigid robot model. Already at this step the position update `β'h² q̈` of
/// an acceleration of 1 m/s² (or rad/s²) is 1e-18, two orders below the rounding of a coordinate
/// of size 1 (positions then move through the velocity alone), and far smaller steps make `h²`
/// underflow (subnormal below 1.5e-154 s, zero below 2.2e-162 s), which leaves the scaled Newton
/// system without its mass term.
pub const MIN_STEP_S: f64 = 1e-9;

/// Most bytes of results a command may keep in memory (the recorded series of `simulate`, the
/// envelopes of `analyze` and `compare`, with the copies the summary JSON makes). 4 GiB leaves a
/// laptop usable; a run over it records at a rate or horizon that no plot or table can show.
pub const MEMORY_BUDGET_BYTES: u64 = 4 << 30;

/// Dense `nv × nv` matrices one simulated robot holds at once (mass matrix, Newton matrix, their
/// factors, the integrator's and the report's work space): measured from the peak resident memory
/// of `ribbon simulate` on generated chains (1 000 links: 71 MB, 8.9 × 8 nv² bytes; 2 000 links:
/// 262 MB, 8.2 ×), rounded up.
pub const DENSE_MATRICES_PER_SYSTEM: u64 = 9;

/// Refuses a robot whose dense matrices ([`DENSE_MATRICES_PER_SYSTEM`] of `nv × nv` doubles) would
/// take more than [`MEMORY_BUDGET_BYTES`], before anything allocates them (a 50 000-link chain
/// would need 20 GB per matrix and abort on the allocation); `command` names what was asked. Loading
/// and listing (`ribbon params`) hold no such matrix and are not limited. Returns the bytes.
pub fn check_dense_matrices(command: &str, model: &Model) -> Result<u64, SceneError> {
    let nv = model.nv as f64;
    let bytes = DENSE_MATRICES_PER_SYSTEM as f64 * nv * nv * 8.0;
    if bytes > MEMORY_BUDGET_BYTES as f64 {
        let largest = (MEMORY_BUDGET_BYTES as f64 / (DENSE_MATRICES_PER_SYSTEM as f64 * 8.0))
            .sqrt()
            .floor();
        return Err(SceneError::TooManyCoordinates {
            urdf: model.description.path.clone(),
            message: format!(
                "robot '{}' has {} velocity coordinates: {command} works on dense {}×{} matrices (mass matrix, Newton matrix, their factors; {DENSE_MATRICES_PER_SYSTEM} of them), {} in all, more than the budget of {} (MEMORY_BUDGET_BYTES); ribbon's dynamics are dense (CRBA and Cholesky), for robots of up to {largest} coordinates. `ribbon params` lists this robot's parameters without them",
                model.name(),
                model.nv,
                model.nv,
                model.nv,
                format_bytes(bytes),
                format_bytes(MEMORY_BUDGET_BYTES as f64)
            ),
        });
    }
    Ok(bytes as u64)
}

/// Most worker threads (`--threads`; 0 means all cores). Each thread holds its own model copy,
/// dynamics workspace and integrator, and a stack; beyond the cores there is nothing to gain, and
/// the largest machines have a few hundred cores.
pub const MAX_THREADS: usize = 1024;

/// Checks a `--threads` value (0 = all cores); `flag` names it in the message.
pub fn check_threads(flag: &str, threads: usize) -> Result<usize, SceneError> {
    if threads > MAX_THREADS {
        let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
        return Err(SceneError::Flag {
            flag: flag.to_string(),
            message: format!(
                "{threads} worker threads is more than the limit of {MAX_THREADS} (this machine has {cores} cores); use 0 (all cores) or at most {MAX_THREADS}"
            ),
        });
    }
    Ok(threads)
}

/// Formats a byte count with a binary prefix (`3.2 GiB`).
pub fn format_bytes(bytes: f64) -> String {
    const UNITS: [&str; 6] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut value = bytes;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{value:.0} bytes")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

impl Scene {
    /// Record times of a run: every `record_every` steps from t = 0, plus the end.
    pub fn record_count(&self) -> u64 {
        (self.n_steps as u64).div_ceil(self.record_every as u64) + 1
    }

    /// Checks that `command` fits [`MEMORY_BUDGET_BYTES`] when it keeps `values_per_record` f64
    /// values per record time (its series and their copies) plus `fixed_bytes`; returns the bytes.
    /// The message says how many record times and bytes the run would take and what to change.
    pub fn check_memory(
        &self,
        command: &str,
        values_per_record: u64,
        fixed_bytes: u64,
    ) -> Result<u64, SceneError> {
        let records = self.record_count();
        let bytes = (records as f64) * (values_per_record as f64) * 8.0 + fixed_bytes as f64;
        if bytes > MEMORY_BUDGET_BYTES as f64 {
            return Err(self.size_error(format!(
                "{command} would keep {records} record times ({} s at {} Hz) × {values_per_record} values × 8 bytes = {} in memory, more than the budget of {}; shorten the duration, record less often ([outputs] rate) or fewer outputs",
                self.duration_s,
                self.rate_hz,
                format_bytes(bytes),
                format_bytes(MEMORY_BUDGET_BYTES as f64)
            )));
        }
        Ok(bytes as u64)
    }

    /// An error about the run's size, naming the flag when the duration came from one.
    fn size_error(&self, message: String) -> SceneError {
        self.origins.duration.error(&self.origins.sidecar, message)
    }
}

/// Checks the step count of `duration_s / step_s` before anything is allocated: finite, at most
/// [`MAX_STEPS`], with a step of at least [`MIN_STEP_S`]. Returns the exact quotient (the caller
/// checks that it is whole).
pub fn check_step_count(duration_s: f64, step_s: f64) -> Result<f64, String> {
    if step_s < MIN_STEP_S {
        return Err(format!(
            "a step of {step_s:e} s is below the smallest step {MIN_STEP_S:e} s (MIN_STEP_S): no robot's dynamics need it, and the integrator's position updates would drown in rounding; use a step of 1e-5 … 1e-3 s"
        ));
    }
    let steps = duration_s / step_s;
    if !steps.is_finite() || steps > MAX_STEPS as f64 {
        return Err(format!(
            "{duration_s} s in steps of {step_s} s is {steps:.3e} steps, more than the limit of {MAX_STEPS:.0e} (MAX_STEPS) — hours of computing per run at a few µs per step; use a larger step or a shorter duration"
        ));
    }
    Ok(steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_counts_are_checked() {
        assert_eq!(check_step_count(1.0, 1e-3).unwrap(), 1000.0);
        let e = check_step_count(1.0, 5e-324).unwrap_err();
        assert!(e.contains("below the smallest step"), "{e}");
        let e = check_step_count(1e9, 1e-3).unwrap_err();
        assert!(
            e.contains("1.000e12 steps") && e.contains("MAX_STEPS"),
            "{e}"
        );
        let e = check_step_count(f64::MAX, 1.0).unwrap_err();
        assert!(e.contains("more than the limit"), "{e}");
    }

    #[test]
    fn threads_are_checked() {
        assert_eq!(check_threads("--threads", 0).unwrap(), 0);
        assert_eq!(
            check_threads("--threads", MAX_THREADS).unwrap(),
            MAX_THREADS
        );
        let e = check_threads("--threads", 100_000).unwrap_err().to_string();
        assert!(e.starts_with("--threads: 100000 worker threads"), "{e}");
    }

    #[test]
    fn bytes_are_readable() {
        assert_eq!(format_bytes(512.0), "512 bytes");
        assert_eq!(format_bytes(4.0 * 1024.0 * 1024.0 * 1024.0), "4.0 GiB");
    }
}
