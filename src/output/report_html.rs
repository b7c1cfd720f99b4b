//! The report page for the browser, `DIR/index.html` of `ribbon analyze --report DIR`
//! (docs/mcap.md §7): one self-contained file — no script, no style sheet, font or picture from
//! elsewhere, so it reads the same without a network — holding, top to bottom, the study's
//! warnings, what ran (method, design, runs, the check's verdict), the envelope table, the box,
//! a band plot per output and a sensitivity plot per output (inline SVG), and how to open the
//! MCAP log in Foxglove and rerun.
//!
//! Every number on the page comes from the study's [`Summary`], the one the summary JSON holds:
//! a number's cell carries it exactly (`data-value`, Rust's shortest text that reads back to the
//! same `f64`) beside the rounded text a reader sees, so a test reads the page and compares it
//! with the JSON bit for bit (tests/report_page.rs).
//!
//! Does not: draw the plots (`report::band_plot`, `plot`), decide what is a warning
//! (`study_front::warnings`), or write files (`report::write_analyze_report`).

use super::envelope_log::plotted_dimensions;
use super::plot::axis_label;
use super::plot::{Layer, PlotError, Stroke, TimePlot};
use super::report::untrusted_plots_text;
use super::summary::{EnvelopeSeries, Summary};
use super::viewer::{untrusted_title, FOXGLOVE_LAYOUT_NAME, SENSITIVITY_COLOURS};
use std::fmt::Write as _;
use std::path::Path;

/// Name of the page.
pub const REPORT_HTML: &str = "index.html";

/// The page's style sheet (inline: the page needs no other file).
const STYLE: &str = "body{font-family:system-ui,sans-serif;max-width:1000px;margin:1em auto;\
padding:0 1em;color:#222}\
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:2em;border-bottom:1px solid #ccc}\
.warning{background:#fff4e5;border-left:4px solid #d55e00;padding:.5em 1em;margin:.5em 0;\
white-space:pre-wrap}\
.verdict-trusted{color:#007a50;font-weight:bold}.verdict-untrusted{color:#b34700;font-weight:bold}\
table{border-collapse:collapse;font-size:.9em}td,th{border:1px solid #ddd;padding:.2em .5em}\
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}th{background:#f3f3f3;text-align:left}\
tr.untrusted td{background:#fff4e5}\
figure{margin:1em 0}figure svg{max-width:100%;height:auto;display:block}\
figcaption{font-weight:bold}pre{background:#f7f7f7;padding:.5em;overflow-x:auto}\
code{background:#f3f3f3;padding:0 .2em}";

/// What the page shows beyond the summary.
#[derive(Clone, Debug)]
pub struct HtmlReport<'a> {
    /// Heading (`ribbon analyze: ur5`).
    pub title: &'a str,
    /// The study's warnings (as printed on stderr, without `warning: `), shown first.
    pub warnings: &'a [String],
    /// The stdout table, shown as printed under the envelope table.
    pub table: &'a str,
    /// The study's summary: every number on the page.
    pub summary: &'a Summary,
    /// Per output (in the summary's order), its band plot as SVG text.
    pub band_svgs: &'a [String],
    /// The MCAP log the study wrote (`--out`), if any.
    pub log: Option<&'a Path>,
}

/// Text with `&`, `<`, `>`, `"` and `'` escaped, safe in HTML text and in quoted attributes.
pub fn escape_html(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A table cell holding a number: `data-key` names it, `data-value` holds it exactly (Rust's
/// shortest round-trip text), the visible text has the stdout table's seven significant digits.
fn number_cell(key: &str, value: f64) -> String {
    format!("<td class=\"num\" data-key=\"{key}\" data-value=\"{value}\">{value:.6e}</td>")
}

/// A cell for a number the study may not have (`–` without one).
fn optional_number_cell(key: &str, value: Option<f64>) -> String {
    match value {
        Some(v) => number_cell(key, v),
        None => format!("<td data-key=\"{key}\">–</td>"),
    }
}

/// The record of an output's widest envelope (the first, at ties), as in the stdout table.
pub fn widest_record(output: &EnvelopeSeries) -> Option<usize> {
    crate::analysis::widest_index(&output.lower, &output.upper)
}

/// The check's relative misfit of output `o` and whether the check trusted it, from the
/// summary's `stats.check` (`None` without a check).
fn check_of(summary: &Summary, name: &str) -> Option<(f64, bool)> {
    let check = summary.stats.get("check").filter(|c| !c.is_null())?;
    let misfit = check["outputs"]
        .as_array()?
        .iter()
        .find(|o| o["name"] == name)?["relative_misfit"]
        .as_f64()?;
    let untrusted = check["untrusted_outputs"]
        .as_array()
        .is_some_and(|list| list.iter().any(|n| n == name));
    Some((misfit, !untrusted))
}

/// The sensitivity plot of output `o`: the total Sobol' index over time of each parameter
/// `plotted_dimensions` picks (the parameters the log's layout plots); `None` when the study has
/// no Sobol' indices for it or no parameter reaches the floor.
pub fn sensitivity_svg(summary: &Summary, o: usize) -> Option<Result<String, PlotError>> {
    let sobol = summary.sobol_indices.as_ref()?;
    let output = sobol.outputs.get(o)?;
    let records = output.total.len();
    let dims = sobol.dimensions.len();
    let peaks: Vec<f64> = (0..dims)
        .map(|j| output.total.iter().map(|row| row[j]).fold(0.0, f64::max))
        .collect();
    let shown = plotted_dimensions(&peaks);
    if shown.is_empty() {
        return None;
    }
    let series: Vec<Vec<f64>> = shown
        .iter()
        .map(|&j| output.total.iter().map(|row| row[j]).collect())
        .collect();
    let times = &summary.outputs.get(o)?.time;
    let layers = shown
        .iter()
        .zip(&series)
        .zip(SENSITIVITY_COLOURS)
        .map(|((&j, values), colour)| Layer::Line {
            label: sobol.dimensions[j].name.clone(),
            values,
            colour,
            width: 2,
            stroke: Stroke::Solid,
        })
        .collect();
    let plot = TimePlot {
        title: format!("{}: total Sobol' index", output.name),
        y_label: "total Sobol' index".to_string(),
        times: &times[..records.min(times.len())],
        layers,
        y_limits: None,
        note: String::new(),
    };
    Some(plot.svg())
}

/// The page (module documentation).
pub fn html_page(report: &HtmlReport<'_>) -> Result<String, PlotError> {
    let s = report.summary;
    let mut page = String::new();
    let title = escape_html(report.title);
    // Writing to a String cannot fail: the `let _ =` below drop an Ok(()).
    let _ = write!(
        page,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{title}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{title}</h1>\n"
    );

    page.push_str("<section id=\"warnings\">\n");
    if report.warnings.is_empty() {
        page.push_str("<p>No warnings.</p>\n");
    }
    for warning in report.warnings {
        let _ = writeln!(
            page,
            "<div class=\"warning\"><strong>Warning:</strong> {}</div>",
            escape_html(warning)
        );
    }
    page.push_str("</section>\n");

    let check = s.stats.get("check").filter(|c| !c.is_null());
    let verdict = match check.and_then(|c| c["trusted"].as_bool()) {
        Some(true) => "<span class=\"verdict-trusted\" data-key=\"trusted\" data-value=\"true\">trusted</span>: the a-posteriori check ran the true model where the surrogate put the extremes and found it within the tolerance".to_string(),
        Some(false) => "<span class=\"verdict-untrusted\" data-key=\"trusted\" data-value=\"false\">NOT TRUSTED</span>: the a-posteriori check found outputs whose bounds may be too narrow (the warnings above say which and what to do)".to_string(),
        None => "<span data-key=\"trusted\" data-value=\"none\">no check</span>".to_string(),
    };
    let _ = write!(
        page,
        "<section id=\"study\">\n<h2>The study</h2>\n<table>\n\
         <tr><th>robot</th><td data-key=\"robot\">{}</td></tr>\n\
         <tr><th>method</th><td data-key=\"method\">{}</td></tr>\n\
         <tr><th>bounds</th><td data-key=\"bound_kind\">{}</td></tr>\n\
         <tr><th>order</th><td data-key=\"order\">{}</td></tr>\n\
         <tr><th>design</th><td data-key=\"design\">{}</td></tr>\n\
         <tr><th>model runs</th><td data-key=\"samples\" data-value=\"{}\">{}</td></tr>\n\
         <tr><th>check</th><td>{verdict}</td></tr>\n\
         <tr><th>wall time</th><td data-key=\"wall_seconds\" data-value=\"{}\">{:.3} s</td></tr>\n\
         </table>\n</section>\n",
        escape_html(&s.robot),
        escape_html(&s.method),
        escape_html(&s.bound_kind),
        s.order.map_or("–".to_string(), |k| k.to_string()),
        escape_html(s.design.as_deref().unwrap_or("–")),
        s.samples,
        s.samples,
        s.wall_seconds,
        s.wall_seconds,
    );

    page.push_str(
        "<section id=\"envelopes\">\n<h2>Envelopes</h2>\n<p>Per output, where its envelope is \
         widest: the width, the time, and the lower bound, nominal run and upper bound there; \
         the error estimate there and the check's largest misfit relative to the width.</p>\n\
         <table id=\"envelope-table\">\n<tr><th>output</th><th>unit</th><th>max width</th>\
         <th>at t (s)</th><th>lower there</th><th>nominal there</th><th>upper there</th>\
         <th>error estimate there</th><th>check misfit</th></tr>\n",
    );
    for output in &s.outputs {
        let Some(k) = widest_record(output) else {
            continue;
        };
        let check = check_of(s, &output.name);
        let _ = writeln!(
            page,
            "<tr data-output=\"{}\"{}><td>{}</td><td>{}</td>{}{}{}{}{}{}{}</tr>",
            escape_html(&output.name),
            if check.is_some_and(|(_, trusted)| !trusted) {
                " class=\"untrusted\""
            } else {
                ""
            },
            escape_html(&output.name),
            escape_html(&output.unit),
            number_cell("max_width", output.upper[k] - output.lower[k]),
            number_cell("time", output.time[k]),
            number_cell("lower", output.lower[k]),
            number_cell("nominal", output.nominal[k]),
            number_cell("upper", output.upper[k]),
            optional_number_cell(
                "error_estimate",
                output.error_estimate.as_ref().map(|e| e[k])
            ),
            optional_number_cell("relative_misfit", check.map(|c| c.0)),
        );
    }
    let _ = write!(
        page,
        "</table>\n<details><summary>The table as printed on stdout</summary>\n<pre>{}</pre>\n\
         </details>\n</section>\n",
        escape_html(report.table)
    );

    page.push_str(
        "<section id=\"parameters\">\n<h2>The box</h2>\n<table id=\"parameter-table\">\n\
         <tr><th>parameter</th><th>lower</th><th>nominal</th><th>upper</th><th>unit</th>\
         <th>sidecar key</th></tr>\n",
    );
    for p in &s.parameters {
        let _ = writeln!(
            page,
            "<tr data-parameter=\"{}\"><td>{}</td>{}{}{}<td>{}</td><td><code>{}</code></td></tr>",
            escape_html(&p.name),
            escape_html(&p.name),
            number_cell("lower", p.lower),
            number_cell("nominal", p.nominal),
            number_cell("upper", p.upper),
            escape_html(&p.unit),
            escape_html(&p.source)
        );
    }
    page.push_str("</table>\n</section>\n");

    let _ = write!(
        page,
        "<section id=\"band-plots\">\n<h2>Band plots</h2>\n<p>The shaded region lies between the \
         lower and upper {} bound, the solid line is the nominal run; dashed lines (where drawn) \
         are an outer bound, dots true-model runs where the surrogate predicted an extreme (a dot \
         away from the band's edge is a misfit).</p>\n",
        escape_html(&s.bound_kind)
    );
    // An untrusted output's plot: what its caption says (None for a trusted one).
    let untrusted_caption = |output: &EnvelopeSeries| {
        check_of(s, &output.name)
            .filter(|&(_, trusted)| !trusted)
            .map(|(misfit, _)| {
                untrusted_title(
                    &axis_label(&output.name, &output.unit),
                    misfit,
                    output.runs_lower.is_some() && output.runs_upper.is_some(),
                )
            })
    };
    if s.outputs
        .iter()
        .any(|o| o.runs_lower.is_some() && untrusted_caption(o).is_some())
    {
        let _ = writeln!(page, "<p>{}</p>", escape_html(&untrusted_plots_text()));
    }
    for (output, svg) in s.outputs.iter().zip(report.band_svgs) {
        let (marker, caption) = match untrusted_caption(output) {
            Some(caption) => (" data-untrusted=\"true\"", caption),
            None => ("", axis_label(&output.name, &output.unit)),
        };
        let _ = writeln!(
            page,
            "<figure class=\"band\"{marker} data-output=\"{}\"><figcaption>{}</figcaption>\n{}\n</figure>",
            escape_html(&output.name),
            escape_html(&caption),
            inline_svg(svg)
        );
    }
    page.push_str("</section>\n");

    page.push_str("<section id=\"sensitivity-plots\">\n<h2>Sensitivity</h2>\n");
    let mut any_sensitivity = false;
    for (o, output) in s.outputs.iter().enumerate() {
        if let Some(svg) = sensitivity_svg(s, o) {
            if !any_sensitivity {
                page.push_str(
                    "<p>Per output, the total Sobol' index over time of the parameters that \
                     reach 1 % of its variance at some time: the share of the output's variance \
                     each parameter takes part in (docs/sobol-indices.md).</p>\n",
                );
                any_sensitivity = true;
            }
            let _ = writeln!(
                page,
                "<figure class=\"sensitivity\" data-output=\"{}\"><figcaption>{}: total Sobol' \
                 index</figcaption>\n{}\n</figure>",
                escape_html(&output.name),
                escape_html(&output.name),
                inline_svg(&svg?)
            );
        }
    }
    if !any_sensitivity {
        page.push_str(
            "<p>This study has no Sobol' indices (they come from the surrogate methods' \
             polynomial coefficients; scans, Monte Carlo and taylor have none), or no parameter \
             reaches 1 % of an output's variance.</p>\n",
        );
    }
    page.push_str("</section>\n");

    page.push_str(&viewer_section(report.log));
    page.push_str("</body>\n</html>\n");
    Ok(page)
}

/// An SVG document as an element inside HTML: without an XML declaration.
fn inline_svg(svg: &str) -> &str {
    match svg.trim_start().strip_prefix("<?xml") {
        Some(rest) => rest
            .split_once("?>")
            .map_or(svg, |(_, body)| body.trim_start()),
        None => svg,
    }
}

/// How to open the log in Foxglove and rerun (README "Looking at the MCAP").
fn viewer_section(log: Option<&Path>) -> String {
    let Some(log) = log else {
        return format!(
            "<section id=\"viewers\">\n<h2>Viewers</h2>\n<p>This study wrote no MCAP log. \
             Run it again with <code>--out FILE.mcap</code> to get one, which Foxglove and rerun \
             open with a ready layout (one plot per output, the moving nominal robot); \
             <code>--report</code> then also writes that layout here as \
             <code>{FOXGLOVE_LAYOUT_NAME}</code>.</p>\n</section>\n"
        );
    };
    let path = escape_html(&log.display().to_string());
    let stem = escape_html(
        &log.file_stem()
            .map_or("log".to_string(), |s| s.to_string_lossy().into_owned()),
    );
    format!(
        "<section id=\"viewers\">\n<h2>Viewers</h2>\n<p>The envelopes, error estimates, \
         Sobol' indices and the nominal robot's frames are in the MCAP log \
         <code>{path}</code>.</p>\n<ul>\n<li><strong>Foxglove</strong>: <em>Open local \
         file…</em> → <code>{path}</code>; then <em>Layouts → Import from file…</em> → \
         <a href=\"{FOXGLOVE_LAYOUT_NAME}\"><code>{FOXGLOVE_LAYOUT_NAME}</code></a> beside this \
         page (the same layout is attached to the log).</li>\n<li><strong>rerun</strong> (0.41): \
         <pre>rerun mcap convert --timeline-type duration --application-id ribbon {path} -o \
         {stem}.rrd\ntarget/reference-venv/bin/python scripts/viewers/rerun_blueprint.py {path} \
         {stem}.rbl\nrerun {stem}.rrd {stem}.rbl</pre></li>\n</ul>\n</section>\n"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping_covers_text_and_attributes() {
        assert_eq!(
            escape_html(r#"a<b>&"c"'d'"#),
            "a&lt;b&gt;&amp;&quot;c&quot;&#39;d&#39;"
        );
    }

    #[test]
    fn a_number_cell_holds_the_exact_value() {
        let cell = number_cell("upper", 0.1 + 0.2);
        assert!(
            cell.contains("data-value=\"0.30000000000000004\""),
            "{cell}"
        );
        assert!(cell.contains(">3.000000e-1<"), "{cell}");
    }

    #[test]
    fn the_widest_record_is_the_first_widest() {
        let series = EnvelopeSeries {
            name: "q".to_string(),
            unit: "rad".to_string(),
            time: vec![0.0, 1.0, 2.0],
            lower: vec![0.0, -1.0, -1.0],
            upper: vec![0.0, 1.0, 1.0],
            nominal: vec![0.0; 3],
            error_estimate: None,
            outer_lower: None,
            outer_upper: None,
            runs_lower: None,
            runs_upper: None,
        };
        assert_eq!(widest_record(&series), Some(1));
    }

    #[test]
    fn an_xml_declaration_is_dropped_inline() {
        assert_eq!(
            inline_svg("<?xml version=\"1.0\"?>\n<svg></svg>"),
            "<svg></svg>"
        );
        assert_eq!(inline_svg("<svg></svg>"), "<svg></svg>");
    }
}
