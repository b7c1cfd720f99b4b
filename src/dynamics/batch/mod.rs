//! The dynamics kernels over a batch of samples of one robot (docs/batch.md): the samples share
//! the tree; every value a parameter can move (inertias, joint placements and axes, gravity) and
//! every state is stored once per sample, `W` samples side by side in the lanes of a chunk
//! (structure of arrays), and each kernel walks the tree once per chunk doing every lane's
//! arithmetic together.
//!
//! Every lane's result is **bit for bit** what the scalar kernel ([`crate::dynamics::crba`],
//! [`crate::dynamics::rnea`], …) gives on the scalar model of that sample: the same IEEE
//! operations in the same order (docs/batch.md §2). `W` is the chunk width (4 is the default,
//! [`LANES`]); a batch whose size is not a multiple of `W` fills the last chunk's spare lanes with
//! sample 0's values and ignores them.
//!
//! - [`BatchModel`] — the shared tree and per-sample values, built from one [`crate::model::Model`]
//!   per sample;
//! - [`BatchVectors`] — one vector per sample (`q`, `v`, `q̈`, `τ`, …); [`BatchData`] — work
//!   buffers and results;
//! - [`forward_kinematics`], [`rnea`], [`nonlinear_effects`], [`crba`], and the per-sample
//!   Cholesky factorisation and solve of `M` ([`cholesky_factor`], [`cholesky_solve`]);
//! - [`Isa`] — the instruction set the kernels run with (baseline x86-64 SSE2, or AVX2 when the
//!   CPU has it; docs/batch.md §3).

mod cholesky;
mod crba;
mod joint;
mod kinematics;
pub mod lanes;
mod model;
mod rnea;
mod state;

pub use crate::isa::Isa;
pub(crate) use crate::isa::IsaKind;
pub use cholesky::{cholesky_factor, cholesky_factor_with_min_pivots, cholesky_solve};
pub use crba::crba;
pub use kinematics::forward_kinematics;
pub use model::{lane_transform, BatchError, BatchJoint, BatchModel, ChunkValues, LaneAxes};
pub use rnea::{nonlinear_effects, rnea, rnea_at_placements};
pub use state::{BatchData, BatchVectors};

/// The default chunk width: 4 `f64` lanes, one AVX2 register (docs/batch.md §3).
pub const LANES: usize = 4;
