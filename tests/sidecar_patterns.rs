//! End-to-end: `[parameters]` patterns, shared groups and `link.NAME.scale` through the binary —
//! `ribbon params --uncertainty` (the expanded box), `dynamics --set …scale`, the summary JSON of
//! `analyze`, and bad input (clear errors or notes naming the key, exit 2 for errors).

mod common;

use common::{ribbon_outcome, Outcome};

use serde_json::Value;
use std::path::PathBuf;

fn json(outcome: &Outcome) -> Value {
    assert_eq!(outcome.code, Some(0), "stderr: {}", outcome.stderr);
    serde_json::from_str(&outcome.stdout).expect("valid JSON on stdout")
}

/// Writes a file into a fresh directory under target/ and returns its path as a string.
fn temp_file(name: &str, text: &str) -> String {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("sidecar_patterns");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write temp file");
    path.display().to_string()
}

fn assert_input_error(outcome: &Outcome, fragments: &[&str]) {
    assert_eq!(
        outcome.code,
        Some(2),
        "exit code; stderr: {}",
        outcome.stderr
    );
    assert!(outcome.stdout.is_empty(), "stdout: {}", outcome.stdout);
    for fragment in fragments {
        assert!(
            outcome.stderr.contains(fragment),
            "expected '{fragment}' in: {}",
            outcome.stderr
        );
    }
}

const UR5: &str = "robots/ur5/ur5.urdf";
const ALL_VALUES: &str = "robots/ur5/ur5.all-values.uncertainty.toml";

#[test]
fn the_shipped_all_values_sidecar_expands_to_72_dimensions() {
    let box_json = json(&ribbon_outcome(&[
        "params",
        UR5,
        "--uncertainty",
        ALL_VALUES,
        "--json",
    ]));
    assert_eq!(box_json["robot"], "ur5");
    assert_eq!(box_json["d"], 72);
    let dimensions = box_json["dimensions"].as_array().unwrap();
    assert_eq!(dimensions.len(), 72);
    let from = |source: &str| dimensions.iter().filter(|d| d["source"] == source).count();
    // 6 moving links (the payload overrides one mass and one COM coordinate), 7 joints.
    assert_eq!(from("link.*.mass"), 5);
    assert_eq!(from("link.*.com.*"), 17);
    assert_eq!(from("link.*.scale"), 6);
    assert_eq!(from("joint.*.origin.*"), 21);
    for angle in ["roll", "pitch", "yaw"] {
        assert_eq!(from(&format!("joint.*.origin.{angle}")), 7);
    }
    assert_eq!(from("link.wrist_3_link.mass"), 1);
    assert_eq!(from("link.wrist_3_link.com.z"), 1);
    for d in dimensions {
        let (lower, nominal, upper) = (
            d["lower"].as_f64().unwrap(),
            d["nominal"].as_f64().unwrap(),
            d["upper"].as_f64().unwrap(),
        );
        assert!(lower < upper && lower <= nominal && nominal <= upper, "{d}");
        assert_eq!(d["kind"], "path", "{d}");
        let name = d["name"].as_str().unwrap();
        let unit = d["unit"].as_str().unwrap();
        let expected_unit = if name.ends_with(".mass") {
            "kg"
        } else if name.ends_with(".scale") {
            ""
        } else if name.ends_with("roll") || name.ends_with("pitch") || name.ends_with("yaw") {
            "rad"
        } else {
            "m"
        };
        assert_eq!(unit, expected_unit, "{d}");
    }
    // The payload bounds are the shipped sidecar's.
    let payload = dimensions
        .iter()
        .find(|d| d["name"] == "link.wrist_3_link.mass")
        .unwrap();
    assert_eq!(
        (payload["lower"].as_f64(), payload["upper"].as_f64()),
        (Some(0.15), Some(1.2))
    );
    // No inertia value is a dimension, so the box check has no link to visit.
    assert_eq!(box_json["box_check"]["links"], 0);
    let notes: Vec<&str> = box_json["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap())
        .collect();
    assert_eq!(notes.len(), 8, "{notes:#?}");
    assert!(notes.iter().any(|n| n.contains(
        "[parameters] \"link.wrist_3_link.mass\" overrides the match of [parameters] \"link.*.mass\""
    )));
    // The readable form says d first and lists the notes after the dimensions.
    let table = ribbon_outcome(&["params", UR5, "--uncertainty", ALL_VALUES]);
    assert_eq!(table.code, Some(0), "{}", table.stderr);
    assert!(
        table.stdout.starts_with(&format!(
            "d = 72 dimensions of robot 'ur5' from {ALL_VALUES}\n"
        )),
        "{}",
        table.stdout
    );
    assert_eq!(table.stdout.matches("\nnote: ").count(), 8);
}

#[test]
fn params_without_uncertainty_lists_scale_like_any_value() {
    let listed = json(&ribbon_outcome(&["params", UR5, "--json"]));
    let rows = listed.as_array().unwrap();
    let scale = rows
        .iter()
        .find(|r| r["path"] == "link.forearm_link.scale")
        .expect("scale listed");
    assert_eq!(
        (scale["nominal"].as_f64(), scale["unit"].as_str()),
        (Some(1.0), Some(""))
    );
    // 8 links × 11 values, 6 moving joints × 11, 1 fixed joint × 6, gravity 3.
    assert_eq!(rows.len(), 8 * 11 + 6 * 11 + 6 + 3);
}

#[test]
fn scale_on_dynamics_equals_the_same_change_through_mass_and_inertia() {
    // forearm_link and wrist_2_link of our ur5 (values from robots/ur5/ur5.urdf).
    let links: [(&str, f64, [f64; 6], f64); 2] = [
        (
            "forearm_link",
            2.33,
            [0.0029125, 0.0, 0.0, 0.031330745469, 0.0, 0.031330745469],
            1.05,
        ),
        (
            "wrist_2_link",
            1.219,
            [0.0019504, 0.0, 0.0, 0.0019504, 0.0, 0.0009752],
            0.93,
        ),
    ];
    let state = [
        "--q=0.3,-1.1,0.9,-0.4,0.7,0.2",
        "--v=0.5,-0.2,0.1,0.9,-0.6,0.3",
        "--tau=1,-2,3,0.5,-0.25,0.1",
        "--qdd=0.2,0.1,-0.3,0.4,-0.5,0.6",
    ];
    let mut scaled: Vec<String> = vec!["dynamics".into(), UR5.into(), "--json".into()];
    let mut explicit = scaled.clone();
    for arg in state {
        scaled.push(arg.into());
        explicit.push(arg.into());
    }
    const FIELDS: [&str; 6] = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"];
    for (link, mass, inertia, factor) in links {
        scaled.push(format!("--set=link.{link}.scale={factor}"));
        // `{}` prints the shortest decimal that reads back to the same f64.
        explicit.push(format!("--set=link.{link}.mass={}", mass * factor));
        for (field, value) in FIELDS.iter().zip(inertia) {
            explicit.push(format!(
                "--set=link.{link}.inertia.{field}={}",
                value * factor
            ));
        }
    }
    let run = |args: &[String]| {
        json(&ribbon_outcome(
            &args.iter().map(String::as_str).collect::<Vec<_>>(),
        ))
    };
    let (a, b) = (run(&scaled), run(&explicit));
    for key in ["mass_matrix", "bias", "qdd", "tau", "frames"] {
        assert!(!a[key].is_null(), "{key} missing");
        // Bitwise: the same products reach the same body inertias.
        assert_eq!(
            a[key], b[key],
            "{key} differs between scale and mass + inertia"
        );
    }
    // And the scale changed something.
    let nominal = run(&[
        "dynamics", UR5, "--json", state[0], state[1], state[2], state[3],
    ]
    .map(String::from));
    assert_ne!(a["mass_matrix"], nominal["mass_matrix"]);
    // A scale ≤ 0 is refused naming the flag's path.
    let out = ribbon_outcome(&["dynamics", UR5, "--set=link.forearm_link.scale=0"]);
    assert_input_error(&out, &["link.forearm_link.scale", "a scale must be > 0"]);
}

#[test]
fn the_analyze_summary_lists_every_dimension_with_source_and_unit() {
    let sidecar = temp_file(
        "dp_patterns.toml",
        r#"[parameters]
"link.*.mass" = { rel = 0.05, shared = true }
"joint.*.origin.x" = { abs = 0.001 }
[outputs]
frames = ["tip"]
"#,
    );
    let summary = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("sidecar_patterns")
        .join("dp_summary.json");
    let out = ribbon_outcome(&[
        "analyze",
        "robots/double_pendulum/double_pendulum.urdf",
        "--uncertainty",
        &sidecar,
        "--duration",
        "0.02",
        "--order",
        "1",
        "--summary",
        summary.to_str().unwrap(),
    ]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let parameters = summary["parameters"].as_array().unwrap();
    let box_json = json(&ribbon_outcome(&[
        "params",
        "robots/double_pendulum/double_pendulum.urdf",
        "--uncertainty",
        &sidecar,
        "--json",
    ]));
    let dimensions = box_json["dimensions"].as_array().unwrap();
    assert_eq!(parameters.len(), dimensions.len());
    assert!(parameters.len() >= 2, "{parameters:?}");
    assert_eq!(parameters[0]["name"], "link.*.mass");
    assert_eq!(
        (
            parameters[0]["unit"].as_str(),
            parameters[0]["nominal"].as_f64()
        ),
        (Some(""), Some(1.0))
    );
    for (p, d) in parameters.iter().zip(dimensions) {
        for key in ["name", "lower", "upper", "nominal", "source", "unit"] {
            assert_eq!(p[key], d[key], "{key} of {p}");
        }
    }
    assert!(parameters[1]["source"] == "joint.*.origin.x" && parameters[1]["unit"] == "m");
}

#[test]
fn bad_patterns_are_named_errors() {
    let cases: [(&str, &str, &[&str]); 4] = [
        (
            "nothing.toml",
            "[parameters]\n\"link.*.mas\" = { rel = 0.05 }\n",
            &[
                "nothing.toml:2: [parameters] \"link.*.mas\": the pattern matches no parameter of robot 'ur5'",
                "did you mean 'link.*.mass'?",
            ],
        ),
        (
            "mixed.toml",
            "[parameters]\n\"joint.*.origin.*\" = { abs = 0.0005, shared = true }\n",
            &[
                "mixed.toml:2: [parameters] \"joint.*.origin.*\" = { abs = 0.0005, shared = true }",
                "different units (m: joint.shoulder_pan_joint.origin.x; rad: joint.shoulder_pan_joint.origin.roll)",
            ],
        ),
        (
            "bounds.toml",
            "[parameters]\n\"link.*.mass\" = [1, 2]\n",
            &["[parameters] \"link.*.mass\" = [1, 2]", "one [lower, upper] would have to contain each of them"],
        ),
        (
            "shared.toml",
            "[parameters]\n\"link.forearm_link.mass\" = { rel = 0.1, shared = true }\n",
            &["nothing to share"],
        ),
    ];
    for (name, text, fragments) in cases {
        let path = temp_file(name, text);
        for command in ["params", "analyze"] {
            let out = ribbon_outcome(&[command, UR5, "--uncertainty", &path]);
            assert_input_error(&out, fragments);
        }
    }
}

#[test]
fn a_pattern_and_a_bind_on_the_same_path_give_a_note() {
    let path = temp_file(
        "bind.toml",
        r#"[parameters]
"joint.*.origin.x" = { abs = 0.0005 }
l = [0.42, 0.43]
[bind]
"joint.elbow_joint.origin.x" = "-l"
"#,
    );
    let box_json = json(&ribbon_outcome(&[
        "params",
        UR5,
        "--uncertainty",
        &path,
        "--json",
    ]));
    assert_eq!(box_json["d"], 7, "6 of the 7 origins, and the symbol");
    let notes = box_json["notes"].to_string();
    assert!(
        notes.contains("[bind] \\\"joint.elbow_joint.origin.x\\\" is taken out of the matches of [parameters] \\\"joint.*.origin.x\\\""),
        "{notes}"
    );
    assert_eq!(
        box_json["bindings"][0]["path"],
        "joint.elbow_joint.origin.x"
    );
}

#[test]
fn a_rel_pattern_on_a_robot_with_massless_links_gives_a_counted_note() {
    let urdf = temp_file(
        "massless.urdf",
        r#"<robot name="m"><link name="base"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="b"/>
  <link name="c"><inertial><mass value="2"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="ja" type="continuous"><parent link="base"/><child link="a"/></joint>
  <joint name="jb" type="continuous"><parent link="a"/><child link="b"/></joint>
  <joint name="jc" type="continuous"><parent link="b"/><child link="c"/></joint></robot>"#,
    );
    let sidecar = temp_file(
        "massless.toml",
        "[parameters]\n\"link.*.mass\" = { rel = 0.05 }\n",
    );
    let out = ribbon_outcome(&["params", &urdf, "--uncertainty", &sidecar]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    assert!(
        out.stdout.contains("link.a.mass") && out.stdout.contains("link.c.mass"),
        "{}",
        out.stdout
    );
    assert!(
        out.stdout.contains(
            "note: ") && out.stdout.contains("[parameters] \"link.*.mass\": 2 links are not matched because they carry no dynamics: base (fixed to the world), b (no <inertial>)"
        ),
        "{}",
        out.stdout
    );
}

/// Issue 41: an error about one `[parameters]` entry names the sidecar's line of its key
/// (`FILE:LINE: [parameters] "KEY" …`), counted through comments and blank lines, for a key that
/// is no path, an interval that is not one, and a path whose URDF value the interval leaves out.
#[test]
fn errors_about_a_parameters_entry_name_its_line() {
    let cases: [(&str, &str, &str); 3] = [
        (
            "unknown_key.toml",
            "# a comment\n[parameters]\n\"link.forearm_link.mass\" = { rel = 0.05 }\n\"link.forearm_link.mas\" = { rel = 0.05 }\n",
            "unknown_key.toml:4: [parameters] \"link.forearm_link.mas\": ",
        ),
        (
            "bad_interval.toml",
            "[parameters]\n\n\"link.forearm_link.mass\" = [3, 1]\n",
            "bad_interval.toml:3: [parameters] \"link.forearm_link.mass\" = [3, 1]: ",
        ),
        (
            "outside.toml",
            "[parameters]\n\"link.forearm_link.mass\" = { rel = 0.05 }\n\"link.upper_arm_link.mass\" = [100.0, 200.0]\n",
            "outside.toml:3: [parameters] \"link.upper_arm_link.mass\" = [100, 200] does not contain",
        ),
    ];
    for (name, text, fragment) in cases {
        let path = temp_file(name, text);
        for command in ["params", "analyze"] {
            let out = ribbon_outcome(&[command, UR5, "--uncertainty", &path]);
            assert_input_error(&out, &[fragment]);
        }
    }
}
