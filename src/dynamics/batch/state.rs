//! Per-sample vectors and the work buffers of the batched kernels, in structure-of-arrays layout
//! (docs/batch.md §1): entry `k` of sample `s` is lane `s % W` of `chunks[(s / W) · dim + k]`.

use super::lanes::{ForceLanes, InertiaLanes, Lanes, MotionLanes, TransformLanes};
use super::model::{BatchError, BatchModel};

/// One `dim`-vector per sample (a configuration `q`, a velocity `v`, torques …) in chunks of `W`
/// lanes. Tail lanes (after the last sample) are zero unless written.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchVectors<const W: usize> {
    /// Length of each sample's vector.
    pub dim: usize,
    /// Number of samples.
    pub size: usize,
    /// `chunks[c · dim + k]`: entry `k` of the samples of chunk `c`.
    pub chunks: Vec<Lanes<W>>,
}

impl<const W: usize> BatchVectors<W> {
    /// `size` zero vectors of length `dim`.
    pub fn zeros(dim: usize, size: usize) -> Self {
        Self {
            dim,
            size,
            chunks: vec![Lanes::zero(); dim * size.div_ceil(W)],
        }
    }

    /// Writes sample `sample`'s vector (`values: dim self.dim`; another length is an error).
    pub fn set_sample(&mut self, sample: usize, values: &[f64]) -> Result<(), BatchError> {
        if sample >= self.size {
            return Err(BatchError::NoSuchSample {
                sample,
                size: self.size,
            });
        }
        if values.len() != self.dim {
            return Err(BatchError::WrongLength {
                sample,
                expected: self.dim,
                got: values.len(),
            });
        }
        let (chunk, lane) = (sample / W, sample % W);
        for (k, value) in values.iter().enumerate() {
            self.chunks[chunk * self.dim + k].0[lane] = *value;
        }
        Ok(())
    }

    /// Copies sample `sample`'s vector into `out` (`out: dim self.dim`); `sample < self.size`.
    pub fn copy_sample(&self, sample: usize, out: &mut [f64]) {
        let (chunk, lane) = (sample / W, sample % W);
        let dim = self.dim;
        for (value, entry) in out
            .iter_mut()
            .zip(&self.chunks[chunk * dim..(chunk + 1) * dim])
        {
            *value = entry.0[lane];
        }
    }

    /// Sample `sample`'s vector (allocates; for tests and reports).
    pub fn sample(&self, sample: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.dim];
        self.copy_sample(sample, &mut out);
        out
    }

    /// The entries of chunk `chunk` (`dim` lane values).
    pub fn chunk(&self, chunk: usize) -> &[Lanes<W>] {
        &self.chunks[chunk * self.dim..(chunk + 1) * self.dim]
    }
}

/// Work buffers and results of the batched kernels for one [`BatchModel`]: the scalar
/// [`crate::dynamics::Data`]'s fields, per chunk. Per-body arrays are indexed like `model.joints`.
#[derive(Clone, Debug)]
pub struct BatchData<const W: usize> {
    /// `parent_from_body` of every body, `chunks · nb` (chunk-major).
    pub parent_from_body: Vec<TransformLanes<W>>,
    /// `world_from_body` of every body.
    pub world_from_body: Vec<TransformLanes<W>>,
    /// Body spatial velocities (body frame).
    pub velocity: Vec<MotionLanes<W>>,
    /// Body spatial accelerations (body frame, gravity as a base acceleration).
    pub acceleration: Vec<MotionLanes<W>>,
    /// Body forces (body frame).
    pub force: Vec<ForceLanes<W>>,
    /// Composite inertias (CRBA).
    pub composite: Vec<InertiaLanes<W>>,
    /// Mass matrices, `nv × nv` column-major per sample ([`super::crba`]).
    pub mass_matrix: BatchVectors<W>,
    /// Joint torques (`nv` per sample, [`super::rnea`]).
    pub tau: BatchVectors<W>,
    /// Bias `C(q, v) v + g(q)` (`nv` per sample, [`super::nonlinear_effects`]).
    pub bias: BatchVectors<W>,
}

impl<const W: usize> BatchData<W> {
    /// Allocates the buffers for `model`.
    pub fn new(model: &BatchModel<W>) -> Self {
        let per_body = model.joints.len() * model.chunk_count();
        Self {
            parent_from_body: vec![TransformLanes::identity(); per_body],
            world_from_body: vec![TransformLanes::identity(); per_body],
            velocity: vec![MotionLanes::zero(); per_body],
            acceleration: vec![MotionLanes::zero(); per_body],
            force: vec![ForceLanes::zero(); per_body],
            composite: vec![InertiaLanes::zero(); per_body],
            mass_matrix: BatchVectors::zeros(model.nv * model.nv, model.size),
            tau: BatchVectors::zeros(model.nv, model.size),
            bias: BatchVectors::zeros(model.nv, model.size),
        }
    }
}
