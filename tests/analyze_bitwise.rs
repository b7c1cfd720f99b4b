//! `analyze` and `simulate` on every shipped robot against reference outputs committed from main's
//! binary (commit e57b9dd) before the study was split into plan / simulate / reduce stages: the
//! refactor must leave every number bitwise unchanged.
//!
//! Compared: the CSV byte for byte, the summary JSON with its machine-dependent fields masked
//! (`wall_seconds`, `stats.simulate_seconds`, `stats.bound_seconds`, `stats.phase_seconds`,
//! `stats.threads`, `stats.peak_memory_bytes`), the stdout table with its wall time masked, and the MCAP log by its
//! FNV-1a 64 hash. The fixtures live in `tests/fixtures/analyze_reference/` (see its README).

mod common;

use common::fresh_test_scratch_dir;

use common::{masked_summary, masked_table};
use std::path::{Path, PathBuf};
use std::process::Command;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/analyze_reference")
}

/// FNV-1a, 64 bit: the hash the fixtures' `*.mcap.fnv1a64` files hold.
fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

fn check_case(name: &str, command: &str, args: &[&str]) {
    let dir = fresh_test_scratch_dir("analyze_bitwise", name);
    let (summary, csv, mcap) = (
        dir.join("summary.json"),
        dir.join("out.csv"),
        dir.join("out.mcap"),
    );
    let output = Command::new(env!("CARGO_BIN_EXE_ribbon"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg(command)
        .args(args)
        .arg("--summary")
        .arg(&summary)
        .arg("--csv")
        .arg(&csv)
        .arg("--out")
        .arg(&mcap)
        .output()
        .expect("run ribbon");
    assert!(
        output.status.success(),
        "{name}: ribbon {command} {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let reference = |suffix: &str| {
        std::fs::read(fixtures().join(format!("{name}.{suffix}")))
            .unwrap_or_else(|e| panic!("{name}.{suffix}: {e}"))
    };
    let read = |path: &Path| std::fs::read(path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
    assert!(
        read(&csv) == reference("csv"),
        "{name}: the CSV differs from tests/fixtures/analyze_reference/{name}.csv"
    );
    assert_eq!(
        masked_summary(&String::from_utf8_lossy(&read(&summary))),
        masked_summary(&String::from_utf8_lossy(&reference("summary.json"))),
        "{name}: the summary differs (timing fields masked)"
    );
    assert_eq!(
        masked_table(&String::from_utf8_lossy(&output.stdout)),
        masked_table(&String::from_utf8_lossy(&reference("table.txt"))),
        "{name}: the stdout table differs (wall time masked)"
    );
    let expected_hash = String::from_utf8_lossy(&reference("mcap.fnv1a64"))
        .trim()
        .to_string();
    assert_eq!(
        format!("{:016x}", fnv1a64(&read(&mcap))),
        expected_hash,
        "{name}: the MCAP log differs"
    );
}

#[test]
fn analyze_double_pendulum_is_unchanged() {
    check_case(
        "dp",
        "analyze",
        &[
            "robots/double_pendulum/double_pendulum.urdf",
            "--duration",
            "0.5",
        ],
    );
}

#[test]
fn analyze_double_pendulum_monte_carlo_is_unchanged() {
    check_case(
        "dpmc",
        "analyze",
        &[
            "robots/double_pendulum/double_pendulum.urdf",
            "--duration",
            "0.5",
            "--method",
            "monte-carlo",
            "--samples",
            "40",
            "--keep-going",
        ],
    );
}

#[test]
fn analyze_four_bar_is_unchanged() {
    check_case(
        "fb",
        "analyze",
        &["robots/four_bar/four_bar.urdf", "--duration", "0.5"],
    );
}

#[test]
fn analyze_slider_crank_is_unchanged() {
    check_case(
        "sc",
        "analyze",
        &["robots/slider_crank/slider_crank.urdf", "--duration", "0.5"],
    );
}

#[test]
fn analyze_ur5_is_unchanged() {
    check_case(
        "ur5",
        "analyze",
        &["robots/ur5/ur5.urdf", "--duration", "0.2"],
    );
}

#[test]
fn analyze_ur5_all_values_adaptive_is_unchanged() {
    check_case(
        "ur5all",
        "analyze",
        &[
            "robots/ur5/ur5.urdf",
            "--uncertainty",
            "robots/ur5/ur5.all-values.uncertainty.toml",
            "--duration",
            "0.05",
        ],
    );
}

#[test]
fn analyze_ur5_all_values_screened_is_unchanged() {
    check_case(
        "ur5scr",
        "analyze",
        &[
            "robots/ur5/ur5.urdf",
            "--uncertainty",
            "robots/ur5/ur5.all-values.uncertainty.toml",
            "--duration",
            "0.05",
            "--design",
            "screened",
            "--method",
            "legendre-scan",
            "--max-runs",
            "600",
        ],
    );
}

#[test]
fn simulate_double_pendulum_is_unchanged() {
    check_case(
        "sim_double_pendulum",
        "simulate",
        &[
            "robots/double_pendulum/double_pendulum.urdf",
            "--duration",
            "0.5",
        ],
    );
}

#[test]
fn simulate_four_bar_is_unchanged() {
    check_case(
        "sim_four_bar",
        "simulate",
        &["robots/four_bar/four_bar.urdf", "--duration", "0.5"],
    );
}

#[test]
fn the_masks_hide_only_timing() {
    let summary = r#"{"wall_seconds": 1.5, "samples": 3, "stats": {"threads": 2, "steps": 10}}"#;
    let masked = masked_summary(summary);
    assert!(masked.contains("\"samples\": 3") && masked.contains("\"steps\": 10"));
    assert!(!masked.contains("1.5") && !masked.contains("\"threads\": 2"));
    assert_eq!(
        masked_table("method x, 30 model runs, 0.045 s wall\nq 1.0"),
        "method x, 30 model runs, X s wall\nq 1.0"
    );
    assert_ne!(fnv1a64(b"a"), fnv1a64(b"b"));
}
