//! `ribbon dynamics ROBOT.urdf [--q …] [--v …] [--tau …] [--qdd …] [--set PATH=VALUE …] [--json]`:
//! rigid-body dynamics at one state, in the JSON shape of the design contract.

use super::{print_warnings, write_stdout, DynamicsArgs};
use crate::environment::Environment;
use crate::model::{LoadOptions, Model};
use crate::set_flags::{apply_set_flags, parse_vector};
use crate::state_dynamics::{coordinate_names, StateDynamics, StateRequest};
use crate::Error;
use serde_json::{json, Map, Value};

/// Runs `ribbon dynamics`.
pub fn run(args: &DynamicsArgs) -> Result<(), Error> {
    let mut model = Model::from_urdf_file(
        &args.urdf,
        LoadOptions {
            floating_base: args.floating,
        },
    )?;
    print_warnings(&model);
    let mut environment = Environment::default();
    apply_set_flags(&mut model, &mut environment, &args.set)?;
    let (q_names, v_names) = coordinate_names(&model);
    let vector = |flag: &str, text: &Option<String>, n: usize, names: &str| {
        text.as_deref()
            .map(|t| parse_vector(flag, t, n, names))
            .transpose()
    };
    let state = StateRequest {
        q: vector("--q", &args.q, model.nq, &q_names)?,
        v: vector("--v", &args.v, model.nv, &v_names)?,
        tau: vector("--tau", &args.tau, model.nv, &v_names)?,
        qdd: vector("--qdd", &args.qdd, model.nv, &v_names)?,
    };
    let StateDynamics {
        q,
        v,
        mass_matrix,
        bias,
        qdd: qdd_out,
        tau: tau_out,
        frames,
    } = StateDynamics::at(&model, &environment.gravity, &state)?;

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
