//! The report directory of `ribbon analyze --report DIR` (docs/mcap.md §7): `index.html`, the
//! self-contained page for the browser (`report_html`), `report.md` with the study's table, one
//! band plot per output as `<output>.svg` and `<output>.png`, and, when the study also wrote a log
//! (`--out`), the log's Foxglove layout as `foxglove-layout.json`.
//!
//! A band plot shades the region between the lower and upper bound (labelled with the bound's
//! kind: inner, outer, reference), draws the nominal run as a solid line and, where a sparse
//! design also gives an outer bound, that bound as dashed lines. The engine does not keep the
//! true-model runs of the a-posteriori check per output and time, so they are not drawn.

use super::error::OutputError;
use super::plot::{axis_label, Layer, PlotError, TimePlot};
use super::report_html::{html_page, HtmlReport, REPORT_HTML};
use super::summary::Summary;
use super::viewer::FOXGLOVE_LAYOUT_NAME;
use super::write_atomically;
use std::collections::HashSet;
use std::path::Path;

/// Name of the report page.
pub const REPORT_PAGE: &str = "report.md";
/// Colour of the shaded bound.
pub const BAND_COLOUR: &str = "#0072b2";
/// Colour of the nominal line.
pub const NOMINAL_COLOUR: &str = "#009e73";
/// Colour of an outer bound's dashed lines.
pub const OUTER_COLOUR: &str = "#d55e00";
/// Colour of the dots of true-model runs (Okabe–Ito black: apart from the three series colours).
pub const TRUE_RUN_COLOUR: &str = "#000000";
/// Colour of the elements' own bounds, drawn faintly under the union (docs/method.md §12).
pub const ELEMENT_COLOUR: &str = "#a6bddb";
/// Colour of a second method's dashed bound (compare's report).
pub const SECOND_COLOUR: &str = "#cc79a7";
/// Longest file stem made from an output name (bytes), leaving room for a suffix and extension
/// under the usual 255-byte file-name limit.
pub const MAX_STEM_BYTES: usize = 120;

/// One output of a study, as plotted.
#[derive(Clone, Copy, Debug)]
pub struct ReportOutput<'a> {
    /// Its name (`frame.tool0.z`).
    pub name: &'a str,
    /// Its unit (`m`; empty when unitless).
    pub unit: &'a str,
    /// Lower bound per record time.
    pub lower: &'a [f64],
    /// Upper bound per record time.
    pub upper: &'a [f64],
    /// The nominal run per record time.
    pub nominal: &'a [f64],
    /// The outer bound (lower, upper) per record time, where the method gives one.
    pub outer: Option<(&'a [f64], &'a [f64])>,
    /// True-model runs to draw as dots, `(time, value)`: the a-posteriori check's runs at the
    /// times where the surrogate put this output's extremes (empty without a check).
    pub true_runs: &'a [(f64, f64)],
    /// Where the box was split into elements: each leaf's own `(lower, upper)` per record time,
    /// drawn faintly under the union (empty otherwise).
    pub elements: &'a [(&'a [f64], &'a [f64])],
}

/// The band plot of one output; `bound_kind` names the shaded bound (`inner`, `outer`, …).
pub fn band_plot<'a>(
    times: &'a [f64],
    output: &ReportOutput<'a>,
    bound_kind: &str,
) -> TimePlot<'a> {
    let mut layers = vec![Layer::Band {
        label: format!("lower – upper ({bound_kind} bound)"),
        lower: output.lower,
        upper: output.upper,
        colour: BAND_COLOUR,
    }];
    for (e, &(lower, upper)) in output.elements.iter().enumerate() {
        for (side, values) in [lower, upper].into_iter().enumerate() {
            layers.push(Layer::Line {
                label: if e == 0 && side == 0 {
                    format!("bounds of each of {} elements", output.elements.len())
                } else {
                    String::new()
                },
                values,
                colour: ELEMENT_COLOUR,
                width: 1,
                dashed: false,
            });
        }
    }
    if let Some((lower, upper)) = output.outer {
        for (label, values) in [("outer bound", lower), ("", upper)] {
            layers.push(Layer::Line {
                label: label.to_string(),
                values,
                colour: OUTER_COLOUR,
                width: 2,
                dashed: true,
            });
        }
    }
    if !output.true_runs.is_empty() {
        layers.push(Layer::Points {
            label: "true runs at predicted extremes".to_string(),
            points: output.true_runs,
            colour: TRUE_RUN_COLOUR,
        });
    }
    layers.push(Layer::Line {
        label: "nominal".to_string(),
        values: output.nominal,
        colour: NOMINAL_COLOUR,
        width: 2,
        dashed: false,
    });
    TimePlot {
        title: axis_label(output.name, output.unit),
        y_label: axis_label(output.name, output.unit),
        times,
        layers,
    }
}

/// File stems for outputs: the name with every character outside `[A-Za-z0-9._-]` replaced by
/// `_`, cut to [`MAX_STEM_BYTES`], made unique with `-2`, `-3`, … and never `report` or
/// `foxglove-layout` (the page and the layout keep their names).
pub fn file_stems<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let mut taken: HashSet<String> = ["report", "foxglove-layout"]
        .into_iter()
        .map(str::to_string)
        .collect();
    names
        .into_iter()
        .map(|name| {
            let mut stem: String = name
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            // Every character is ASCII now, so any byte index is a character boundary.
            stem.truncate(MAX_STEM_BYTES);
            if stem.is_empty() || stem.starts_with('.') {
                stem.insert(0, '_');
            }
            let mut candidate = stem.clone();
            let mut k = 2;
            while !taken.insert(candidate.to_lowercase()) {
                candidate = format!("{stem}-{k}");
                k += 1;
            }
            candidate
        })
        .collect()
}

/// Every file `--report DIR` writes, for checking before the study runs.
pub fn report_files(stems: &[String], with_layout: bool) -> Vec<String> {
    let mut files = vec![REPORT_HTML.to_string(), REPORT_PAGE.to_string()];
    for stem in stems {
        files.push(format!("{stem}.svg"));
        files.push(format!("{stem}.png"));
    }
    if with_layout {
        files.push(FOXGLOVE_LAYOUT_NAME.to_string());
    }
    files
}

fn plot_error(path: &Path, error: PlotError) -> OutputError {
    OutputError::Write {
        what: format!("plot '{}'", path.display()),
        source: std::io::Error::other(error),
    }
}

/// Writes one plot as `<dir>/<stem>.svg` and `.png` (each atomically).
pub fn write_plot(
    dir: &Path,
    stem: &str,
    svg: Result<String, PlotError>,
    png: Result<Vec<u8>, PlotError>,
) -> Result<(), OutputError> {
    let svg_path = dir.join(format!("{stem}.svg"));
    let png_path = dir.join(format!("{stem}.png"));
    let svg = svg.map_err(|e| plot_error(&svg_path, e))?;
    let png = png.map_err(|e| plot_error(&png_path, e))?;
    write_atomically(&svg_path, "plot", svg.as_bytes())?;
    write_atomically(&png_path, "plot", &png)
}

/// What an `analyze` report shows.
#[derive(Clone, Debug)]
pub struct AnalyzeReport<'a> {
    /// Heading (`ribbon analyze: ur5`).
    pub title: String,
    /// The study's text table (as printed on stdout).
    pub table: &'a str,
    /// The warnings the study printed on stderr (untrusted surrogates with what to do, chaos,
    /// joints past unenforced limits), shown above the table; empty when there were none.
    pub warnings: &'a [String],
    /// Record times, s.
    pub times: &'a [f64],
    /// The outputs, in order.
    pub outputs: Vec<ReportOutput<'a>>,
    /// File stems, one per output ([`file_stems`]).
    pub stems: &'a [String],
    /// The shaded bound's kind (`inner`, `outer`, `reference`, `nominal`).
    pub bound_kind: &'a str,
    /// The log's Foxglove layout, when the study wrote a log.
    pub foxglove_layout: Option<serde_json::Value>,
    /// The study's summary (every number of `index.html`).
    pub summary: &'a Summary,
    /// The log the study wrote (`--out`), named on the page with how to open it.
    pub log: Option<&'a Path>,
}

/// Writes the report into `dir` (which [`crate::output::prepare_output_directory`] has checked
/// for [`report_files`]): the plots, the layout, `report.md`, then `index.html`.
pub fn write_analyze_report(dir: &Path, report: &AnalyzeReport<'_>) -> Result<(), OutputError> {
    let warnings: String = report
        .warnings
        .iter()
        .map(|w| format!("> **Warning:** {}\n>\n", w.replace('\n', " ")))
        .collect();
    let warnings = match warnings.strip_suffix(">\n") {
        Some(block) => format!("{block}\n"),
        None => warnings,
    };
    let mut page = format!(
        "# {}\n\n{warnings}```text\n{}```\n\n",
        report.title,
        if report.table.ends_with('\n') {
            report.table.to_string()
        } else {
            format!("{}\n", report.table)
        }
    );
    page.push_str(&format!(
        "Each plot: the shaded region lies between the lower and upper {} bound, the solid line is \
         the nominal run{}{}. Every plot is also a PNG beside its SVG.\n\n",
        report.bound_kind,
        if report.outputs.iter().any(|o| o.outer.is_some()) {
            ", dashed lines are the outer bound"
        } else {
            ""
        },
        if report.outputs.iter().any(|o| !o.true_runs.is_empty()) {
            ", dots are true-model runs where the surrogate predicted an extreme (the a-posteriori \
             check: a dot away from the band's edge is a misfit)"
        } else {
            ""
        }
    ));
    if let Some(layout) = &report.foxglove_layout {
        write_atomically(
            &dir.join(FOXGLOVE_LAYOUT_NAME),
            "Foxglove layout",
            format!("{layout:#}").as_bytes(),
        )?;
        page.push_str(&format!(
            "Foxglove layout of the log: [{FOXGLOVE_LAYOUT_NAME}]({FOXGLOVE_LAYOUT_NAME}) \
             (*Layouts → Import from file…*).\n\n"
        ));
    }
    let mut band_svgs = Vec::with_capacity(report.outputs.len());
    for (output, stem) in report.outputs.iter().zip(report.stems) {
        let plot = band_plot(report.times, output, report.bound_kind);
        let svg_path = dir.join(format!("{stem}.svg"));
        let svg = plot.svg().map_err(|e| plot_error(&svg_path, e))?;
        write_plot(dir, stem, Ok(svg.clone()), plot.png())?;
        band_svgs.push(svg);
        page.push_str(&format!(
            "## {}\n\n![{}]({stem}.svg)\n\n",
            axis_label(output.name, output.unit),
            output.name
        ));
    }
    write_atomically(&dir.join(REPORT_PAGE), "report", page.as_bytes())?;
    let html_path = dir.join(REPORT_HTML);
    let html = html_page(&HtmlReport {
        title: &report.title,
        warnings: report.warnings,
        table: report.table,
        summary: report.summary,
        band_svgs: &band_svgs,
        log: report.log,
    })
    .map_err(|e| plot_error(&html_path, e))?;
    write_atomically(&html_path, "report page", html.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stems_are_safe_and_unique() {
        let stems = file_stems([
            "q.elbow_joint",
            "frame.a/b.z",
            "frame.a_b.z",
            "report",
            ".x",
            "Q.ELBOW_JOINT",
        ]);
        assert_eq!(
            stems,
            [
                "q.elbow_joint",
                "frame.a_b.z",
                "frame.a_b.z-2",
                "report-2",
                "_.x",
                "Q.ELBOW_JOINT-2"
            ]
        );
        assert_eq!(
            report_files(&stems[..1], true),
            [
                "index.html",
                "report.md",
                "q.elbow_joint.svg",
                "q.elbow_joint.png",
                "foxglove-layout.json"
            ]
        );
    }

    #[test]
    fn a_band_plot_shades_the_bound_and_dashes_the_outer_one() {
        let times = [0.0, 0.5, 1.0];
        let (lower, nominal, upper) = ([0.0, 0.1, 0.2], [0.5, 0.6, 0.7], [1.0, 1.1, 1.2]);
        let (outer_lower, outer_upper) = ([-0.1, 0.0, 0.1], [1.1, 1.2, 1.3]);
        let output = ReportOutput {
            name: "q.j1",
            unit: "rad",
            lower: &lower,
            upper: &upper,
            nominal: &nominal,
            outer: Some((&outer_lower, &outer_upper)),
            true_runs: &[],
            elements: &[],
        };
        let plot = band_plot(&times, &output, "inner");
        assert_eq!(plot.y_label, "q.j1 [rad]");
        assert_eq!(plot.layers.len(), 4);
        assert!(matches!(plot.layers[1], Layer::Line { dashed: true, .. }));
        let svg = plot.svg().unwrap();
        assert!(
            svg.contains("outer bound") && svg.contains("inner bound") && svg.contains("nominal")
        );
        // With check runs, their dots are drawn and named in the legend.
        let dots = [(0.5, 1.1), (1.0, 0.2)];
        let with_dots = ReportOutput {
            true_runs: &dots,
            ..output
        };
        let plot = band_plot(&times, &with_dots, "inner");
        assert_eq!(plot.layers.len(), 5);
        assert!(matches!(plot.layers[3], Layer::Points { points, .. } if points.len() == 2));
        assert!(plot
            .svg()
            .unwrap()
            .contains("true runs at predicted extremes"));
        // With elements, each leaf's bounds as two faint lines, named once.
        let (element_lower, element_upper) = ([0.05, 0.1, 0.2], [0.6, 0.7, 0.8]);
        let elements = [
            (&element_lower[..], &element_upper[..]),
            (&lower[..], &upper[..]),
        ];
        let with_elements = ReportOutput {
            elements: &elements,
            ..output
        };
        let plot = band_plot(&times, &with_elements, "inner");
        assert_eq!(plot.layers.len(), 4 + 4);
        assert!(plot.svg().unwrap().contains("bounds of each of 2 elements"));
    }
}
