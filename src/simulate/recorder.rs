//! Evaluates a scene's outputs at a state: `(q, v, q̈) ⇒ one value per output`.

use crate::dynamics::{forward_kinematics, frame_placements, Data};
use crate::model::Model;
use crate::scene::{Output, OutputKind};
use nalgebra::{Quaternion, UnitQuaternion};

/// Evaluates outputs; remembers each floating joint's initial orientation for the rotation-vector
/// outputs.
#[derive(Clone, Debug)]
pub struct Recorder {
    outputs: Vec<Output>,
    needs_kinematics: bool,
    initial_orientation: Vec<Option<UnitQuaternion<f64>>>,
}

fn orientation(q: &[f64], q_index: usize) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(Quaternion::new(
        q[q_index + 6],
        q[q_index + 3],
        q[q_index + 4],
        q[q_index + 5],
    ))
}

impl Recorder {
    /// A recorder of `outputs`; `initial_q` (dim nq) fixes the reference orientation of floating
    /// joints.
    pub fn new(model: &Model, outputs: &[Output], initial_q: &[f64]) -> Self {
        let initial_orientation = model
            .joints
            .iter()
            .map(|j| (j.nq() == 7).then(|| orientation(initial_q, j.q_index)))
            .collect();
        Self {
            outputs: outputs.to_vec(),
            needs_kinematics: outputs
                .iter()
                .any(|o| matches!(o.kind, OutputKind::FramePosition { .. })),
            initial_orientation,
        }
    }

    /// The outputs, in recording order.
    pub fn outputs(&self) -> &[Output] {
        &self.outputs
    }

    /// Writes one value per output into `row` (`dim outputs.len()`). `q: dim nq`, `v, qdd: dim nv`,
    /// `lambda: dim m`.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        model: &Model,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        qdd: &[f64],
        lambda: &[f64],
        row: &mut [f64],
    ) {
        if self.needs_kinematics {
            forward_kinematics(model, data, q);
        }
        for (value, output) in row.iter_mut().zip(&self.outputs) {
            *value = match output.kind {
                OutputKind::Position { q_index } => q[q_index],
                OutputKind::Velocity { v_index } => v[v_index],
                OutputKind::Acceleration { v_index } => qdd[v_index],
                OutputKind::FramePosition { link, axis } => {
                    frame_placements(model, data, link).translation[axis]
                }
                OutputKind::BasePosition { joint, axis } => q[model.joints[joint].q_index + axis],
                OutputKind::BaseRotation { joint, axis } => {
                    let now = orientation(q, model.joints[joint].q_index);
                    let initial = self.initial_orientation[joint].unwrap_or(now);
                    (initial.inverse() * now).scaled_axis()[axis]
                }
                OutputKind::Multiplier { row, sign } => sign * lambda[row],
            };
        }
    }
}
