//! The report directory of `ribbon analyze --report DIR` (docs/mcap.md §7): `index.html`, the
//! self-contained page for the browser (`report_html`), `report.md` with the study's table, one
//! band plot per output as `<output>.svg` and `<output>.png`, and, when the study also wrote a log
//! (`--out`), the log's Foxglove layout as `foxglove-layout.json`.
//!
//! A band plot shades the region between the lower and upper bound (labelled with the bound's
//! kind: inner, outer, reference), draws the nominal run as a solid line and, where a sparse
//! design also gives an outer bound, that bound as dashed lines; dots are the check's true runs
//! where the surrogate put the extremes. On an output the check did not trust, the plot's title
//! says so with its misfit, and dotted lines are the lowest and highest value every true-model
//! run of the study took (the "true runs' range", the summary's `runs_lower` / `runs_upper`):
//! what the study can claim. Where the bounds are more than 1 / [`HULL_MIN_AXIS_SHARE`] times as
//! tall as that range, the y axis follows the range instead ([`hull_axis`]) and a note on the plot
//! says how far the clipped bounds reach (docs/mcap.md §7).

use super::error::OutputError;
use super::plot::{axis_label, finite_span, Layer, PlotError, Stroke, TimePlot};
use super::report_html::{html_page, HtmlReport, REPORT_HTML};
use super::summary::Summary;
use super::viewer::{untrusted_title_words, FOXGLOVE_LAYOUT_NAME, RUNS_HULL_SERIES};
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
/// Colour of the dotted lines of the true runs' range: the viewers' colour for the same series
/// (reddish purple).
pub const RUNS_HULL_COLOUR: &str = RUNS_HULL_SERIES[0].1;
/// Stroke width of the true runs' range, pixels: wider than the other lines (2), so its dots read
/// over the band, the elements' lines and the dashed outer bound.
pub const RUNS_HULL_WIDTH: u32 = 3;
/// Smallest share of the y axis's height the true runs' range (with the nominal run and the
/// check's dots) must fill on an untrusted output's plot: below it (bounds more than four times as
/// tall as every true run went) the range would be a thin stripe, so the axis follows the range
/// and clips the bounds.
pub const HULL_MIN_AXIS_SHARE: f64 = 0.25;
/// Room left above and below the true runs' range on an axis that follows it, as a share of the
/// range's height: the clipped band shows beyond the range, so the reader sees it goes on.
pub const HULL_AXIS_MARGIN: f64 = 0.25;
/// Significant digits of the numbers in a clipped plot's note.
const NOTE_DIGITS: usize = 4;
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
    /// Where the a-posteriori check did not trust this output: its misfit and its true runs'
    /// range; `None` for a trusted or unchecked output (its plot is then as before).
    pub untrusted: Option<UntrustedOutput<'a>>,
}

/// What an untrusted output's plot shows beside its bounds.
#[derive(Clone, Copy, Debug)]
pub struct UntrustedOutput<'a> {
    /// The check's largest misfit over the output's largest envelope width.
    pub relative_misfit: f64,
    /// The lowest and highest value of every true-model run of the study per record time, when
    /// the study has them ([`crate::analysis::StudyReport::shows_runs_hull`]).
    pub hull: Option<RunsHull<'a>>,
}

/// The true runs' range of one output: the summary's `runs_lower` / `runs_upper`.
#[derive(Clone, Copy, Debug)]
pub struct RunsHull<'a> {
    /// The lowest value any true-model run took, per record time.
    pub lower: &'a [f64],
    /// The highest value, per record time.
    pub upper: &'a [f64],
    /// How many true-model runs it covers (the study's model runs, less excluded samples).
    pub runs: usize,
}

/// `value` with [`NOTE_DIGITS`] significant digits: fixed notation from 1e-3 to 1e5, otherwise
/// scientific.
fn short_number(value: f64) -> String {
    let magnitude = value.abs();
    if value == 0.0 || !value.is_finite() {
        return format!("{value}");
    }
    if (1e-3..1e5).contains(&magnitude) {
        let decimals = (NOTE_DIGITS as i32 - 1 - magnitude.log10().floor() as i32).max(0) as usize;
        format!("{value:.decimals$}")
    } else {
        format!("{value:.digits$e}", digits = NOTE_DIGITS - 1)
    }
}

/// The y axis of an untrusted output's plot and its note: `None` when the true runs' range (with
/// the nominal run and the check's dots) fills at least [`HULL_MIN_AXIS_SHARE`] of the span of
/// everything drawn, so the whole plot shows; otherwise the range widened by [`HULL_AXIS_MARGIN`]
/// of its height on each side (never past the data), with a note saying how far the clipped
/// bounds reach.
pub fn hull_axis(output: &ReportOutput<'_>, hull: &RunsHull<'_>) -> Option<((f64, f64), String)> {
    let focus = hull
        .lower
        .iter()
        .chain(hull.upper)
        .chain(output.nominal)
        .chain(output.true_runs.iter().map(|(_, y)| y));
    let (focus_lo, focus_hi) = finite_span(focus.clone().copied())?;
    let outer = output
        .outer
        .map_or(&[][..], |(lower, _)| lower)
        .iter()
        .chain(output.outer.map_or(&[][..], |(_, upper)| upper));
    let elements = output
        .elements
        .iter()
        .flat_map(|(l, u)| l.iter().chain(u.iter()));
    let bounds = output
        .lower
        .iter()
        .chain(output.upper)
        .chain(outer)
        .chain(elements);
    let (all_lo, all_hi) = finite_span(bounds.chain(focus).copied())?;
    let focus_span = focus_hi - focus_lo;
    if focus_span >= HULL_MIN_AXIS_SHARE * (all_hi - all_lo) || focus_span <= 0.0 {
        return None;
    }
    let margin = HULL_AXIS_MARGIN * focus_span;
    let limits = (
        (focus_lo - margin).max(all_lo),
        (focus_hi + margin).min(all_hi),
    );
    let unit = if output.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", output.unit)
    };
    let note = format!(
        "bounds clipped: they reach {} … {}{unit}; the axis follows the true runs",
        short_number(all_lo),
        short_number(all_hi)
    );
    Some((limits, note))
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
                stroke: Stroke::Solid,
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
                stroke: Stroke::Dashed,
            });
        }
    }
    let hull = output.untrusted.and_then(|u| u.hull);
    if let Some(hull) = &hull {
        for (label, values) in [
            (format!("true runs' range ({} runs)", hull.runs), hull.lower),
            (String::new(), hull.upper),
        ] {
            layers.push(Layer::Line {
                label,
                values,
                colour: RUNS_HULL_COLOUR,
                width: RUNS_HULL_WIDTH,
                stroke: Stroke::Dotted,
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
        stroke: Stroke::Solid,
    });
    let label = axis_label(output.name, output.unit);
    let title = match output.untrusted {
        Some(untrusted) => untrusted_title_words(&label, untrusted.relative_misfit, hull.is_some()),
        None => label.clone(),
    };
    let (y_limits, note) = match hull.and_then(|hull| hull_axis(output, &hull)) {
        Some((limits, note)) => (Some(limits), note),
        None => (None, String::new()),
    };
    TimePlot {
        title,
        y_label: label,
        times,
        layers,
        y_limits,
        note,
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

/// What the report page and `index.html` say of an untrusted output's plot (shown only when some
/// plot has the true runs' range).
pub fn untrusted_plots_text() -> String {
    format!(
        "On an output the check did not trust, the title says NOT TRUSTED with its misfit, and \
         dotted reddish-purple lines are the lowest and highest value that every true-model run of \
         the study took (the true runs' range): the motion the study can claim, where the bounds \
         are the untrusted surrogate's. Where the bounds are more than {:.0} times as tall as that \
         range, the y axis follows the range and clips the band; a note on the plot says how far \
         the bounds reach.",
        1.0 / HULL_MIN_AXIS_SHARE
    )
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
    if report
        .outputs
        .iter()
        .any(|o| o.untrusted.is_some_and(|u| u.hull.is_some()))
    {
        page.push_str(&untrusted_plots_text());
        page.push_str("\n\n");
    }
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
            plot.title, output.name
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
            untrusted: None,
        };
        let plot = band_plot(&times, &output, "inner");
        assert_eq!(plot.y_label, "q.j1 [rad]");
        assert_eq!(plot.layers.len(), 4);
        assert!(matches!(
            plot.layers[1],
            Layer::Line {
                stroke: Stroke::Dashed,
                ..
            }
        ));
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

    /// The y coordinates of every point of every polygon and polyline of an SVG, pixels.
    fn drawn_ys(svg: &str) -> Vec<f64> {
        svg.split("points=\"")
            .skip(1)
            .flat_map(|rest| {
                let list = &rest[..rest.find('"').unwrap()];
                list.split_whitespace()
                    .map(|point| point.split(',').nth(1).unwrap().parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// An untrusted output: its title says so with the misfit, its true runs' range is two dotted
    /// lines of exactly the hull's values, named once in the legend with the run count; bounds
    /// 100 times as tall as the range are clipped to an axis that follows it, with a note.
    #[test]
    fn an_untrusted_band_plot_draws_the_true_runs_range_and_follows_it() {
        let times: Vec<f64> = (0..60).map(|k| k as f64 * 0.05).collect();
        let nominal: Vec<f64> = times.iter().map(|t| t.sin()).collect();
        let runs_lower: Vec<f64> = nominal.iter().map(|v| v - 0.5).collect();
        let runs_upper: Vec<f64> = nominal.iter().map(|v| v + 0.5).collect();
        let exploded_lower: Vec<f64> = times.iter().map(|t| -100.0 * t).collect();
        let exploded_upper: Vec<f64> = times.iter().map(|t| 90.0 * t).collect();
        let dots = [(1.0, 1.2)];
        let hull = RunsHull {
            lower: &runs_lower,
            upper: &runs_upper,
            runs: 742,
        };
        let output = ReportOutput {
            name: "q.j2",
            unit: "rad",
            lower: &exploded_lower,
            upper: &exploded_upper,
            nominal: &nominal,
            outer: None,
            true_runs: &dots,
            elements: &[],
            untrusted: Some(UntrustedOutput {
                relative_misfit: 0.656,
                hull: Some(hull),
            }),
        };
        let plot = band_plot(&times, &output, "inner");
        assert_eq!(
            plot.title,
            "q.j2 [rad] — NOT TRUSTED (misfit 65.6 %): true runs dotted"
        );
        assert_eq!(plot.y_label, "q.j2 [rad]");
        let dotted: Vec<(&str, &[f64])> = plot
            .layers
            .iter()
            .filter_map(|layer| match layer {
                Layer::Line {
                    label,
                    values,
                    stroke: Stroke::Dotted,
                    colour,
                    ..
                } if *colour == RUNS_HULL_COLOUR => Some((label.as_str(), *values)),
                _ => None,
            })
            .collect();
        assert_eq!(dotted.len(), 2, "{:?}", plot.layers);
        assert_eq!(dotted[0].0, "true runs' range (742 runs)");
        assert_eq!(dotted[1].0, "", "named once");
        assert!(std::ptr::eq(dotted[0].1, &runs_lower[..]));
        assert!(std::ptr::eq(dotted[1].1, &runs_upper[..]));
        // The axis: the hull, the nominal run and the dot, a quarter of the range to spare, and
        // the bounds clipped (they reach -295 … 265.5).
        let (lo, hi) = plot.y_limits.expect("the axis follows the true runs");
        let (hull_lo, hull_hi) = (-1.5, 1.5);
        let focus_lo = runs_lower.iter().copied().fold(f64::INFINITY, f64::min);
        let focus_hi = runs_upper.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(focus_lo > hull_lo && focus_hi < hull_hi);
        let margin = HULL_AXIS_MARGIN * (focus_hi - focus_lo);
        assert!((lo - (focus_lo - margin)).abs() < 1e-12, "{lo}");
        assert!((hi - (focus_hi + margin)).abs() < 1e-12, "{hi}");
        assert_eq!(
            plot.note,
            "bounds clipped: they reach -295.0 … 265.5 rad; the axis follows the true runs"
        );
        let svg = plot.svg().unwrap();
        for text in [
            "NOT TRUSTED (misfit 65.6 %)",
            "true runs&apos; range (742 runs)",
            "bounds clipped",
        ] {
            assert!(svg.contains(text), "{text} not in the SVG");
        }
        // Clipped, nothing is drawn outside the picture.
        let (_, height) = crate::output::plot::PLOT_SIZE;
        let ys = drawn_ys(&svg);
        assert!(ys.len() > 100);
        assert!(
            ys.iter().all(|y| (0.0..=height as f64).contains(y)),
            "{:?}",
            ys.iter()
                .filter(|y| !(0.0..=height as f64).contains(*y))
                .collect::<Vec<_>>()
        );

        // Bounds at most four times as tall as the range: the whole plot, no note.
        let near_lower: Vec<f64> = runs_lower.iter().map(|v| v - 1.0).collect();
        let near_upper: Vec<f64> = runs_upper.iter().map(|v| v + 1.0).collect();
        let moderate = ReportOutput {
            lower: &near_lower,
            upper: &near_upper,
            ..output
        };
        let plot = band_plot(&times, &moderate, "inner");
        assert_eq!(plot.y_limits, None);
        assert!(plot.note.is_empty());
        assert_eq!(
            plot.layers
                .iter()
                .filter(|l| matches!(
                    l,
                    Layer::Line {
                        stroke: Stroke::Dotted,
                        ..
                    }
                ))
                .count(),
            2
        );

        // Trusted: the plot it always was.
        let trusted = ReportOutput {
            untrusted: None,
            ..output
        };
        let plot = band_plot(&times, &trusted, "inner");
        assert_eq!(plot.title, "q.j2 [rad]");
        assert!(plot.y_limits.is_none() && plot.note.is_empty());
        assert!(!plot.layers.iter().any(|l| matches!(
            l,
            Layer::Line {
                stroke: Stroke::Dotted,
                ..
            }
        )));
        // Untrusted without a hull: said in the title, nothing more drawn.
        let without_hull = ReportOutput {
            untrusted: Some(UntrustedOutput {
                relative_misfit: 0.08,
                hull: None,
            }),
            ..output
        };
        let plot = band_plot(&times, &without_hull, "inner");
        assert_eq!(plot.title, "q.j2 [rad] — NOT TRUSTED (misfit 8.0 %)");
        assert!(plot.y_limits.is_none());
    }

    #[test]
    fn note_numbers_have_four_significant_digits() {
        assert_eq!(short_number(-2512.345), "-2512");
        assert_eq!(short_number(17.00592), "17.01");
        assert_eq!(short_number(0.0123456), "0.01235");
        assert_eq!(short_number(2.5e6), "2.500e6");
        assert_eq!(short_number(0.0), "0");
    }
}
