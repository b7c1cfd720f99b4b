//! The first study a new user runs on their own robot: `ribbon init ROBOT.urdf`, then `ribbon
//! analyze ROBOT.urdf`, on robots nobody here wrote (example-robot-data 5.0.0). The starter scene
//! (`src/starter.rs`: every link's mass ±5 % and centre of mass ±2 mm; the robot holding a pose
//! inside its limits on PD joint controllers under gravity, limits enforced) must give a study
//! the a-posteriori check trusts — exit 0 — whose joint envelopes stay inside the URDF limits.
//!
//! Measured when written (2 cores, shared): panda 3 000 runs, largest misfit 2.5e-4 of the width;
//! ur10 1 420 runs, 5.1e-4; solo12 (fixed base, legs in the air) 3 000 runs, 2.0e-4. Before the
//! starter scene, the same box on a limp fall from q = 0 left the panda's 9 of 9 outputs
//! untrusted with envelopes of 10⁴ rad (issue 38).

mod common;

use common::{example_robot_data_dir, fresh_test_scratch_dir, ribbon_outcome};
use ribbon::model::{LoadOptions, Model};
use serde_json::Value;

/// The robots tried, as paths under example-robot-data's `robots` directory.
const ROBOTS: [&str; 3] = [
    "panda_description/urdf/panda.urdf",
    "ur_description/urdf/ur10_robot.urdf",
    "solo_description/robots/solo12.urdf",
];

/// A held pose settles within this of the envelope's limits check: the penalty of a limit lets a
/// joint a little past it, and a held pose never goes near one (the controllers hold within
/// `starter::MAX_GRAVITY_SAG` = 0.02 rad of a pose at least 10 % of the range inside).
const INSIDE_LIMIT_TOLERANCE: f64 = 1e-9;

#[test]
fn the_starter_scene_of_public_robots_is_trusted_and_stays_inside_their_limits() {
    let robots = example_robot_data_dir();
    for robot in ROBOTS {
        let source = robots.join(robot);
        let name = source.file_stem().unwrap().to_string_lossy().to_string();
        let dir = fresh_test_scratch_dir("example_robot_data_starter", &name);
        let urdf = dir.join(source.file_name().unwrap());
        std::fs::copy(&source, &urdf).unwrap();
        let urdf_text = urdf.to_str().unwrap();

        let init = ribbon_outcome(&["init", urdf_text]);
        assert_eq!(init.code, Some(0), "{name}: {}", init.stderr);
        let summary_path = dir.join("summary.json");
        let study = ribbon_outcome(&[
            "analyze",
            urdf_text,
            "--summary",
            summary_path.to_str().unwrap(),
        ]);
        assert_eq!(
            study.code,
            Some(0),
            "{name}: not trusted:\n{}",
            study.stderr
        );
        let summary: Value =
            serde_json::from_str(&std::fs::read_to_string(&summary_path).unwrap()).unwrap();
        assert_eq!(summary["stats"]["check"]["trusted"], true, "{name}");

        let model = Model::from_urdf_file(&urdf, LoadOptions::default()).unwrap();
        let mut joints_seen = 0;
        for output in summary["outputs"].as_array().unwrap() {
            let output_name = output["name"].as_str().unwrap();
            let Some(joint_name) = output_name.strip_prefix("q.") else {
                continue;
            };
            let joint = model
                .description
                .joints
                .iter()
                .find(|j| j.name == joint_name)
                .unwrap_or_else(|| panic!("{name}: no joint {joint_name}"));
            let [lower, upper] = joint.limits;
            joints_seen += 1;
            if !(lower.is_finite() && upper.is_finite()) {
                continue;
            }
            let values = |key: &str| -> Vec<f64> {
                output[key]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect()
            };
            let lowest = values("lower").into_iter().fold(f64::INFINITY, f64::min);
            let highest = values("upper")
                .into_iter()
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(
                lowest >= lower - INSIDE_LIMIT_TOLERANCE && highest <= upper + INSIDE_LIMIT_TOLERANCE,
                "{name}: {joint_name}'s envelope [{lowest}, {highest}] leaves its limits [{lower}, {upper}]"
            );
        }
        assert!(joints_seen >= 6, "{name}: only {joints_seen} joint outputs");
    }
}
