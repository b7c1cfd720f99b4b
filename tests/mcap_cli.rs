//! MCAP logs written by the command line: `ribbon analyze --out` checked by the Rust `mcap` reader
//! and by the reference tools (Python `mcap` + ROS 2 decoder, foxglove-sdk, rerun) against the summary
//! JSON of the same run; and an analysis interrupted by SIGINT leaves a valid file marked partial.

mod common;

use common::scratch_file;

use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::manifest;

/// Every message of the file through the Rust reader: (topic, log time) pairs, and the metadata.
fn read_with_rust(path: &Path) -> (Vec<(String, u64)>, Vec<mcap::records::Metadata>) {
    let bytes = std::fs::read(path).expect("mcap file");
    let messages = mcap::MessageStream::new(&bytes)
        .expect("mcap header")
        .map(|m| {
            let m = m.expect("message decodes");
            (m.channel.topic.clone(), m.log_time)
        })
        .collect();
    let summary = mcap::Summary::read(&bytes)
        .expect("summary")
        .expect("has a summary");
    let metadata = summary
        .metadata_indexes
        .iter()
        .map(|index| mcap::read::metadata(&bytes, index).expect("metadata record"))
        .collect();
    (messages, metadata)
}

/// The expected Sobol' channels of check_mcap.py from the summary's `sobol_indices`: per output,
/// `main` and `total`, one series per dimension.
fn sobol_entries(summary: &Value) -> Vec<Value> {
    let sobol = &summary["sobol_indices"];
    let dimensions: Vec<Value> = sobol["dimensions"]
        .as_array()
        .expect("a surrogate study's summary has sobol_indices")
        .iter()
        .map(|d| d["name"].clone())
        .collect();
    let times = &summary["outputs"][0]["time"];
    let mut entries = Vec::new();
    for output in sobol["outputs"].as_array().unwrap() {
        let name = output["name"].as_str().unwrap();
        for index in ["main", "total"] {
            entries.push(json!({
                "name": name,
                "topic": format!("/ribbon/sobol/{index}/{}", name.replace('.', "/")),
                "index": index,
                "dimensions": dimensions,
                "time": times,
                "values": output[index],
            }));
        }
    }
    entries
}

#[test]
fn analyze_log_matches_its_summary_in_every_reader() {
    let out = scratch_file("mcap_cli", "double_pendulum.mcap");
    let summary_path = scratch_file("mcap_cli", "double_pendulum.summary.json");
    let status = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            "robots/double_pendulum/double_pendulum.urdf",
            "--duration",
            "0.5",
            "--out",
        ])
        .arg(&out)
        .arg("--summary")
        .arg(&summary_path)
        .status()
        .expect("ribbon runs");
    assert!(status.success());
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(&summary_path).unwrap()).unwrap();
    let outputs = summary["outputs"].as_array().unwrap();
    let times = outputs[0]["time"].clone();

    let (messages, metadata) = read_with_rust(&out);
    let envelope_messages = messages
        .iter()
        .filter(|(t, _)| t.starts_with("/ribbon/envelope/"))
        .count();
    assert_eq!(
        envelope_messages,
        outputs.len() * times.as_array().unwrap().len()
    );
    assert_eq!(
        messages.iter().filter(|(t, _)| t == "/tf").count(),
        times.as_array().unwrap().len()
    );
    assert_eq!(metadata.len(), 1);
    assert_eq!(metadata[0].name, "ribbon");
    let ribbon_record = &metadata[0];
    assert_eq!(
        ribbon_record.metadata.get("partial").map(String::as_str),
        Some("false")
    );

    // The `ribbon` record's study description, from what this test asked for and from the
    // summary (not from the file under test): robot, method, order, runs, version, partial, and the
    // parameters the summary lists.
    let record = &ribbon_record.metadata;
    let study_keys = [
        ("robot", "double_pendulum".to_string()),
        ("method", "legendre-scan".to_string()),
        ("order", "4".to_string()),
        ("runs", summary["samples"].as_u64().unwrap().to_string()),
        ("ribbon_version", env!("CARGO_PKG_VERSION").to_string()),
        ("partial", "false".to_string()),
    ];
    for (key, want) in &study_keys {
        assert_eq!(record.get(*key), Some(want), "`ribbon` record key {key}");
    }
    let parameters: Value =
        serde_json::from_str(record.get("parameters").expect("parameters")).unwrap();
    assert_eq!(parameters, summary["parameters"]);
    let mut keys: Vec<&str> = record.keys().map(String::as_str).collect();
    keys.sort_unstable();
    assert_eq!(
        keys,
        [
            "method",
            "order",
            "parameters",
            "partial",
            "ribbon_version",
            "robot",
            "runs",
            "scene_centre_m",
            "scene_radius_m"
        ],
        "no other key in the `ribbon` record"
    );

    let topic = |name: &str| format!("/{}", name.replace('.', "/"));
    let expected = json!({
        "urdf_path": manifest("robots/double_pendulum/double_pendulum.urdf"),
        "robot": "double_pendulum",
        "envelopes": outputs.iter().map(|o| json!({
            "name": o["name"], "unit": o["unit"], "topic": format!("/ribbon/envelope{}", topic(o["name"].as_str().unwrap())),
            "time": o["time"], "lower": o["lower"], "nominal": o["nominal"], "upper": o["upper"],
        })).collect::<Vec<_>>(),
        "errors": outputs.iter().map(|o| json!({
            "name": o["name"], "topic": format!("/ribbon/error{}", topic(o["name"].as_str().unwrap())),
            "time": o["time"], "estimate": o["error_estimate"],
        })).collect::<Vec<_>>(),
        "sobol": sobol_entries(&summary),
        "transform_times": times,
        "transform_links": ["base", "bar1", "bar2", "tip"],
        // Checked above against the request and the summary; the Python reader must read the same.
        "metadata": ribbon_record.metadata,
        "viewer": true,
        "attachments": [
            {"name": "foxglove-layout.json", "media_type": "application/json", "foxglove_layout": true},
            {"name": "double_pendulum.urdf", "media_type": "application/xml", "path": manifest("robots/double_pendulum/double_pendulum.urdf")},
            {"name": "double_pendulum.uncertainty.toml", "media_type": "application/toml", "path": manifest("robots/double_pendulum/double_pendulum.uncertainty.toml")},
        ],
    });
    check_mcap(&out, &expected, "double_pendulum");
}

/// Runs tests/reference/check_mcap.py on `log` with `expected` (written beside it as
/// `NAME.expected.json`); fails with its report unless every check passes.
fn check_mcap(log: &Path, expected: &Value, name: &str) {
    let expected_path = scratch_file("mcap_cli", &format!("{name}.expected.json"));
    std::fs::write(&expected_path, expected.to_string()).unwrap();
    let python = common::reference_python();
    let result = Command::new(&python)
        .arg(manifest("tests/reference/check_mcap.py"))
        .arg(log)
        .arg(&expected_path)
        .arg("--work-dir")
        .arg(scratch_file("mcap_cli", &format!("{name}.check_work")))
        .output()
        .expect("python runs");
    assert!(
        result.status.success(),
        "check_mcap.py failed:\n{}\n{}",
        String::from_utf8_lossy(&result.stdout),
        String::from_utf8_lossy(&result.stderr)
    );
    println!("{}", String::from_utf8_lossy(&result.stdout));
}

/// The CSV's columns by name, each value as written.
fn csv_columns(text: &str) -> std::collections::BTreeMap<String, Vec<f64>> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let mut columns = std::collections::BTreeMap::<String, Vec<f64>>::new();
    for line in lines {
        for (name, value) in header.iter().zip(line.split(',')) {
            columns
                .entry(name.to_string())
                .or_default()
                .push(value.parse().expect("a number"));
        }
    }
    columns
}

/// An untrusted study's log (exit 4: the double pendulum from upright, tests/untrusted_outputs.rs)
/// through check_mcap.py: its hull channels hold the CSV's `NAME.runs_lower` / `NAME.runs_upper`
/// columns, and every hull series of the layout names one of them, on the untrusted outputs' plots
/// only, which say NOT TRUSTED.
#[test]
fn an_untrusted_log_passes_the_reference_readers_with_its_true_runs() {
    let dir = common::fresh_test_scratch_dir("mcap_cli", "untrusted");
    let urdf = "robots/double_pendulum/double_pendulum.urdf";
    let sidecar = "tests/fixtures/refine_chaos/upright.uncertainty.toml";
    let (out, csv, summary_path) = (
        dir.join("untrusted.mcap"),
        dir.join("untrusted.csv"),
        dir.join("summary.json"),
    );
    let status = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            urdf,
            "--uncertainty",
            sidecar,
            "--max-runs",
            "600",
        ])
        .arg("--out")
        .arg(&out)
        .arg("--csv")
        .arg(&csv)
        .arg("--summary")
        .arg(&summary_path)
        .stderr(Stdio::null())
        .status()
        .expect("ribbon runs");
    assert_eq!(status.code(), Some(i32::from(ribbon::UNTRUSTED_EXIT_CODE)));
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(&summary_path).unwrap()).unwrap();
    let columns = csv_columns(&std::fs::read_to_string(&csv).unwrap());
    let outputs = summary["outputs"].as_array().unwrap();
    let topic = |kind: &str, name: &str| format!("/ribbon/{kind}/{}", name.replace('.', "/"));
    let untrusted = summary["stats"]["check"]["untrusted_outputs"].clone();
    assert!(
        !untrusted.as_array().unwrap().is_empty(),
        "the study must be untrusted"
    );
    let (_, metadata) = read_with_rust(&out);
    let expected = json!({
        "urdf_path": manifest(urdf),
        "robot": "double_pendulum",
        "envelopes": outputs.iter().map(|o| json!({
            "name": o["name"], "unit": o["unit"], "topic": topic("envelope", o["name"].as_str().unwrap()),
            "time": o["time"], "lower": o["lower"], "nominal": o["nominal"], "upper": o["upper"],
        })).collect::<Vec<_>>(),
        "errors": outputs.iter().map(|o| json!({
            "name": o["name"], "topic": topic("error", o["name"].as_str().unwrap()),
            "time": o["time"], "estimate": o["error_estimate"],
        })).collect::<Vec<_>>(),
        // The hull as the CSV has it (tests/untrusted_outputs.rs: the CSV's is the summary's).
        "runs": outputs.iter().map(|o| {
            let name = o["name"].as_str().unwrap();
            json!({
                "name": name, "topic": topic("runs", name), "time": o["time"],
                "runs_lower": columns[&format!("{name}.runs_lower")],
                "runs_upper": columns[&format!("{name}.runs_upper")],
            })
        }).collect::<Vec<_>>(),
        "untrusted_outputs": untrusted,
        "sobol": sobol_entries(&summary),
        "transform_times": outputs[0]["time"],
        "transform_links": ["base", "bar1", "bar2", "tip"],
        // The record's keys are checked against the summary in tests/untrusted_outputs.rs.
        "metadata": metadata[0].metadata,
        "viewer": true,
        "attachments": [
            {"name": "foxglove-layout.json", "media_type": "application/json", "foxglove_layout": true},
            {"name": "double_pendulum.urdf", "media_type": "application/xml", "path": manifest(urdf)},
            {"name": "upright.uncertainty.toml", "media_type": "application/toml", "path": manifest(sidecar)},
        ],
    });
    check_mcap(&out, &expected, "untrusted");
}

#[test]
fn sigint_finishes_a_valid_partial_log() {
    let out = scratch_file("mcap_cli", "interrupted.mcap");
    let _ = std::fs::remove_file(&out);
    // Long enough not to finish first: 21² true-model runs of a 200 s double pendulum.
    let mut child = Command::new(common::ribbon_bin())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "analyze",
            "robots/double_pendulum/double_pendulum.urdf",
            "--method",
            "scan",
            "--duration",
            "200",
            "--threads",
            "1",
            "--out",
        ])
        .arg(&out)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .expect("ribbon starts");
    let stderr = child.stderr.take().expect("stderr");
    let mut lines = BufReader::new(stderr).lines();
    let started = Instant::now();
    let mut seen = String::new();
    loop {
        let line = lines
            .next()
            .expect("ribbon prints progress before it ends")
            .expect("utf-8");
        seen.push_str(&line);
        seen.push('\n');
        if line.starts_with("progress:") {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no progress line: {seen}"
        );
    }
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(killed.success());
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let status = child.wait().expect("ribbon ends");
    let stderr = format!("{seen}{}", rest.join("\n"));
    assert_eq!(
        status.code(),
        Some(1),
        "exit code after SIGINT; stderr:\n{stderr}"
    );
    assert!(stderr.contains("interrupted"), "{stderr}");
    let (messages, metadata) = read_with_rust(&out);
    assert_eq!(
        metadata
            .iter()
            .find(|m| m.name == "ribbon")
            .and_then(|m| m.metadata.get("partial"))
            .map(String::as_str),
        Some("true")
    );
    let envelope_times: std::collections::BTreeSet<u64> = messages
        .iter()
        .filter(|(t, _)| t == "/ribbon/envelope/q/j1")
        .map(|(_, time)| *time)
        .collect();
    assert!(!envelope_times.is_empty(), "some envelopes were written");
    assert!(
        *envelope_times.iter().max().unwrap() < 200_000_000_000,
        "the run did not finish: the log stops before t = 200 s"
    );
    let leftovers: Vec<String> = std::fs::read_dir(scratch_file("mcap_cli", ""))
        .expect("scratch directory")
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("interrupted.mcap.") && n.ends_with(".tmp"))
        .collect();
    assert!(
        leftovers.is_empty(),
        "no temporary file left: {leftovers:?}"
    );
    println!(
        "interrupted after {} record times: {stderr}",
        envelope_times.len()
    );
}
