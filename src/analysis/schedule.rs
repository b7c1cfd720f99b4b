//! The record time grid of a study: which steps are recorded, at what times, and how the horizon
//! is cut into blocks of records. Every stage (design, check, adaptive rounds, shards, merge) asks
//! this one type, so that they agree on the grid bit for bit.

use crate::scene::Scene;

/// Values (samples × outputs × records) one block may hold: 4 M values = 32 MB.
pub const BLOCK_VALUE_BUDGET: usize = 4_000_000;
/// Most record times per block: keeps memory flat in the horizon (the 10×-longer-run test) while a
/// block still amortises the threads' start-up.
pub const MAX_BLOCK_RECORDS: usize = 50;

/// Record times of a horizon of fixed steps: every `record_every` steps from t = 0, and the last
/// step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordSchedule {
    /// Steps of the horizon.
    pub n_steps: usize,
    /// Steps between records (≥ 1).
    pub record_every: usize,
    /// The step, s, as its IEEE-754 bits (so that the schedule compares exactly).
    pub step_bits: u64,
}

impl RecordSchedule {
    /// The schedule of `scene`.
    pub fn of(scene: &Scene) -> RecordSchedule {
        RecordSchedule {
            n_steps: scene.n_steps,
            record_every: scene.record_every.max(1),
            step_bits: scene.step_s.to_bits(),
        }
    }

    /// The step, s.
    pub fn step_s(&self) -> f64 {
        f64::from_bits(self.step_bits)
    }

    /// Number of record times (t = 0 included).
    pub fn len(&self) -> usize {
        self.n_steps.div_ceil(self.record_every) + 1
    }

    /// Whether the schedule has no records (never: t = 0 is always recorded).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The step at which record `record` is taken.
    pub fn step_of(&self, record: usize) -> usize {
        (record * self.record_every).min(self.n_steps)
    }

    /// The time of record `record`, s.
    pub fn time(&self, record: usize) -> f64 {
        self.step_of(record) as f64 * self.step_s()
    }

    /// Record times per block for `runs` samples of `n_outputs` outputs: as many as
    /// [`BLOCK_VALUE_BUDGET`] values allow, at most [`MAX_BLOCK_RECORDS`] and the horizon.
    pub fn block_records(&self, runs: usize, n_outputs: usize) -> usize {
        (BLOCK_VALUE_BUDGET / (runs * n_outputs).max(1))
            .clamp(1, MAX_BLOCK_RECORDS)
            .min(self.len())
    }

    /// The blocks `(first record, records)` of `block` records each (the last may be shorter).
    pub fn blocks(&self, block: usize) -> impl Iterator<Item = (usize, usize)> {
        let (n, block) = (self.len(), block.max(1));
        (0..n.div_ceil(block)).map(move |b| (b * block, block.min(n - b * block)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_step_is_recorded_and_blocks_cover_the_horizon() {
        let schedule = RecordSchedule {
            n_steps: 10,
            record_every: 3,
            step_bits: 0.01_f64.to_bits(),
        };
        assert_eq!(schedule.len(), 5);
        assert_eq!(
            (0..5).map(|r| schedule.step_of(r)).collect::<Vec<_>>(),
            [0, 3, 6, 9, 10]
        );
        assert_eq!(schedule.time(4), 10.0 * 0.01);
        let blocks: Vec<_> = schedule.blocks(2).collect();
        assert_eq!(blocks, [(0, 2), (2, 2), (4, 1)]);
        assert_eq!(schedule.block_records(1, 1), 5);
    }
}
