//! Evaluates a scene's outputs at a state: `(q, v, q̈) ⇒ one value per output`.

use crate::dynamics::{forward_kinematics, world_from_link, Data};
use crate::effects::Effects;
use crate::environment::Environment;
use crate::model::Model;
use crate::scene::{Output, OutputKind};
use crate::spatial::quaternion::unit_quaternion_from_xyzw;
use nalgebra::UnitQuaternion;

/// Evaluates outputs. The rotation-vector outputs of a floating base are relative to its initial
/// orientation, which each trajectory keeps ([`Recorder::initial_orientations`]).
#[derive(Clone, Debug)]
pub struct Recorder {
    outputs: Vec<Output>,
    needs_kinematics: bool,
    needs_contact_forces: bool,
    /// Whether contact normal forces are recorded signed (a study's records, which fit the
    /// smooth continuation and report its clamp): see [`Recorder::for_study`].
    signed_contact_forces: bool,
}

/// The initial orientation of each floating joint of a trajectory (`None` for other joints).
pub type InitialOrientations = Vec<Option<UnitQuaternion<f64>>>;

fn orientation(q: &[f64], q_index: usize) -> UnitQuaternion<f64> {
    unit_quaternion_from_xyzw(&q[q_index + 3..q_index + 7])
}

impl Recorder {
    /// A recorder of `outputs`.
    pub fn new(outputs: &[Output]) -> Self {
        Self {
            outputs: outputs.to_vec(),
            needs_kinematics: outputs
                .iter()
                .any(|o| matches!(o.kind, OutputKind::FramePosition { .. })),
            needs_contact_forces: outputs
                .iter()
                .any(|o| matches!(o.kind, OutputKind::ContactNormalForce { .. })),
            signed_contact_forces: false,
        }
    }

    /// A recorder of `outputs` for a study's runs: as [`Recorder::new`], except that a contact
    /// pair apart records its signed normal force `−k·gap^e` instead of 0
    /// ([`Effects::contact_normal_forces`] with `signed`). An output's value is its
    /// recorded value after [`crate::scene::OutputKind::reported`]; a surrogate fits the
    /// recorded value, which passes smoothly through touch-down (docs/contacts.md §7).
    pub fn for_study(outputs: &[Output]) -> Self {
        Self {
            signed_contact_forces: true,
            ..Self::new(outputs)
        }
    }

    /// The reference orientations of a trajectory starting at `initial_q` (dim nq).
    pub fn initial_orientations(model: &Model, initial_q: &[f64]) -> InitialOrientations {
        model
            .joints
            .iter()
            .map(|j| (j.nq() == 7).then(|| orientation(initial_q, j.q_index)))
            .collect()
    }

    /// The outputs, in recording order.
    pub fn outputs(&self) -> &[Output] {
        &self.outputs
    }

    /// [`Recorder::record`] of `system` at an integrator state.
    pub fn record_state(
        &self,
        system: &mut super::RobotSystem,
        state: &crate::integrate::HhtState,
        initial: &[Option<UnitQuaternion<f64>>],
        row: &mut [f64],
    ) {
        self.record(
            &system.model,
            &system.environment,
            &mut system.data,
            &mut system.effects,
            state.q.as_slice(),
            state.v.as_slice(),
            state.qdd.as_slice(),
            state.lambda.as_slice(),
            initial,
            row,
        );
    }

    /// Writes one value per output into `row` (`dim outputs.len()`). `q: dim nq`, `v, qdd: dim nv`,
    /// `lambda: dim m`; `initial` from [`Recorder::initial_orientations`]; `effects` only for
    /// contact-force outputs. Overwrites the kinematic buffers of `data`.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        effects: &mut Effects,
        q: &[f64],
        v: &[f64],
        qdd: &[f64],
        lambda: &[f64],
        initial: &[Option<UnitQuaternion<f64>>],
        row: &mut [f64],
    ) {
        let contact_forces: &[f64] = if self.needs_contact_forces {
            effects.contact_normal_forces(
                model,
                environment,
                data,
                q,
                v,
                self.signed_contact_forces,
            )
        } else {
            &[]
        };
        if self.needs_kinematics {
            forward_kinematics(model, data, q);
        }
        for (value, output) in row.iter_mut().zip(&self.outputs) {
            *value = match output.kind {
                OutputKind::Position { q_index } => q[q_index],
                OutputKind::Velocity { v_index } => v[v_index],
                OutputKind::Acceleration { v_index } => qdd[v_index],
                OutputKind::FramePosition { link, axis } => {
                    world_from_link(model, data, link).translation[axis]
                }
                OutputKind::BasePosition { joint, axis } => q[model.joints[joint].q_index + axis],
                OutputKind::BaseRotation { joint, axis } => {
                    let now = orientation(q, model.joints[joint].q_index);
                    let reference = initial.get(joint).copied().flatten().unwrap_or(now);
                    (reference.inverse() * now).scaled_axis()[axis]
                }
                OutputKind::Multiplier { row, sign } => sign * lambda[row],
                OutputKind::ContactNormalForce { pair } => {
                    contact_forces.get(pair).copied().unwrap_or(0.0)
                }
            };
        }
    }
}
