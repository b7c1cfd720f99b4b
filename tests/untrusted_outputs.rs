//! What an untrusted study's files say beside its envelope (issue 38 item 3, docs/mcap.md §1,
//! §4): the hull of its true runs as CSV columns and MCAP channels, equal to the summary's
//! `runs_lower` / `runs_upper`; the check's verdict as the `check` entry of the MCAP's `ribbon`
//! record; the untrusted outputs' plots titled as such in the Foxglove layout, their true runs
//! beside the envelope; every message in time order; and `plan` / `run` / `merge` writing the same
//! bytes. The scene: the double pendulum falling from upright (fixture `refine_chaos`), untrusted
//! over its 3 s. Its report (`--report`): each untrusted output's band plot titled NOT TRUSTED,
//! with the true runs' range drawn dotted where the summary's values map on the plot. A trusted
//! study's files keep every byte (tests/analyze_bitwise.rs); here, that it has none of the above.

mod common;

use common::{fresh_test_scratch_dir, ribbon_metadata, ribbon_outcome, summary_series};
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

const URDF: &str = "robots/double_pendulum/double_pendulum.urdf";
const SIDECAR: &str = "tests/fixtures/refine_chaos/upright.uncertainty.toml";
const OUTPUTS: [&str; 2] = ["q.j1", "q.j2"];

/// `sensor_msgs/msg/JointState` as the test reads it back.
#[derive(Debug, Deserialize)]
struct JointState {
    #[allow(dead_code)]
    header: (i32, u32, String),
    name: Vec<String>,
    position: Vec<f64>,
    #[allow(dead_code)]
    velocity: Vec<f64>,
    #[allow(dead_code)]
    effort: Vec<f64>,
}

/// The study's files: (CSV text, MCAP bytes, summary); its report is in `dir/report`.
fn study(dir: &Path, command: &[&str], expected_code: i32) -> (String, Vec<u8>, Value) {
    let file = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let mut args = command.to_vec();
    let (csv, mcap, summary) = (file("out.csv"), file("out.mcap"), file("summary.json"));
    let report = file("report");
    args.extend(["--csv", &csv, "--out", &mcap, "--summary", &summary]);
    args.extend(["--report", &report]);
    let outcome = ribbon_outcome(&args);
    assert_eq!(outcome.code, Some(expected_code), "{}", outcome.stderr);
    (
        std::fs::read_to_string(&csv).unwrap(),
        std::fs::read(&mcap).unwrap(),
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap(),
    )
}

/// The CSV's header and its columns by name.
fn csv_columns(text: &str) -> (Vec<String>, BTreeMap<String, Vec<f64>>) {
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut columns: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for line in lines {
        for (name, value) in header.iter().zip(line.split(',')) {
            columns
                .entry(name.clone())
                .or_default()
                .push(value.parse().unwrap());
        }
    }
    (header, columns)
}

/// The Foxglove layout attached to the log.
fn layout(bytes: &[u8]) -> Value {
    mcap::read::LinearReader::new(bytes)
        .unwrap()
        .find_map(|record| match record.unwrap() {
            mcap::records::Record::Attachment { header, data, .. }
                if header.name == "foxglove-layout.json" =>
            {
                Some(serde_json::from_slice(&data).unwrap())
            }
            _ => None,
        })
        .expect("the log holds the layout")
}

/// Per topic, its channel's metadata and its messages (log time, names, values), in file order;
/// and whether the file's messages come in time order.
type Topics = BTreeMap<String, (BTreeMap<String, String>, Vec<(u64, Vec<String>, Vec<f64>)>)>;

fn read_topics(bytes: &[u8]) -> (Topics, bool) {
    let mut topics = Topics::new();
    let mut last = 0;
    let mut in_time_order = true;
    for message in mcap::MessageStream::new(bytes).unwrap() {
        let message = message.unwrap();
        in_time_order &= message.log_time >= last;
        last = message.log_time;
        let topic = message.channel.topic.clone();
        let entry = topics
            .entry(topic.clone())
            .or_insert_with(|| (message.channel.metadata.clone(), Vec::new()));
        if topic.starts_with("/ribbon/") {
            let state: JointState = cdr::deserialize(&message.data).unwrap();
            entry.1.push((message.log_time, state.name, state.position));
        }
    }
    (topics, in_time_order)
}

/// Every `points` list of the SVG's elements whose attributes contain `attribute` (e.g.
/// `stroke="#CC79A7"`), drawn before the legend's box (the `<rect` edged `#A0A0A0`): `(x, y)`
/// pixels.
fn plotted_points(svg: &str, attribute: &str) -> Vec<(f64, f64)> {
    let plot = &svg[..svg.find("stroke=\"#A0A0A0\"").expect("a legend")];
    plot.split('<')
        .filter(|element| element.contains(attribute))
        .filter_map(|element| element.split("points=\"").nth(1))
        .flat_map(|rest| {
            rest[..rest.find('"').unwrap()]
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Smallest and largest of `values`.
fn span(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    values
        .into_iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// How far (pixels) a dotted line's drawn extreme may be from where its extreme value maps: a dot
/// and a gap (6 px along the line) may fall on the extreme, plus a pixel of rounding each side.
const DOTTED_EXTREME_PIXELS: f64 = 8.0;

/// The report of an untrusted study (`--report`): each untrusted output's band plot is titled NOT
/// TRUSTED with the summary's misfit, names the true runs' range with the study's run count, and
/// draws it where the summary's `runs_lower` / `runs_upper` map on the plot's axis (the axis read
/// off the band's own extremes); the axis clips the band exactly when the bounds are more than
/// four times as tall as the range; the page and `report.md` say so too.
fn assert_the_report_shows_the_true_runs(dir: &Path, summary: &Value) {
    let check = &summary["stats"]["check"];
    // The study's model runs less its excluded samples.
    let runs = summary["samples"].as_u64().unwrap()
        - summary["excluded_samples"].as_array().unwrap().len() as u64;
    let mut cases = Vec::new();
    for output in OUTPUTS {
        let svg = std::fs::read_to_string(dir.join(format!("report/{output}.svg"))).unwrap();
        let misfit = check["outputs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["name"] == output)
            .unwrap()["relative_misfit"]
            .as_f64()
            .unwrap();
        let title = format!(
            "{output} [rad] — NOT TRUSTED (misfit {:.1} %): true runs dotted",
            100.0 * misfit
        );
        assert!(svg.contains(&title), "{output}: no title {title:?}");
        assert!(
            svg.contains(&format!("true runs&apos; range ({runs} runs)")),
            "{output}: the range is not named with {runs} runs"
        );
        let series = |key: &str| summary_series(summary, output, key);
        let (hull_lo, hull_hi) = span(series("runs_lower").into_iter().chain(series("runs_upper")));
        let (all_lo, all_hi) = span(
            [
                "lower",
                "upper",
                "outer_lower",
                "outer_upper",
                "runs_lower",
                "runs_upper",
                "nominal",
            ]
            .into_iter()
            .filter(|key| summary["outputs"][0].get(*key).is_some())
            .flat_map(series),
        );
        let clipped = svg.contains("bounds clipped");
        // The nominal run lies inside the range here, and the check's dots are true runs.
        assert_eq!(
            clipped,
            (hull_hi - hull_lo) < 0.25 * (all_hi - all_lo),
            "{output}: range {hull_lo} … {hull_hi}, everything {all_lo} … {all_hi}"
        );
        cases.push(clipped);
        // The axis, from the band's polygon: its top is the largest upper bound, its bottom the
        // smallest lower one, each clipped to the axis where it follows the range (a quarter of
        // the range's height beyond it, never past the data).
        let band = plotted_points(&svg, "fill=\"#0072B2\"");
        let (band_top, band_bottom) = span(band.iter().map(|p| p.1));
        let (lower, upper) = (series("lower"), series("upper"));
        let (value_lo, value_hi) = span(lower.iter().chain(&upper).copied());
        let (value_lo, value_hi) = if clipped {
            let margin = 0.25 * (hull_hi - hull_lo);
            let (axis_lo, axis_hi) = (
                (hull_lo - margin).max(all_lo),
                (hull_hi + margin).min(all_hi),
            );
            (
                value_lo.clamp(axis_lo, axis_hi),
                value_hi.clamp(axis_lo, axis_hi),
            )
        } else {
            (value_lo, value_hi)
        };
        let pixels_per_unit = (band_bottom - band_top) / (value_hi - value_lo);
        let pixel_of = |v: f64| band_top + (value_hi - v) * pixels_per_unit;
        let hull = plotted_points(&svg, "stroke=\"#CC79A7\"");
        assert!(
            hull.len() > 100,
            "{output}: {} hull points drawn",
            hull.len()
        );
        let (drawn_top, drawn_bottom) = span(hull.iter().map(|p| p.1));
        for (what, drawn, expected) in [
            ("highest", drawn_top, pixel_of(hull_hi)),
            ("lowest", drawn_bottom, pixel_of(hull_lo)),
        ] {
            assert!(
                (drawn - expected).abs() <= DOTTED_EXTREME_PIXELS,
                "{output}: the range's {what} value is drawn at y = {drawn} px, it maps to {expected:.1} px"
            );
        }
        // Over the whole time axis, as the band.
        let (band_left, band_right) = span(band.iter().map(|p| p.0));
        let (hull_left, hull_right) = span(hull.iter().map(|p| p.0));
        assert!(
            hull_left - band_left <= DOTTED_EXTREME_PIXELS
                && band_right - hull_right <= DOTTED_EXTREME_PIXELS,
            "{output}: the range spans x {hull_left} … {hull_right}, the band {band_left} … {band_right}"
        );
    }
    // q.j1's bounds (its outer bound's) are 4.1 times as tall as its range, q.j2's 3.7 times: the
    // fixture draws both kinds of axis.
    assert_eq!(cases, [true, false], "clipped, per output");
    let page = std::fs::read_to_string(dir.join("report/index.html")).unwrap();
    let markdown = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    for output in OUTPUTS {
        assert!(
            page.contains(&format!(
                "<figure class=\"band\" data-untrusted=\"true\" data-output=\"{output}\"><figcaption>⚠ {output} [rad] — NOT TRUSTED"
            )),
            "index.html: {output}'s caption"
        );
        assert!(
            markdown.contains(&format!("## {output} [rad] — NOT TRUSTED")),
            "report.md: {output}'s heading"
        );
    }
    for text in [&page, &markdown] {
        assert!(text.contains("the true runs&#39; range") || text.contains("the true runs' range"));
    }
}

#[test]
fn an_untrusted_study_shows_its_true_runs_and_the_verdict_in_the_csv_and_the_log() {
    let dir = fresh_test_scratch_dir("untrusted_outputs", "refine_chaos");
    let command = [
        "analyze",
        URDF,
        "--uncertainty",
        SIDECAR,
        "--max-runs",
        "600",
    ];
    let (csv, mcap, summary) = study(&dir, &command, 4);
    let check = &summary["stats"]["check"];
    assert_eq!(check["trusted"], false, "the scene must be untrusted");
    let times = summary_series(&summary, OUTPUTS[0], "time");
    assert_the_report_shows_the_true_runs(&dir, &summary);

    // CSV: every column of a trusted study's CSV in its place, then the hull per output.
    let (header, columns) = csv_columns(&csv);
    let columns_of = |series: &[&str]| -> Vec<String> {
        OUTPUTS
            .iter()
            .flat_map(|o| series.iter().map(move |s| format!("{o}.{s}")))
            .collect()
    };
    let expected = [
        vec!["t".to_string()],
        columns_of(&["lower", "nominal", "upper"]),
        columns_of(&["runs_lower", "runs_upper"]),
    ]
    .concat();
    assert_eq!(header, expected);
    for output in OUTPUTS {
        for series in ["lower", "nominal", "upper", "runs_lower", "runs_upper"] {
            let from_summary = summary_series(&summary, output, series);
            let from_csv = &columns[&format!("{output}.{series}")];
            assert!(
                from_csv
                    .iter()
                    .map(|x| x.to_bits())
                    .eq(from_summary.iter().map(|x| x.to_bits())),
                "{output}.{series}: the CSV's column is not the summary's series"
            );
        }
        // The hull is not the envelope: the study's point is that they differ.
        assert_ne!(
            columns[&format!("{output}.runs_upper")],
            columns[&format!("{output}.upper")],
            "{output}"
        );
    }

    // MCAP: one hull channel per output, every record, the summary's values, in time order.
    let (topics, in_time_order) = read_topics(&mcap);
    assert!(in_time_order, "the log's messages are not in time order");
    for output in OUTPUTS {
        let suffix = output.replace('.', "/");
        let (metadata, messages) = &topics[&format!("/ribbon/runs/{suffix}")];
        assert_eq!(metadata, &topics[&format!("/ribbon/envelope/{suffix}")].0);
        assert_eq!(
            messages.len(),
            times.len(),
            "{output}: one message per record"
        );
        let lowest = summary_series(&summary, output, "runs_lower");
        let highest = summary_series(&summary, output, "runs_upper");
        for (k, (log_time, names, values)) in messages.iter().enumerate() {
            assert_eq!(*log_time, (times[k] * 1e9).round() as u64);
            assert_eq!(names, &["runs_lower", "runs_upper"]);
            assert_eq!(
                values.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                [lowest[k].to_bits(), highest[k].to_bits()],
                "{output} at t = {} s",
                times[k]
            );
        }
    }

    // The verdict in the `ribbon` record: the summary's.
    let metadata = ribbon_metadata(&mcap);
    let verdict: Value = serde_json::from_str(&metadata["check"]).expect("`check` is JSON");
    assert_eq!(verdict["trusted"], false);
    let untrusted: Vec<&str> = verdict["untrusted_outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["name"].as_str().unwrap())
        .collect();
    let summary_untrusted: Vec<&str> = check["untrusted_outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o.as_str().unwrap())
        .collect();
    assert!(!untrusted.is_empty());
    assert_eq!(untrusted, summary_untrusted);
    for entry in verdict["untrusted_outputs"].as_array().unwrap() {
        let from_summary = check["outputs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["name"] == entry["name"])
            .unwrap();
        assert_eq!(entry["relative_misfit"], from_summary["relative_misfit"]);
    }
    assert_eq!(verdict["passes_until_time_s"], check["passes_until_time_s"]);
    assert_eq!(
        verdict["verified_until_time_s"],
        check["horizon"]["verified_until_time_s"]
    );

    // The layout: an untrusted output's plot says so and shows its true runs.
    let layout = layout(&mcap);
    let plots: Vec<&Value> = layout["configById"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(id, _)| id.starts_with("Plot!ribbon") && !id.starts_with("Plot!ribbon-sobol"))
        .map(|(_, plot)| plot)
        .collect();
    for output in OUTPUTS {
        let plot = plots
            .iter()
            .find(|p| {
                p["foxglovePanelTitle"]
                    .as_str()
                    .unwrap()
                    .contains(&format!("{output} [rad]"))
            })
            .unwrap_or_else(|| panic!("no plot of {output}"));
        let title = plot["foxglovePanelTitle"].as_str().unwrap();
        if untrusted.contains(&output) {
            let entry = untrusted.iter().position(|u| *u == output).unwrap();
            let misfit = 100.0
                * verdict["untrusted_outputs"][entry]["relative_misfit"]
                    .as_f64()
                    .unwrap();
            assert_eq!(
                title,
                format!("⚠ {output} [rad] — NOT TRUSTED (misfit {misfit:.1} %): true runs dotted")
            );
            let values: Vec<&str> = plot["paths"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| p["value"].as_str().unwrap())
                .collect();
            let suffix = output.replace('.', "/");
            assert!(
                values.contains(&format!("/ribbon/runs/{suffix}.position[0]").as_str())
                    && values.contains(&format!("/ribbon/runs/{suffix}.position[1]").as_str()),
                "{values:?}"
            );
        }
    }

    // plan / run / merge in two shards: the same bytes.
    let sharded = dir.join("sharded");
    std::fs::create_dir_all(&sharded).unwrap();
    let file = |name: &str| sharded.join(name).to_str().unwrap().to_string();
    let (plan, blocks) = (file("study.plan"), file("blocks"));
    let mut plan_args = vec!["plan", URDF, "--uncertainty", SIDECAR, "--max-runs", "600"];
    plan_args.extend(["--plan", &plan]);
    assert_eq!(ribbon_outcome(&plan_args).code, Some(0));
    let merged = loop {
        for shard in ["0/2", "1/2"] {
            let run = ribbon_outcome(&["run", &plan, "--shard", shard, "--into", &blocks]);
            assert_eq!(run.code, Some(0), "{}", run.stderr);
        }
        let merge_dir = sharded.join("merged");
        std::fs::create_dir_all(&merge_dir).unwrap();
        let (merged_csv, merged_mcap) = (file("merged/out.csv"), file("merged/out.mcap"));
        let outcome = ribbon_outcome(&[
            "merge",
            &plan,
            &blocks,
            "--csv",
            &merged_csv,
            "--out",
            &merged_mcap,
        ]);
        match outcome.code {
            Some(3) => continue,
            Some(4) => break merge_dir,
            other => panic!("merge exited {other:?}: {}", outcome.stderr),
        }
    };
    assert!(
        std::fs::read_to_string(merged.join("out.csv")).unwrap() == csv,
        "merge's CSV differs from analyze's"
    );
    assert!(
        std::fs::read(merged.join("out.mcap")).unwrap() == mcap,
        "merge's MCAP differs from analyze's"
    );
}

#[test]
fn a_trusted_study_shows_no_hull_and_no_verdict() {
    let dir = fresh_test_scratch_dir("untrusted_outputs", "trusted");
    let command = ["analyze", URDF, "--duration", "0.3"];
    let (csv, mcap, summary) = study(&dir, &command, 0);
    assert_eq!(summary["stats"]["check"]["trusted"], true);
    assert!(!csv.lines().next().unwrap().contains("runs_"), "{csv}");
    let (topics, in_time_order) = read_topics(&mcap);
    assert!(in_time_order);
    assert!(!topics.keys().any(|t| t.starts_with("/ribbon/runs/")));
    assert!(!ribbon_metadata(&mcap).contains_key("check"));
    assert!(!layout(&mcap).to_string().contains("NOT TRUSTED"));
    // Its report: no verdict, no range.
    for entry in std::fs::read_dir(dir.join("report")).unwrap() {
        let path = entry.unwrap().path();
        if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("svg" | "html" | "md")
        ) {
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(
                !text.contains("NOT TRUSTED") && !text.contains("runs&apos; range"),
                "{}",
                path.display()
            );
        }
    }
}
