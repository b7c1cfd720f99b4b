//! What `compare` reports: its rows ([`Row`]), the stdout table, and the report directory
//! (`--report DIR`): `report.md` with the table and the plots, `compare.json` with the rows,
//! `error_vs_time.{svg,png}` (every row's error against its wall time) and `envelope.{svg,png}`
//! (the widest output: the reference's band against the highest-order legendre-scan run's
//! bounds).
//!
//! Does not: compute a row (`compare.rs`) or draw (`output::plot`).

use crate::analysis::StudyReport;
use crate::output::plot::axis_label;
use crate::output::plot::{Layer, ScatterPlot, ScatterSeries, Stroke, TimePlot, PALETTE};
use crate::output::report::{write_plot, BAND_COLOUR, NOMINAL_COLOUR, SECOND_COLOUR};
use crate::output::write_atomically;
use crate::Error;
use std::path::Path;

/// One compared configuration.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// Method name.
    pub method: String,
    /// Order (surrogates, Taylor 1) or Monte Carlo runs.
    pub setting: Option<usize>,
    /// Bound kind.
    pub bound_kind: String,
    /// The design that ran (`auto` resolved).
    pub design: String,
    /// Model runs, the nominal one included.
    pub runs: usize,
    /// Wall time, s.
    pub wall_seconds: f64,
    /// Worst over outputs of the max-over-time error.
    pub max_error: f64,
    /// Mean over outputs of the mean-over-time error.
    pub mean_error: f64,
    /// The output with the worst error.
    pub worst_output: String,
    /// The record time of the worst error, s.
    pub worst_time_s: f64,
    /// Worst over outputs of the largest share of the reference's range the envelope misses
    /// ([`crate::uq::EnvelopeError::max_missed`]).
    pub max_missed: f64,
}

/// The stdout table: the reference, then one line per row with its error, where it is worst, the
/// share of the reference it misses and its speed-up over the reference.
pub fn render_table(
    rows: &[Row],
    reference_runs: usize,
    reference_seconds: f64,
    reference_label: &str,
) -> String {
    let mut text = format!(
        "reference: {reference_label}, {reference_runs} runs, {reference_seconds:.3} s\n\
         error: docs/method.md §4, max over time and outputs (mean over time, averaged over outputs); \
         missed: the largest share of the reference's range an envelope does not cover (against \
         true runs, certainly wrong; the rest of the error is an envelope wider than the runs)\n\n"
    );
    text.push_str(&format!(
        "| {:<24} | {:>7} | {:<15} | {:<11} | {:>7} | {:>10} | {:>10} | {:>13} | {:>10} | {:>10} | {:>9} |\n",
        "method",
        "setting",
        "design",
        "bounds",
        "runs",
        "wall (s)",
        "max error",
        "at",
        "mean error",
        "missed",
        "speed-up"
    ));
    text.push_str("|--------------------------|---------|-----------------|-------------|---------|------------|------------|---------------|------------|------------|-----------|\n");
    for row in rows {
        let setting = match (row.method.as_str(), row.setting) {
            ("monte-carlo", Some(n)) => format!("N={n}"),
            ("taylor", _) => "1".to_string(),
            (_, Some(k)) => format!("k={k}"),
            _ => String::new(),
        };
        text.push_str(&format!(
            "| {:<24} | {:>7} | {:<15} | {:<11} | {:>7} | {:>10.3} | {:>10.3e} | {:>13} | {:>10.3e} | {:>10.3e} | {:>8.1}× |\n",
            row.method,
            setting,
            row.design,
            row.bound_kind,
            row.runs,
            row.wall_seconds,
            row.max_error,
            format!("{} {:.3}s", short_output(&row.worst_output), row.worst_time_s),
            row.mean_error,
            row.max_missed,
            reference_seconds / row.wall_seconds.max(1e-9),
        ));
    }
    text
}

/// The last dotted segment of an output's name, at most 7 characters (the table's `at` column).
fn short_output(name: &str) -> String {
    let last = name.rsplit('.').next().unwrap_or(name);
    last.chars().take(7).collect()
}

/// The files `--report DIR` receives.
pub const REPORT_FILES: [&str; 6] = [
    "report.md",
    "compare.json",
    "error_vs_time.svg",
    "error_vs_time.png",
    "envelope.svg",
    "envelope.png",
];

/// Writes `report.md` (the table and the plots), `compare.json` (the rows) and the plots — error
/// against wall time per method, and the widest output's reference band against the best
/// surrogate's bounds — into `dir`.
pub fn write_report(
    dir: &Path,
    table: &str,
    rows: &[Row],
    reference: &StudyReport,
    reference_seconds: f64,
    reference_label: &str,
    best: Option<&(String, StudyReport)>,
) -> Result<(), Error> {
    let markdown = format!(
        "# ribbon compare\n\nWhat accuracy costs in time: every method against a reference made of true-model runs ({reference_label}).\n\n```text\n{table}```\n\n\
         ![error vs time](error_vs_time.svg)\n\nThe widest output: the shaded band is the reference (true-model runs), \
         the solid line the nominal run, the dashed lines the bounds of the legendre-scan run of the highest order.\n\n\
         ![envelope](envelope.svg)\n\nEvery plot is also a PNG beside its SVG.\n"
    );
    write_atomically(&dir.join("report.md"), "report", markdown.as_bytes())?;
    let json = serde_json::json!({
        "reference": {"method": reference_label, "runs": reference.runs, "wall_seconds": reference_seconds},
        "rows": rows,
    });
    write_atomically(
        &dir.join("compare.json"),
        "report JSON",
        serde_json::to_string_pretty(&json)
            .unwrap_or_default()
            .as_bytes(),
    )?;

    let mut series: Vec<ScatterSeries> = Vec::new();
    for row in rows {
        let label = format!("{} ({})", row.method, row.bound_kind);
        let point_label = match (row.method.as_str(), row.setting) {
            ("monte-carlo", Some(n)) => format!("N={n}"),
            ("taylor", _) => String::new(),
            (_, Some(k)) => format!("k={k}"),
            _ => String::new(),
        };
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => {
                s.points.push((row.wall_seconds, row.max_error));
                s.point_labels.push(point_label);
            }
            None => {
                let colour = PALETTE[series.len() % PALETTE.len()];
                series.push(ScatterSeries {
                    label,
                    points: vec![(row.wall_seconds, row.max_error)],
                    point_labels: vec![point_label],
                    colour,
                })
            }
        }
    }
    let plot = ScatterPlot {
        title: format!(
            "error vs wall time (reference: {reference_label}, {} runs, {reference_seconds:.2} s)",
            reference.runs
        ),
        x_label: "wall time [s]".to_string(),
        y_label: "max envelope error [fraction of the reference width]".to_string(),
        log_x: true,
        log_y: true,
        series,
    };
    write_plot(dir, "error_vs_time", plot.svg(), plot.png())?;

    // The widest output: the reference band against the best surrogate's bounds.
    let r = &reference.envelope;
    let widest = (0..r.outputs.len())
        .max_by(|a, b| {
            let width = |o: usize| {
                r.upper[o]
                    .iter()
                    .zip(&r.lower[o])
                    .map(|(u, l)| u - l)
                    .fold(0.0, f64::max)
            };
            width(*a).total_cmp(&width(*b))
        })
        .unwrap_or(0);
    let output = &r.outputs[widest];
    let mut layers = vec![
        Layer::Band {
            label: format!("reference: {reference_label}"),
            lower: &r.lower[widest],
            upper: &r.upper[widest],
            colour: BAND_COLOUR,
        },
        Layer::Line {
            label: "nominal".to_string(),
            values: &r.nominal[widest],
            colour: NOMINAL_COLOUR,
            width: 2,
            stroke: Stroke::Solid,
        },
    ];
    if let Some((label, report)) = best {
        let e = &report.envelope;
        for (line_label, values) in [
            (label.clone(), &e.lower[widest]),
            (String::new(), &e.upper[widest]),
        ] {
            layers.push(Layer::Line {
                label: line_label,
                values,
                colour: SECOND_COLOUR,
                width: 2,
                stroke: Stroke::Dashed,
            });
        }
    }
    let envelope_plot = TimePlot {
        title: format!("envelope of {}", axis_label(&output.name, output.unit)),
        y_label: axis_label(&output.name, output.unit),
        times: &r.times,
        layers,
        y_limits: None,
        note: String::new(),
    };
    Ok(write_plot(
        dir,
        "envelope",
        envelope_plot.svg(),
        envelope_plot.png(),
    )?)
}
