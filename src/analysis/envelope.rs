//! The envelopes of a study: per output and record time, the lower and upper bound, the nominal
//! run, and what the method adds (an error estimate, an outer bound, the hull of true runs); one
//! output's envelope at one time as the phases build it (`EnvelopePoint`) and its two sides
//! (`Side`).
//!
//! Kept whole for the study's outputs (a few numbers per output per record time). Does not: build
//! them (the phases widen an `Accumulator`, which fills this at the end) or write them (`output/`).

use crate::scene::Output;

/// The envelopes of a whole study (kept: a few numbers per output per record time).
#[derive(Clone, Debug)]
pub struct Envelope {
    /// The outputs.
    pub outputs: Vec<Output>,
    /// Record times, s.
    pub times: Vec<f64>,
    /// `lower[o][k]`.
    pub lower: Vec<Vec<f64>>,
    /// `upper[o][k]`.
    pub upper: Vec<Vec<f64>>,
    /// `nominal[o][k]`.
    pub nominal: Vec<Vec<f64>>,
    /// `error[o][k]`, where the method has an estimate: the larger of the method's own estimate
    /// and the misfit the check observed at that output and time.
    pub error: Option<Vec<Vec<f64>>>,
    /// `outer_lower[o][k]`, `outer_upper[o][k]`: an outer bound of the surrogate beside the inner
    /// one, where the method has both (sparse designs); the gap between them is what the inner
    /// search might have missed on the surrogate.
    pub outer: Option<OuterBounds>,
    /// `runs_lower[o][k]`, `runs_upper[o][k]`: the smallest and largest value of every true-model
    /// run the study made (design, nominal, screening and check runs; excluded samples left out).
    /// The envelope contains them; where a surrogate is not trusted, they say how much of its
    /// envelope true runs actually reached.
    pub runs_lower: Vec<Vec<f64>>,
    /// See [`Envelope::runs_lower`].
    pub runs_upper: Vec<Vec<f64>>,
}

/// `(outer_lower[o][k], outer_upper[o][k])`.
pub type OuterBounds = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// One output's envelope at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvelopePoint {
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
    /// Error estimate, where the method has one.
    pub error: Option<f64>,
    /// An outer bound of the surrogate's range beside an inner one (sparse designs: interval
    /// arithmetic with exact `P_n` ranges), so that the gap between them can be reported.
    pub outer: Option<(f64, f64)>,
}

impl EnvelopePoint {
    /// The empty envelope (`lower = +∞`, `upper = −∞`), which the first value widened into it
    /// replaces.
    pub const EMPTY: EnvelopePoint = EnvelopePoint {
        lower: f64::INFINITY,
        upper: f64::NEG_INFINITY,
        error: None,
        outer: None,
    };
}

/// A side of an envelope: which extreme a candidate predicts, which bound a refinement moved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The surrogate's minimum.
    Lower,
    /// The surrogate's maximum.
    Upper,
}

/// The record where output `o`'s envelope is widest (the first of equal widths); `None` without
/// records.
pub fn widest_record(envelope: &Envelope, o: usize) -> Option<usize> {
    widest_index(envelope.lower.get(o)?, envelope.upper.get(o)?)
}

/// The index where `upper − lower` is largest (the first of equal widths); `None` when empty.
pub fn widest_index(lower: &[f64], upper: &[f64]) -> Option<usize> {
    lower
        .iter()
        .zip(upper)
        .map(|(l, u)| u - l)
        .enumerate()
        .fold(None, |best: Option<(usize, f64)>, (k, w)| match best {
            Some((_, b)) if w <= b => best,
            _ => Some((k, w)),
        })
        .map(|(k, _)| k)
}
