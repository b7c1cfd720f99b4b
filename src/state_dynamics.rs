//! Rigid-body dynamics at one given state, as `ribbon dynamics` computes it and the Python
//! package's `Robot.dynamics` returns it: the state checked (lengths, finite values, unit
//! quaternions), the mass matrix, the bias `C(q, v) v + g(q)`, forward dynamics from `tau`,
//! inverse dynamics from `qdd`, and every URDF link's world placement — never a NaN or infinity.
//!
//! Does not: parse text (`cli/values.rs`) or format results (`cli/dynamics_cmd.rs`).

use crate::dynamics::{
    crba, forward_dynamics, forward_kinematics, nonlinear_effects, rnea, world_from_link, Data,
};
use crate::model::{JointKind, Model};
use crate::spatial::quaternion::xyzw_norm;
use crate::spatial::{Transform, Vec3};
use crate::Error;
use nalgebra::DMatrix;

/// A quaternion whose norm is within this of 1 is normalised; further away it is refused (a typo,
/// not rounding).
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-6;

/// The state asked for (`None`: the default — neutral `q`, zero `v` — or not computed).
#[derive(Clone, Debug, Default)]
pub struct StateRequest {
    /// Joint positions (`--q`), one per coordinate.
    pub q: Option<Vec<f64>>,
    /// Joint velocities (`--v`).
    pub v: Option<Vec<f64>>,
    /// Joint torques (`--tau`): forward dynamics is computed.
    pub tau: Option<Vec<f64>>,
    /// Joint accelerations (`--qdd`): inverse dynamics is computed.
    pub qdd: Option<Vec<f64>>,
}

/// The dynamics at one state.
#[derive(Clone, Debug)]
pub struct StateDynamics {
    /// The positions used (quaternions normalised).
    pub q: Vec<f64>,
    /// The velocities used.
    pub v: Vec<f64>,
    /// The joint-space mass matrix `M(q)`, `nv × nv`.
    pub mass_matrix: DMatrix<f64>,
    /// `C(q, v) v + g(q)`.
    pub bias: Vec<f64>,
    /// Forward dynamics from the given `tau`.
    pub qdd: Option<Vec<f64>>,
    /// Inverse dynamics from the given `qdd`.
    pub tau: Option<Vec<f64>>,
    /// Every URDF link's name and world placement, in URDF order.
    pub frames: Vec<(String, Transform)>,
}

/// Descriptions of the q and v coordinates for error messages.
pub fn coordinate_names(model: &Model) -> (String, String) {
    let describe = |floating: &str| {
        model
            .joints
            .iter()
            .map(|j| match j.kind {
                JointKind::Floating => format!("{} ({floating})", j.name),
                _ => j.name.clone(),
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    (describe("x y z qx qy qz qw"), describe("vx vy vz wx wy wz"))
}

/// Refuses a vector of the wrong length or with a NaN or infinity, with the messages of
/// [`crate::cli::parse_vector`].
fn check_vector(flag: &str, values: &[f64], expected: usize, what: &str) -> Result<(), Error> {
    let bad = |message: String| Error::BadArgument {
        flag: flag.to_string(),
        message,
    };
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(bad(format!(
            "element {} is {}; give finite numbers",
            i + 1,
            values[i]
        )));
    }
    if values.len() != expected {
        return Err(bad(format!(
            "expected {expected} comma-separated numbers ({what}), got {}",
            values.len()
        )));
    }
    Ok(())
}

/// Normalises each floating joint's quaternion when within [`QUATERNION_NORM_TOLERANCE`] of unit.
fn normalise_quaternions(model: &Model, q: &mut [f64]) -> Result<(), Error> {
    for joint in model
        .joints
        .iter()
        .filter(|j| j.kind == JointKind::Floating)
    {
        let quaternion = &mut q[joint.q_index + 3..joint.q_index + 7];
        let norm = xyzw_norm(quaternion);
        if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            return Err(Error::BadArgument {
                flag: "--q".to_string(),
                message: format!(
                    "the quaternion of '{}' (qx qy qz qw = {:?}) has norm {norm}; give a unit quaternion",
                    joint.name, quaternion
                ),
            });
        }
        quaternion.iter_mut().for_each(|x| *x /= norm);
    }
    Ok(())
}

impl StateDynamics {
    /// Checks `state` against `model` (each vector named by its flag) and computes the dynamics
    /// there under `gravity` (m/s², world frame); a result that overflows f64 is refused naming the
    /// quantity and joint.
    pub fn at(model: &Model, gravity: &Vec3, state: &StateRequest) -> Result<StateDynamics, Error> {
        crate::scene::check_dense_matrices("`ribbon dynamics`", model)?;
        let (q_names, v_names) = coordinate_names(model);
        let mut q = match &state.q {
            Some(q) => {
                check_vector("--q", q, model.nq, &q_names)?;
                q.clone()
            }
            None => model.neutral_configuration(),
        };
        normalise_quaternions(model, &mut q)?;
        let velocity = |flag: &str, values: &Option<Vec<f64>>| -> Result<(), Error> {
            match values {
                Some(values) => check_vector(flag, values, model.nv, &v_names),
                None => Ok(()),
            }
        };
        velocity("--v", &state.v)?;
        velocity("--tau", &state.tau)?;
        velocity("--qdd", &state.qdd)?;
        let v = state.v.clone().unwrap_or_else(|| vec![0.0; model.nv]);

        let mut data = Data::new(model);
        let mass_matrix = crba(model, &mut data, &q).clone();
        let bias = nonlinear_effects(model, gravity, &mut data, &q, &v).to_vec();
        forward_kinematics(model, &mut data, &q);
        let frames: Vec<(String, Transform)> = (0..model.description.links.len())
            .map(|l| {
                (
                    model.description.links[l].name.clone(),
                    world_from_link(model, &data, l),
                )
            })
            .collect();
        let qdd = match &state.tau {
            Some(tau) => Some(forward_dynamics(model, gravity, &mut data, &q, &v, tau)?.to_vec()),
            None => None,
        };
        let tau = state
            .qdd
            .as_ref()
            .map(|a| rnea(model, gravity, &mut data, &q, &v, a).to_vec());
        let dynamics = StateDynamics {
            q,
            v,
            mass_matrix,
            bias,
            qdd,
            tau,
            frames,
        };
        dynamics.check_finite(model)?;
        Ok(dynamics)
    }

    /// A NaN or infinity is never reported: the given state overflows f64 arithmetic.
    fn check_finite(&self, model: &Model) -> Result<(), Error> {
        let mut results: Vec<(&str, &[f64])> = vec![
            ("the mass matrix", self.mass_matrix.as_slice()),
            ("the bias forces C(q, v) v + g(q)", &self.bias),
        ];
        if let Some(qdd) = &self.qdd {
            results.push(("the accelerations qdd", qdd));
        }
        if let Some(tau) = &self.tau {
            results.push(("the torques tau", tau));
        }
        for (quantity, values) in results {
            if let Some(i) = values.iter().position(|x| !x.is_finite()) {
                let coordinate = i % model.nv.max(1);
                return Err(Error::BadArgument {
                    flag: "--q/--v/--tau/--qdd".to_string(),
                    message: format!(
                        "{quantity}: {} at coordinate {coordinate} (joint '{}'); the given values overflow f64 arithmetic, give smaller ones",
                        values[i],
                        crate::dynamics::joint_of_velocity(model, coordinate)
                    ),
                });
            }
        }
        if let Some((name, _)) = self.frames.iter().find(|(_, placement)| {
            placement
                .translation
                .iter()
                .chain(placement.rotation.iter())
                .any(|x| !x.is_finite())
        }) {
            return Err(Error::BadArgument {
                flag: "--q".to_string(),
                message: format!(
                    "the placement of link '{name}' is not finite: the given positions overflow f64 arithmetic; give smaller ones"
                ),
            });
        }
        Ok(())
    }
}
