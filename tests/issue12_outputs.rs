//! Issue 12 §1: outputs never destroy anything. Each test reproduces a measured failure of the
//! issue through the binary: an output path equal to an input replaced the input, a symlink or FIFO
//! output was replaced by a rename, outputs were checked only after the run, two outputs could name
//! one file, two runs writing one output shared one temporary file, and CSV headers were not escaped.

mod common;

use common::{fresh_scratch_dir, ribbon_outcome, Outcome};

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A generous guard against a hang (the test fails instead of waiting forever); never a speed check.
const HANG_GUARD: Duration = Duration::from_secs(300);

/// A fresh scratch directory for one test with a copy of the double pendulum and its sidecar.
fn scratch_with_double_pendulum(test: &str) -> PathBuf {
    let dir = fresh_scratch_dir("issue12_outputs", test);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in ["double_pendulum.urdf", "double_pendulum.uncertainty.toml"] {
        std::fs::copy(
            root.join("robots/double_pendulum").join(name),
            dir.join(name),
        )
        .expect("copy the robot");
    }
    dir
}

fn text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn s(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Temporary files (`*.tmp`) left in `dir`.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("read dir")
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

/// Exit 2, the flag and the fragments named, and no simulation ran (its statistics line is
/// printed after the run).
fn assert_refused_before_running(out: &Outcome, fragments: &[&str]) {
    assert_eq!(out.code, Some(2), "exit code; stderr: {}", out.stderr);
    assert!(out.stdout.is_empty(), "nothing on stdout: {}", out.stdout);
    for fragment in fragments {
        assert!(
            out.stderr.contains(fragment),
            "expected '{fragment}' in: {}",
            out.stderr
        );
    }
    assert!(
        !out.stderr.contains("simulated") && !out.stderr.contains("model runs"),
        "refused before any simulation: {}",
        out.stderr
    );
}

#[test]
fn an_output_equal_to_an_input_is_refused_and_the_input_kept() {
    let dir = scratch_with_double_pendulum("input");
    let urdf = dir.join("double_pendulum.urdf");
    let sidecar = dir.join("double_pendulum.uncertainty.toml");
    let (urdf_before, sidecar_before) = (text(&urdf), text(&sidecar));
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    let respelled = dir.join("sub/../double_pendulum.uncertainty.toml");
    let hard_link = dir.join("hard_link.urdf");
    std::fs::hard_link(&urdf, &hard_link).unwrap();
    let cases: [(&str, &Path, &str); 5] = [
        ("--csv", &urdf, "is the URDF input"),
        ("--summary", &sidecar, "is the sidecar input"),
        ("--out", &respelled, "is the sidecar input"),
        ("--csv", &hard_link, "the same file under another name"),
        ("--summary", &hard_link, "the same file under another name"),
    ];
    for (flag, output, fragment) in cases {
        let out = ribbon_outcome(&["simulate", s(&urdf), flag, s(output)]);
        assert_refused_before_running(&out, &[&format!("error: {flag}:"), fragment]);
        let out = ribbon_outcome(&["analyze", s(&urdf), flag, s(output)]);
        assert_refused_before_running(&out, &[&format!("error: {flag}:"), fragment]);
    }
    assert_eq!(text(&urdf), urdf_before, "the URDF is untouched");
    assert_eq!(text(&sidecar), sidecar_before, "the sidecar is untouched");
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
}

#[test]
fn a_symlink_output_is_refused_and_its_target_kept() {
    let dir = scratch_with_double_pendulum("symlink");
    let precious = dir.join("precious.txt");
    std::fs::write(&precious, "keep me").unwrap();
    let link = dir.join("link.csv");
    std::os::unix::fs::symlink(&precious, &link).unwrap();
    let urdf = dir.join("double_pendulum.urdf");
    for flag in ["--csv", "--summary", "--out"] {
        let out = ribbon_outcome(&["simulate", s(&urdf), flag, s(&link)]);
        assert_refused_before_running(&out, &[flag, "is a symbolic link", "precious.txt"]);
    }
    assert_eq!(text(&precious), "keep me");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
}

#[test]
fn a_fifo_or_directory_output_is_refused() {
    let dir = scratch_with_double_pendulum("special");
    let fifo = dir.join("pipe.csv");
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let urdf = dir.join("double_pendulum.urdf");
    let out = ribbon_outcome(&["simulate", s(&urdf), "--csv", s(&fifo)]);
    assert_refused_before_running(&out, &["--csv", "is a FIFO (named pipe)"]);
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    let out = ribbon_outcome(&["simulate", s(&urdf), "--summary", s(&dir)]);
    assert_refused_before_running(&out, &["--summary", "is a directory"]);
}

#[test]
fn a_bad_output_directory_is_refused_before_a_long_run() {
    let dir = scratch_with_double_pendulum("missing");
    let urdf = dir.join("double_pendulum.urdf");
    let missing = dir.join("no/such/dir/out.csv");
    // 200 s of simulated time would run before the old check; now nothing runs.
    let out = ribbon_outcome(&[
        "simulate",
        s(&urdf),
        "--duration",
        "200",
        "--csv",
        s(&missing),
    ]);
    assert_refused_before_running(&out, &["--csv", "create it first"]);
    let out = ribbon_outcome(&[
        "analyze",
        s(&urdf),
        "--duration",
        "200",
        "--out",
        s(&missing),
    ]);
    assert_refused_before_running(&out, &["--out", "create it first"]);
    let report = dir.join("double_pendulum.urdf");
    let out = ribbon_outcome(&["compare", s(&urdf), "--report", s(&report)]);
    assert_refused_before_running(&out, &["--report", "is not a directory"]);
}

#[test]
fn two_outputs_naming_one_file_are_refused() {
    let dir = scratch_with_double_pendulum("twice");
    let urdf = dir.join("double_pendulum.urdf");
    let one = dir.join("out.json");
    let same = dir.join("./sub/../out.json");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    let out = ribbon_outcome(&[
        "simulate",
        s(&urdf),
        "--csv",
        s(&one),
        "--summary",
        s(&same),
    ]);
    assert_refused_before_running(&out, &["--summary", "is the same file as --csv"]);
    assert!(!one.exists(), "nothing written");
}

/// Before: both runs wrote `<path>.tmp`; the second run truncated the first one's temporary,
/// renamed it, and the first then wrote into the second's file and failed to rename (measured: a
/// 71 669-byte file became 84 370 bytes of two runs mixed, exit 1).
#[test]
fn two_runs_writing_one_output_do_not_share_a_temporary_file() {
    let dir = scratch_with_double_pendulum("concurrent");
    let urdf = dir.join("double_pendulum.urdf");
    let out = dir.join("shared.mcap");
    let mut long = Command::new(env!("CARGO_BIN_EXE_ribbon"))
        .args([
            "analyze",
            s(&urdf),
            "--duration",
            "60",
            "--threads",
            "1",
            "--out",
            s(&out),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ribbon starts");
    let stderr = long.stderr.take().expect("stderr");
    let mut lines = BufReader::new(stderr).lines();
    let started = Instant::now();
    // The first progress line: the long run's temporary file exists and is being written.
    loop {
        let line = lines.next().expect("a progress line").expect("utf-8");
        if line.starts_with("progress:") {
            break;
        }
        assert!(started.elapsed() < HANG_GUARD, "no progress line");
    }
    let short = ribbon_outcome(&["simulate", s(&urdf), "--duration", "0.5", "--out", s(&out)]);
    assert_eq!(short.code, Some(0), "{}", short.stderr);
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let status = long.wait().expect("the long run ends");
    assert_eq!(status.code(), Some(0), "the long run: {}", rest.join("\n"));
    // The last rename wins: a complete, valid file of the long run.
    let bytes = std::fs::read(&out).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .expect("a valid MCAP")
        .expect("with a summary");
    assert_eq!(summary.metadata_indexes.len(), 1, "one metadata record");
    let metadata = mcap::read::metadata(&bytes, &summary.metadata_indexes[0])
        .expect("the metadata record")
        .metadata;
    assert_eq!(
        metadata.get("method").map(String::as_str),
        Some("legendre-scan")
    );
    assert_eq!(metadata.get("partial").map(String::as_str), Some("false"));
    let mut messages = 0;
    for message in mcap::MessageStream::new(&bytes).expect("readable") {
        message.expect("every message decodes");
        messages += 1;
    }
    assert!(messages > 0);
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
}

#[test]
fn csv_headers_are_quoted_as_rfc_4180_asks() {
    let dir = scratch_with_double_pendulum("csv_header");
    let urdf = dir.join("odd_names.urdf");
    std::fs::write(
        &urdf,
        r#"<robot name="odd"><link name="base"/>
  <link name="arm, &quot;upper&quot;"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="shoulder,1" type="continuous"><parent link="base"/><child link="arm, &quot;upper&quot;"/>
    <axis xyz="0 0 1"/></joint>
</robot>"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("odd_names.uncertainty.toml"),
        "[outputs]\nframes = ['arm, \"upper\"']\n",
    )
    .unwrap();
    let csv = dir.join("out.csv");
    let out = ribbon_outcome(&["simulate", s(&urdf), "--duration", "0.02", "--csv", s(&csv)]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    let written = text(&csv);
    let header = written.lines().next().unwrap();
    assert_eq!(
        header,
        r#"t,"q.shoulder,1","frame.arm, ""upper"".x","frame.arm, ""upper"".y","frame.arm, ""upper"".z""#
    );
    // Numbers hold no comma: every row has the 5 fields the header declares.
    for row in written.lines().skip(1) {
        assert_eq!(row.split(',').count(), 5, "{row}");
    }
}

/// The MCAP sink refuses a NaN (naming the output and time) instead of logging it; the unfinished
/// log leaves nothing at the path.
#[test]
fn the_mcap_log_refuses_a_nan() {
    use ribbon::output::mcap::McapMetadata;
    use ribbon::output::EnvelopeLog;
    use ribbon::scene::{Output, OutputKind};
    let dir = scratch_with_double_pendulum("mcap_nan");
    let path = dir.join("nan.mcap");
    let outputs = vec![Output {
        name: "q.j1".to_string(),
        parts: vec!["q".to_string(), "j1".to_string()],
        unit: "rad",
        kind: OutputKind::Position { q_index: 0 },
    }];
    let metadata = McapMetadata {
        robot: "double_pendulum".to_string(),
        method: "nominal".to_string(),
        order: None,
        runs: 1,
        parameters_json: "[]".to_string(),
    };
    let mut log = EnvelopeLog::create(
        &path,
        &dir.join("double_pendulum.urdf"),
        None,
        metadata,
        &outputs,
        false,
    )
    .expect("log created");
    log.write_time(0.0, &[0.0], &[0.0], &[0.0], None)
        .expect("finite values are written");
    let e = log
        .write_time(0.01, &[0.0], &[f64::NAN], &[0.0], None)
        .expect_err("NaN refused");
    assert_eq!(e.exit_code(), 1);
    assert!(
        e.to_string()
            .contains("output 'q.j1 (nominal)' is NaN at t = 0.01 s"),
        "{e}"
    );
    drop(log);
    assert!(!path.exists());
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
}
