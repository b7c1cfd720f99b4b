//! Issue 12 §1–§2: interruptions. A single run (`simulate`) ignored nothing but also saved nothing:
//! it had no handler, and a legal tiny step ran on until killed; a second Ctrl-C of `analyze` left
//! its temporary file behind; `kill -9` must keep the previous output. Each test spawns the binary
//! and signals it by process id.

mod common;

use common::fresh_scratch_dir;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A generous guard against a hang (the test fails instead of waiting forever); never a speed check.
const HANG_GUARD: Duration = Duration::from_secs(300);

fn urdf() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/double_pendulum/double_pendulum.urdf")
}

fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("read dir")
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

fn signal(child: &Child, name: &str) {
    let sent = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success(), "kill -{name}");
}

/// Waits for the child, failing (and killing it) if it outlives the hang guard.
fn wait(child: &mut Child) -> Option<i32> {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            return status.code();
        }
        if started.elapsed() > HANG_GUARD {
            let _ = child.kill();
            panic!("ribbon did not end within {HANG_GUARD:?} of the signal");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Spawns `analyze` with a slow scene and returns once it printed its first progress line (its
/// MCAP temporary exists then), with the stderr lines read so far.
fn analyze_until_progress(out: &Path) -> (Child, String) {
    analyze_until_progress_with(out, &[])
}

/// [`analyze_until_progress`] with extra arguments.
fn analyze_until_progress_with(out: &Path, extra: &[&str]) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ribbon"))
        .arg("analyze")
        .arg(urdf())
        // 1e-6 s steps: one block of 50 record times takes tens of seconds.
        .args([
            "--step",
            "1e-6",
            "--duration",
            "1",
            "--threads",
            "1",
            "--out",
        ])
        .arg(out)
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ribbon starts");
    let stderr = child.stderr.take().expect("stderr");
    let mut reader = BufReader::new(stderr);
    let mut seen = String::new();
    let started = Instant::now();
    loop {
        let mut line = String::new();
        let n = reader.read_line(&mut line).expect("utf-8");
        assert!(n > 0, "ribbon ended before running: {seen}");
        seen.push_str(&line);
        if line.starts_with("analyze:") {
            break;
        }
        assert!(started.elapsed() < HANG_GUARD, "no start line: {seen}");
    }
    // Keep draining stderr so that the child never blocks on a full pipe.
    std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = reader.read_to_string(&mut rest);
    });
    (child, seen)
}

/// The MCAP temporary of `out` exists (the run is writing).
fn wait_for_temporary(dir: &Path) {
    let started = Instant::now();
    while leftovers(dir).is_empty() {
        assert!(started.elapsed() < HANG_GUARD, "no temporary file appeared");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Before: `simulate` had no handler (SIGTERM killed it with nothing written) and at a legal tiny
/// step it ran for minutes. Now the run checks the signal once per step, writes what it computed,
/// marks it partial and exits 1.
#[test]
fn sigterm_stops_a_single_run_after_the_current_step_and_saves_it() {
    let dir = fresh_scratch_dir("issue12_signals", "simulate_sigterm");
    let summary = dir.join("summary.json");
    let csv = dir.join("series.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_ribbon"))
        .arg("simulate")
        .arg(urdf())
        // 5e8 steps: an hour of work if the signal were not seen.
        .args(["--step", "1e-7", "--duration", "50", "--summary"])
        .arg(&summary)
        .arg("--csv")
        .arg(&csv)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("ribbon starts");
    // Time to start and install the handler (milliseconds; a second is ample on a loaded machine).
    std::thread::sleep(Duration::from_secs(1));
    signal(&child, "TERM");
    let code = wait(&mut child);
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut stderr)
        .unwrap();
    assert_eq!(code, Some(1), "exit code after SIGTERM: {stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).expect("summary written"))
            .expect("valid JSON");
    assert_eq!(json["stats"]["partial"], serde_json::json!(true));
    let times = json["outputs"][0]["time"].as_array().expect("times");
    let last = times.last().and_then(|t| t.as_f64()).expect("a time");
    assert!(last < 50.0, "stopped early: last record at {last} s");
    let rows = std::fs::read_to_string(&csv)
        .expect("CSV written")
        .lines()
        .count();
    assert_eq!(
        rows,
        times.len() + 1,
        "CSV and summary hold the same records"
    );
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
}

/// Before: the second Ctrl-C ended the process at once and left `out.mcap.tmp` behind. Now it
/// removes the temporary first. The study sees the first signal within one step and commits a
/// partial log within milliseconds, so two signals in a row race that commit: either the second
/// one wins (the previous output stays as it was) or the partial log is complete and committed.
/// Both are safe; a temporary left behind or a broken output is not.
#[test]
fn a_second_sigint_removes_the_temporaries_and_keeps_the_old_output() {
    let dir = fresh_scratch_dir("issue12_signals", "double_sigint");
    let out = dir.join("envelopes.mcap");
    std::fs::write(&out, "previous result").unwrap();
    let (mut child, _) = analyze_until_progress(&out);
    wait_for_temporary(&dir);
    signal(&child, "INT");
    signal(&child, "INT");
    let code = wait(&mut child);
    assert_eq!(code, Some(1));
    let bytes = std::fs::read(&out).unwrap();
    let previous = bytes == b"previous result";
    // A committed log is a whole MCAP file: magic at both ends.
    let magic = b"\x89MCAP0\r\n";
    let whole_mcap = bytes.starts_with(magic) && bytes.ends_with(magic);
    assert!(
        previous || whole_mcap,
        "the output is neither the old file nor a whole MCAP ({} bytes)",
        bytes.len()
    );
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
}

/// `kill -9` cannot be handled: the previous output must still be intact (only the temporary,
/// named after the process, is left, and it is never the output).
#[test]
fn kill_9_keeps_the_old_output() {
    let dir = fresh_scratch_dir("issue12_signals", "kill_9");
    let out = dir.join("envelopes.mcap");
    std::fs::write(&out, "previous result").unwrap();
    let (mut child, _) = analyze_until_progress(&out);
    wait_for_temporary(&dir);
    signal(&child, "KILL");
    let _ = wait(&mut child);
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous result");
    let left = leftovers(&dir);
    assert_eq!(left.len(), 1, "{left:?}");
    assert!(
        left[0].starts_with("envelopes.mcap.ribbon-") && left[0].contains(&child.id().to_string()),
        "the temporary names its process: {left:?}"
    );
}

/// Before: the study checked signals between blocks only, so at a 1e-6 s step SIGTERM took effect
/// after a whole block (tens of seconds to minutes). Now every sample checks before each step:
/// the run stops inside its first block, which the step counter shows without timing anything.
#[test]
fn sigterm_stops_a_study_inside_a_block() {
    let dir = fresh_scratch_dir("issue12_signals", "study_sigterm");
    let out = dir.join("envelopes.mcap");
    let summary = dir.join("summary.json");
    let (mut child, _) =
        analyze_until_progress_with(&out, &["--summary", summary.to_str().unwrap()]);
    wait_for_temporary(&dir);
    signal(&child, "TERM");
    assert_eq!(wait(&mut child), Some(1));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).expect("summary written"))
            .expect("valid JSON");
    assert_eq!(json["stats"]["partial"], serde_json::json!(true));
    // One block is 50 records of 10 000 steps for each of the 26 runs.
    let one_block = 26 * 50 * 10_000;
    let steps = json["stats"]["steps"].as_u64().expect("steps");
    assert!(
        steps < one_block,
        "{steps} steps: the study ran a whole block before stopping"
    );
    let bytes = std::fs::read(&out).expect("partial MCAP written");
    assert!(bytes.starts_with(b"\x89MCAP0\r\n") && bytes.ends_with(b"\x89MCAP0\r\n"));
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
}
