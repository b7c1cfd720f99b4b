//! The report directory of a study (`--report DIR`, docs/mcap.md §7): checked and created before
//! the study runs (every file it will hold a valid output), then written from the study's report —
//! the table and the warnings, a band plot per output with a few of the check's true runs on it
//! (and, on an output the check did not trust, the range of every true run of the study),
//! the page for the browser (`index.html`, from the study's summary) and the log's Foxglove layout.
//!
//! Does not: draw or format (`output::report`, `output::plot`).

use super::options::StudyOutputs;
use crate::analysis::StudyReport;
use crate::output::report::{
    file_stems, report_files, write_analyze_report, AnalyzeReport, ReportOutput, RunsHull,
    UntrustedOutput,
};
use crate::output::{check_outputs, prepare_output_directory, Summary};
use crate::scene::Scene;
use crate::Error;
use std::path::{Path, PathBuf};

/// Checks and creates `--report DIR` before the study runs: every file it will hold (one plot pair
/// per output) must be a valid output, distinct from the inputs and from `--summary`, `--csv` and
/// `--out`. Returns the plot file stems, one per output.
pub fn prepare_report(
    urdf: &Path,
    outputs: &StudyOutputs,
    sidecar_path: &Path,
    scene: &Scene,
) -> Result<Option<Vec<String>>, Error> {
    let Some(dir) = &outputs.report else {
        return Ok(None);
    };
    let stems = file_stems(scene.outputs.iter().map(|o| o.name.as_str()));
    let files = report_files(&stems, outputs.out.is_some());
    let names: Vec<&str> = files.iter().map(String::as_str).collect();
    let inputs = [("URDF", urdf), ("sidecar", sidecar_path)];
    prepare_output_directory("--report", dir, &names, &inputs)?;
    let paths: Vec<PathBuf> = files.iter().map(|f| dir.join(f)).collect();
    let mut checked: Vec<(&str, &Path)> = paths.iter().map(|p| ("--report", p.as_path())).collect();
    for (flag, path) in outputs.files() {
        if let Some(path) = path {
            checked.push((flag, path));
        }
    }
    check_outputs(&inputs, &checked)?;
    Ok(Some(stems))
}

/// Most dots of true-model runs in one report plot.
const REPORT_TRUE_RUN_DOTS: usize = 40;

/// What a study printed and wrote, for its report pages.
pub struct ReportText<'a> {
    /// The stdout table.
    pub table: &'a str,
    /// The warnings printed on stderr (without the `warning: ` prefix).
    pub warnings: &'a [String],
    /// The study's summary (the numbers of `index.html`; the same as `--summary`'s).
    pub summary: &'a Summary,
    /// The MCAP log the study wrote (`--out`), if any.
    pub log: Option<&'a Path>,
}

/// Writes `--report DIR` (docs/mcap.md §7): the table, a band plot per output, the browser page,
/// the log's layout.
pub fn write_report(
    dir: &Path,
    robot: &str,
    report: &StudyReport,
    text: &ReportText<'_>,
    stems: &[String],
    foxglove_layout: Option<serde_json::Value>,
) -> Result<(), Error> {
    let e = &report.envelope;
    // The check's true runs at the predicted extremes, per output.
    let mut true_runs: Vec<Vec<(f64, f64)>> = vec![Vec::new(); e.outputs.len()];
    if let Some(check) = &report.check {
        for &(output, record, truth) in &check.checked {
            if let (Some(runs), Some(&t)) = (true_runs.get_mut(output), e.times.get(record)) {
                runs.push((t, truth));
            }
        }
    }
    // A dot per record would hide a narrow band: at most REPORT_TRUE_RUN_DOTS, evenly spread in time.
    for runs in &mut true_runs {
        runs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        if runs.len() > REPORT_TRUE_RUN_DOTS {
            let n = runs.len();
            *runs = (0..REPORT_TRUE_RUN_DOTS)
                .map(|k| runs[k * (n - 1) / (REPORT_TRUE_RUN_DOTS - 1)])
                .collect();
        }
    }
    // The leaves' own bounds of the outputs the elements were made for.
    let mut element_bounds: Vec<Vec<(&[f64], &[f64])>> = vec![Vec::new(); e.outputs.len()];
    if let Some(elements) = &report.elements {
        for leaf in elements.elements.iter().filter(|leaf| leaf.leaf) {
            for (output, lower, upper) in &leaf.series {
                if let Some(bounds) = element_bounds.get_mut(*output) {
                    bounds.push((lower.as_slice(), upper.as_slice()));
                }
            }
        }
    }
    // Each untrusted output's misfit, and its true runs' range where the study shows it.
    let shows_hull = report.shows_runs_hull();
    let hull_runs = report.runs.saturating_sub(report.excluded.len());
    let untrusted = |o: usize| {
        let check = report.check.as_ref()?;
        if !check.untrusted_outputs.contains(&o) {
            return None;
        }
        Some(UntrustedOutput {
            relative_misfit: *check.relative_misfit.get(o)?,
            hull: shows_hull.then(|| RunsHull {
                lower: &e.runs_lower[o],
                upper: &e.runs_upper[o],
                runs: hull_runs,
            }),
        })
    };
    let outputs = e
        .outputs
        .iter()
        .enumerate()
        .map(|(o, output)| ReportOutput {
            name: &output.name,
            unit: output.unit,
            lower: &e.lower[o],
            upper: &e.upper[o],
            nominal: &e.nominal[o],
            outer: e
                .outer
                .as_ref()
                .map(|(lower, upper)| (lower[o].as_slice(), upper[o].as_slice())),
            true_runs: &true_runs[o],
            elements: &element_bounds[o],
            untrusted: untrusted(o),
        })
        .collect();
    write_analyze_report(
        dir,
        &AnalyzeReport {
            title: format!(
                "ribbon analyze: {robot}{}",
                if report.partial {
                    " (partial: stopped early)"
                } else {
                    ""
                }
            ),
            table: text.table,
            warnings: text.warnings,
            times: &e.times,
            outputs,
            stems,
            bound_kind: report.method.bound_kind(),
            foxglove_layout,
            summary: text.summary,
            log: text.log,
        },
    )?;
    eprintln!("report written to {}", dir.display());
    Ok(())
}
