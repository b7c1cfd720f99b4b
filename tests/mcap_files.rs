//! The MCAP sink end to end (design contract "MCAP"): a small synthetic study written through
//! `ribbon::output::mcap`, read back with the Rust `mcap` reader (every message), then cross-checked
//! by `tests/reference/check_mcap.py` with Python `mcap` + `mcap-ros2-support` +
//! `mcap-protobuf-support`, foxglove-sdk (schema bytes, payload bytes) and rerun-sdk
//! (`rerun mcap convert`, `rerun rrd print`). Plus the crash-safety rules: an unfinished sink leaves
//! nothing at its path, and `finish(true)` marks the file partial.

mod common;

use ribbon::output::mcap::{McapError, McapMetadata, McapSink, OutputName, ParentFromLink};
use serde::Deserialize;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const URDF: &str = "robots/double_pendulum/double_pendulum.urdf";
const SIDECAR_TEXT: &str = "[parameters]\nl1 = [0.99, 1.01]\n\n[scene]\nduration = 0.5\n";
/// Record times: 0, 0.01, …, 0.5 s (most of them inexact in binary, which exercises the rounding
/// to nanoseconds).
const STEPS: usize = 50;
const STEP_S: f64 = 0.01;

/// A fresh directory for one test's files under the target directory.
fn work_dir(test: &str) -> PathBuf {
    let dir = common::target_dir().join("mcap_files").join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
    dir
}

/// The temporary files of `path` on disk (`<name>.ribbon-<pid>-<n>.tmp` beside it).
fn temporaries_of(path: &Path) -> Vec<PathBuf> {
    let prefix = format!(
        "{}.ribbon-",
        path.file_name().unwrap_or_default().to_string_lossy()
    );
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| {
                    let name = p.file_name().unwrap_or_default().to_string_lossy();
                    name.starts_with(&prefix) && name.ends_with(".tmp")
                })
                .collect()
        })
        .unwrap_or_default()
}

fn metadata() -> McapMetadata {
    McapMetadata {
        robot: "double_pendulum".to_string(),
        method: "legendre-scan".to_string(),
        order: Some(4),
        runs: 5,
        parameters_json: r#"[{"name":"l1","lower":0.99,"upper":1.01,"nominal":1.0}]"#.to_string(),
    }
}

fn urdf_text() -> String {
    let path = common::manifest_dir().join(URDF);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// The nominal joint angles of the synthetic study at time `t`, rad.
fn angles(t: f64) -> [f64; 2] {
    [
        0.8 * (2.0 * std::f64::consts::PI * t).sin(),
        -0.5 * t + 0.3 * (5.0 * t).cos(),
    ]
}

/// `(name, nominal(t), half-width(t))` of each synthetic output.
type Series = (&'static str, fn(f64) -> f64, fn(f64) -> f64);
const OUTPUTS: [Series; 3] = [
    ("q.j1", |t| angles(t)[0], |t| 0.01 + 0.05 * t),
    ("q.j2", |t| angles(t)[1], |t| 0.02 * t * t),
    (
        "frame.tip.x",
        |t| (angles(t)[0]).cos() + 2.0 * (angles(t)[0] + angles(t)[1]).cos(),
        |t| 0.03 * t,
    ),
];

/// Units of [`OUTPUTS`], in order.
const UNITS: [&str; 3] = ["rad", "rad", "m"];

/// Planar double pendulum (bars along +x, joints about z): each link's pose in its parent link (the
/// URDF tree: base ← bar1 ← bar2 ← tip), the root in `world`.
fn frames(t: f64) -> Vec<(String, &'static str, [f64; 3], [f64; 4])> {
    let [q1, q2] = angles(t);
    let about_z = |angle: f64| [0.0, 0.0, (angle / 2.0).sin(), (angle / 2.0).cos()];
    vec![
        ("base".to_string(), "world", [0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        ("bar1".to_string(), "base", [0.0; 3], about_z(q1)),
        ("bar2".to_string(), "bar1", [1.0, 0.0, 0.0], about_z(q2)),
        (
            "tip".to_string(),
            "bar2",
            [2.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ),
    ]
}

/// Writes the synthetic study to `path`; returns the expected-JSON document for check_mcap.py.
fn write_study(path: &Path, sidecar_path: &Path, partial: bool) -> serde_json::Value {
    let urdf = urdf_text();
    let meta = metadata();
    let mut sink = McapSink::create(
        path,
        "double_pendulum.urdf",
        &urdf,
        Some(("double_pendulum.uncertainty.toml", SIDECAR_TEXT)),
        meta.clone(),
    )
    .unwrap_or_else(|e| panic!("create: {e}"));
    let envelope_ids: Vec<_> = OUTPUTS
        .iter()
        .zip(UNITS)
        .map(|((name, _, _), unit)| sink.add_output(*name, unit).unwrap())
        .collect();
    // Error estimates for the two joints only (frame.tip.x has none).
    let error_ids: Vec<_> = OUTPUTS[..2]
        .iter()
        .zip(UNITS)
        .map(|((name, _, _), unit)| sink.add_error_channel(*name, unit).unwrap())
        .collect();

    let mut envelopes: Vec<BTreeMap<&str, Vec<f64>>> = vec![BTreeMap::new(); OUTPUTS.len()];
    let mut errors: Vec<BTreeMap<&str, Vec<f64>>> = vec![BTreeMap::new(); 2];
    let mut transforms = Vec::new();
    for k in 0..=STEPS {
        let t = k as f64 * STEP_S;
        for (i, (_, nominal, half_width)) in OUTPUTS.iter().enumerate() {
            let (n, w) = (nominal(t), half_width(t));
            let (lower, upper) = (n - w, n + w);
            sink.write_envelope(envelope_ids[i], t, lower, n, upper)
                .unwrap();
            for (key, value) in [
                ("time", t),
                ("lower", lower),
                ("nominal", n),
                ("upper", upper),
            ] {
                envelopes[i].entry(key).or_default().push(value);
            }
            if i < 2 {
                let estimate = 1e-4 * w;
                sink.write_error(error_ids[i], t, estimate).unwrap();
                errors[i].entry("time").or_default().push(t);
                errors[i].entry("estimate").or_default().push(estimate);
            }
        }
        let poses = frames(t);
        let parent_from_links: Vec<ParentFromLink<'_>> = poses
            .iter()
            .map(
                |(link, parent, translation_m, rotation_xyzw)| ParentFromLink {
                    parent,
                    link,
                    translation_m: *translation_m,
                    rotation_xyzw: *rotation_xyzw,
                },
            )
            .collect();
        sink.write_transforms(t, &parent_from_links).unwrap();
        transforms.push(json!({
            "time": t,
            "frames": poses.iter().map(|(link, parent, tr, rot)| json!({"link": link, "parent": parent, "translation": tr, "rotation": rot}))
                .collect::<Vec<_>>(),
        }));
    }
    assert!(
        temporaries_of(path).len() == 1,
        "the sink writes to one temporary file beside <path> until finished"
    );
    assert!(!path.exists(), "nothing at the path before finish");
    sink.finish(partial)
        .unwrap_or_else(|e| panic!("finish: {e}"));
    assert!(path.exists(), "finish renames the file to its path");
    assert!(
        temporaries_of(path).is_empty(),
        "finish leaves no temporary file"
    );

    std::fs::write(sidecar_path, SIDECAR_TEXT).unwrap();
    let topic =
        |prefix: &str, name: &str| format!("{prefix}{}", OutputName::from(name).topic_suffix());
    json!({
        "urdf_path": common::manifest_dir().join(URDF),
        "robot": "double_pendulum",
        "envelopes": OUTPUTS.iter().zip(&envelopes).zip(UNITS).map(|(((name, _, _), series), unit)| {
            let mut entry = json!(series);
            entry["name"] = json!(name);
            entry["unit"] = json!(unit);
            entry["topic"] = json!(topic("/ribbon/envelope/", name));
            entry
        }).collect::<Vec<_>>(),
        "errors": OUTPUTS[..2].iter().zip(&errors).map(|((name, _, _), series)| {
            let mut entry = json!(series);
            entry["name"] = json!(name);
            entry["topic"] = json!(topic("/ribbon/error/", name));
            entry
        }).collect::<Vec<_>>(),
        "transforms": transforms,
        "metadata": {
            "robot": meta.robot,
            "method": meta.method,
            "order": "4",
            "runs": "5",
            "ribbon_version": env!("CARGO_PKG_VERSION"),
            "partial": partial.to_string(),
            "parameters": meta.parameters_json,
        },
        "attachments": [
            {"name": "double_pendulum.urdf", "media_type": "application/xml",
             "path": common::manifest_dir().join(URDF)},
            {"name": "double_pendulum.uncertainty.toml", "media_type": "application/toml", "path": sidecar_path},
        ],
    })
}

/// `sensor_msgs/msg/JointState` as the test reads it back.
#[derive(Debug, Deserialize)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

#[derive(Debug, Deserialize)]
struct Header {
    stamp: Time,
    #[allow(dead_code)]
    frame_id: String,
}

#[derive(Debug, Deserialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

/// One message as read back: log time, JointState names and values (empty for other topics).
type ReadBack = (u64, Vec<String>, Vec<f64>);

#[test]
fn every_reader_decodes_what_was_written() {
    let dir = work_dir("every_reader");
    let path = dir.join("double_pendulum.mcap");
    let expected = write_study(&path, &dir.join("double_pendulum.uncertainty.toml"), false);

    // The Rust reader: summary, lz4 chunks, and every message.
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("a summary section");
    assert!(!summary.chunk_indexes.is_empty(), "chunk indexes");
    assert!(
        summary.chunk_indexes.iter().all(|c| c.compression == "lz4"),
        "lz4 chunks"
    );
    assert_eq!(
        summary.attachment_indexes.len(),
        2,
        "the URDF and the sidecar attached"
    );
    let mut by_topic: BTreeMap<String, Vec<ReadBack>> = BTreeMap::new();
    let mut messages = 0_u64;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        messages += 1;
        assert_eq!(
            message.log_time, message.publish_time,
            "log time = publish time"
        );
        let topic = message.channel.topic.clone();
        if topic.starts_with("/ribbon/") {
            let state: JointState = cdr::deserialize(&message.data).unwrap();
            let stamp_ns = u64::from(state.header.stamp.sec as u32) * 1_000_000_000
                + u64::from(state.header.stamp.nanosec);
            assert_eq!(
                stamp_ns, message.log_time,
                "{topic}: header.stamp = log time"
            );
            assert!(state.velocity.is_empty() && state.effort.is_empty());
            by_topic
                .entry(topic)
                .or_default()
                .push((message.log_time, state.name, state.position));
        } else {
            by_topic
                .entry(topic)
                .or_default()
                .push((message.log_time, Vec::new(), Vec::new()));
        }
    }
    assert_eq!(
        Some(messages),
        summary.stats.as_ref().map(|s| s.message_count)
    );
    for (group, names) in [
        ("envelopes", vec!["lower", "nominal", "upper"]),
        ("errors", vec!["estimate"]),
    ] {
        for entry in expected[group].as_array().unwrap() {
            let topic = entry["topic"].as_str().unwrap();
            let got = &by_topic[topic];
            let times = entry["time"].as_array().unwrap();
            assert_eq!(got.len(), times.len(), "{topic}: message count");
            for (i, (log_time, got_names, values)) in got.iter().enumerate() {
                let t = times[i].as_f64().unwrap();
                assert_eq!(
                    *log_time,
                    (t * 1e9).round() as u64,
                    "{topic}[{i}]: log time"
                );
                assert_eq!(got_names, &names, "{topic}[{i}]: names");
                let want: Vec<f64> = names
                    .iter()
                    .map(|n| entry[n][i].as_f64().unwrap())
                    .collect();
                assert_eq!(
                    values, &want,
                    "{topic}[{i}]: values are the numbers given, bit for bit"
                );
            }
        }
    }
    assert_eq!(by_topic["/tf"].len(), STEPS + 1);
    assert_eq!(by_topic["/robot_description"].len(), 1);
    assert_eq!(by_topic["/robot_description"][0].0, 0, "the URDF at t = 0");
    assert_eq!(common::ribbon_metadata(&bytes)["partial"], "false");

    // The Python readers, foxglove-sdk and rerun.
    let expected_path = dir.join("expected.json");
    std::fs::write(
        &expected_path,
        serde_json::to_string_pretty(&expected).unwrap(),
    )
    .unwrap();
    let python = common::reference_python();
    let script = common::manifest_dir().join("tests/reference/check_mcap.py");
    let output = common::run_checked(
        &python,
        &common::args([
            script.display().to_string(),
            path.display().to_string(),
            expected_path.display().to_string(),
            "--work-dir".to_string(),
            dir.join("check").display().to_string(),
        ]),
        "tests/reference/check_mcap.py",
    );
    println!("{}", String::from_utf8_lossy(&output.stdout));
}

#[test]
fn finish_partial_marks_the_metadata() {
    let dir = work_dir("partial");
    let path = dir.join("partial.mcap");
    let mut sink = McapSink::create(
        &path,
        "double_pendulum.urdf",
        &urdf_text(),
        None,
        metadata(),
    )
    .unwrap();
    let q1 = sink.add_output("q.j1", "rad").unwrap();
    sink.write_envelope(q1, 0.0, -0.1, 0.0, 0.1).unwrap();
    sink.metadata_mut().runs = 3; // stopped early: fewer runs than planned
    sink.finish(true).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let metadata = common::ribbon_metadata(&bytes);
    assert_eq!(metadata["partial"], "true");
    assert_eq!(metadata["order"], "4");
    assert_eq!(metadata["runs"], "3");
    assert_eq!(metadata["ribbon_version"], env!("CARGO_PKG_VERSION"));
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert_eq!(
        summary.attachment_indexes.len(),
        1,
        "no sidecar, only the URDF attached"
    );
    assert_eq!(
        mcap::MessageStream::new(&bytes).unwrap().count(),
        2,
        "the URDF and one envelope"
    );
}

#[test]
fn dropping_an_unfinished_sink_leaves_no_file() {
    let dir = work_dir("dropped");
    let path = dir.join("dropped.mcap");
    let mut sink = McapSink::create(
        &path,
        "double_pendulum.urdf",
        &urdf_text(),
        None,
        metadata(),
    )
    .unwrap();
    let q1 = sink.add_output("q.j1", "rad").unwrap();
    for k in 0..1000 {
        sink.write_envelope(q1, k as f64 * 1e-3, -0.1, 0.0, 0.1)
            .unwrap();
    }
    assert_eq!(temporaries_of(&path).len(), 1);
    drop(sink);
    assert!(!path.exists(), "no file at the path");
    assert!(temporaries_of(&path).is_empty(), "no temporary file left");

    // An older file at the path survives an unfinished run untouched.
    std::fs::write(&path, b"previous result").unwrap();
    let sink = McapSink::create(
        &path,
        "double_pendulum.urdf",
        &urdf_text(),
        None,
        metadata(),
    )
    .unwrap();
    drop(sink);
    assert_eq!(std::fs::read(&path).unwrap(), b"previous result");
    assert!(temporaries_of(&path).is_empty());
}

#[test]
fn errors_name_the_file_and_the_problem() {
    let dir = work_dir("errors");
    let path = dir.join("errors.mcap");
    let mut sink = McapSink::create(
        &path,
        "double_pendulum.urdf",
        &urdf_text(),
        None,
        metadata(),
    )
    .unwrap();
    let q1 = sink.add_output("q.j1", "rad").unwrap();

    let e = sink.add_output("q.j1", "rad").unwrap_err();
    assert!(matches!(e, McapError::DuplicateTopic { .. }), "{e}");
    assert!(
        e.to_string().contains("errors.mcap") && e.to_string().contains("/ribbon/envelope/q/j1"),
        "{e}"
    );
    let e = sink.add_output("q..j1", "rad").unwrap_err();
    assert!(matches!(e, McapError::BadOutputName { .. }), "{e}");
    for bad in [-1e-3, f64::NAN, f64::INFINITY, 3e9] {
        let e = sink.write_envelope(q1, bad, 0.0, 0.0, 0.0).unwrap_err();
        assert!(matches!(e, McapError::BadTime { .. }), "{e}");
        assert!(e.to_string().contains("errors.mcap"), "{e}");
    }
    // The study description's keys cannot be overwritten by extra metadata entries.
    let e = sink
        .add_metadata_entries(BTreeMap::from([("runs".to_string(), "0".to_string())]))
        .unwrap_err();
    assert!(matches!(e, McapError::ReservedMetadataName { .. }), "{e}");
    assert!(e.to_string().contains("'runs'"), "{e}");
    // A dotted joint name keeps its dot when given as parts.
    sink.add_output(OutputName::from_parts(&["q", "joint_0.0"]), "rad")
        .unwrap();
    drop(sink);

    let mut bad = metadata();
    bad.parameters_json = "{}".to_string();
    let e = McapSink::create(&path, "double_pendulum.urdf", &urdf_text(), None, bad).unwrap_err();
    assert!(matches!(e, McapError::BadParameters { .. }), "{e}");
    let missing = dir.join("no/such/dir/x.mcap");
    let e = McapSink::create(
        &missing,
        "double_pendulum.urdf",
        &urdf_text(),
        None,
        metadata(),
    )
    .unwrap_err();
    assert!(matches!(e, McapError::Io { .. }), "{e}");
    assert!(e.to_string().contains("x.mcap"), "{e}");
}
