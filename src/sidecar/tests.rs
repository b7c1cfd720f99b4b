//! Tests of the expansion of `[parameters]` on the shipped ur5 and small inline robots.

use super::*;
use crate::model::{parse_description, LoadOptions, Model};
use crate::params::ParamTarget;

const FILE: &str = "ur5.test.toml";

fn ur5() -> Model {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5/ur5.urdf");
    Model::from_urdf_file(&path, LoadOptions::default()).unwrap()
}

fn expand(model: &Model, text: &str) -> Result<ExpandedParameters, SidecarError> {
    let file = parse_sidecar(text).unwrap();
    expand_parameters(
        &file.parameters,
        &file.bind,
        model,
        &crate::environment::Environment::default(),
        FILE,
    )
}

fn names(expanded: &ExpandedParameters) -> Vec<&str> {
    expanded.entries.iter().map(ParameterEntry::name).collect()
}

const MOVING_LINKS: [&str; 6] = [
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
];

#[test]
fn patterns_expand_in_place_in_registry_order() {
    let m = ur5();
    let e = expand(
        &m,
        r#"[parameters]
        "joint.*.origin.z" = { abs = 0.0005 }
        l1 = [0.9, 1.1]
        "link.*.mass" = { rel = 0.03 }
        "link.*.com.*" = { abs = 0.002 }"#,
    )
    .unwrap();
    let names = names(&e);
    // 7 joints (6 moving + the fixed tool0 joint), the symbol, 6 masses, 18 COM coordinates.
    assert_eq!(names.len(), 7 + 1 + 6 + 18, "{names:?}");
    assert_eq!(names[0], "joint.shoulder_pan_joint.origin.z");
    assert_eq!(names[6], "joint.wrist_3_link-tool0_fixed_joint.origin.z");
    assert_eq!(names[7], "l1");
    let masses: Vec<String> = MOVING_LINKS
        .iter()
        .map(|l| format!("link.{l}.mass"))
        .collect();
    assert_eq!(&names[8..14], masses);
    // COM: link by link, x y z within a link (registry order).
    assert_eq!(
        &names[14..17],
        [
            "link.shoulder_link.com.x",
            "link.shoulder_link.com.y",
            "link.shoulder_link.com.z"
        ]
    );
    assert_eq!(names[31], "link.wrist_3_link.com.z");
    // Sources: the pattern key for matches, the key itself otherwise.
    assert_eq!(e.entries[8].source, "link.*.mass");
    assert_eq!(e.entries[7].source, "l1");
    assert!(matches!(
        e.entries[8].kind,
        EntryKind::Path {
            target: ParamTarget::LinkMass(1),
            from_pattern: true,
            ..
        }
    ));
    // base_link (fixed to the world) and tool0 (no <inertial>) are not matched, and say so.
    let notes = e.notes.join("\n");
    for pattern in ["link.*.mass", "link.*.com.*"] {
        assert!(
            notes.contains(&format!(
                "[parameters] \"{pattern}\": 2 links are not matched because they carry no dynamics: base_link (fixed to the world), tool0 (no <inertial>)"
            )),
            "{notes}"
        );
    }
    assert_eq!(e.notes.len(), 2, "{notes}");
}

#[test]
fn an_explicit_key_overrides_a_pattern_wherever_it_appears() {
    let m = ur5();
    let e = expand(
        &m,
        r#"[parameters]
        "link.wrist_3_link.mass" = [0.15, 1.2]
        "link.*.mass" = { rel = 0.03 }
        "link.forearm_link.mass" = { rel = 0.1 }"#,
    )
    .unwrap();
    let names = names(&e);
    assert_eq!(
        names,
        [
            "link.wrist_3_link.mass",
            "link.shoulder_link.mass",
            "link.upper_arm_link.mass",
            "link.wrist_1_link.mass",
            "link.wrist_2_link.mass",
            "link.forearm_link.mass",
        ]
    );
    assert_eq!(e.entries[0].interval.form, IntervalForm::Bounds(0.15, 1.2));
    assert_eq!(e.entries[5].interval.form, IntervalForm::Relative(0.1));
    assert_eq!(e.entries[5].source, "link.forearm_link.mass");
    let notes = e.notes.join("\n");
    for key in ["link.wrist_3_link.mass", "link.forearm_link.mass"] {
        assert!(
            notes.contains(&format!(
                "[parameters] \"{key}\" overrides the match of [parameters] \"link.*.mass\""
            )),
            "{notes}"
        );
    }
}

#[test]
fn a_bound_path_is_taken_out_of_a_pattern() {
    let m = ur5();
    let e = expand(
        &m,
        r#"[parameters]
        "joint.*.origin.x" = { abs = 0.0005 }
        l1 = [0.42, 0.43]
        [bind]
        "joint.elbow_joint.origin.x" = "-l1""#,
    )
    .unwrap();
    let names = names(&e);
    assert_eq!(names.len(), 7, "{names:?}");
    assert!(!names.contains(&"joint.elbow_joint.origin.x"), "{names:?}");
    assert!(
        e.notes.iter().any(|n| n.contains(
            "[bind] \"joint.elbow_joint.origin.x\" is taken out of the matches of [parameters] \"joint.*.origin.x\""
        )),
        "{:?}",
        e.notes
    );
}

#[test]
fn of_two_patterns_the_later_wins() {
    let m = ur5();
    let e = expand(
        &m,
        r#"[parameters]
        "joint.*.origin.*" = { abs = 0.0005 }
        "joint.*.origin.roll" = { abs = 0.001 }"#,
    )
    .unwrap();
    assert_eq!(e.entries.len(), 42);
    let (first, second) = e.entries.split_at(35);
    assert!(first
        .iter()
        .all(|x| x.source == "joint.*.origin.*" && !x.name().ends_with(".roll")));
    assert!(second
        .iter()
        .all(|x| x.source == "joint.*.origin.roll" && x.name().ends_with(".roll")));
    let notes = e.notes.join("\n");
    assert!(
        notes.contains(
            "[parameters] \"joint.*.origin.roll\" takes 7 matches from the earlier [parameters] \"joint.*.origin.*\" (of two patterns, the later one in the file wins): joint.shoulder_pan_joint.origin.roll"
        ),
        "{notes}"
    );
}

#[test]
fn rel_patterns_skip_zero_values_with_one_note() {
    let m = ur5();
    let e = expand(&m, "[parameters]\n\"link.*.com.*\" = { rel = 0.1 }\n").unwrap();
    // Zero COM coordinates: shoulder x, upper arm y, forearm y, wrist 1 x, wrist 2 x, wrist 3 x y.
    assert_eq!(e.entries.len(), 18 - 7);
    let zero_notes: Vec<&String> = e
        .notes
        .iter()
        .filter(|n| n.contains("0 in the URDF"))
        .collect();
    assert_eq!(zero_notes.len(), 1, "{:?}", e.notes);
    assert!(
        zero_notes[0].contains("[parameters] \"link.*.com.*\" = { rel = 0.1 }: 7 matches are 0 in the URDF and skipped")
            && zero_notes[0].contains("link.shoulder_link.com.x")
            && zero_notes[0].contains("and 1 more"),
        "{}",
        zero_notes[0]
    );
}

#[test]
fn a_pattern_matching_nothing_names_the_key_and_the_shapes() {
    let m = ur5();
    let message = expand(&m, "[parameters]\n\"link.*.mas\" = { rel = 0.1 }\n")
        .unwrap_err()
        .to_string();
    assert!(
        message.starts_with(FILE)
            && message.contains("[parameters] \"link.*.mas\": the pattern matches no parameter of robot 'ur5'; did you mean 'link.*.mass'?")
            && message.contains("link.*.scale"),
        "{message}"
    );
    let message = expand(
        &m,
        "[parameters]\n\"joint.elbw_joint.origin.*\" = { abs = 0.001 }\n",
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.contains("did you mean 'joint.elbow_joint.origin.*'?"),
        "{message}"
    );
    let message = expand(&m, "[parameters]\n\"link.wrist_*.mass\" = { abs = 0.1 }\n")
        .unwrap_err()
        .to_string();
    assert!(message.contains("one whole dotted segment"), "{message}");
}

#[test]
fn a_pattern_left_with_nothing_is_an_error() {
    let m = ur5();
    let message = expand(&m, "[parameters]\n\"link.tool0.com.*\" = { rel = 0.1 }\n")
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("[parameters] \"link.tool0.com.*\": the pattern matches 3 paths but gives no dimension: 3 are 0 with rel"),
        "{message}"
    );
    // A literal NAME is not skipped for lack of mass: that is how a payload is declared.
    let e = expand(&m, "[parameters]\n\"link.tool0.com.*\" = { abs = 0.01 }\n").unwrap();
    assert_eq!(e.entries.len(), 3);
    // The ur5 has inertials: no kinematic-only advice there.
    let message = expand(&m, "[parameters]\n\"link.tool0.com.*\" = { rel = 0.1 }\n")
        .unwrap_err()
        .to_string();
    assert!(!message.contains("kinematic-only"), "{message}");
}

#[test]
fn a_kinematic_only_robot_is_told_to_add_inertials() {
    // Two moving links without <inertial>, as ROS-Industrial support packages ship them.
    let text = r#"<robot name="k"><link name="base"/><link name="a"/><link name="b"/>
      <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
    let m = Model::from_description(
        parse_description(text, "k.urdf").unwrap(),
        LoadOptions::default(),
        "k.urdf",
    )
    .unwrap();
    let message = expand(&m, "[parameters]\n\"link.*.mass\" = { rel = 0.05 }\n")
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("gives no dimension: 3 are on links without dynamics")
            && message.contains("no moving link of this robot has an <inertial>")
            && message.contains("add <inertial> elements"),
        "{message}"
    );
}

#[test]
fn shared_groups_are_one_dimension_named_by_the_pattern() {
    let m = ur5();
    let e = expand(
        &m,
        r#"[parameters]
        "link.*.mass" = { rel = 0.05, shared = true }
        "joint.*.origin.z" = { abs = 0.0005, shared = true }"#,
    )
    .unwrap();
    assert_eq!(names(&e), ["link.*.mass", "joint.*.origin.z"]);
    let EntryKind::Group { members, unit } = &e.entries[0].kind else {
        panic!("not a group: {:?}", e.entries[0]);
    };
    assert_eq!((members.len(), *unit), (6, ""));
    let EntryKind::Group { members, unit } = &e.entries[1].kind else {
        panic!("not a group: {:?}", e.entries[1]);
    };
    assert_eq!((members.len(), *unit), (7, "m"));
}

#[test]
fn shared_abs_over_mixed_units_is_refused() {
    let m = ur5();
    let message = expand(
        &m,
        "[parameters]\n\"joint.*.origin.*\" = { abs = 0.0005, shared = true }\n",
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.contains("[parameters] \"joint.*.origin.*\" = { abs = 0.0005, shared = true }")
            && message.contains("different units (m: joint.shoulder_pan_joint.origin.x; rad: joint.shoulder_pan_joint.origin.roll)"),
        "{message}"
    );
    // A shared factor is unitless: mixed units are fine.
    let e = expand(
        &m,
        "[parameters]\n\"joint.*.origin.*\" = { rel = 0.01, shared = true }\n",
    )
    .unwrap();
    assert_eq!(e.entries.len(), 1);
}

#[test]
fn forms_that_do_not_fit_the_key_are_refused() {
    let m = ur5();
    for (line, expected) in [
        (
            "\"link.*.mass\" = [1, 2]",
            "a pattern's matches have different URDF values",
        ),
        (
            "\"link.forearm_link.mass\" = { rel = 0.1, shared = true }",
            "a single path or symbol has nothing to share",
        ),
        ("l1 = { abs = 0.1 }", "explicit bounds only"),
        ("sqrt = [1, 2]", "'sqrt' is the square-root function"),
        (
            "\"link.forarm_link.mass\" = [1, 3]",
            "did you mean 'link.forearm_link.mass'",
        ),
    ] {
        let message = expand(&m, &format!("[parameters]\n{line}\n"))
            .unwrap_err()
            .to_string();
        assert!(message.contains(expected), "{line}: {message}");
    }
}

#[test]
fn massless_links_are_counted_in_a_note() {
    // A chain whose middle link has no <inertial> and whose tip has mass 0.
    let text = r#"<robot name="m"><link name="base"/>
      <link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
      <link name="b"/>
      <link name="c"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
      <joint name="ja" type="continuous"><parent link="base"/><child link="a"/></joint>
      <joint name="jb" type="continuous"><parent link="a"/><child link="b"/></joint>
      <joint name="jc" type="continuous"><parent link="b"/><child link="c"/></joint></robot>"#;
    let m = Model::from_description(
        parse_description(text, "m.urdf").unwrap(),
        LoadOptions::default(),
        "m.urdf",
    )
    .unwrap();
    let e = expand(&m, "[parameters]\n\"link.*.mass\" = { rel = 0.1 }\n").unwrap();
    assert_eq!(names(&e), ["link.a.mass"]);
    assert_eq!(
        e.notes,
        [format!(
            "{FILE}: [parameters] \"link.*.mass\": 3 links are not matched because they carry no dynamics: base (fixed to the world), b (no <inertial>), c (mass 0)"
        )]
    );
    // With a floating base the root is a body and is matched when it has mass.
    let m = Model::from_description(
        parse_description(text, "m.urdf").unwrap(),
        LoadOptions {
            floating_base: true,
        },
        "m.urdf",
    );
    // The root has no <inertial> here, so it stays unmatched (for lack of mass).
    let e = expand(
        &m.unwrap(),
        "[parameters]\n\"link.*.mass\" = { rel = 0.1 }\n",
    )
    .unwrap();
    assert!(e.notes[0].contains("base (no <inertial>)"), "{:?}", e.notes);
}
