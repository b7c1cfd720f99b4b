//! `ribbon dynamics ROBOT.urdf [--q …] [--v …] [--tau …] [--qdd …] [--set PATH=VALUE …] [--json]`:
//! rigid-body dynamics at one state, in the JSON shape of the design contract.

use super::{print_warnings, write_stdout, DynamicsArgs};
use crate::cli::values::{apply_set_flags, parse_vector};
use crate::dynamics::{
    crba, forward_dynamics, forward_kinematics, nonlinear_effects, rnea, world_from_link, Data,
};
use crate::model::{JointKind, LoadOptions, Model};
use crate::spatial::quaternion::xyzw_norm;
use crate::Error;
use serde_json::{json, Map, Value};

/// A quaternion whose norm is within this of 1 is normalised; further away it is refused (a typo,
/// not rounding).
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-6;

/// Runs `ribbon dynamics`.
pub fn run(args: &DynamicsArgs) -> Result<(), Error> {
    let mut model = Model::from_urdf_file(
        &args.urdf,
        LoadOptions {
            floating_base: args.floating,
        },
    )?;
    print_warnings(&model);
    crate::scene::check_dense_matrices("`ribbon dynamics`", &model)?;
    apply_set_flags(&mut model, &args.set)?;
    let (q_names, v_names) = coordinate_names(&model);
    let mut q = match &args.q {
        Some(text) => parse_vector("--q", text, model.nq, &q_names)?,
        None => model.neutral_configuration(),
    };
    normalise_quaternions(&model, &mut q)?;
    let velocity = |flag: &str, text: &Option<String>| -> Result<Option<Vec<f64>>, Error> {
        text.as_deref()
            .map(|t| parse_vector(flag, t, model.nv, &v_names))
            .transpose()
    };
    let v = velocity("--v", &args.v)?.unwrap_or_else(|| vec![0.0; model.nv]);
    let tau = velocity("--tau", &args.tau)?;
    let qdd = velocity("--qdd", &args.qdd)?;

    let mut data = Data::new(&model);
    let mass_matrix = crba(&model, &mut data, &q).clone();
    let bias = nonlinear_effects(&model, &mut data, &q, &v).to_vec();
    forward_kinematics(&model, &mut data, &q);
    let frames: Vec<(String, crate::spatial::Transform)> = (0..model.description.links.len())
        .map(|l| {
            (
                model.description.links[l].name.clone(),
                world_from_link(&model, &data, l),
            )
        })
        .collect();
    let qdd_out = match &tau {
        Some(tau) => Some(forward_dynamics(&model, &mut data, &q, &v, tau)?.to_vec()),
        None => None,
    };
    let tau_out = qdd
        .as_ref()
        .map(|a| rnea(&model, &mut data, &q, &v, a).to_vec());

    // A NaN or infinity is never printed: the given state overflows f64 arithmetic.
    let mut results: Vec<(&str, &[f64])> = vec![
        ("the mass matrix", mass_matrix.as_slice()),
        ("the bias forces C(q, v) v + g(q)", &bias),
    ];
    if let Some(qdd) = &qdd_out {
        results.push(("the accelerations qdd", qdd));
    }
    if let Some(tau) = &tau_out {
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
                    crate::dynamics::joint_of_velocity(&model, coordinate)
                ),
            });
        }
    }
    if let Some((name, _)) = frames.iter().find(|(_, placement)| {
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

    let joints: Vec<Value> = model
        .joints
        .iter()
        .map(|j| {
            json!({
                "name": j.name, "type": j.type_name, "q_index": j.q_index, "nq": j.nq(),
                "v_index": j.v_index, "nv": j.nv(),
            })
        })
        .collect();
    let rows: Vec<Vec<f64>> = mass_matrix
        .row_iter()
        .map(|r| r.iter().copied().collect())
        .collect();
    let mut frame_map = Map::new();
    for (name, placement) in &frames {
        let rotation: Vec<Vec<f64>> = placement
            .rotation
            .row_iter()
            .map(|r| r.iter().copied().collect())
            .collect();
        frame_map.insert(
            name.clone(),
            json!({ "position": placement.translation.as_slice(), "rotation": rotation }),
        );
    }
    let mut out = Map::new();
    out.insert("robot".into(), json!(model.name()));
    out.insert("joints".into(), Value::Array(joints));
    out.insert("nq".into(), json!(model.nq));
    out.insert("nv".into(), json!(model.nv));
    out.insert("q".into(), json!(q));
    out.insert("v".into(), json!(v));
    out.insert("mass_matrix".into(), json!(rows));
    out.insert("bias".into(), json!(bias));
    if let Some(qdd) = &qdd_out {
        out.insert("qdd".into(), json!(qdd));
    }
    if let Some(tau) = &tau_out {
        out.insert("tau".into(), json!(tau));
    }
    out.insert("frames".into(), Value::Object(frame_map));
    let text = if args.json {
        format!("{}\n", Value::Object(out))
    } else {
        readable_report(&model, &out)
    };
    write_stdout(&text)
}

/// Descriptions of the q and v coordinates for error messages.
fn coordinate_names(model: &Model) -> (String, String) {
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

fn readable_report(model: &Model, out: &Map<String, Value>) -> String {
    let vector = |key: &str| {
        out.get(key).and_then(Value::as_array).map(|a| {
            a.iter()
                .map(|x| format!("{:>12.6}", x.as_f64().unwrap_or(f64::NAN)))
                .collect::<Vec<_>>()
                .join(" ")
        })
    };
    let mut text = format!(
        "robot '{}': nq = {}, nv = {}\n",
        model.name(),
        model.nq,
        model.nv
    );
    for joint in &model.joints {
        text.push_str(&format!(
            "  {:<28} {:<10} q[{}..{}] v[{}..{}]\n",
            joint.name,
            joint.type_name,
            joint.q_index,
            joint.q_index + joint.nq(),
            joint.v_index,
            joint.v_index + joint.nv()
        ));
    }
    for key in ["q", "v"] {
        if let Some(line) = vector(key) {
            text.push_str(&format!("{key:<5} {line}\n"));
        }
    }
    text.push_str("mass matrix:\n");
    if let Some(rows) = out.get("mass_matrix").and_then(Value::as_array) {
        for row in rows {
            let cells: Vec<String> = row
                .as_array()
                .map(|r| {
                    r.iter()
                        .map(|x| format!("{:>12.6}", x.as_f64().unwrap_or(f64::NAN)))
                        .collect()
                })
                .unwrap_or_default();
            text.push_str(&format!("      {}\n", cells.join(" ")));
        }
    }
    for key in ["bias", "qdd", "tau"] {
        if let Some(line) = vector(key) {
            text.push_str(&format!("{key:<5} {line}\n"));
        }
    }
    text.push_str("(--json gives every URDF link's frame as well)\n");
    text
}
