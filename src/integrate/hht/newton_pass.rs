//! One Newton pass's tests (one matrix): convergence, the rate-based acceptance, the first
//! correction accepted by the last step's contraction, an aged reused matrix, multipliers at their
//! rounding floor, divergence (docs/step-control.md §2).

use super::super::error::WorstEntry;
use super::super::settings::NEWTON_REUSE_MAX_RATE;
use super::stats::HhtStats;

/// The rate-based convergence test trusts a contraction estimate only below this: a slowly
/// contracting iteration (ρ near 1) says little about the remaining error.
pub const RATE_TEST_MAX_CONTRACTION: f64 = 0.5;

/// What a converging Newton pass with a matrix factorised at the predictor measured over two or
/// more iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct MeasuredContraction {
    /// Slowest contraction `ρ = ‖Δ_k‖/‖Δ_{k−1}‖` of the pass.
    pub(super) rate: f64,
    /// `‖Δ_1‖_WRMS` of the pass's first correction.
    pub(super) first_correction: f64,
    /// The step size it was measured at, s.
    pub(super) h: f64,
    /// Measured with the full Newton matrix (else the diagonal one).
    pub(super) full: bool,
}

/// The previous step's contraction, carried into the first iteration of a Newton matrix
/// factorised at the predictor (docs/step-control.md §2, "Accepting the first correction"). As in
/// Radau5 and IDA, the remaining error after the first correction `Δ_1` is estimated as
/// `ρ/(1−ρ)·‖Δ_1‖`, with `ρ` the last measured contraction — raised in proportion when `‖Δ_1‖` is
/// larger than the first correction it was measured after (the quadratic part of Newton's error
/// grows with it), floored at [`CARRIED_RATE_FLOOR`], and the estimate required below
/// `1/`[`CARRIED_RATE_SAFETY`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CarriedContraction {
    /// Slowest contraction the last measuring pass saw.
    pub(super) rate: f64,
    /// `‖Δ_1‖_WRMS` of that pass.
    pub(super) first_correction: f64,
}

impl CarriedContraction {
    /// Whether a first correction of weighted RMS `first_correction` (≥ 1) leaves an iterate
    /// within tolerance by this contraction.
    fn accepts(self, first_correction: f64) -> bool {
        let growth = (first_correction / self.first_correction).max(1.0);
        let rate = (self.rate * growth).max(CARRIED_RATE_FLOOR);
        rate < RATE_TEST_MAX_CONTRACTION
            && CARRIED_RATE_SAFETY * rate / (1.0 - rate) * first_correction < 1.0
    }
}

/// Smallest contraction a carried estimate is taken to be. Contractions measured below it are
/// dominated by rounding (the second correction at its floor, not a linear contraction): on the
/// four-bar consecutive steps measured 4e-6 and then 7e-4, which a carried 4e-6 would have judged
/// 22 times its tolerance off.
pub const CARRIED_RATE_FLOOR: f64 = 1e-3;

/// Safety factor on the carried estimate of the first iterate's remaining error (the contraction
/// of this step is not measured, only the last one's).
pub const CARRIED_RATE_SAFETY: f64 = 2.0;

/// Result of the last Newton iteration, for the convergence test and the failure report.
#[derive(Debug, Clone, Copy)]
pub(super) struct IterationReport {
    /// ‖β'h² Δq̈‖_WRMS.
    pub(super) wrms_position: f64,
    /// ‖Δλ‖_WRMS (0 without constraints).
    pub(super) wrms_multiplier: f64,
    /// max-norm of the residual the correction was computed from.
    pub(super) residual_inf: f64,
    /// Largest weighted entry of the correction.
    pub(super) worst: WorstEntry,
}

impl IterationReport {
    /// The convergence measure: converged when < 1.
    pub(super) fn wrms(&self) -> f64 {
        self.wrms_position.max(self.wrms_multiplier)
    }
}

/// What a Newton pass does after an iteration ([`NewtonPass::judge`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum PassVerdict {
    /// The iterate is accepted.
    Converged,
    /// Iterate again with the same matrix (if the iteration limit allows).
    Continue,
    /// Stop this pass: the matrix has aged (pass 0) or the iteration diverges.
    GiveUp,
}

/// The tests after each iteration of one Newton pass (one matrix): convergence, the rate-based
/// acceptance, an aged reused matrix, multipliers at their rounding floor, divergence. Pass 0
/// iterates with the trajectory's stored factorisation, pass 1 with a fresh one at the predictor,
/// pass 2 with the refresh.
#[derive(Debug, Clone, Copy)]
pub(super) struct NewtonPass {
    pass: u8,
    previous: Option<IterationReport>,
    /// Slowest contraction `ρ` seen in this pass (0 before the second iteration).
    pub(super) slowest: f64,
    /// `‖Δ_1‖_WRMS` of the pass's first correction (0 before it).
    first_correction: f64,
    /// The matrix was factorised at the predictor: what the pass measures is carried to the next
    /// step, and `carried` may accept the first correction.
    pub(super) at_predictor: bool,
    /// The last step's contraction, for the first correction.
    carried: Option<CarriedContraction>,
}

impl NewtonPass {
    pub(super) fn new(pass: u8) -> Self {
        Self {
            pass,
            previous: None,
            slowest: 0.0,
            first_correction: 0.0,
            at_predictor: false,
            carried: None,
        }
    }

    /// Pass 1 with the matrix factorised at the predictor; `carried`: the last step's contraction
    /// ([`NewtonMemory::carried_contraction`]).
    pub(super) fn at_predictor(carried: Option<CarriedContraction>) -> Self {
        Self {
            at_predictor: true,
            carried,
            ..Self::new(1)
        }
    }

    /// What a converged pass measured, to carry to the next step (`None` for a pass that did not
    /// start at the predictor, or that converged at its first correction).
    pub(super) fn measured(&self, h: f64, full: bool) -> Option<MeasuredContraction> {
        (self.at_predictor && self.previous.is_some()).then_some(MeasuredContraction {
            rate: self.slowest,
            first_correction: self.first_correction,
            h,
            full,
        })
    }

    /// Judges the iteration that produced `report` (counting a rounding-limited acceptance in
    /// `stats`).
    #[inline]
    pub(super) fn judge(&mut self, report: IterationReport, stats: &mut HhtStats) -> PassVerdict {
        let rate = self.previous.map(|prev| report.wrms() / prev.wrms());
        if let Some(rate) = rate {
            self.slowest = self.slowest.max(rate);
        }
        if report.wrms() < 1.0 {
            return PassVerdict::Converged;
        }
        if self.previous.is_none() {
            self.first_correction = report.wrms();
            if self
                .carried
                .is_some_and(|carried| carried.accepts(report.wrms()))
            {
                stats.carried_rate_acceptances += 1;
                return PassVerdict::Converged;
            }
        }
        if let (Some(prev), Some(rate)) = (self.previous, rate) {
            // Rate-based test (Hairer & Wanner, Radau5): modified Newton contracts linearly with
            // ρ = ‖Δ_k‖/‖Δ_{k−1}‖, so the iterate's remaining error is about ρ/(1−ρ)·‖Δ_k‖; accept
            // when that estimate is within tolerance instead of spending one more iteration to see
            // a correction below it.
            if rate < RATE_TEST_MAX_CONTRACTION && rate / (1.0 - rate) * report.wrms() < 1.0 {
                return PassVerdict::Converged;
            }
            if self.pass == 0 && rate > NEWTON_REUSE_MAX_RATE {
                // The stored matrix has aged (a stagnating Δλ included: that test is for a fresh
                // matrix): factorise a fresh one now rather than spend the iterations a slow
                // contraction needs.
                return PassVerdict::GiveUp;
            }
            // Multipliers at the rounding floor of Φ/(β'h²): positions converged twice in a row
            // and Δλ stopped shrinking. Accept and count it.
            if report.wrms_position < 1.0
                && prev.wrms_position < 1.0
                && report.wrms_multiplier > LAMBDA_STAGNATION_RATIO * prev.wrms_multiplier
            {
                stats.rounding_limited_steps += 1;
                return PassVerdict::Converged;
            }
            if report.wrms() > prev.wrms() {
                // Diverging: refresh now rather than after the remaining iterations.
                return PassVerdict::GiveUp;
            }
        }
        self.previous = Some(report);
        PassVerdict::Continue
    }
}

/// When the position-level correction has passed the test in two consecutive iterations but the
/// multiplier correction shrank by less than this factor, `Δλ` is rounding noise: `Φ` is evaluated to
/// ~1e-16 (relative to the mechanism's size), and the scaled row turns that into a `Δλ` of
/// ~1e-16 · m_eff / (β'h²) — 1e-9 N at h = 5e-4, 1e-5 N at h = 1e-5 — which no tolerance below it can
/// pass. A genuinely converging modified Newton shrinks `Δλ` by far more than 2× per iteration.
const LAMBDA_STAGNATION_RATIO: f64 = 0.5;

#[cfg(test)]
mod tests {
    use super::*;

    /// A report whose convergence measure is `wrms` (positions only).
    fn report(wrms: f64) -> IterationReport {
        IterationReport {
            wrms_position: wrms,
            wrms_multiplier: 0.0,
            residual_inf: 0.0,
            worst: WorstEntry::Coordinate {
                index: 0,
                weighted_correction: wrms,
            },
        }
    }

    fn carried(rate: f64, first_correction: f64) -> CarriedContraction {
        CarriedContraction {
            rate,
            first_correction,
        }
    }

    #[test]
    fn carried_contraction_accepts_within_its_safety_factor() {
        // ρ = 0.01: 2 · 0.01/0.99 · w < 1 ⇔ w < 49.5.
        assert!(carried(0.01, 60.0).accepts(49.0));
        assert!(!carried(0.01, 60.0).accepts(50.0));
    }

    #[test]
    fn carried_contraction_grows_with_a_larger_first_correction() {
        // Measured after a first correction of 10: one of 30 is judged at ρ = 0.03 (2 · 0.03/0.97
        // · 30 = 1.86, refused), where the measured ρ = 0.01 alone would accept it (0.61).
        const { assert!(CARRIED_RATE_SAFETY * 0.01 / 0.99 * 30.0 < 1.0) };
        assert!(!carried(0.01, 10.0).accepts(30.0));
        // One of 20: ρ = 0.02, 2 · 0.02/0.98 · 20 = 0.82, accepted.
        assert!(carried(0.01, 10.0).accepts(20.0));
        // A smaller first correction keeps the measured rate (no credit below it).
        assert_eq!(
            carried(0.01, 60.0).accepts(40.0),
            carried(0.01, 40.0).accepts(40.0)
        );
    }

    #[test]
    fn carried_contraction_is_floored_against_rounding() {
        // ρ = 1e-6 counts as the floor 1e-3: accepted below w = 499.5, refused above.
        assert!(carried(1e-6, 1e3).accepts(400.0));
        assert!(!carried(1e-6, 1e3).accepts(600.0));
        assert!(!carried(0.0, 1e3).accepts(600.0));
    }

    #[test]
    fn carried_contraction_is_not_trusted_near_one() {
        // ρ ≥ RATE_TEST_MAX_CONTRACTION says nothing, however small the correction.
        assert!(!carried(0.5, 1.0).accepts(1.0));
        assert!(!carried(0.2, 1.0).accepts(3.0));
    }

    #[test]
    fn only_a_pass_at_the_predictor_accepts_its_first_correction_by_the_carried_rate() {
        let mut stats = HhtStats::default();
        let mut at_predictor = NewtonPass::at_predictor(Some(carried(0.01, 10.0)));
        assert_eq!(
            at_predictor.judge(report(5.0), &mut stats),
            PassVerdict::Converged
        );
        assert_eq!(stats.carried_rate_acceptances, 1);
        // Accepted at its first correction: nothing measured to carry on.
        assert_eq!(at_predictor.measured(1e-3, false), None);

        let mut without = NewtonPass::at_predictor(None);
        assert_eq!(
            without.judge(report(5.0), &mut stats),
            PassVerdict::Continue
        );
        let mut refresh = NewtonPass::new(2);
        assert_eq!(
            refresh.judge(report(5.0), &mut stats),
            PassVerdict::Continue
        );
        assert_eq!(stats.carried_rate_acceptances, 1);
    }

    #[test]
    fn a_pass_at_the_predictor_measures_its_slowest_contraction() {
        let mut stats = HhtStats::default();
        let mut pass = NewtonPass::at_predictor(None);
        assert_eq!(pass.judge(report(100.0), &mut stats), PassVerdict::Continue);
        // ρ = 0.4: 0.4/0.6 · 40 > 1, iterate again.
        assert_eq!(pass.judge(report(40.0), &mut stats), PassVerdict::Continue);
        // ρ = 0.02: 0.02/0.98 · 0.8 < 1 (and 0.8 < 1 anyway).
        assert_eq!(pass.judge(report(0.8), &mut stats), PassVerdict::Converged);
        assert_eq!(
            pass.measured(1e-3, true),
            Some(MeasuredContraction {
                rate: 0.4,
                first_correction: 100.0,
                h: 1e-3,
                full: true,
            })
        );
        let mut refresh = NewtonPass::new(2);
        refresh.judge(report(100.0), &mut stats);
        refresh.judge(report(0.5), &mut stats);
        assert_eq!(refresh.measured(1e-3, false), None);
    }
}
