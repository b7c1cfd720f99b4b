//! Unit tests of the URDF reader: the policy of the module documentation, case by case.

use super::*;

fn urdf(body: &str) -> String {
    format!("<?xml version=\"1.0\"?>\n<robot name=\"t\">\n{body}\n</robot>\n")
}

#[test]
fn malformed_xml_names_line() {
    let err = parse_description(
        "<robot name=\"x\">\n<link name=\"a\">\n</robot>",
        "bad.urdf",
    )
    .unwrap_err();
    let msg = err.to_string();
    assert!(msg.starts_with("bad.urdf:"), "{msg}");
    assert!(msg.contains("malformed XML"), "{msg}");
}

#[test]
fn texture_without_filename_is_accepted() {
    let text = urdf(
        "<link name=\"a\"><visual><geometry><box size=\"1 1 1\"/></geometry>\
         <material name=\"m\"><texture/></material></visual></link>",
    );
    let description = parse_description(&text, "t.urdf").unwrap();
    assert_eq!(description.links.len(), 1);
}

#[test]
fn missing_inertial_is_distinguished_from_zero() {
    let text = urdf(
        "<link name=\"a\"/>\n<link name=\"b\"><inertial><mass value=\"0\"/>\
         <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial></link>\n\
         <joint name=\"j\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint>",
    );
    let d = parse_description(&text, "t.urdf").unwrap();
    assert!(!d.links[0].has_inertial);
    assert!(d.links[1].has_inertial);
    assert_eq!(d.joints[0].line, 5);
}

#[test]
fn missing_link_suggests_closest() {
    let text = urdf(
        "<link name=\"base\"/><link name=\"arm\"/>\n\
         <joint name=\"j\" type=\"revolute\"><parent link=\"bas\"/><child link=\"arm\"/>\
         <limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>",
    );
    let msg = parse_description(&text, "t.urdf").unwrap_err().to_string();
    assert!(
        msg.contains("t.urdf:4: joint 'j' names parent link 'bas'"),
        "{msg}"
    );
    assert!(msg.contains("did you mean 'base'"), "{msg}");
}

#[test]
fn negative_mass_and_nan_are_refused() {
    let neg = urdf(
        "<link name=\"a\"><inertial><mass value=\"-1\"/>\
         <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>",
    );
    let msg = parse_description(&neg, "t.urdf").unwrap_err().to_string();
    assert!(msg.contains("negative mass -1 kg"), "{msg}");
    let nan = urdf(
        "<link name=\"a\"><inertial><mass value=\"NaN\"/>\
         <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>",
    );
    let msg = parse_description(&nan, "t.urdf").unwrap_err().to_string();
    assert!(
        msg.contains("non-finite value NaN in <mass value>"),
        "{msg}"
    );
}

#[test]
fn planar_joint_is_refused_clearly() {
    let text = urdf(
        "<link name=\"a\"/><link name=\"b\"/>\
         <joint name=\"p\" type=\"planar\"><parent link=\"a\"/><child link=\"b\"/></joint>",
    );
    let msg = parse_description(&text, "t.urdf").unwrap_err().to_string();
    assert!(msg.contains("joint 'p' is of type 'planar'"), "{msg}");
    assert!(msg.contains("does not support yet"), "{msg}");
}

const LIMIT: &str = "<limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>";
const INERTIAL: &str = "<inertial><mass value=\"1\"/>\
    <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial>";

/// Two links and one revolute joint whose body is `joint_body`, after a line of links.
fn arm(link_body: &str, joint_body: &str) -> String {
    urdf(&format!(
        "<link name=\"a\"/>\n<link name=\"b\">{INERTIAL}{link_body}</link>\n\
         <joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\n{joint_body}\n</joint>"
    ))
}

fn error(text: &str) -> String {
    parse_description(text, "t.urdf").unwrap_err().to_string()
}

fn notes(text: &str) -> Vec<String> {
    parse_description(text, "t.urdf")
        .unwrap_or_else(|e| panic!("should load: {e}"))
        .notes
}

#[test]
fn markup_without_dynamics_loads_with_notes_naming_the_line() {
    // A second <material> in one <visual>, a <material> without a name, an unknown shape, a mesh
    // scale of four numbers: urdf-rs refused all of these; Pinocchio loads them.
    let visual = "<visual><geometry><box size=\"1 1 1\"/></geometry>\
        <material name=\"m\"/><material name=\"n\"/></visual>\n\
        <visual><geometry><plane normal=\"0 0 1\"/></geometry><material><color rgba=\"1 0 0 1\"/></material></visual>\n\
        <collision><geometry><mesh filename=\"x.stl\" scale=\"1 1 1 1\"/></geometry></collision>";
    let found = notes(&arm(visual, LIMIT));
    let expect = [
        "t.urdf:4: link 'b' <visual>: a second <material> (line 4)",
        "t.urdf:5: link 'b' <visual>: unknown shape <plane> (line 5)",
        "t.urdf:5: link 'b' <visual>: <material> (line 5) has no name",
        "t.urdf:6: link 'b' <collision>: <mesh scale=\"1 1 1 1\"> (line 6) is not three numbers",
    ];
    for e in expect {
        assert!(found.iter().any(|n| n.starts_with(e)), "{e}\n{found:#?}");
    }
    assert_eq!(found.len(), expect.len(), "{found:#?}");
}

#[test]
fn whitespace_before_the_declaration_loads_with_a_note() {
    let text = format!("\n  \n{}", arm("", LIMIT));
    let d = parse_description(&text, "t.urdf").unwrap();
    assert_eq!(d.joints[0].line, 7, "line numbers are those of the file");
    assert!(
        d.notes[0].starts_with("t.urdf:3: whitespace before the XML declaration"),
        "{:?}",
        d.notes
    );
    // A comment before the declaration is refused, by Pinocchio too.
    let msg = error(&format!("<!-- c -->\n{}", arm("", LIMIT)));
    assert!(msg.starts_with("t.urdf:2:"), "{msg}");
}

#[test]
fn identical_repeats_load_with_a_note_and_conflicting_ones_name_both_lines() {
    let same = format!("<axis xyz=\"0 0 1\"/>{LIMIT}\n<axis xyz=\"0 0 1\"/>");
    let found = notes(&arm("", &same));
    assert!(
        found[0].starts_with("t.urdf:7: joint 'j' repeats <axis> identically (first at line 6)"),
        "{found:?}"
    );
    let different = format!("<axis xyz=\"0 0 1\"/>{LIMIT}\n<axis xyz=\"0 1 0\"/>");
    let msg = error(&arm("", &different));
    assert!(
        msg.starts_with(
            "t.urdf:7: joint 'j' has a second <axis> (line 7) that differs from the first (line 6)"
        ),
        "{msg}"
    );
    let inertial = error(&arm(
        "\n<inertial><mass value=\"2\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial>",
        LIMIT,
    ));
    assert!(
        inertial.contains(
            "link 'b' has a second <inertial> (line 5) that differs from the first (line 4)"
        ),
        "{inertial}"
    );
}

#[test]
fn every_value_error_names_line_element_and_text() {
    let cases: [(&str, &str, &str); 10] = [
        (
            "",
            "<limit lower=\"-1.57.\" upper=\"1\" effort=\"1\" velocity=\"1\"/>",
            "t.urdf:6: joint 'j' <limit>: lower=\"-1.57.\" is not a number",
        ),
        (
            "",
            "<limit lower=\"NaN\" upper=\"1\" effort=\"1\" velocity=\"1\"/>",
            "t.urdf:6: joint 'j' has the non-finite value NaN in <limit lower>",
        ),
        (
            "",
            "<limit lower=\"-1\" upper=\"1\" velocity=\"1\"/>",
            "t.urdf:6: joint 'j' <limit> has no effort attribute",
        ),
        (
            "",
            "<limit lower=\"-1\" upper=\"1\" effort=\"-1\" velocity=\"1\"/>",
            "t.urdf:6: joint 'j' <limit> has effort=\"-1\"",
        ),
        (
            "",
            "<origin xyz=\"$(optenv X 0 0)\"/>",
            // Xacro left unexpanded: refused as xacro, with the command (docs/ros.md §1).
            "t.urdf:6: this is a xacro file, not a URDF (<origin xyz=\"$(optenv X 0 0)\">); ribbon reads URDF only\n  expand it with xacro, then run ribbon on t.expanded.urdf:",
        ),
        (
            "",
            "<origin rpy=\"0 1\"/>",
            "t.urdf:6: joint 'j' <origin>: rpy=\"0 1\" is not three numbers",
        ),
        (
            "",
            &format!("{LIMIT}<dynamics damping=\"-0.5\"/>"),
            "t.urdf:6: joint 'j' <dynamics> has damping=\"-0.5\"; a negative damping adds energy",
        ),
        (
            "",
            &format!("{LIMIT}<dynamics friction=\"-0.5\"/>"),
            "t.urdf:6: joint 'j' <dynamics> has friction=\"-0.5\"",
        ),
        (
            "",
            &format!("{LIMIT}<mimic/>"),
            "t.urdf:6: joint 'j' <mimic> has no joint attribute",
        ),
        (
            "",
            &format!("{LIMIT}<axis xyz=\"0 0 0\"/>"),
            "t.urdf:6: joint 'j' has the zero axis",
        ),
    ];
    for (link, joint, expected) in cases {
        let msg = error(&arm(link, joint));
        assert!(
            msg.starts_with(expected),
            "expected {expected}\n     got {msg}"
        );
    }
}

#[test]
fn broken_inertial_is_refused_not_dropped() {
    // Pinocchio would load link 'b' massless; ribbon refuses with the line.
    let no_mass = urdf("<link name=\"a\">\n<inertial><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>");
    assert!(error(&no_mass).starts_with("t.urdf:4: link 'a' <inertial> has no <mass> element"));
    let no_ixy = urdf("<link name=\"a\"><inertial><mass value=\"1\"/>\n<inertia ixx=\"1\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>");
    assert!(error(&no_ixy).starts_with("t.urdf:4: link 'a' <inertia> has no ixy attribute"));
    let bad_mass = urdf("<link name=\"a\"><inertial><mass value=\"1kg\"/></inertial></link>");
    assert!(
        error(&bad_mass).starts_with("t.urdf:3: link 'a' <mass>: value=\"1kg\" is not a number")
    );
}

#[test]
fn limits_policy() {
    // Inverted limits load as written, with a note; a revolute joint without <limit> too.
    let inverted = arm(
        "",
        "<limit lower=\"1\" upper=\"-1\" effort=\"1\" velocity=\"1\"/>",
    );
    let d = parse_description(&inverted, "t.urdf").unwrap();
    assert_eq!(d.joints[0].limits, [1.0, -1.0]);
    assert!(d.notes[0]
        .starts_with("t.urdf:6: joint 'j' <limit lower=\"1\" upper=\"-1\">: lower > upper"));
    let missing = parse_description(&arm("", ""), "t.urdf").unwrap();
    assert_eq!(missing.joints[0].limits, [f64::NEG_INFINITY, f64::INFINITY]);
    assert!(missing.notes[0].contains("joint 'j' is revolute but has no <limit>"));
    // Missing lower/upper read as 0, as urdfdom does.
    let partial = arm("", "<limit upper=\"2\" effort=\"1\" velocity=\"1\"/>");
    assert_eq!(
        parse_description(&partial, "t.urdf").unwrap().joints[0].limits,
        [0.0, 2.0]
    );
}

#[test]
fn structure_errors_name_the_line() {
    assert!(
        error("<sdf version=\"1.6\">\n</sdf>").starts_with("t.urdf:1: the root element is <sdf>")
    );
    let unnamed = parse_description("<robot>\n<link name=\"a\"/></robot>", "dir/arm.urdf").unwrap();
    assert_eq!(unnamed.robot_name, "arm");
    assert!(unnamed.notes[0].starts_with("dir/arm.urdf:1: <robot> has no name attribute"));
    assert!(error("<robot name=\"r\">\n</robot>")
        .starts_with("t.urdf:1: robot 'r' has no <link> element"));
    let no_type = urdf("<link name=\"a\"/><link name=\"b\"/>\n<joint name=\"j\"><parent link=\"a\"/><child link=\"b\"/></joint>");
    assert!(error(&no_type).starts_with("t.urdf:4: joint 'j' has no type attribute"));
    let ball = no_type.replace("name=\"j\">", "name=\"j\" type=\"ball\">");
    assert!(error(&ball)
        .starts_with("t.urdf:4: joint 'j' has type 'ball', which is not a URDF joint type"));
    let no_child =
        urdf("<link name=\"a\"/>\n<joint name=\"j\" type=\"fixed\"><parent link=\"a\"/></joint>");
    assert!(error(&no_child).starts_with("t.urdf:4: joint 'j' has no <child> element"));
    let dup = urdf("<link name=\"a\"/>\n<link name=\"a\"/>");
    assert!(error(&dup).starts_with("t.urdf:4: link 'a' is defined twice (first at line 3)"));
}

#[test]
fn prefixed_elements_are_other_vocabularies() {
    let text = "<robot name=\"r\" xmlns:gz=\"http://gazebosim.org/schema\">\
        <gz:property name=\"p\" value=\"1\"/><gz:link name=\"ghost\"/><link name=\"a\"/></robot>";
    let d = parse_description(text, "t.urdf").unwrap();
    assert_eq!(d.links.len(), 1);
    // Xacro's are not: its macros would make links this file does not hold (docs/ros.md §1).
    let xacro = text
        .replace(
            "xmlns:gz=\"http://gazebosim.org/schema\"",
            "xmlns:xacro=\"http://www.ros.org/wiki/xacro\"",
        )
        .replace("gz:", "xacro:");
    assert!(matches!(
        parse_description(&xacro, "t.urdf"),
        Err(ModelError::Xacro { line: 1, ref what, .. }) if what == "<xacro:property>"
    ));
}

#[test]
fn undeclared_prefixes_load_as_foreign_markup_with_a_note_and_lines_stay_true() {
    // Gazebo blocks of older ROS descriptions (fetch, PR2) use `sensor:` and `controller:`
    // without declaring them; tinyxml2, and so Pinocchio, loads such files.
    let plain = arm(
        "",
        "<limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>",
    );
    let gazebo = "<gazebo reference=\"b\">\n<sensor:camera name=\"rgb\">\
         <sensor:imageSize>192 128</sensor:imageSize></sensor:camera>\n\
         <controller:plugin controller:name=\"p\"/><sensor:link name=\"ghost\"/></gazebo>";
    let text = plain.replace("</robot>", &format!("{gazebo}\n</robot>"));
    let d = parse_description(&text, "t.urdf").unwrap_or_else(|e| panic!("should load: {e}"));
    let reference = parse_description(&plain, "t.urdf").unwrap();
    assert_eq!(
        d.links.len(),
        reference.links.len(),
        "a prefixed <link> is not a link"
    );
    assert_eq!(d.joints.len(), reference.joints.len());
    assert_eq!(format!("{:?}", d.links), format!("{:?}", reference.links));
    assert_eq!(format!("{:?}", d.joints), format!("{:?}", reference.joints));
    let prefix_notes: Vec<_> = d
        .notes
        .iter()
        .filter(|n| n.contains("namespace prefix"))
        .collect();
    assert_eq!(
        prefix_notes.len(),
        2,
        "one note per prefix: {prefix_notes:?}"
    );
    assert!(
        prefix_notes[0].starts_with("t.urdf:9: namespace prefix 'sensor'"),
        "{prefix_notes:?}"
    );
    assert!(
        prefix_notes[1].starts_with("t.urdf:10: namespace prefix 'controller'"),
        "{prefix_notes:?}"
    );

    // The declarations go on the root's line: an error after them still names its own line.
    let broken = text.replace(
        "</robot>",
        "<joint name=\"k\" type=\"fixed\"><parent link=\"a\"/><child link=\"zz\"/></joint>\n</robot>",
    );
    let msg = error(&broken);
    assert!(msg.starts_with("t.urdf:11: joint 'k'"), "{msg}");
    // A root start tag behind comments, a processing instruction and a DOCTYPE is found.
    let preamble = "<?xml version=\"1.0\"?>\n<!-- <robot> in a comment -->\n<?pi x?>\n\
         <!DOCTYPE robot [<!ENTITY e \"v\">]>\n";
    let text = text.replacen("<?xml version=\"1.0\"?>\n", preamble, 1);
    let d = parse_description(&text, "t.urdf").unwrap_or_else(|e| panic!("should load: {e}"));
    assert_eq!(d.links.len(), 2);
    // Declared prefixes are not touched and give no note.
    let declared = plain.replace(
        "<robot name=\"t\">",
        "<robot name=\"t\" xmlns:sensor=\"http://example.org/sensor\">",
    );
    let declared = declared.replace("</robot>", "<sensor:camera/>\n</robot>");
    assert!(notes(&declared)
        .iter()
        .all(|n| !n.contains("namespace prefix")));
}

#[test]
fn a_missing_link_gets_advice_and_world_is_explained() {
    let world = urdf(
        "<link name=\"base\"/>\n<joint name=\"fix\" type=\"fixed\"><parent link=\"world\"/>\
         <child link=\"base\"/></joint>",
    );
    let msg = error(&world);
    assert!(
        msg.contains("t.urdf:4: joint 'fix' names parent link 'world'"),
        "{msg}"
    );
    assert!(msg.contains("add <link name=\"world\"/>"), "{msg}");
    let cut = urdf(
        "<link name=\"arm\"/>\n<joint name=\"mount\" type=\"fixed\"><parent link=\"body\"/>\
         <child link=\"arm\"/></joint>",
    );
    let msg = error(&cut);
    assert!(
        msg.contains("add <link name=\"body\"/> if the link belongs to this robot"),
        "{msg}"
    );
}

#[test]
fn nesting_beyond_the_limit_is_refused_without_overflowing_the_stack() {
    // 100 000 nested elements: roxmltree builds its tree iteratively, and the depth walk is
    // iterative, so this returns an error instead of aborting on a stack overflow.
    let depth = 100_000;
    let text = format!(
        "<robot name=\"r\"><link name=\"a\">\n{}{}</link></robot>",
        "<x>".repeat(depth),
        "</x>".repeat(depth)
    );
    let msg = error(&text);
    assert!(
        msg.starts_with(&format!(
            "t.urdf:2: <x> is nested {} elements deep",
            MAX_XML_DEPTH + 1
        )),
        "{msg}"
    );
    // At the limit itself the file loads.
    let ok = MAX_XML_DEPTH - 2;
    let text = format!(
        "<robot name=\"r\"><link name=\"a\">{}{}</link></robot>",
        "<x>".repeat(ok),
        "</x>".repeat(ok)
    );
    assert!(parse_description(&text, "t.urdf").is_ok());
}

#[test]
fn invalid_utf8_is_read_with_a_note() {
    let mut bytes = b"<robot name=\"r\">\n<!-- caf".to_vec();
    bytes.push(0xe9); // Latin-1 é
    bytes.extend_from_slice(b" -->\n<link name=\"a\"/></robot>");
    let dir = std::env::temp_dir().join(format!("ribbon-urdf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("latin1.urdf");
    std::fs::write(&path, &bytes).unwrap();
    let d = read_description(&path).unwrap();
    assert!(
        d.notes[0].contains("latin1.urdf:2: the file has bytes that are not UTF-8"),
        "{:?}",
        d.notes
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn trailing_nul_and_extra_geometry_elements_load_with_notes() {
    let visual = "<visual><geometry><mesh filename=\"m.obj\"/>\n<material name=\"grey\"/></geometry></visual>";
    let text = format!("{}\0\0", arm(visual, LIMIT));
    let found = notes(&text);
    assert!(
        found[1].starts_with("t.urdf:4: link 'b' <visual>: <geometry> holds more than one element (<material> at line 5)"),
        "{found:?}"
    );
    assert!(
        found
            .iter()
            .any(|n| n.starts_with("t.urdf:10: NUL bytes after the end of the document")),
        "{found:?}"
    );
    // A NUL inside the document is malformed XML, with its position.
    let inside = arm("", LIMIT).replace("<joint", "\0<joint");
    assert!(error(&inside).starts_with("t.urdf:5:1: malformed XML"));
}

#[test]
fn whitespace_around_a_number_is_read() {
    // urdfdom (Pinocchio) and urdf-rs read value=" 2.5"; a vector's spacing was already free.
    let text = urdf(
        "<link name=\"a\"><inertial><mass value=\" 2.5 \"/>\
         <inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"\t1\" iyz=\"0\" izz=\"1\n\"/></inertial></link>",
    );
    let d = parse_description(&text, "t.urdf").unwrap();
    assert_eq!(d.links[0].inertial.mass, 2.5);
    assert_eq!(d.links[0].inertial.inertia, [1.0, 0.0, 0.0, 1.0, 0.0, 1.0]);
    let inner = urdf("<link name=\"a\"><inertial><mass value=\"2 .5\"/></inertial></link>");
    assert!(error(&inner).starts_with("t.urdf:3: link 'a' <mass>: value=\"2 .5\" is not a number"));
}

/// `arm` with `<robot version="VERSION">`.
fn versioned(version: &str, link_body: &str, joint_body: &str) -> String {
    arm(link_body, joint_body).replace(
        "<robot name=\"t\">",
        &format!("<robot name=\"t\" version=\"{version}\">"),
    )
}

#[test]
fn the_urdf_version_is_read_and_unknown_versions_are_refused() {
    for good in ["1.0", "1.1", "1.2", " 1.2 "] {
        parse_description(&versioned(good, "", LIMIT), "t.urdf")
            .unwrap_or_else(|e| panic!("version {good:?} should load: {e}"));
    }
    for bad in ["1.3", "2.0", "0.9", "1", "1.x", "", "+1.0", "1.0.0"] {
        let msg = error(&versioned(bad, "", LIMIT));
        assert!(
            msg.starts_with(&format!(
                "t.urdf:2: <robot>: version=\"{bad}\" is not a URDF version ribbon reads"
            )),
            "{bad:?}: {msg}"
        );
    }
}

/// The rotation of the unit quaternion `[x, y, z, w]` (the textbook matrix).
fn quaternion_matrix([x, y, z, w]: [f64; 4]) -> [[f64; 3]; 3] {
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Largest entry difference between the rotation of `rpy` and of the unit quaternion `q`.
fn rpy_error(q: [f64; 4]) -> f64 {
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    let unit = q.map(|c| c / norm);
    let [roll, pitch, yaw] = origin::rpy_from_quaternion(q).unwrap();
    let r = crate::spatial::rotation_from_rpy(roll, pitch, yaw);
    let expected = quaternion_matrix(unit);
    (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| (r[(i, j)] - expected[i][j]).abs())
        .fold(0.0, f64::max)
}

#[test]
fn quaternions_become_rpy_of_the_same_rotation() {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // Identity, quarter turns about each axis (pitch ±90° is the gimbal lock), a half turn, an
    // unnormalised quaternion, and near-lock cases.
    let special = [
        [0.0, 0.0, 0.0, 1.0],
        [h, 0.0, 0.0, h],
        [0.0, h, 0.0, h],
        [0.0, -h, 0.0, h],
        [0.0, 0.0, h, h],
        [0.0, 0.0, 1.0, 0.0],
        [0.3, h, -0.2, h],
        [0.0, 0.0, 1.0, 1.0],
        [1e-9, h, 1e-9, h],
        [0.0, h + 1e-9, 0.0, h],
    ];
    for q in special {
        let err = rpy_error(q);
        assert!(err <= 2e-8, "{q:?}: rotation differs by {err:e}");
    }
    assert_eq!(
        origin::rpy_from_quaternion([0.0, 0.0, 0.0, 1.0]),
        Some([0.0; 3])
    );
    assert_eq!(origin::rpy_from_quaternion([0.0; 4]), None);
    assert_eq!(origin::rpy_from_quaternion([f64::MAX, 0.0, 0.0, 1.0]), None);
    // Quaternions spread over the sphere (a fixed linear congruential sequence): away from the
    // lock the rotation is reproduced to rounding.
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut worst: f64 = 0.0;
    for _ in 0..2000 {
        let q = [next(), next(), next(), next()];
        worst = worst.max(rpy_error(q));
    }
    assert!(worst <= 1e-12, "worst rotation error {worst:e}");
}

#[test]
fn quat_xyzw_gives_the_orientation_from_version_1_1() {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let quarter_turn = format!("<origin xyz=\"1 2 3\" quat_xyzw=\"0 0 {h} {h}\"/>{LIMIT}");
    let d = parse_description(&versioned("1.1", "", &quarter_turn), "t.urdf").unwrap();
    let [x, y, z, roll, pitch, yaw] = d.joints[0].origin;
    assert_eq!([x, y, z], [1.0, 2.0, 3.0]);
    assert_eq!([roll, pitch], [0.0, 0.0]);
    assert!((yaw - std::f64::consts::FRAC_PI_2).abs() <= 1e-15, "{yaw}");
    // In the <inertial> too.
    let inertial = versioned("1.2", "", LIMIT).replace(
        "<inertial><mass",
        &format!("<inertial><origin quat_xyzw=\"{h} 0 0 {h}\"/><mass"),
    );
    let d = parse_description(&inertial, "t.urdf").unwrap();
    assert!((d.links[1].inertial.rpy[0] - std::f64::consts::FRAC_PI_2).abs() <= 1e-15);

    // Version 1.0: ignored with a note, as urdfdom ignores it.
    let old = parse_description(&arm("", &quarter_turn), "t.urdf").unwrap();
    assert_eq!(old.joints[0].origin, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
    assert!(
        old.notes[0].starts_with("t.urdf:6: joint 'j' <origin quat_xyzw="),
        "{:?}",
        old.notes
    );
    assert!(old.notes[0].contains("ignored, as Pinocchio ignores it"));

    // Errors: with rpy, a wrong count, zero length, not finite.
    let with = |origin: &str| error(&versioned("1.1", "", &format!("{origin}{LIMIT}")));
    assert!(
        with("<origin rpy=\"0 0 1\" quat_xyzw=\"0 0 0 1\"/>").starts_with(
            "t.urdf:6: joint 'j' <origin>: quat_xyzw=\"0 0 0 1\" is not allowed together with rpy"
        )
    );
    assert!(with("<origin quat_xyzw=\"0 0 1\"/>").starts_with(
        "t.urdf:6: joint 'j' <origin>: quat_xyzw=\"0 0 1\" is not four numbers x y z w"
    ));
    assert!(with("<origin quat_xyzw=\"0 0 0 0\"/>")
        .starts_with("t.urdf:6: joint 'j' <origin>: quat_xyzw=\"0 0 0 0\" is not a rotation"));
    assert!(with("<origin quat_xyzw=\"0 0 nan 1\"/>")
        .starts_with("t.urdf:6: joint 'j' has the non-finite value NaN in <origin quat_xyzw>"));
}

#[test]
fn limits_from_version_1_2() {
    // Effort and velocity may be omitted: no limit.
    let d = parse_description(
        &versioned("1.2", "", "<limit lower=\"-1\" upper=\"2\"/>"),
        "t.urdf",
    )
    .unwrap();
    assert_eq!(d.joints[0].limits, [-1.0, 2.0]);
    assert_eq!(d.joints[0].effort_velocity, [f64::INFINITY; 2]);
    // A revolute joint needs lower and upper, in order.
    let no_upper = versioned(
        "1.2",
        "",
        "<limit lower=\"-1\" effort=\"1\" velocity=\"1\"/>",
    );
    assert!(error(&no_upper)
        .starts_with("t.urdf:6: joint 'j' <limit> has no upper attribute; from URDF 1.2 on"));
    let inverted = versioned("1.2", "", "<limit lower=\"1\" upper=\"-1\"/>");
    assert!(error(&inverted)
        .starts_with("t.urdf:6: joint 'j' <limit>: upper=\"-1\" is not ≥ lower: from URDF 1.2 on"));
    let negative = versioned(
        "1.2",
        "",
        "<limit lower=\"-1\" upper=\"1\" velocity=\"-1\"/>",
    );
    assert!(error(&negative).contains("velocity=\"-1\""));
    // A continuous joint reads omitted lower and upper as no limit.
    let continuous =
        versioned("1.2", "", "<limit effort=\"3\"/>").replace("revolute", "continuous");
    let d = parse_description(&continuous, "t.urdf").unwrap();
    assert_eq!(d.joints[0].limits, [f64::NEG_INFINITY, f64::INFINITY]);
    assert_eq!(d.joints[0].effort_velocity, [3.0, f64::INFINITY]);
    // Version 1.1 keeps the 1.0 rules.
    let old = versioned("1.1", "", "<limit lower=\"-1\" upper=\"2\"/>");
    assert!(error(&old).starts_with("t.urdf:6: joint 'j' <limit> has no effort attribute"));
}

/// Lines come from a search of the line feeds, numbered as roxmltree's `text_pos_at` numbers them
/// (CRLF, blank lines, elements spanning lines, several elements on a line).
#[test]
fn lines_are_counted_as_roxmltree_counts_them() {
    let text = "<?xml version=\"1.0\"?>\r\n<robot name=\"t\">\r\n\r\n<link\n name=\"a\"><inertial><mass value=\"1\"/>\n<inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link><link name=\"b\"/>\n\n\n<joint name=\"j\" type=\"fixed\"><parent link=\"a\"/>\n<child link=\"b\"/></joint>\n</robot>\n";
    let doc = xml::parse(text, "t.urdf").expect("parses");
    let reader = xml::Reader::new(&doc, doc.root_element(), "t.urdf");
    let mut checked = 0;
    for node in doc.descendants() {
        assert_eq!(
            reader.line(node),
            doc.text_pos_at(node.range().start).row,
            "{node:?}"
        );
        checked += 1;
    }
    assert!(checked > 10, "{checked} nodes");
}
