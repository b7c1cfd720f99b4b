//! The samples the batch benches time (`batch_kernels.rs`, `kernel_timing.rs`): `size` copies of a
//! model whose link masses differ by 1 % from sample to sample, and per-sample states near the
//! scalar benches' state (q_i = 0.3 + 0.1 i, v_i = 0.5 − 0.2 i, a_i = −0.4 + 0.15 i, each shifted
//! by 0.01 per sample). Shared through `#[path]`.

#![allow(dead_code)]

use ribbon::dynamics::batch::{BatchModel, BatchVectors};
use ribbon::environment::Environment;
use ribbon::model::Model;
use ribbon::spatial::Vec3;

/// `base` with every link mass scaled by `1 + 0.01 · sample`.
pub fn sample_model(base: &Model, sample: usize) -> Model {
    let mut model = base.clone();
    for link in &mut model.description.links {
        link.inertial.mass *= 1.0 + 0.01 * sample as f64;
    }
    model.refresh();
    model
}

/// `offset + step · i + 0.01 · sample` for i = 0 … n−1.
pub fn sample_ramp(n: usize, offset: f64, step: f64, sample: usize) -> Vec<f64> {
    (0..n)
        .map(|i| offset + step * i as f64 + 0.01 * sample as f64)
        .collect()
}

/// A batch of `size` samples of `base` under the default gravity and its states `(q, v, a)`.
pub fn batch<const W: usize>(
    base: &Model,
    size: usize,
) -> (
    BatchModel<W>,
    BatchVectors<W>,
    BatchVectors<W>,
    BatchVectors<W>,
) {
    let models: Vec<Model> = (0..size).map(|s| sample_model(base, s)).collect();
    let gravity = Environment::default().gravity;
    let refs: Vec<(&Model, &Vec3)> = models.iter().map(|m| (m, &gravity)).collect();
    let model = BatchModel::<W>::from_models(&refs).expect("samples of one robot");
    let mut q = BatchVectors::zeros(base.nq, size);
    let mut v = BatchVectors::zeros(base.nv, size);
    let mut a = BatchVectors::zeros(base.nv, size);
    for s in 0..size {
        q.set_sample(s, &sample_ramp(base.nq, 0.3, 0.1, s))
            .expect("in the batch");
        v.set_sample(s, &sample_ramp(base.nv, 0.5, -0.2, s))
            .expect("in the batch");
        a.set_sample(s, &sample_ramp(base.nv, -0.4, 0.15, s))
            .expect("in the batch");
    }
    (model, q, v, a)
}
