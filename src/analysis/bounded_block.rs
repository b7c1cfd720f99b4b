//! What bounding one block of records hands back, as plain data: each output's envelope point at
//! each record, where the method predicts its extremes, and the surrogates' Sobol' indices and
//! variances.
//!
//! Filled by `bounds.rs` and `sparse_bounds.rs`, read by the phases, the check's candidates and
//! `sobol_indices.rs`. Does not: fit or bound anything, or widen the envelopes (`accumulator.rs`).

use super::envelope::EnvelopePoint;

/// Where a surrogate (or `taylor`'s linearisation) predicts one output's extremes at one time. The
/// a-posteriori check runs the true model there.
#[derive(Clone, Debug, PartialEq)]
pub struct Extremes {
    /// Where the surrogate takes its minimum (standard coordinates, length d).
    pub argmin: Vec<f64>,
    /// Where it takes its maximum.
    pub argmax: Vec<f64>,
    /// The surrogate's minimum there (before the envelope takes in the model runs).
    pub at_min: f64,
    /// The surrogate's maximum.
    pub at_max: f64,
}

/// The envelopes of one block: `records × outputs` points, record-major, and beside each the
/// predicted extremes where the method locates them.
#[derive(Clone, Debug, Default)]
pub struct BoundedBlock {
    /// Envelope points, record-major.
    pub points: Vec<EnvelopePoint>,
    /// Predicted extremes, record-major (`None` where the method does not locate them).
    pub extremes: Vec<Option<Extremes>>,
    /// Surrogate methods: the main Sobol' index of every dimension for every output, from the
    /// surrogate's coefficients (record-major `records × outputs × d`, docs/sobol-indices.md);
    /// empty otherwise.
    pub main_indices: Vec<f64>,
    /// Surrogate methods: the total Sobol' indices, laid out as `main_indices`; empty otherwise.
    pub total_indices: Vec<f64>,
    /// Surrogate methods: each surrogate's variance under uniform ξ (record-major `records ×
    /// outputs`, the output's unit squared); empty otherwise.
    pub variances: Vec<f64>,
}
