//! The envelopes under construction: per record time and output, the envelope point the bounding
//! gave (widened by every true run a phase makes), the nominal run's values and configuration,
//! and the hull of every true run. The design phase and the adaptive rounds fill the records,
//! the check widens them, and at the end they become the study's [`Envelope`] and the sinks'
//! blocks.
//!
//! Record-major `records × outputs` throughout: one block of records is a contiguous slice.
//! Does not: bound anything (the phases hand it their bounds and runs).

use super::envelope::Envelope;
use super::envelope::EnvelopePoint;

/// The envelopes under construction, and the hull of every true run.
#[derive(Clone)]
pub(super) struct Accumulator {
    /// Outputs per record.
    pub n_outputs: usize,
    /// Record times done, s.
    pub times: Vec<f64>,
    /// Record-major `records × outputs`.
    pub points: Vec<EnvelopePoint>,
    /// The nominal run's values, record-major `records × outputs`.
    pub nominal: Vec<f64>,
    /// The nominal run's configuration per record (`records × nq`).
    pub nominal_positions: Vec<f64>,
    /// The hull of every true run, record-major `records × outputs` (`(lowest, highest)`;
    /// `(+∞, −∞)` before any run).
    runs: Vec<(f64, f64)>,
    /// Each output's known range (`OutputKind::known_range`): every true value taken in is
    /// clamped to it first, since a study records some outputs continued beyond it (a contact
    /// pair apart records its signed force, docs/contacts.md §7). Empty: no output has one.
    known_ranges: Vec<Option<(f64, f64)>>,
}

impl Accumulator {
    /// Empty, with room for `n_records` records of `n_outputs` outputs.
    pub fn new(n_outputs: usize, n_records: usize) -> Accumulator {
        Accumulator {
            n_outputs,
            times: Vec::with_capacity(n_records),
            points: Vec::with_capacity(n_records * n_outputs),
            nominal: Vec::with_capacity(n_records * n_outputs),
            nominal_positions: Vec::new(),
            runs: Vec::with_capacity(n_records * n_outputs),
            known_ranges: Vec::new(),
        }
    }

    /// The same, taking every true value in clamped to its output's known range
    /// (`known_ranges[o]`, one per output; docs/contacts.md §7, "The signed force").
    pub fn with_known_ranges(mut self, known_ranges: &[Option<(f64, f64)>]) -> Accumulator {
        if known_ranges.iter().any(Option::is_some) {
            self.known_ranges = known_ranges.to_vec();
        }
        self
    }

    /// A true value of output `o` as reported: clamped to its known range.
    #[inline]
    pub fn reported(&self, o: usize, value: f64) -> f64 {
        crate::scene::clamp_to_range(value, self.known_ranges.get(o).copied().flatten())
    }

    /// Appends the nominal run's record at `time_s`: its outputs `values` and configuration
    /// `positions` (the next record's envelope points come from the bounding).
    pub fn push_nominal(&mut self, time_s: f64, values: &[f64], positions: &[f64]) {
        self.times.push(time_s);
        for (o, &value) in values.iter().enumerate() {
            let value = self.reported(o, value);
            self.nominal.push(value);
        }
        self.nominal_positions.extend_from_slice(positions);
    }

    /// Widens the envelopes and the hull of true runs at `record` to contain `values`, a true
    /// run's outputs (or the lowest or highest of several), as recorded (clamped here).
    pub fn widen(&mut self, record: usize, values: &[f64]) {
        let n_outputs = self.n_outputs;
        for (o, &value) in values.iter().enumerate().take(n_outputs) {
            let value = self.reported(o, value);
            let point = &mut self.points[record * n_outputs + o];
            point.lower = point.lower.min(value);
            point.upper = point.upper.max(value);
        }
        self.widen_runs(record, values);
    }

    /// Widens the hull of true runs at `record` to contain `values` (the envelopes already do).
    pub fn widen_runs(&mut self, record: usize, values: &[f64]) {
        let needed = (record + 1) * self.n_outputs;
        if self.runs.len() < needed {
            self.runs.resize(needed, (f64::INFINITY, f64::NEG_INFINITY));
        }
        for (o, &value) in values.iter().enumerate().take(self.n_outputs) {
            let value = self.reported(o, value);
            let hull = &mut self.runs[record * self.n_outputs + o];
            *hull = (hull.0.min(value), hull.1.max(value));
        }
    }

    /// The hull of every true run at `record` for `output`: `(lowest, highest)`, `(+∞, −∞)` before
    /// any run.
    pub fn run_hull(&self, record: usize, output: usize) -> (f64, f64) {
        self.runs
            .get(record * self.n_outputs + output)
            .copied()
            .unwrap_or((f64::INFINITY, f64::NEG_INFINITY))
    }

    /// The hull of every true run at `records`, record-major `(lowest, highest)` per output;
    /// `None` when some of those records never had a run.
    pub fn run_hulls(&self, records: std::ops::Range<usize>) -> Option<&[(f64, f64)]> {
        self.runs
            .get(records.start * self.n_outputs..records.end * self.n_outputs)
    }

    /// Widens every envelope point to the hull of true runs at its record and output (after
    /// runs that only widened the hull).
    pub fn widen_to_runs(&mut self) {
        for (point, &(lowest, highest)) in self.points.iter_mut().zip(&self.runs) {
            point.lower = point.lower.min(lowest);
            point.upper = point.upper.max(highest);
        }
    }

    /// Fills `envelope`'s series (times, bounds, nominal, hull of true runs, and the error
    /// estimate and outer bound where the points have them) from the records done.
    pub fn fill(&self, envelope: &mut Envelope) {
        let n_outputs = self.n_outputs;
        let n_done = self.times.len();
        envelope.times = self.times.clone();
        envelope.lower = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.upper = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.nominal = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.runs_lower = vec![Vec::with_capacity(n_done); n_outputs];
        envelope.runs_upper = vec![Vec::with_capacity(n_done); n_outputs];
        let has_error = self.points.iter().any(|p| p.error.is_some());
        if has_error {
            envelope.error = Some(vec![Vec::with_capacity(n_done); n_outputs]);
        }
        if self.points.iter().any(|p| p.outer.is_some()) {
            envelope.outer = Some((
                vec![Vec::with_capacity(n_done); n_outputs],
                vec![Vec::with_capacity(n_done); n_outputs],
            ));
        }
        for r in 0..n_done {
            for o in 0..n_outputs {
                let point = self.points[r * n_outputs + o];
                envelope.lower[o].push(point.lower);
                envelope.upper[o].push(point.upper);
                envelope.nominal[o].push(self.nominal[r * n_outputs + o]);
                let (lowest, highest) = self
                    .runs
                    .get(r * n_outputs + o)
                    .copied()
                    .unwrap_or((f64::INFINITY, f64::NEG_INFINITY));
                envelope.runs_lower[o].push(lowest);
                envelope.runs_upper[o].push(highest);
                if let Some(errors) = &mut envelope.error {
                    errors[o].push(point.error.unwrap_or(0.0));
                }
                if let Some((outer_lower, outer_upper)) = &mut envelope.outer {
                    // The outer bound contains the envelope (which contains every run).
                    let (lo, hi) = point.outer.unwrap_or((point.lower, point.upper));
                    outer_lower[o].push(lo.min(point.lower));
                    outer_upper[o].push(hi.max(point.upper));
                }
            }
        }
    }
}
