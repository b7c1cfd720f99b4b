//! A batch of samples of one robot: the tree shared by all of them, and every value a parameter can
//! move (joint placements and axes, body inertias, gravity) once per sample, laid out in chunks of
//! `W` lanes (docs/batch.md §1).

use super::lanes::{InertiaLanes, Lanes, TransformLanes, V3};
use super::Isa;
use crate::model::{JointKind, Model};
use crate::spatial::{Inertia, Mat3, Transform, Vec3};
use thiserror::Error;

/// Why a set of models cannot be batched.
#[derive(Debug, Error, PartialEq)]
pub enum BatchError {
    /// No model was given.
    #[error("a batch needs at least one model (sample), got none")]
    Empty,
    /// A sample's model has another tree than the first one.
    #[error("sample {sample}'s model differs from sample 0's in {what}: a batch holds samples of one robot (same joints, parents and joint types; only values may differ); build it from models loaded from the same URDF with the same options")]
    DifferentTree {
        /// Index of the offending sample.
        sample: usize,
        /// What differs (`"the number of joints"`, `"joint 'j2' (type or parent)"`, …).
        what: String,
    },
    /// A sample's vector of the wrong length.
    #[error(
        "sample {sample}'s vector has {got} entries, expected {expected} (one per coordinate)"
    )]
    WrongLength {
        /// The sample written.
        sample: usize,
        /// The batch vectors' length.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// A lane index outside the batch.
    #[error("sample {sample} is outside a batch of {size} samples")]
    NoSuchSample {
        /// The index asked for.
        sample: usize,
        /// The batch size.
        size: usize,
    },
}

/// The part of a joint that every sample shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchJoint {
    /// What motion the joint allows.
    pub kind: JointKind,
    /// The parent body, `None` for the world.
    pub parent: Option<usize>,
    /// Index of the first coordinate in `q`.
    pub q_index: usize,
    /// Index of the first velocity coordinate in `v`.
    pub v_index: usize,
}

impl BatchJoint {
    /// Number of position coordinates (1, or 7 for a floating joint).
    pub fn nq(&self) -> usize {
        match self.kind {
            JointKind::Floating => 7,
            _ => 1,
        }
    }

    /// Number of velocity coordinates (1, or 6 for a floating joint).
    pub fn nv(&self) -> usize {
        match self.kind {
            JointKind::Floating => 6,
            _ => 1,
        }
    }
}

/// One chunk of `W` samples' values: per joint its placement in the parent body and its unit axis,
/// per body its spatial inertia, and gravity.
#[derive(Clone, Debug)]
pub struct ChunkValues<const W: usize> {
    /// `parent_from_joint` of every joint (same order as `model.joints`).
    pub parent_from_joint: Vec<TransformLanes<W>>,
    /// Unit axis of every joint in its joint frame.
    pub axis: Vec<V3<W>>,
    /// Per joint, which lanes are a revolute joint about a coordinate axis of its frame
    /// ([`crate::model::Joint::revolute_coordinate_axis`]; docs/batch.md §7).
    pub coordinate_axes: Vec<LaneAxes<W>>,
    /// Merged spatial inertia of every body, about the body origin.
    pub inertia: Vec<InertiaLanes<W>>,
    /// Gravity in the world frame (m/s²).
    pub gravity: V3<W>,
}

/// `size` samples of one robot, in `ceil(size / W)` chunks of `W` lanes; sample `s` is lane
/// `s % W` of chunk `s / W`. The lanes after the last sample (the tail of the last chunk) hold
/// sample 0's values: they are computed and ignored.
#[derive(Clone, Debug)]
pub struct BatchModel<const W: usize> {
    /// The shared tree, joint `i` moving body `i`.
    pub joints: Vec<BatchJoint>,
    /// Number of position coordinates.
    pub nq: usize,
    /// Number of velocity coordinates.
    pub nv: usize,
    /// Number of samples (lanes in use).
    pub size: usize,
    /// Per-sample values, one entry per chunk.
    pub chunks: Vec<ChunkValues<W>>,
    /// The instruction set the kernels run with ([`Isa::best`] after [`BatchModel::from_models`]).
    pub isa: Isa,
    /// Column-major indices (`row + column · nv`) of the entries of `M` that couple two joints
    /// neither of which is an ancestor of the other: zero in every configuration, and the only
    /// entries the batched CRBA does not write (it zeroes them instead of the whole matrix).
    pub mass_matrix_zeros: Vec<usize>,
}

impl<const W: usize> BatchModel<W> {
    /// Batches `samples` (one model and the gravity it is simulated in, m/s² in the world frame,
    /// per sample, in sample order): the models' trees must be identical; their values may differ.
    /// Allocates once.
    pub fn from_models(samples: &[(&Model, &Vec3)]) -> Result<Self, BatchError> {
        let &(first, first_gravity) = samples.first().ok_or(BatchError::Empty)?;
        let joints: Vec<BatchJoint> = first
            .joints
            .iter()
            .map(|j| BatchJoint {
                kind: j.kind,
                parent: j.parent,
                q_index: j.q_index,
                v_index: j.v_index,
            })
            .collect();
        let chunk_count = samples.len().div_ceil(W);
        let nb = joints.len();
        let mass_matrix_zeros = decoupled_entries(&joints, first.nv);
        let blank = ChunkValues {
            parent_from_joint: vec![TransformLanes::identity(); nb],
            axis: vec![[Lanes::zero(); 3]; nb],
            coordinate_axes: vec![LaneAxes::None; nb],
            inertia: vec![InertiaLanes::zero(); nb],
            gravity: [Lanes::zero(); 3],
        };
        let mut batch = BatchModel {
            joints,
            nq: first.nq,
            nv: first.nv,
            size: samples.len(),
            chunks: vec![blank; chunk_count],
            isa: Isa::best(),
            mass_matrix_zeros,
        };
        for (sample, (model, _)) in samples.iter().enumerate() {
            batch.check_tree(sample, model)?;
        }
        for lane in 0..chunk_count * W {
            // Tail lanes take sample 0's values.
            let (model, gravity) = samples.get(lane).copied().unwrap_or((first, first_gravity));
            batch.write_lane(lane, model, gravity);
        }
        Ok(batch)
    }

    /// Replaces sample `sample`'s values with `model`'s (same tree) and its gravity with `gravity`
    /// (m/s², world frame). Allocates nothing.
    pub fn set_sample(
        &mut self,
        sample: usize,
        model: &Model,
        gravity: &Vec3,
    ) -> Result<(), BatchError> {
        if sample >= self.size {
            return Err(BatchError::NoSuchSample {
                sample,
                size: self.size,
            });
        }
        self.check_tree(sample, model)?;
        self.write_lane(sample, model, gravity);
        Ok(())
    }

    /// Number of chunks of `W` lanes.
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    fn check_tree(&self, sample: usize, model: &Model) -> Result<(), BatchError> {
        let differs = |what: String| Err(BatchError::DifferentTree { sample, what });
        if model.joints.len() != self.joints.len() {
            return differs(format!(
                "the number of moving joints ({} against {})",
                model.joints.len(),
                self.joints.len()
            ));
        }
        for (joint, shared) in model.joints.iter().zip(&self.joints) {
            if joint.kind != shared.kind
                || joint.parent != shared.parent
                || joint.q_index != shared.q_index
                || joint.v_index != shared.v_index
            {
                return differs(format!(
                    "joint '{}' (type, parent or coordinates)",
                    joint.name
                ));
            }
        }
        Ok(())
    }

    /// Writes one lane's values from `model` and `gravity` (tree already checked).
    fn write_lane(&mut self, lane: usize, model: &Model, gravity: &Vec3) {
        let (chunk, l) = (&mut self.chunks[lane / W], lane % W);
        for (i, joint) in model.joints.iter().enumerate() {
            set_transform(&mut chunk.parent_from_joint[i], l, &joint.parent_from_joint);
            set_v3(&mut chunk.axis[i], l, joint.axis());
            chunk.coordinate_axes[i] =
                chunk.coordinate_axes[i].with_lane(l, joint.revolute_coordinate_axis());
        }
        for (i, body) in model.bodies.iter().enumerate() {
            set_inertia(&mut chunk.inertia[i], l, &body.inertia);
        }
        set_v3(&mut chunk.gravity, l, gravity);
    }
}

/// Which lanes of a chunk turn one joint about a coordinate axis `e_k` of its frame: the batched
/// kernels leave out the joint motion's zero products where the scalar kernels do, lane for lane,
/// so that every lane keeps the scalar bits, signs of zero included (docs/batch.md §7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LaneAxes<const W: usize> {
    /// Every lane, about `e_k` (`k` ∈ {0, 1, 2}): the kernels' aligned path.
    Every(usize),
    /// No lane: the general formulas.
    None,
    /// Some lanes (each `Some(k)`), not all about one axis (a study that moves an axis, its
    /// nominal sample exactly on `e_k`): the general formulas for the chunk, then the aligned
    /// lanes again by the scalar kernels' aligned path.
    Mixed([Option<usize>; W]),
}

impl<const W: usize> LaneAxes<W> {
    /// Every lane's `Some(k)` or `None`.
    pub fn per_lane(&self) -> [Option<usize>; W] {
        match *self {
            LaneAxes::Every(k) => [Some(k); W],
            LaneAxes::None => [None; W],
            LaneAxes::Mixed(lanes) => lanes,
        }
    }

    /// `self` with lane `lane` set to `axis`, summarised again.
    fn with_lane(&self, lane: usize, axis: Option<usize>) -> Self {
        let mut lanes = self.per_lane();
        lanes[lane] = axis;
        match lanes[0] {
            first if lanes.iter().any(|a| *a != first) => LaneAxes::Mixed(lanes),
            Some(k) => LaneAxes::Every(k),
            None => LaneAxes::None,
        }
    }
}

pub(super) fn set_v3<const W: usize>(target: &mut V3<W>, lane: usize, value: &Vec3) {
    for (t, v) in target.iter_mut().zip(value.iter()) {
        t.0[lane] = *v;
    }
}

fn set_m3<const W: usize>(target: &mut [[Lanes<W>; 3]; 3], lane: usize, value: &Mat3) {
    for (i, row) in target.iter_mut().enumerate() {
        for (j, t) in row.iter_mut().enumerate() {
            t.0[lane] = value[(i, j)];
        }
    }
}

pub(super) fn set_transform<const W: usize>(
    target: &mut TransformLanes<W>,
    lane: usize,
    value: &Transform,
) {
    set_m3(&mut target.rotation, lane, &value.rotation);
    set_v3(&mut target.translation, lane, &value.translation);
}

fn set_inertia<const W: usize>(target: &mut InertiaLanes<W>, lane: usize, value: &Inertia) {
    target.mass.0[lane] = value.mass;
    set_v3(&mut target.first_moment, lane, &value.first_moment);
    set_m3(&mut target.rotational, lane, &value.rotational);
}

/// Lane `lane` of a lane 3-vector.
pub(crate) fn lane_v3<const W: usize>(value: &V3<W>, lane: usize) -> Vec3 {
    Vec3::new(value[0].0[lane], value[1].0[lane], value[2].0[lane])
}

/// Lane `lane` of a lane transform.
pub fn lane_transform<const W: usize>(value: &TransformLanes<W>, lane: usize) -> Transform {
    let r = &value.rotation;
    let rotation = Mat3::from_fn(|i, j| r[i][j].0[lane]);
    Transform::new(rotation, lane_v3(&value.translation, lane))
}

/// The column-major indices of the `nv × nv` entries that couple two joints neither of which is an
/// ancestor of the other (`BatchModel::mass_matrix_zeros`).
fn decoupled_entries(joints: &[BatchJoint], nv: usize) -> Vec<usize> {
    let mut coupled = vec![false; nv * nv];
    for (i, joint) in joints.iter().enumerate() {
        let mut ancestor = Some(i);
        while let Some(a) = ancestor {
            let other = &joints[a];
            for column in joint.v_index..joint.v_index + joint.nv() {
                for row in other.v_index..other.v_index + other.nv() {
                    coupled[row + column * nv] = true;
                    coupled[column + row * nv] = true;
                }
            }
            ancestor = other.parent;
        }
    }
    (0..nv * nv).filter(|&k| !coupled[k]).collect()
}
