//! Issue 39 item 1: the a-posteriori check follows every surrogate method, and a bound that true
//! runs break never exits 0. The box: a bar on a spring hinge (k = 100 N·m/rad, no gravity,
//! released from 0.3 rad, 5 s) whose mass ranges over eleven decades, [0.01, 1e9] kg. Its velocity
//! peaks at ~50 rad/s for the lightest bar and ~1e-4 rad/s for the heaviest, a response no
//! order-4 polynomial in the mass follows.
//!
//! - Every surrogate method (`legendre-scan`, `legendre-ia`, `legendre-bernstein`,
//!   `chebyshev-scan`, `chebyshev-ia`) and `taylor` exits 4 with the message of its kind
//!   (a scan's surrogate "cannot be trusted"; an outer bound "was broken by the true model"), and
//!   every true run the study made lies inside its envelopes — the check's runs re-made
//!   independently by `ribbon simulate` at the check's points, the others through the summary's
//!   hull of true runs.
//! - `auto` splits the box into elements, scans the leaf where halving stalls and refines that
//!   scan's cells (docs/method.md §12, "Refined scans"): exit 0, trusted, and light bars run apart
//!   from the study lie inside its envelopes.
//! - `scan` and `monte-carlo` are made of true runs only: nothing to check, exit 0, and their
//!   envelope is exactly the hull of their runs (an inner bound of the true range). Independent
//!   light-mass runs show how far short of the true range that is here (printed, not asserted:
//!   neither method claims to contain them; docs/method.md §7).
//! - `--check-runs 0` stays possible and is said (summary, stdout).

mod common;

use common::{
    fresh_scratch_dir, ribbon_outcome, summary_series as series, NINE_DECADE_SIDECAR, SPRING_URDF,
};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Light bars, each run by `ribbon simulate` apart from any study (kg).
const LIGHT_MASSES: [f64; 4] = [0.03, 0.1, 0.3, 3.0];

/// One `analyze` of the nine-decade box: its exit code, stderr, stdout and summary.
struct Analyzed {
    dir: PathBuf,
    code: Option<i32>,
    stdout: String,
    stderr: String,
    summary: Value,
}

fn analyze(method: &str, extra: &[&str]) -> Analyzed {
    let dir = fresh_scratch_dir("check_every_method", &format!("{method}{}", extra.join("")));
    std::fs::write(dir.join("spring.urdf"), SPRING_URDF).unwrap();
    std::fs::write(dir.join("spring.uncertainty.toml"), NINE_DECADE_SIDECAR).unwrap();
    let summary = dir.join("summary.json");
    let urdf = dir.join("spring.urdf");
    let mut args = vec![
        "analyze",
        urdf.to_str().unwrap(),
        "--method",
        method,
        "--summary",
        summary.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let outcome = ribbon_outcome(&args);
    let summary = std::fs::read_to_string(&summary)
        .unwrap_or_else(|e| panic!("{method}: no summary ({e}): {}", outcome.stderr));
    Analyzed {
        dir,
        code: outcome.code,
        stdout: outcome.stdout,
        stderr: outcome.stderr,
        summary: serde_json::from_str(&summary).unwrap(),
    }
}

const OUTPUTS: [&str; 3] = ["q.hinge", "v.hinge", "qdd.hinge"];

/// `ribbon simulate` at `mass`: per output, its value at every record time.
fn simulate(dir: &Path, mass: f64, tag: &str) -> Vec<(String, Vec<f64>)> {
    let csv = dir.join(format!("simulate_{tag}.csv"));
    let urdf = dir.join("spring.urdf");
    let run = ribbon_outcome(&[
        "simulate",
        urdf.to_str().unwrap(),
        "--set",
        &format!("link.bar.mass={mass:e}"),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(run.code, Some(0), "simulate at {mass} kg: {}", run.stderr);
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    header
        .iter()
        .enumerate()
        .skip(1)
        .map(|(c, name)| (name.clone(), rows.iter().map(|row| row[c]).collect()))
        .collect()
}

/// The largest distance of `run` outside the envelope of `output`, relative to the output's
/// widest envelope (0 inside).
fn excess_over_width(summary: &Value, output: &str, run: &[f64]) -> f64 {
    let (lower, upper) = (
        series(summary, output, "lower"),
        series(summary, output, "upper"),
    );
    assert_eq!(run.len(), lower.len(), "{output}: record times");
    let width = lower
        .iter()
        .zip(&upper)
        .map(|(l, u)| u - l)
        .fold(0.0, f64::max);
    let excess = run
        .iter()
        .zip(lower.iter().zip(&upper))
        .map(|(&y, (&l, &u))| (l - y).max(y - u).max(0.0))
        .fold(0.0, f64::max);
    excess / width
}

/// The hull of the study's true runs (design, nominal, check) lies inside the envelope at every
/// output and record time.
fn assert_every_study_run_inside(method: &str, summary: &Value) {
    for output in OUTPUTS {
        let (lower, upper) = (
            series(summary, output, "lower"),
            series(summary, output, "upper"),
        );
        let (runs_lower, runs_upper) = (
            series(summary, output, "runs_lower"),
            series(summary, output, "runs_upper"),
        );
        for k in 0..lower.len() {
            assert!(
                lower[k] <= runs_lower[k] && runs_upper[k] <= upper[k],
                "{method}: {output} at record {k}: true runs [{}, {}] outside the envelope [{}, {}]",
                runs_lower[k],
                runs_upper[k],
                lower[k],
                upper[k]
            );
        }
    }
}

/// A surrogate method (or `taylor`) on the nine-decade box: exit 4 with the message of its kind,
/// the check in the summary not trusted, and every true run inside the envelopes — the check's
/// runs re-made by `ribbon simulate` at its points bit for bit inside.
fn assert_checked_and_untrusted(method: &str, finding: &str) {
    let study = analyze(method, &[]);
    assert_eq!(
        study.code,
        Some(i32::from(ribbon::UNTRUSTED_EXIT_CODE)),
        "{method}: {}",
        study.stderr
    );
    let error = study
        .stderr
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("{method}: no error line: {}", study.stderr));
    assert!(
        error.contains(finding) && error.contains("exits with status 4"),
        "{method}: {error}"
    );
    // The warning line says the same.
    assert!(
        study
            .stderr
            .lines()
            .any(|l| l.starts_with("warning: ") && l.contains(finding)),
        "{method}: {}",
        study.stderr
    );
    assert!(
        study.stdout.contains("NOT TRUSTED"),
        "{method}: {}",
        study.stdout
    );
    let check = &study.summary["stats"]["check"];
    assert_eq!(check["trusted"], false, "{method}: {check}");
    let runs = check["runs"].as_u64().unwrap();
    assert!(runs > 0, "{method}: {check}");
    assert_every_study_run_inside(method, &study.summary);
    let (lower, upper) = (
        study.summary["parameters"][0]["lower"].as_f64().unwrap(),
        study.summary["parameters"][0]["upper"].as_f64().unwrap(),
    );
    let points = check["points_xi"].as_array().unwrap();
    assert_eq!(points.len() as u64, runs, "{method}: {check}");
    for (i, point) in points.iter().enumerate() {
        let xi = point[0].as_f64().unwrap();
        let mass = 0.5 * ((1.0 - xi) * lower + (1.0 + xi) * upper);
        for (output, values) in simulate(&study.dir, mass, &format!("check_{i}")) {
            let excess = excess_over_width(&study.summary, &output, &values);
            assert!(
                excess == 0.0,
                "{method}: the check run at {mass} kg leaves the envelope of {output} by {excess} of its width"
            );
        }
    }
    println!(
        "{method}: exit 4, {runs} check runs, worst relative misfit {}",
        check["outputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| o["relative_misfit"].as_f64().unwrap())
            .fold(0.0, f64::max)
    );
}

const SCAN_FINDING: &str = "the surrogate cannot be trusted";
const OUTER_FINDING: &str = "the outer bound of the surrogate was broken by the true model";
const TAYLOR_FINDING: &str =
    "the range of the first-order Taylor linearisation was broken by the true model";

#[test]
fn legendre_scan_is_not_trusted() {
    assert_checked_and_untrusted("legendre-scan", SCAN_FINDING);
}

#[test]
fn legendre_ia_is_checked_and_its_outer_bound_broken() {
    assert_checked_and_untrusted("legendre-ia", OUTER_FINDING);
}

#[test]
fn legendre_bernstein_is_checked_and_its_outer_bound_broken() {
    assert_checked_and_untrusted("legendre-bernstein", OUTER_FINDING);
}

#[test]
fn chebyshev_scan_is_not_trusted() {
    assert_checked_and_untrusted("chebyshev-scan", SCAN_FINDING);
}

#[test]
fn chebyshev_ia_is_checked_and_its_outer_bound_broken() {
    assert_checked_and_untrusted("chebyshev-ia", OUTER_FINDING);
}

#[test]
fn taylor_is_checked_at_its_linearisations_vertices_and_broken() {
    assert_checked_and_untrusted("taylor", TAYLOR_FINDING);
}

/// A light bar run apart from the study may lie outside `auto`'s envelope by at most this share
/// of the width: the refined scan's cells pass at 2 % (`SCAN_CELL_TOLERANCE`); measured when
/// written, the study missed a 6 400-run reference (dense scans of [0.01, 0.02], [0.02, 0.1] and
/// [0.1, 10] kg, 401 points over [10, 1e9]) by at most 0.24 % of the width, where the study before
/// refined scans (exit 4) missed it by 44 %.
const AUTO_MAX_LIGHT_EXCESS: f64 = 0.01;

/// `auto` splits the box, scans the leaf where halving stalls (the light end, where the period
/// changes fastest) and refines that scan's cells until no cell can hide an extreme: trusted, and
/// light bars run by `ribbon simulate` lie inside.
#[test]
fn auto_is_trusted_once_its_stalled_leaf_is_scanned_and_refined() {
    let study = analyze("auto", &[]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    let check = &study.summary["stats"]["check"];
    assert_eq!(check["trusted"], true, "{check}");
    assert!(check["runs"].as_u64().unwrap() > 0, "{check}");
    assert!(
        study.stdout.contains("trusted") && !study.stdout.contains("NOT TRUSTED"),
        "{}",
        study.stdout
    );
    let elements = &study.summary["stats"]["elements"];
    let scanned = elements["elements"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| !e["scan_grid"].is_null())
        .count();
    assert_eq!(scanned, 1, "{elements}");
    assert_every_study_run_inside("auto", &study.summary);
    for mass in LIGHT_MASSES {
        for (output, values) in simulate(&study.dir, mass, &format!("light_{mass}")) {
            let excess = excess_over_width(&study.summary, &output, &values);
            assert!(
                excess <= AUTO_MAX_LIGHT_EXCESS,
                "auto: a {mass} kg bar leaves the envelope of {output} by {excess} of its width"
            );
            println!("auto: a {mass} kg bar leaves the envelope of {output} by {excess:.4}");
        }
    }
}

/// `scan` and `monte-carlo`: exit 0, no check (nothing but true runs), and the envelope is exactly
/// the hull of the study's runs. How far light bars run by `simulate` lie outside is printed.
fn assert_made_of_true_runs(method: &str, extra: &[&str], bound_kind: &str) {
    let study = analyze(method, extra);
    assert_eq!(study.code, Some(0), "{method}: {}", study.stderr);
    assert_eq!(study.summary["bound_kind"], bound_kind);
    assert!(study.summary["stats"]["check"].is_null());
    assert_every_study_run_inside(method, &study.summary);
    for output in OUTPUTS {
        assert_eq!(
            series(&study.summary, output, "lower"),
            series(&study.summary, output, "runs_lower"),
            "{method}: {output}"
        );
        assert_eq!(
            series(&study.summary, output, "upper"),
            series(&study.summary, output, "runs_upper"),
            "{method}: {output}"
        );
    }
    for mass in LIGHT_MASSES {
        let runs = simulate(&study.dir, mass, &format!("light_{mass}"));
        let outside: Vec<String> = runs
            .iter()
            .map(|(output, values)| {
                format!(
                    "{output} {:.3}",
                    excess_over_width(&study.summary, output, values)
                )
            })
            .collect();
        println!(
            "{method} ({bound_kind}): a {mass} kg bar leaves the envelope by (of the width) {}",
            outside.join(", ")
        );
    }
}

#[test]
fn scan_is_made_of_true_runs_and_exits_0() {
    assert_made_of_true_runs("scan", &[], "reference");
}

#[test]
fn monte_carlo_is_made_of_true_runs_and_exits_0() {
    assert_made_of_true_runs("monte-carlo", &["--samples", "200"], "inner");
}

/// `--check-runs 0` turns the check off for an outer method too, and says so: the summary's
/// `stats.check` holds `runs: 0` and the reason, the stdout method line says it was skipped, and
/// stderr notes that nothing verified the envelopes. The exit is then 0: nothing was found.
#[test]
fn a_check_turned_off_is_said() {
    let study = analyze("legendre-ia", &["--check-runs", "0"]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    let check = &study.summary["stats"]["check"];
    assert_eq!(check["runs"], 0, "{check}");
    assert!(
        check["skipped"]
            .as_str()
            .is_some_and(|s| s.starts_with("--check-runs 0")),
        "{check}"
    );
    let method_line = study
        .stdout
        .lines()
        .find(|l| l.starts_with("method legendre-ia"))
        .unwrap_or_else(|| panic!("{}", study.stdout));
    assert!(
        method_line.contains("6 model runs, check skipped (--check-runs 0"),
        "{method_line}"
    );
    assert!(
        study
            .stderr
            .contains("the surrogate was not checked against the true model (--check-runs 0)"),
        "{}",
        study.stderr
    );
}
