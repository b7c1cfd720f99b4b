//! Elements (docs/method.md §12): where the a-posteriori check does not trust one surrogate,
//! `--method auto` splits the box into sub-boxes with their own designs, surrogates and checks,
//! and reports their union. Checked against a dense scan of the true model on a planted kink.
//!
//! The planted kink: a bar on a torsion spring (no gravity, `k = 10 N·m/rad` towards 1 rad)
//! released at 0 onto a joint stop at 0.5 rad with no rebound; its mass `m ∈ [0.5, 1.5] kg` sets
//! `ω = √(k / (I_c + m l²))`, so the bar reaches the stop at `t* = (π/3)/ω` (0.17–0.21 s) and stays:
//! `q(t, m) = min(1 − cos ω t, 0.5)`, a kink in `m` whose place moves with `t`. One order-4
//! surrogate misses it (measured: 8.2 % of the width, exit 4 with `--elements off`); halving the
//! mass interval once gives two trusted elements (3.5 %), and splitting on while a leaf's misfit is
//! above 1 % of the width (docs/method.md §12, "Precision") gives five whose union contains every
//! one of 401 true runs of a dense scan and is at most 1 % of the width wider (measured when
//! written: 144 runs, 0.90 %; 2.2 % with the first two elements alone).

mod common;

use common::{
    fresh_test_scratch_dir, masked_summary_file, plan_run_merge_in_two_shards, ribbon_outcome,
    NINE_DECADE_SIDECAR, SPRING_URDF,
};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The union may be wider than the dense scan by at most this share of the output's largest
/// width: trusted elements may overshoot a little (measured when written: 0.6 % on the nine-decade
/// box, 1.8 % on the joint stops, 2.3 % on the two-parameter kink), inside the trust threshold the
/// check applies (5 %).
const MAX_WIDER_THAN_SCAN: f64 = 0.05;

/// The planted kink's union may be wider than its dense scan by at most this share of the width
/// (issue 38's goal; measured when written: 0.90 %).
const KINK_MAX_WIDER_THAN_SCAN: f64 = 0.01;

/// A dense scan's run may lie outside the union by at most this share of the output's largest
/// width: the union is an inner bound of the true range, which it approaches, not an enclosure
/// (measured when written: 5e-7 on the planted kink — a joint resting on its stop — and 3.4e-5
/// on the nine-decade box, at a time where a 2001-point scan finds a slightly higher value).
const MAX_MISSED_OF_SCAN: f64 = 1e-3;

/// An output whose scan spreads less than this (m, rad, N) is rounding: the vehicle's sideways
/// motion, which its mirror symmetry keeps at zero, spreads 1e-14 m.
const ROUNDING_WIDTH: f64 = 1e-9;

/// The vehicle's union may be wider than a scan of its box's corners, faces' middles and centre
/// by at most this share of the width (issue 38's goal for the showcase robots; measured when
/// written: 8.7 % on the rear wheels' ground force, 18.7 % before trusted outputs' overshoots were
/// checked, docs/method.md §12).
const VEHICLE_MAX_WIDER_THAN_SCAN: f64 = 0.10;

/// How far past an enforced limit a surrogate's bound of a joint position may reach
/// (`ribbon::scene::ENFORCED_LIMIT_BOUND_MARGIN`: the penalty's depth at 1000 rad/s²).
const ENFORCED_LIMIT_BOUND_MARGIN: f64 = 0.025;

/// Points of the dense reference scan (odd, so the centre is on it).
const SCAN_POINTS: &str = "401";

const URDF: &str = r#"<?xml version="1.0"?>
<robot name="stopped_pendulum">
  <link name="base"/>
  <link name="bar">
    <inertial><origin xyz="0.5 0 0"/><mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="bar"/><axis xyz="0 0 1"/>
    <limit lower="-1.0" upper="0.5" effort="10" velocity="10"/></joint>
</robot>
"#;

const SIDECAR: &str = r#"[parameters]
"link.bar.mass" = [0.5, 1.5]
[scene]
duration = 0.5
gravity = [0.0, 0.0, 0.0]
effects = ["joint_springs", "joint_limits"]
limit_restitution = 0.0
[[scene.spring]]
joint = "hinge"
stiffness = 10.0
rest = 1.0
[outputs]
joints = "all"
"#;

/// The planted kink's files in a fresh directory: (URDF, directory).
fn planted_kink(test: &str) -> (PathBuf, PathBuf) {
    let dir = fresh_test_scratch_dir("elements", test);
    let urdf = dir.join("stop.urdf");
    std::fs::write(&urdf, URDF).unwrap();
    std::fs::write(dir.join("stop.uncertainty.toml"), SIDECAR).unwrap();
    (urdf, dir)
}

fn summary(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn series(output: &Value, key: &str) -> Vec<f64> {
    output[key]
        .as_array()
        .unwrap_or_else(|| panic!("no {key}"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

#[test]
fn a_kink_one_surrogate_misses_is_trusted_once_split_and_contains_a_dense_scan() {
    let (urdf, dir) = planted_kink("kink");
    let urdf = urdf.to_str().unwrap();
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();

    // One surrogate: not trusted. Its bound overshoots the stop at 0.5 rad (measured: to 0.5266
    // unclipped) and is clipped to the stop plus the penalty's margin (0.025 rad), while every
    // true run stays within the penalty's depth of the stop.
    let single = ribbon_outcome(&[
        "analyze",
        urdf,
        "--elements",
        "off",
        "--summary",
        &path("single.json"),
    ]);
    assert_eq!(single.code, Some(4), "{}", single.stderr);
    let single = summary(&dir.join("single.json"));
    let hinge = &single["outputs"][0];
    let upper = series(hinge, "upper");
    let clipped = upper.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(clipped, 0.5 + ENFORCED_LIMIT_BOUND_MARGIN, "{upper:?}");
    let runs_upper = series(hinge, "runs_upper");
    // Pressed into the stop by the spring (≈ 15 rad/s²), the runs rest a/ω² ≈ 5e-4 rad past it.
    assert!(
        runs_upper.iter().all(|&q| q <= 0.5 + 1e-3),
        "{runs_upper:?}"
    );

    // With elements (the default of --method auto): trusted, and the summary says how.
    let study = ribbon_outcome(&[
        "analyze",
        urdf,
        "--summary",
        &path("elements.json"),
        "--report",
        &path("report"),
        "--out",
        &path("elements.mcap"),
    ]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    assert!(
        study.stdout.contains(", trusted)") && study.stdout.contains("elements: "),
        "{}",
        study.stdout
    );
    assert!(
        study.stderr.contains("so the box was split into"),
        "{}",
        study.stderr
    );
    let with_elements = summary(&dir.join("elements.json"));
    let elements = &with_elements["stats"]["elements"];
    assert_eq!(elements["stop"], "trusted", "{elements}");
    assert!(elements["leaves"].as_u64().unwrap() >= 2, "{elements}");
    assert!(elements["splits"]["link.bar.mass"].as_u64().unwrap() >= 1);
    assert_eq!(with_elements["stats"]["check"]["trusted"], true);
    // The leaves tile the box: their mass intervals cover [0.5, 1.5] without overlap.
    let mut leaves: Vec<(f64, f64)> = elements["elements"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["leaf"] == true)
        .map(|e| (series(e, "lower")[0], series(e, "upper")[0]))
        .collect();
    leaves.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(leaves.first().unwrap().0, 0.5);
    assert_eq!(leaves.last().unwrap().1, 1.5);
    for pair in leaves.windows(2) {
        assert!((pair[0].1 - pair[1].0).abs() < 1e-12, "{leaves:?}");
    }

    // Against a dense scan of the true model: no scan run outside, at most a little wider; and
    // every true run the study made inside.
    assert_contains_scan(
        urdf,
        None,
        &with_elements,
        &dir,
        SCAN_POINTS,
        KINK_MAX_WIDER_THAN_SCAN,
    );

    // The report draws the elements' own bounds under the union; the log names them.
    let svg = std::fs::read_to_string(dir.join("report").join("q.hinge.svg")).unwrap();
    assert!(
        svg.contains("bounds of each of"),
        "no element bounds in the plot"
    );
    let mcap = std::fs::read(dir.join("elements.mcap")).unwrap();
    let needle = b"\"stop\":\"trusted\"";
    assert!(
        mcap.windows(needle.len()).any(|w| w == needle),
        "the MCAP's ribbon metadata has no elements entry"
    );
}

/// Runs a dense `scan` of `points` per dimension of the study (`urdf`, `sidecar`) into `dir` and
/// asserts that `ours` (a study's summary) contains every scan run at every record up to
/// [`MAX_MISSED_OF_SCAN`], is wider by at most [`MAX_WIDER_THAN_SCAN`] of each output's largest
/// width, and holds `lower ≤ runs_lower ≤ runs_upper ≤ upper` (every true run it made inside).
fn assert_contains_dense_scan(
    urdf: &str,
    sidecar: Option<&str>,
    ours: &Value,
    dir: &Path,
    points: &str,
) {
    assert_contains_scan(urdf, sidecar, ours, dir, points, MAX_WIDER_THAN_SCAN);
}

/// [`assert_contains_dense_scan`] with `max_wider` for [`MAX_WIDER_THAN_SCAN`]; outputs whose
/// scan width stays below [`ROUNDING_WIDTH`] (a motion that symmetry keeps at zero) are judged by
/// the runs inside only.
fn assert_contains_scan(
    urdf: &str,
    sidecar: Option<&str>,
    ours: &Value,
    dir: &Path,
    points: &str,
    max_wider: f64,
) {
    let scan_path = dir.join("scan.json");
    let mut args = vec!["analyze", urdf];
    if let Some(sidecar) = sidecar {
        args.extend(["--uncertainty", sidecar]);
    }
    args.extend([
        "--method",
        "scan",
        "--grid",
        points,
        "--summary",
        scan_path.to_str().unwrap(),
    ]);
    let scan = ribbon_outcome(&args);
    assert_eq!(scan.code, Some(0), "{}", scan.stderr);
    let scan = summary(&scan_path);
    for (ours, reference) in ours["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(scan["outputs"].as_array().unwrap())
    {
        let name = ours["name"].as_str().unwrap();
        let (lower, upper) = (series(ours, "lower"), series(ours, "upper"));
        let (scan_lower, scan_upper) = (series(reference, "lower"), series(reference, "upper"));
        let width = scan_lower
            .iter()
            .zip(&scan_upper)
            .map(|(l, u)| u - l)
            .fold(0.0, f64::max);
        let mut wider = 0.0_f64;
        let slack = MAX_MISSED_OF_SCAN * width;
        for k in 0..lower.len() {
            if width < ROUNDING_WIDTH {
                break;
            }
            assert!(
                lower[k] <= scan_lower[k] + slack && upper[k] >= scan_upper[k] - slack,
                "{name}, record {k}: [{}, {}] misses the scan's [{}, {}]",
                lower[k],
                upper[k],
                scan_lower[k],
                scan_upper[k]
            );
            wider = wider.max((scan_lower[k] - lower[k]).max(upper[k] - scan_upper[k]));
        }
        assert!(
            wider <= max_wider * width,
            "{name}: wider than the scan by {} of the width",
            wider / width
        );
        let (runs_lower, runs_upper) = (series(ours, "runs_lower"), series(ours, "runs_upper"));
        for k in 0..lower.len() {
            assert!(
                lower[k] <= runs_lower[k]
                    && runs_lower[k] <= runs_upper[k]
                    && runs_upper[k] <= upper[k],
                "{name}, record {k}: a true run outside the envelope"
            );
        }
    }
}

/// The hostile box of `tests/analysis.rs` (the double pendulum's bar 2 mass across nine decades,
/// 2 s under gravity), which one surrogate misses by 100 % of the width: split twice, every
/// element is trusted and the union contains a 2001-point scan of the true model (measured when
/// written: 144 runs, largest misfit 0.6 % of the width, wider than the scan by 0.6 %, short of it
/// by at most 1e-4 of the width — inside the resolution of the scan's own grid; before the
/// precision splits, 66 runs and 1.6 % wider).
#[test]
fn the_nine_decade_double_pendulum_box_is_trusted_once_split() {
    let dir = fresh_test_scratch_dir("elements", "nine_decades");
    let urdf = dir.join("dp.urdf");
    std::fs::copy(
        common::manifest("robots/double_pendulum/double_pendulum.urdf"),
        &urdf,
    )
    .unwrap();
    let sidecar = dir.join("dp.uncertainty.toml");
    std::fs::write(
        &sidecar,
        "[parameters]\n\"link.bar2.mass\" = [1e-9, 1.0]\n[scene]\nduration = 2.0\ngravity = [0.0, -9.81, 0.0]\n[outputs]\njoints = \"all\"\nrate = 100\n",
    )
    .unwrap();
    let summary_path = dir.join("elements.json");
    let urdf = urdf.to_str().unwrap();
    let study = ribbon_outcome(&["analyze", urdf, "--summary", summary_path.to_str().unwrap()]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    let ours = summary(&summary_path);
    assert_eq!(ours["stats"]["elements"]["stop"], "trusted");
    assert_contains_dense_scan(urdf, None, &ours, &dir, "2001");
}

/// A double pendulum thrown at 5 rad/s onto stops at ±0.5 rad (plastic impacts), bar 2's mass
/// ±5 %: when the shoulder stops moves with the mass, so at a fixed time the joint velocities
/// *jump* across the box (one run has stopped, its neighbour not yet). One surrogate misses by
/// 14 % of the width, and halving stalls (a jump keeps its size in whichever half holds it); the
/// stalled leaf is scanned on a grid of true runs and checked by bisecting its steepest cell down
/// to 2^-32 of a grid cell, so the study is trusted, and its union contains a 2001-point scan
/// (measured when written: 169 runs; against a 4001-point scan missed by at most 1e-4 of the
/// width, wider by at most 1.8 %; exit 4 at 14.4 % before scanned leaves).
#[test]
fn joint_stops_that_jump_across_the_box_are_trusted_once_the_stalled_leaf_is_scanned() {
    let dir = fresh_test_scratch_dir("elements", "joint_stops");
    let urdf = dir.join("dp_limits.urdf");
    let pendulum = std::fs::read_to_string(common::manifest(
        "robots/double_pendulum/double_pendulum.urdf",
    ))
    .unwrap();
    let limited = pendulum.replace("type=\"continuous\"", "type=\"revolute\"").replace(
        "<axis xyz=\"0 0 1\"/>",
        "<axis xyz=\"0 0 1\"/><limit lower=\"-0.5\" upper=\"0.5\" effort=\"10\" velocity=\"10\"/>",
    );
    assert_eq!(limited.matches("<limit ").count(), 2, "{limited}");
    std::fs::write(&urdf, limited).unwrap();
    let sidecar = dir.join("dp_limits.uncertainty.toml");
    std::fs::write(
        &sidecar,
        "[parameters]\n\"link.bar2.mass\" = { rel = 0.05 }\n[scene]\nduration = 1.0\ngravity = [0.0, -9.81, 0.0]\neffects = [\"gravity\", \"joint_limits\"]\ninitial.v = { j1 = 5.0 }\n[outputs]\njoints = \"all\"\nvelocities = true\n",
    )
    .unwrap();
    let (urdf, sidecar) = (urdf.to_str().unwrap(), sidecar.to_str().unwrap());
    let single = ribbon_outcome(&[
        "analyze",
        urdf,
        "--uncertainty",
        sidecar,
        "--elements",
        "off",
    ]);
    assert_eq!(single.code, Some(4), "{}", single.stderr);
    let summary_path = dir.join("elements.json");
    let study = ribbon_outcome(&[
        "analyze",
        urdf,
        "--uncertainty",
        sidecar,
        "--summary",
        summary_path.to_str().unwrap(),
    ]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    assert!(
        study.stderr.contains("scanned on a grid of true runs"),
        "{}",
        study.stderr
    );
    let ours = summary(&summary_path);
    let elements = &ours["stats"]["elements"];
    assert_eq!(elements["stop"], "trusted");
    let scanned: Vec<&Value> = elements["elements"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e.get("scan_grid").is_some())
        .collect();
    assert!(!scanned.is_empty(), "no scanned leaf: {elements}");
    for leaf in scanned {
        assert_eq!(leaf["leaf"], true);
        assert_eq!(leaf["order"], 0);
        // The grid's runs plus its half steps and bisections.
        assert!(leaf["check_runs"].as_u64().unwrap() > 8, "{leaf}");
    }
    assert_contains_dense_scan(urdf, Some(sidecar), &ours, &dir, "2001");
}

#[test]
fn elements_are_the_same_at_one_and_two_threads() {
    let (urdf, dir) = planted_kink("threads");
    assert_same_at_one_and_two_threads(urdf.to_str().unwrap(), &dir);
}

/// `analyze` of `urdf` (its sidecar beside it) exits 0 and writes the same (masked) summary at one
/// and two threads.
fn assert_same_at_one_and_two_threads(urdf: &str, dir: &Path) {
    let run = |threads: &str| {
        let file = dir.join(format!("threads-{threads}.json"));
        let outcome = ribbon_outcome(&[
            "analyze",
            urdf,
            "--threads",
            threads,
            "--summary",
            file.to_str().unwrap(),
        ]);
        assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
        masked_summary_file(&file)
    };
    assert_eq!(run("1"), run("2"));
}

#[test]
fn a_study_the_first_check_trusts_makes_no_element() {
    let dir = fresh_test_scratch_dir("elements", "trusted");
    let summary_path = dir.join("dp.json");
    let outcome = ribbon_outcome(&[
        "analyze",
        "robots/double_pendulum/double_pendulum.urdf",
        "--duration",
        "0.2",
        "--summary",
        summary_path.to_str().unwrap(),
    ]);
    assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
    let study = summary(&summary_path);
    assert!(
        study["stats"].get("elements").is_none(),
        "{}",
        study["stats"]
    );
    assert!(!outcome.stdout.contains("elements:"), "{}", outcome.stdout);
}

#[test]
fn elements_are_refused_for_methods_they_cannot_split() {
    let outcome = ribbon_outcome(&[
        "analyze",
        "robots/double_pendulum/double_pendulum.urdf",
        "--method",
        "monte-carlo",
        "--elements",
        "on",
    ]);
    assert_eq!(outcome.code, Some(2), "{}", outcome.stderr);
    assert!(outcome.stderr.contains("--elements"), "{}", outcome.stderr);
    let outcome = ribbon_outcome(&[
        "analyze",
        "robots/double_pendulum/double_pendulum.urdf",
        "--elements",
        "sometimes",
    ]);
    assert_eq!(outcome.code, Some(2), "{}", outcome.stderr);
    assert!(outcome.stderr.contains("auto"), "{}", outcome.stderr);
}

/// Element rounds are stages of a plan (docs/distributed.md §7): `plan`, `run` and `merge` of
/// the planted kink ask for the round's stage (exit 3, its stage plan beside the blocks), run it
/// in shards like any stage, and merge into the bytes `analyze` writes.
#[test]
fn plan_run_and_merge_of_elements_are_the_bytes_of_analyze() {
    let (urdf, dir) = planted_kink("shards");
    assert_plan_run_merge_is_analyze(urdf.to_str().unwrap(), &dir);
}

/// A refined scan (docs/method.md §12, "Refined scans": the spring bar over eleven decades of
/// mass, whose stalled leaf's scan is refined cell by cell) is the same at one and two threads and
/// through `plan`/`run`/`merge`: its refinement rounds run where the study runs, after the stage
/// of its grid.
#[test]
fn a_refined_scan_is_the_same_at_one_and_two_threads_and_through_shards() {
    let dir = fresh_test_scratch_dir("elements", "refined_scan");
    let urdf = dir.join("spring.urdf");
    std::fs::write(&urdf, SPRING_URDF).unwrap();
    std::fs::write(dir.join("spring.uncertainty.toml"), NINE_DECADE_SIDECAR).unwrap();
    let urdf = urdf.to_str().unwrap();
    assert_same_at_one_and_two_threads(urdf, &dir);
    assert_plan_run_merge_is_analyze(urdf, &dir);
}

/// `plan`, `run` (two shards per stage) and `merge` of the study `urdf` (its sidecar beside it),
/// stage after stage, write the CSV and (masked) summary `analyze` writes; at least one stage is
/// a round of elements.
fn assert_plan_run_merge_is_analyze(urdf: &str, dir: &Path) {
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let merges = plan_run_merge_in_two_shards(dir, &[urdf], 10);
    let (last, stages) = merges.split_last().unwrap();
    assert_eq!(last.code, Some(0), "{}", last.stderr);
    for stage in stages {
        assert!(
            stage.stdout.contains("a round of elements"),
            "{}",
            stage.stdout
        );
    }
    assert!(
        !stages.is_empty(),
        "the kink needs at least one round of elements"
    );
    let analyzed = ribbon_outcome(&[
        "analyze",
        urdf,
        "--summary",
        &path("analyze.json"),
        "--csv",
        &path("analyze.csv"),
    ]);
    assert_eq!(analyzed.code, Some(0), "{}", analyzed.stderr);
    assert!(
        std::fs::read(path("merge.csv")).unwrap() == std::fs::read(path("analyze.csv")).unwrap(),
        "merge's CSV differs from analyze's"
    );
    assert_eq!(
        masked_summary_file(&dir.join("merge.json")),
        masked_summary_file(&dir.join("analyze.json"))
    );
}

/// The planted kink with a second parameter, the bar's centre of mass along it ±10 %: a box of
/// d = 2, so the children nest in the first surrogate's 5 × 5 grid (docs/method.md §12, "Nested
/// elements"). Halved along the mass, each child keeps the parent's 5 nodes along the other
/// dimension and 3 along the mass (the middle one on the face the halves share), so it runs 10 new
/// points and reuses 15; the study makes no other run, contains an 81 × 81 scan and is the same
/// through `plan`/`run`/`merge` (the parent's kept runs come from the first stage's blocks there).
/// Measured when written: 70 runs, two leaves, trusted, 2.3 % wider than the scan, missing none.
#[test]
fn a_two_parameter_kink_nests_its_children_in_the_first_grid() {
    let dir = fresh_test_scratch_dir("elements", "nested");
    let urdf = dir.join("stop.urdf");
    std::fs::write(&urdf, URDF).unwrap();
    let sidecar = SIDECAR.replace(
        "\"link.bar.mass\" = [0.5, 1.5]\n",
        "\"link.bar.mass\" = [0.5, 1.5]\n\"link.bar.com.x\" = [0.45, 0.55]\n",
    );
    assert_ne!(sidecar, SIDECAR);
    let sidecar_path = dir.join("stop.uncertainty.toml");
    std::fs::write(&sidecar_path, sidecar).unwrap();
    let urdf = urdf.to_str().unwrap();
    let summary_path = dir.join("nested.json");
    let study = ribbon_outcome(&["analyze", urdf, "--summary", summary_path.to_str().unwrap()]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    let ours = summary(&summary_path);
    let elements = &ours["stats"]["elements"];
    assert_eq!(elements["stop"], "trusted", "{elements}");
    let list = elements["elements"].as_array().unwrap();
    assert!(list.len() > 1, "{elements}");
    let count = |e: &Value, key: &str| e[key].as_u64().unwrap_or_else(|| panic!("{key}: {e}"));
    let mut runs = 0;
    for (k, element) in list.iter().enumerate() {
        if k > 0 && element["depth"] == 1 {
            assert_eq!(
                (count(element, "design_runs"), count(element, "reused_runs")),
                (10, 15),
                "{element}"
            );
        }
        runs += count(element, "design_runs") + count(element, "check_runs");
    }
    // Every run the study counts is a design's new run or a check's: none made twice.
    assert_eq!(runs, ours["samples"].as_u64().unwrap(), "{elements}");
    assert_contains_dense_scan(
        urdf,
        Some(sidecar_path.to_str().unwrap()),
        &ours,
        &dir,
        "81",
    );
    assert_plan_run_merge_is_analyze(urdf, &dir);
}

/// `robots/vehicle` (d = 4, wheels over a bump): one surrogate misses the wheels' ground forces,
/// the elements make it trusted within the default `--max-runs` (3 000), and the union contains a
/// 3⁴ scan (every corner, face middle and the centre) and is at most 10 % of the width wider. The
/// rear wheels' ground force is trusted by the first check, whose runs go to each output's widest
/// records; its first surrogate overshoots the rear landing (2 000 N where true runs give 1 480 N
/// at t = 0.74 s) until the overshoot check runs there and the output gets elements too.
#[test]
fn the_vehicle_is_trusted_within_the_default_budget_and_close_to_a_corner_scan() {
    let dir = fresh_test_scratch_dir("elements", "vehicle");
    let urdf = common::manifest("robots/vehicle/vehicle.urdf");
    let urdf = urdf.to_str().unwrap();
    let summary_path = dir.join("vehicle.json");
    let study = ribbon_outcome(&["analyze", urdf, "--summary", summary_path.to_str().unwrap()]);
    assert_eq!(study.code, Some(0), "{}", study.stderr);
    let ours = summary(&summary_path);
    let runs = ours["samples"].as_u64().unwrap();
    assert!(runs <= 3000, "{runs} runs");
    let elements = &ours["stats"]["elements"];
    assert_eq!(elements["stop"], "trusted", "{elements}");
    let outputs: Vec<&str> = elements["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o.as_str().unwrap())
        .collect();
    assert!(
        outputs.contains(&"contact.wheel_rl.ground.normal"),
        "the rear wheels' overshoot was not checked: elements for {outputs:?}"
    );
    assert_contains_scan(urdf, None, &ours, &dir, "3", VEHICLE_MAX_WIDER_THAN_SCAN);
}

/// An untrusted study in many dimensions (our ur5 falling limp for 0.5 s, every link's mass,
/// scale and centre of mass and every joint origin's place and angles uncertain: d = 72) plans
/// its elements without building the designs that do not fit: a fresh sparse grid of total degree
/// 4 in 72 dimensions has 1 282 975 points, and building each child's to learn that it exceeds the
/// budget took 2.45 GB and four times the study's wall (measured with the count skipped; 36 MiB
/// with it). Peak memory is what the summary reports, not a time.
#[test]
fn elements_in_many_dimensions_are_planned_without_building_designs_that_cannot_fit() {
    let dir = fresh_test_scratch_dir("elements", "many_dimensions");
    let sidecar = dir.join("limp.uncertainty.toml");
    std::fs::write(
        &sidecar,
        "[parameters]\n\"link.*.mass\" = { rel = 0.03 }\n\"link.*.com.*\" = { abs = 0.002 }\n\
         \"link.*.scale\" = { rel = 0.05 }\n\"joint.*.origin.*\" = { abs = 0.0005 }\n\
         [scene]\nduration = 0.5\neffects = [\"gravity\"]\n[outputs]\njoints = \"all\"\n",
    )
    .unwrap();
    let summary_path = dir.join("summary.json");
    let outcome = ribbon_outcome(&[
        "analyze",
        "robots/ur5/ur5.urdf",
        "--uncertainty",
        sidecar.to_str().unwrap(),
        "--summary",
        summary_path.to_str().unwrap(),
    ]);
    assert_eq!(
        outcome.code,
        Some(i32::from(ribbon::UNTRUSTED_EXIT_CODE)),
        "{}",
        outcome.stderr
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(&summary_path).unwrap()).unwrap();
    let stats = &summary["stats"];
    // The first check failed, so the elements were planned (none fits the budget here) and the
    // extremes refined.
    assert!(stats.get("refinement").is_some(), "{stats}");
    let peak_mib = stats["peak_memory_bytes"].as_f64().unwrap() / (1024.0 * 1024.0);
    assert!(
        peak_mib < 500.0,
        "peak memory {peak_mib:.0} MiB: a design that cannot fit was built"
    );
}
