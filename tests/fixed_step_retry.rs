//! Issue 39 item 5: a valid robot does not fail a study. A run whose step fails at the study's
//! fixed step is re-run from t = 0 with the adaptive step on the same record grid; its records
//! from the record the fixed step failed to reach on are the adaptive run's, the summary and
//! stderr name it, and only a run that fails both ways fails the study (with today's message).
//!
//! The robot: a light rotor (0.1 kg, 1e-5 kg·m² about its spin axis) spinning at 1000 rad/s on
//! the end of an arm that turns about the vertical. Its centre of mass off the spin axis,
//! `link.rotor.com.y` ∈ [0, 0.03] m, decides whether Newton converges at h = 1 ms: 0.0034 m runs
//! through the 1 s; 0.015 m fails at t = 0.93 s and 0.0266 m at 0.543 s, and both run with the
//! adaptive step.

mod common;

use common::{fresh_scratch_dir, masked_summary, masked_table, ribbon_outcome, shipped_setup};
use ribbon::analysis::{BlockOutcome, LockStep};
use ribbon::integrate::{HhtSettings, StepControl};
use ribbon::simulate::{hht_settings, RobotSystem};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

const GYRO_URDF: &str = r#"<?xml version="1.0"?>
<robot name="gyro">
  <link name="base"/>
  <link name="arm">
    <inertial><origin xyz="0.2 0 0"/><mass value="1.0"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <link name="rotor">
    <inertial><origin xyz="0 0 0"/><mass value="0.1"/>
      <inertia ixx="0.00001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="j1" type="continuous"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="continuous"><parent link="arm"/><child link="rotor"/>
    <origin xyz="0.4 0 0"/><axis xyz="1 0 0"/></joint>
</robot>
"#;

const GYRO_SIDECAR: &str = r#"[parameters]
"link.rotor.com.y" = [0.0, 0.03]
[scene]
duration = 1.0
gravity = [0.0, 0.0, -9.81]
initial.v = { j2 = 1000.0 }
[outputs]
joints = "all"
velocities = true
rate = 100
"#;

/// The gyro robot and its sidecar in a fresh scratch directory `name`.
fn gyro_files(name: &str) -> (PathBuf, PathBuf) {
    let dir = fresh_scratch_dir("fixed_step_retry", name);
    let (urdf, sidecar) = (dir.join("gyro.urdf"), dir.join("gyro.uncertainty.toml"));
    std::fs::write(&urdf, GYRO_URDF).unwrap();
    std::fs::write(&sidecar, GYRO_SIDECAR).unwrap();
    (urdf, sidecar)
}

/// The study of the tests: an order-2 Legendre scan, 3 design runs (com.y = 0.0034, 0.015,
/// 0.0266 m) and the nominal run (0 m).
const STUDY: [&str; 4] = ["--method", "legendre-scan", "--order", "2"];

/// `ribbon analyze` of the gyro study in `dir` with `extra` flags: (exit code, stdout, stderr,
/// summary text, CSV bytes).
fn analyze(
    urdf: &Path,
    extra: &[&str],
    tag: &str,
) -> (Option<i32>, String, String, String, Vec<u8>) {
    let dir = urdf.parent().unwrap();
    let (summary, csv) = (
        dir.join(format!("{tag}.summary.json")),
        dir.join(format!("{tag}.csv")),
    );
    let mut args = vec!["analyze", urdf.to_str().unwrap()];
    args.extend_from_slice(&STUDY);
    args.extend_from_slice(&[
        "--summary",
        summary.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    args.extend_from_slice(extra);
    let out = ribbon_outcome(&args);
    let summary = std::fs::read_to_string(&summary)
        .unwrap_or_else(|e| panic!("{tag}: no summary ({e}): {}", out.stderr));
    (
        out.code,
        out.stdout,
        out.stderr,
        summary,
        std::fs::read(&csv).unwrap(),
    )
}

/// The study completes (exit 4: an order-2 surrogate cannot follow this rotor; not 1), names both
/// retried design samples in the summary (phase, run, ξ, value, where and why the fixed step
/// failed, from when the records are the adaptive run's) and on stderr, and gives the same bytes
/// with 1 and 2 threads. Each retried sample's fixed-step failure is the one `ribbon simulate`
/// reports at its parameter value, and `simulate` with the adaptive step runs it to the end.
#[test]
fn a_study_completes_when_samples_fail_only_at_the_fixed_step() {
    let (urdf, _) = gyro_files("analyze");
    let (code, stdout, stderr, summary_text, csv) = analyze(&urdf, &["--threads", "2"], "two");
    assert_eq!(
        code,
        Some(i32::from(ribbon::UNTRUSTED_EXIT_CODE)),
        "{stderr}"
    );
    let summary: Value = serde_json::from_str(&summary_text).unwrap();
    let retried = summary["retried_samples"]
        .as_array()
        .unwrap_or_else(|| panic!("no retried_samples: {summary_text}"));
    let design: Vec<&Value> = retried.iter().filter(|r| r["phase"] == "design").collect();
    assert_eq!(design.len(), 2, "{retried:?}");
    for (entry, run, xi, value, time, from) in [
        (design[0], "sample 2 of 3", 0.0, 0.015, 0.93, 0.93),
        (
            design[1],
            "sample 3 of 3",
            0.7745966692414834,
            0.02661895003862225,
            0.543,
            0.55,
        ),
    ] {
        assert_eq!(entry["run"], run, "{entry}");
        assert_eq!(entry["xi"][0].as_f64(), Some(xi), "{entry}");
        assert_eq!(entry["values"][0].as_f64(), Some(value), "{entry}");
        assert_eq!(entry["time"].as_f64(), Some(time), "{entry}");
        assert_eq!(entry["adaptive_from_time"].as_f64(), Some(from), "{entry}");
        let error = entry["error"].as_str().unwrap();
        assert!(
            error.starts_with(&format!(
                "simulation failed: Newton did not converge at t = {time} s"
            )),
            "{error}"
        );
        assert!(
            stderr.contains(&format!(
                "note: {run} of the design phase failed at the fixed step at t = {time} s and was re-run from t = 0 with the adaptive step on the same record grid (its records from t = {from} s on are that run's); the fixed step's failure: {error}"
            )),
            "{stderr}"
        );
        // The same failure by `ribbon simulate` at that value, and no failure adaptively.
        let fixed = simulate(&urdf, value, false);
        assert_eq!(fixed.code, Some(1), "{}", fixed.stderr);
        // On stderr the long message is laid out: a headline, then its clauses indented.
        assert!(
            fixed.stderr.contains(&ribbon::text::laid_out(error)),
            "{}\nnot in\n{}",
            error,
            fixed.stderr
        );
        let adaptive = simulate(&urdf, value, true);
        assert_eq!(adaptive.code, Some(0), "{}", adaptive.stderr);
    }
    // The same study on one thread: the same bytes.
    let (code_1, stdout_1, _, summary_1, csv_1) = analyze(&urdf, &["--threads", "1"], "one");
    assert_eq!(code_1, code);
    assert!(csv_1 == csv, "the CSV differs between 1 and 2 threads");
    assert_eq!(masked_summary(&summary_1), masked_summary(&summary_text));
    assert_eq!(masked_table(&stdout_1), masked_table(&stdout));
}

/// `ribbon simulate` of the gyro at `link.rotor.com.y = value`, at the fixed step or adaptively.
fn simulate(urdf: &Path, value: f64, adaptive: bool) -> common::Outcome {
    let sidecar = urdf.with_file_name(if adaptive {
        "adaptive.uncertainty.toml"
    } else {
        "gyro.uncertainty.toml"
    });
    if adaptive {
        let text = GYRO_SIDECAR.replace("[scene]\n", "[scene]\nstep_control = \"adaptive\"\n");
        std::fs::write(&sidecar, text).unwrap();
    }
    ribbon_outcome(&[
        "simulate",
        urdf.to_str().unwrap(),
        "--uncertainty",
        sidecar.to_str().unwrap(),
        "--set",
        &format!("link.rotor.com.y={value}"),
    ])
}

/// `plan`, three shards by `run` (each shard one design run, the first also the nominal run: a
/// retried sample then sits in a shard of its own), and `merge`: the CSV, the masked summary with
/// its retry notes, and the stdout table are `analyze`'s, and the shards' `run` lines say which
/// shards re-ran a sample.
#[test]
fn plan_run_merge_of_retried_samples_is_byte_identical_to_analyze() {
    let (urdf, _) = gyro_files("shards");
    let dir = urdf.parent().unwrap().to_path_buf();
    let (code, stdout, _, summary, csv) = analyze(&urdf, &[], "analyze");
    let plan = dir.join("gyro.plan");
    let mut args = vec!["plan", urdf.to_str().unwrap()];
    args.extend_from_slice(&STUDY);
    args.extend_from_slice(&["--plan", plan.to_str().unwrap()]);
    let planned = ribbon_outcome(&args);
    assert_eq!(planned.code, Some(0), "{}", planned.stderr);
    let shards = dir.join("shards");
    let mut retried_shards = 0;
    for k in 0..3 {
        let run = ribbon_outcome(&[
            "run",
            plan.to_str().unwrap(),
            "--shard",
            &format!("{k}/3"),
            "--into",
            shards.to_str().unwrap(),
        ]);
        assert_eq!(run.code, Some(0), "shard {k}: {}", run.stderr);
        if run.stderr.contains("1 re-run with the adaptive step") {
            retried_shards += 1;
        }
    }
    assert_eq!(retried_shards, 2, "two shards hold a retried sample");
    let (merged_summary, merged_csv) = (dir.join("merge.summary.json"), dir.join("merge.csv"));
    let merged = ribbon_outcome(&[
        "merge",
        plan.to_str().unwrap(),
        shards.to_str().unwrap(),
        "--summary",
        merged_summary.to_str().unwrap(),
        "--csv",
        merged_csv.to_str().unwrap(),
    ]);
    assert_eq!(merged.code, code, "{}", merged.stderr);
    assert!(
        std::fs::read(&merged_csv).unwrap() == csv,
        "the merged CSV differs from analyze's"
    );
    let merged_summary = std::fs::read_to_string(&merged_summary).unwrap();
    assert!(merged_summary.contains("retried_samples"));
    assert_eq!(masked_summary(&merged_summary), masked_summary(&summary));
    assert_eq!(masked_table(&merged.stdout), masked_table(&stdout));
}

/// The records of one lock-step run of the gyro's `points` (ξ, one per sample) over `duration_s`,
/// in blocks of `block` records: per sample, the bits of every record, and the retry notes.
fn lockstep_records(
    duration_s: f64,
    settings: impl Fn(HhtSettings) -> HhtSettings,
    points: &[f64],
    block: usize,
    batched: bool,
    threads: usize,
) -> (Vec<Vec<u64>>, String) {
    let (urdf, sidecar) = gyro_files(&format!(
        "lockstep_{duration_s}_{block}_{batched}_{threads}"
    ));
    let setup = shipped_setup(
        urdf.to_str().unwrap(),
        sidecar.to_str().unwrap(),
        duration_s,
    );
    let template = RobotSystem::new(setup.model.clone(), setup.environment, &setup.scene);
    let mut lockstep = LockStep::new(
        template,
        &setup.space,
        &setup.scene,
        settings(hht_settings(&setup.scene)),
        points,
        None,
    );
    assert!(lockstep.batched(), "the gyro scene suits the batched path");
    if !batched {
        lockstep.disable_batching();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let interrupt = AtomicBool::new(false);
    let records = setup.scene.record_count() as usize;
    let mut bits = vec![Vec::new(); points.len()];
    let mut first = 0;
    while first < records {
        let count = block.min(records - first);
        assert_eq!(
            lockstep.advance(first, count, &pool, &interrupt),
            BlockOutcome::Complete
        );
        for (i, sample) in bits.iter_mut().enumerate() {
            assert!(
                !lockstep.failed(i),
                "sample {i} failed: {:?}",
                lockstep.failures()
            );
            for r in 0..count {
                sample.extend(lockstep.record(i, r).iter().map(|x| x.to_bits()));
            }
        }
        first += count;
    }
    (bits, format!("{:?}", lockstep.retries()))
}

/// In the engine itself: a retried sample's records are, bit for bit, the fixed step's up to the
/// record the fixed step failed to reach (a fixed-step run that ends before the failure) and the
/// adaptive run's from there on (a run with `step_control = "adaptive"` from t = 0); the same for
/// blocks of 7, 13 and 101 records (a shard cuts the horizon differently from `analyze`), batched
/// and sample by sample, on 1 and 2 threads. A sample that does not fail keeps the fixed step's
/// records.
#[test]
fn retried_records_are_the_fixed_steps_then_the_adaptive_runs_whatever_the_blocks() {
    // ξ = −0.7746 (0.0034 m: runs), 0 (0.015 m: fails at 0.93 s), 0.7746 (0.0266 m: 0.543 s).
    let points = [-0.7745966692414834, 0.0, 0.7745966692414834];
    let fixed = |s: HhtSettings| s;
    let (reference, notes) = lockstep_records(1.0, fixed, &points, 7, true, 2);
    assert!(
        notes.contains("index: 1,") && notes.contains("index: 2,") && !notes.contains("index: 0,"),
        "{notes}"
    );
    assert!(
        notes.contains("record: 93,") && notes.contains("record: 55,"),
        "{notes}"
    );
    for (block, batched, threads) in [(13, true, 1), (101, true, 2), (7, false, 1), (13, false, 2)]
    {
        let (bits, other_notes) = lockstep_records(1.0, fixed, &points, block, batched, threads);
        assert_eq!(
            other_notes, notes,
            "block {block}, batched {batched}, {threads} threads"
        );
        assert!(
            bits == reference,
            "records differ: block {block}, batched {batched}, {threads} threads"
        );
    }
    let adaptive = |s: HhtSettings| HhtSettings {
        step_control: StepControl::Adaptive,
        ..s
    };
    let (adaptive_bits, adaptive_notes) = lockstep_records(1.0, adaptive, &points, 101, true, 2);
    assert_eq!(adaptive_notes, "[]", "an adaptive study retries nothing");
    let values_per_record = reference[0].len() / 101;
    for (sample, failed_record) in [(0, None), (1, Some(93)), (2, Some(55))] {
        let switch = failed_record.unwrap_or(101);
        // The fixed step's records before the failure: a fixed-step run that ends before it.
        let last_fixed = switch - 1;
        let (short, short_notes) = lockstep_records(
            last_fixed as f64 / 100.0,
            fixed,
            &points[sample..=sample],
            50,
            true,
            1,
        );
        assert_eq!(short_notes, "[]");
        let split = switch * values_per_record;
        assert!(
            reference[sample][..split] == short[0][..split],
            "sample {sample}: the records before {switch} are not the fixed step's"
        );
        assert!(
            reference[sample][split..] == adaptive_bits[sample][split..],
            "sample {sample}: the records from {switch} on are not the adaptive run's"
        );
    }
}

/// A sample that fails both ways — the slider-crank's rod shorter than its crank, so that the loop
/// cannot close past the angle where `r sin θ = l`, whatever the step — still fails the study with
/// today's message and exit code: the fixed step's failure, no retry note. (Measured against
/// main's binary before the retry: the same `error:` line, byte for byte.) Under `--keep-going` a
/// scan excludes it and lists it, as before.
#[test]
fn a_sample_failing_both_ways_fails_the_study_with_the_fixed_steps_message() {
    let dir = fresh_scratch_dir("fixed_step_retry", "both_ways");
    let sidecar = common::short_rod_slider_crank_sidecar(&dir);
    let summary = dir.join("summary.json");
    let analyze = |method: &[&str]| {
        let mut args = vec![
            "analyze",
            "robots/slider_crank/slider_crank.urdf",
            "--uncertainty",
            sidecar.to_str().unwrap(),
            "--summary",
            summary.to_str().unwrap(),
        ];
        args.extend_from_slice(method);
        ribbon_outcome(&args)
    };
    let out = analyze(&["--method", "legendre-scan", "--order", "2"]);
    assert_eq!(out.code, Some(1), "{}", out.stderr);
    let error = out
        .stderr
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("{}", out.stderr));
    // A one-line headline, then the details (the values it failed at among them), indented.
    assert!(
        error.starts_with(
            "error: sample 1 of 27 failed at t = 0.179 s: simulation failed: Newton did not converge at t = 0.179 s (step 179) after 9 iterations"
        ) && out.stderr.contains(
            "\n  at parameter values [0.09992254033307585, 0.08989638954425744,"
        ),
        "{error}"
    );
    assert!(!out.stderr.contains("re-run"), "{}", out.stderr);
    assert!(!summary.exists(), "a failed study writes no summary");
    // A scan may leave such a sample out (--keep-going): it is named as excluded, not retried.
    let out = analyze(&["--method", "scan", "--grid", "3", "--keep-going"]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let excluded = summary["excluded_samples"].as_array().unwrap();
    assert!(!excluded.is_empty(), "{summary}");
    for sample in excluded {
        // The rod of 0.05 m, the grid's shortest.
        assert_eq!(sample["values"][1].as_f64(), Some(0.05), "{sample}");
        assert!(sample["time"].as_f64().is_some_and(|t| t > 0.0), "{sample}");
    }
    assert!(summary.get("retried_samples").is_none(), "{summary}");
}
