//! `ribbon params ROBOT.urdf [--json]`: every value that can be uncertain, with its nominal.

use super::{print_warnings, write_stdout, ParamsArgs};
use crate::model::{LoadOptions, Model};
use crate::{params, Error};

/// Runs `ribbon params`.
pub fn run(args: &ParamsArgs) -> Result<(), Error> {
    let model = Model::from_urdf_file(
        &args.urdf,
        LoadOptions {
            floating_base: args.floating,
        },
    )?;
    print_warnings(&model);
    let listed = params::list(&model);
    let text = if args.json {
        let rows: Vec<serde_json::Value> = listed
            .iter()
            .map(|p| {
                serde_json::json!({
                    "path": p.path,
                    "nominal": params::get(&model, p.target),
                    "unit": p.unit,
                })
            })
            .collect();
        format!("{}\n", serde_json::Value::Array(rows))
    } else {
        let width = listed
            .iter()
            .map(|p| p.path.chars().count())
            .max()
            .unwrap_or(4);
        let mut out = format!("{:<width$}  {:>14}  unit\n", "path", "nominal");
        for p in &listed {
            out.push_str(&format!(
                "{:<width$}  {:>14}  {}\n",
                p.path,
                format_number(params::get(&model, p.target)),
                p.unit
            ));
        }
        out.push_str(&format!(
            "{} parameters of robot '{}'\n",
            listed.len(),
            model.name()
        ));
        out
    };
    write_stdout(&text)
}

/// Shortest exact representation of a number (`0.425`, `-1.5707963267948966`).
fn format_number(value: f64) -> String {
    format!("{value}")
}
