//! `ribbon params ROBOT.urdf [--json] [--uncertainty F]`: every value that can be uncertain, with its
//! nominal; or, with `--uncertainty`, the box a sidecar declares (patterns expanded).

use super::{print_warnings, write_stdout, ParamsArgs};
use crate::environment::Environment;
use crate::model::{LoadOptions, Model};
use crate::scene::{wants_floating_base, Scene, SceneOverrides};
use crate::sidecar::read_sidecar;
use crate::uncertainty::{DimensionKind, ParameterSpace};
use crate::{params, Error};
use serde_json::json;
use std::path::Path;

/// Runs `ribbon params`.
pub fn run(args: &ParamsArgs) -> Result<(), Error> {
    if let Some(sidecar) = &args.uncertainty {
        return print_box(args, sidecar);
    }
    let model = Model::from_urdf_file(
        &args.urdf,
        LoadOptions {
            floating_base: args.floating,
        },
    )?;
    print_warnings(&model);
    let environment = Environment::default();
    let listed = params::list(&model, &environment);
    let text = if args.json {
        let rows: Vec<serde_json::Value> = listed
            .iter()
            .map(|p| {
                json!({
                    "path": p.path,
                    "nominal": params::get(&model, &environment, p.target),
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
                format_number(params::get(&model, &environment, p.target)),
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

/// `--uncertainty F`: the robot and the sidecar are loaded as `analyze` loads them (the sidecar's
/// base and gravity apply), and the expanded box is printed. Warnings go to stderr; notes are part
/// of the listing.
fn print_box(args: &ParamsArgs, sidecar_path: &Path) -> Result<(), Error> {
    let name = sidecar_path.display().to_string();
    let (sidecar, _) = read_sidecar(sidecar_path)?;
    let floating_base = args.floating || wants_floating_base(&sidecar, &name)?;
    let model = Model::from_urdf_file(&args.urdf, LoadOptions { floating_base })?;
    print_warnings(&model);
    let scene = Scene::resolve(&sidecar, &model, &name, SceneOverrides::default())?;
    let space = ParameterSpace::from_sidecar(&sidecar, &model, &scene.environment(), &name)?;
    for warning in space.warnings() {
        eprintln!("warning: {warning}");
    }
    let kind = |k: DimensionKind| match k {
        DimensionKind::Path(_) => "path",
        DimensionKind::Symbol => "symbol",
        DimensionKind::Group(_) => "group",
    };
    let text = if args.json {
        let dimensions: Vec<serde_json::Value> = space
            .dimensions()
            .iter()
            .map(|d| {
                let mut row = json!({
                    "name": d.name,
                    "lower": d.lower,
                    "nominal": d.nominal,
                    "upper": d.upper,
                    "unit": d.unit,
                    "source": d.source,
                    "kind": kind(d.kind),
                });
                if let DimensionKind::Group(g) = d.kind {
                    let group = &space.groups()[g];
                    row["members"] = group
                        .members
                        .iter()
                        .map(|m| json!({"path": m.path, "nominal": m.urdf_value}))
                        .collect();
                }
                row
            })
            .collect();
        let bindings: Vec<serde_json::Value> = space
            .bindings()
            .iter()
            .map(|b| {
                json!({
                    "path": b.path,
                    "expression": b.expression.source(),
                    "unit": params::unit_of(&model, b.target),
                })
            })
            .collect();
        let check = space.box_check();
        let report = json!({
            "robot": model.name(),
            "sidecar": name,
            "d": space.len(),
            "dimensions": dimensions,
            "bindings": bindings,
            "notes": space.notes(),
            "warnings": space.warnings(),
            "box_check": {
                "links": check.links,
                "inertia_points": check.inertia_points,
                "binding_points": check.binding_points,
            },
        });
        format!("{report}\n")
    } else {
        box_table(&space, &model, &name)
    };
    write_stdout(&text)
}

/// The readable listing of [`print_box`].
fn box_table(space: &ParameterSpace, model: &Model, sidecar: &str) -> String {
    let numbered: Vec<[String; 7]> = space
        .dimensions()
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let source = if d.source == d.name {
                String::new()
            } else {
                d.source.clone()
            };
            let name = match d.kind {
                DimensionKind::Group(g) => {
                    format!("{} ({} values)", d.name, space.groups()[g].members.len())
                }
                _ => d.name.clone(),
            };
            [
                (i + 1).to_string(),
                name,
                format_number(d.lower),
                format_number(d.nominal),
                format_number(d.upper),
                d.unit.to_string(),
                source,
            ]
        })
        .collect();
    let header = [
        "#",
        "dimension",
        "lower",
        "nominal",
        "upper",
        "unit",
        "from",
    ];
    let mut widths = header.map(str::len);
    for row in &numbered {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: [&str; 7]| {
        let [i, name, lower, nominal, upper, unit, source] = cells;
        format!(
            "{i:>w0$}  {name:<w1$}  {lower:>w2$}  {nominal:>w3$}  {upper:>w4$}  {unit:<w5$}  {source}",
            w0 = widths[0],
            w1 = widths[1],
            w2 = widths[2],
            w3 = widths[3],
            w4 = widths[4],
            w5 = widths[5],
        )
        .trim_end()
        .to_string()
            + "\n"
    };
    let mut out = format!(
        "d = {} dimensions of robot '{}' from {sidecar}\n",
        space.len(),
        model.name()
    );
    out.push_str(&line(header));
    for row in &numbered {
        out.push_str(&line(row.each_ref().map(String::as_str)));
    }
    if !space.bindings().is_empty() {
        out.push_str(&format!(
            "{} bound values ([bind]):\n",
            space.bindings().len()
        ));
        for b in space.bindings() {
            out.push_str(&format!(
                "  {} = \"{}\"  {}\n",
                b.path,
                b.expression.source(),
                params::unit_of(model, b.target)
            ));
        }
    }
    for note in space.notes() {
        out.push_str(&format!("note: {note}\n"));
    }
    out
}

/// Shortest exact representation of a number (`0.425`, `-1.5707963267948966`).
/// Significant digits in the human-readable tables: enough for any URDF value as written, few
/// enough to hide the last-bit noise of computed bounds (`3.7 · 1.03` prints 3.811, not
/// 3.8110000000000004). `--json` keeps the exact values.
const TABLE_SIGNIFICANT_DIGITS: usize = 12;

fn format_number(value: f64) -> String {
    if !value.is_finite() || value == 0.0 {
        return format!("{value}");
    }
    // Round to TABLE_SIGNIFICANT_DIGITS, then print the shortest form of the rounded value.
    let rounded: f64 = format!("{value:.*e}", TABLE_SIGNIFICANT_DIGITS - 1)
        .parse()
        .unwrap_or(value);
    format!("{rounded}")
}
