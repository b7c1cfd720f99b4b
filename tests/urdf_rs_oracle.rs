//! urdf-rs 0.10 as an independent oracle of ribbon's URDF reader.
//!
//! Pinocchio parity (`tests/pinocchio_parity.rs`, `tests/urdf_corpus.rs`) checks the dynamics a
//! file yields, but not the raw values ribbon's reader extracts that Pinocchio ignores or
//! transforms: joint limits, effort and velocity limits, damping, friction, mimic multiplier and
//! offset, the axis before normalisation, the inertial origin's rpy, joint types, parent and child
//! names. Here every URDF in `robots/`, `tests/urdf_corpus/` and example-robot-data 5.0 (from the
//! reference venv) is read by ribbon ([`read_description`]) and by urdf-rs
//! ([`urdf_rs::read_file`]), and every field both expose is compared **bit for bit**: both read
//! the same decimal text with Rust's `f64` parser, so any difference is a reading bug (an attribute
//! taken from the wrong element, a default applied where a value was given, a lost sign).
//!
//! The readers differ by design where the URDF leaves room, and the comparison maps those
//! documented policies onto each other instead of papering over them ([`compare`]):
//! - no `<limit>`: ribbon reads ±∞ (unlimited; effort and velocity ∞), urdf-rs 0 everywhere;
//! - no `<robot name>`: ribbon names the robot after the file with a note, urdf-rs reads `""`.
//!
//! Files urdf-rs refuses are listed in [`URDF_RS_REFUSES`] with urdf-rs's reason, files ribbon
//! refuses in [`RIBBON_REFUSES`]; the test asserts both sets exactly, so a change in either reader
//! shows. A table of counts is printed (`-- --nocapture`).

mod common;

use ribbon::model::{read_description, Description, UrdfJointType};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Files urdf-rs refuses, by name (`robots/…`, `urdf_corpus/…`, `erd/…`), with the start of
/// urdf-rs's error message, and whether ribbon loads the file. Where ribbon loads it, Pinocchio
/// does too (`tests/urdf_corpus.rs`, `tests/example_robot_data_smoke.rs`): urdf-rs reads every
/// `<visual>` and `<collision>` into types, so markup that does not affect dynamics stops it.
const URDF_RS_REFUSES: &[(&str, &str, Ribbon)] = &[
    // `<texture/>` without `filename` in a `<material>`.
    (
        "erd/icub_description/robots/icub.urdf",
        "custom: missing field `filename`",
        Ribbon::Loads,
    ),
    (
        "erd/icub_description/robots/icub_reduced.urdf",
        "custom: missing field `filename`",
        Ribbon::Loads,
    ),
    (
        "erd/romeo_description/urdf/romeo_laas_small.urdf",
        "custom: missing field `filename`",
        Ribbon::Loads,
    ),
    (
        "urdf_corpus/bullet3/bicycle/bike.urdf",
        "custom: Wrong vector element count, expected 3 found 1 for [0.07, 0, -0.69]",
        Ribbon::Refuses,
    ),
    (
        "urdf_corpus/bullet3/biped/biped2d_pybullet.urdf",
        "custom: invalid float literal",
        Ribbon::Refuses,
    ),
    // Unexpanded xacro in `xyz` and `rpy` of one `<origin>`: which of the two urdf-rs reports
    // varies from run to run (its XML layer keeps attributes in a hash map).
    (
        "urdf_corpus/bullet3/husky/husky.urdf",
        "custom: Wrong vector element count, expected 3 found 2 for [$(optenv HUSKY_IMU_",
        Ribbon::Refuses,
    ),
    // A `<plane>` collision shape (pybullet's extension).
    (
        "urdf_corpus/bullet3/plane_implicit.urdf",
        "custom: unknown variant `plane`",
        Ribbon::Loads,
    ),
    (
        "urdf_corpus/bullet3/quadruped/microtaur/microtaur.urdf",
        "custom: Wrong vector element count, expected 3 found 4 for [-3.14159 1.57079 0 0]",
        Ribbon::Refuses,
    ),
    // Two identical `<axis>` in one joint.
    (
        "urdf_corpus/bullet3/quadruped/spirit40newer.urdf",
        "custom: duplicate field `axis`",
        Ribbon::Loads,
    ),
    // A `<material>` inside a `<geometry>`.
    (
        "urdf_corpus/bullet3/racecar/racecar.urdf",
        "Expected token XmlEvent::EndElement { name, .. }, found StartElement(material,",
        Ribbon::Loads,
    ),
    // `<mesh scale="1 1 1 1">`.
    (
        "urdf_corpus/bullet3/racecar/racecar_differential.urdf",
        "custom: Wrong vector element count, expected 3 found 4 for [1 1 1 1]",
        Ribbon::Loads,
    ),
    // A spherical joint whose `<limit>` has no velocity (ribbon stops at the joint type).
    (
        "urdf_corpus/bullet3/spherical_joint_limit.urdf",
        "custom: missing field `velocity`",
        Ribbon::Refuses,
    ),
    // A `<cdf>` collision shape (pybullet's extension).
    (
        "urdf_corpus/bullet3/toys/concave_box.urdf",
        "custom: unknown variant `cdf`",
        Ribbon::Loads,
    ),
];

/// Files ribbon refuses that urdf-rs loads, with the start of ribbon's message after the path.
/// urdf-rs does not check the tree (links named by joints, at least one link) and knows a
/// `spherical` joint type; Pinocchio refuses all of these too. (Files both refuse are in
/// [`URDF_RS_REFUSES`] with [`Ribbon::Refuses`].)
const RIBBON_REFUSES: &[(&str, &str)] = &[
    (
        "erd/falcon_description/urdf/falcon.urdf",
        ":180: joint 'top_propeller_joint' names child link 'Z_propeller', which the file does not define",
    ),
    (
        "erd/ur_description/urdf/ur3.urdf",
        ":6: robot 'ur3' has no <link> element",
    ),
    (
        "urdf_corpus/bullet3/humanoid/humanoid.urdf",
        ":40: joint 'chest' has type 'spherical', which is not a URDF joint type",
    ),
    (
        "urdf_corpus/bullet3/torus_deform.urdf",
        ":2: robot 'torus' has no <link> element",
    ),
    (
        "urdf_corpus/robot_properties_fingers/edu/trifingeredu_stage.urdf",
        ":50: joint 'base_to_table' names parent link 'base_link', which the file does not define",
    ),
    (
        "urdf_corpus/robot_properties_fingers/finger_macro.urdf",
        ":6: robot 'finger_macro' has no <link> element",
    ),
    (
        "urdf_corpus/robot_properties_fingers/trifinger_stage.urdf",
        ":53: joint 'base_to_table' names parent link 'base_link', which the file does not define",
    ),
];

/// What ribbon does with a file urdf-rs refuses.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Ribbon {
    Loads,
    Refuses,
}

/// Every URDF to compare, with a short name: `robots/…`, `urdf_corpus/…`, `erd/…`.
fn all_urdfs() -> Vec<(String, PathBuf)> {
    let manifest = common::manifest_dir();
    let mut files = Vec::new();
    for (label, dir) in [
        ("robots", manifest.join("robots")),
        ("urdf_corpus", manifest.join("tests/urdf_corpus")),
        ("erd", common::example_robot_data_dir()),
    ] {
        for path in common::files_with_extension(&dir, "urdf") {
            let name = format!("{label}/{}", path.strip_prefix(&dir).unwrap().display());
            files.push((name, path));
        }
    }
    files
}

/// Collects the differences of one file, each as `what: ribbon X, urdf-rs Y`.
struct Differences<'a> {
    file: &'a str,
    found: Vec<String>,
}

impl Differences<'_> {
    fn text(&mut self, what: &str, ribbon: &str, oracle: &str) {
        if ribbon != oracle {
            self.found.push(format!(
                "{}: {what}: ribbon {ribbon:?}, urdf-rs {oracle:?}",
                self.file
            ));
        }
    }

    /// Bit equality (`-0.0` and `0.0` differ: both readers parse the same text).
    fn numbers(&mut self, what: &str, ribbon: &[f64], oracle: &[f64]) {
        let same = ribbon.len() == oracle.len()
            && ribbon
                .iter()
                .zip(oracle)
                .all(|(a, b)| a.to_bits() == b.to_bits());
        if !same {
            self.found.push(format!(
                "{}: {what}: ribbon {ribbon:?}, urdf-rs {oracle:?}",
                self.file
            ));
        }
    }
}

fn joint_type_name(joint_type: &urdf_rs::JointType) -> &'static str {
    match joint_type {
        urdf_rs::JointType::Revolute => "revolute",
        urdf_rs::JointType::Continuous => "continuous",
        urdf_rs::JointType::Prismatic => "prismatic",
        urdf_rs::JointType::Fixed => "fixed",
        urdf_rs::JointType::Floating => "floating",
        urdf_rs::JointType::Planar => "planar",
        urdf_rs::JointType::Spherical => "spherical",
    }
}

/// How many compared values differ from the field's default (the value a reader that missed the
/// attribute would give), per field: a field never compared with a non-default value is not
/// checked by the corpus at all, so the test requires each to be seen.
#[derive(Default)]
struct Coverage(BTreeMap<&'static str, usize>);

impl Coverage {
    fn count(&mut self, field: &'static str, non_default: bool) {
        let entry = self.0.entry(field).or_default();
        *entry += usize::from(non_default);
    }
}

/// Compares every field both readers expose; returns the differences, one line each.
fn compare(
    file: &str,
    ribbon: &Description,
    oracle: &urdf_rs::Robot,
    coverage: &mut Coverage,
) -> Vec<String> {
    let mut diff = Differences {
        file,
        found: Vec::new(),
    };
    if oracle.name.is_empty() && ribbon.robot_name != oracle.name {
        // ribbon's policy: named after the file, with a note.
        if !ribbon
            .notes
            .iter()
            .any(|n| n.contains("<robot> has no name"))
        {
            diff.text("robot name", &ribbon.robot_name, "");
        }
    } else {
        diff.text("robot name", &ribbon.robot_name, &oracle.name);
    }

    let names = |v: Vec<&str>| v.join(", ");
    diff.text(
        "links",
        &names(ribbon.links.iter().map(|l| l.name.as_str()).collect()),
        &names(oracle.links.iter().map(|l| l.name.as_str()).collect()),
    );
    let nonzero = |v: &[f64]| v.iter().any(|x| *x != 0.0);
    for (link, other) in ribbon.links.iter().zip(&oracle.links) {
        let at = |field: &str| format!("link '{}' {field}", link.name);
        let inertial = &link.inertial;
        let o = &other.inertial;
        diff.numbers(&at("<mass value>"), &[inertial.mass], &[o.mass.value]);
        diff.numbers(
            &at("<inertial><origin xyz>"),
            &inertial.com,
            &o.origin.xyz.0,
        );
        diff.numbers(
            &at("<inertial><origin rpy>"),
            &inertial.rpy,
            &o.origin.rpy.0,
        );
        let i = &o.inertia;
        diff.numbers(
            &at("<inertia>"),
            &inertial.inertia,
            &[i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz],
        );
        coverage.count("mass", inertial.mass != 0.0);
        coverage.count("inertial xyz", nonzero(&inertial.com));
        coverage.count("inertial rpy", nonzero(&inertial.rpy));
        coverage.count("inertia", nonzero(&inertial.inertia));
    }

    diff.text(
        "joints",
        &names(ribbon.joints.iter().map(|j| j.name.as_str()).collect()),
        &names(oracle.joints.iter().map(|j| j.name.as_str()).collect()),
    );
    for (joint, other) in ribbon.joints.iter().zip(&oracle.joints) {
        let at = |field: &str| format!("joint '{}' {field}", joint.name);
        diff.text(
            &at("type"),
            joint.joint_type.as_str(),
            joint_type_name(&other.joint_type),
        );
        diff.text(
            &at("<parent link>"),
            &ribbon.links[joint.parent].name,
            &other.parent.link,
        );
        diff.text(
            &at("<child link>"),
            &ribbon.links[joint.child].name,
            &other.child.link,
        );
        diff.numbers(&at("<origin xyz>"), &joint.origin[..3], &other.origin.xyz.0);
        diff.numbers(&at("<origin rpy>"), &joint.origin[3..], &other.origin.rpy.0);
        diff.numbers(&at("<axis xyz>"), &joint.axis, &other.axis.xyz.0);
        coverage.count(
            match joint.joint_type {
                UrdfJointType::Revolute => "type revolute",
                UrdfJointType::Continuous => "type continuous",
                UrdfJointType::Prismatic => "type prismatic",
                UrdfJointType::Fixed => "type fixed",
                UrdfJointType::Floating => "type floating",
            },
            true,
        );
        coverage.count("joint xyz", nonzero(&joint.origin[..3]));
        coverage.count("joint rpy", nonzero(&joint.origin[3..]));
        coverage.count("axis", joint.axis != [1.0, 0.0, 0.0]);
        coverage.count(
            "axis not unit",
            (joint.axis.iter().map(|a| a * a).sum::<f64>() - 1.0).abs() > 1e-12,
        );

        let l = &other.limit;
        let oracle_limit = [l.lower, l.upper, l.effort, l.velocity];
        let ribbon_limit = [
            joint.limits[0],
            joint.limits[1],
            joint.effort_velocity[0],
            joint.effort_velocity[1],
        ];
        let unlimited = [
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::INFINITY,
            f64::INFINITY,
        ];
        let same_bits = ribbon_limit
            .iter()
            .zip(&oracle_limit)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        if ribbon_limit == unlimited && !same_bits {
            // No <limit>: ribbon's policy is ±∞, urdf-rs's default all zero. (A URDF 1.2
            // `<limit/>` on a continuous joint reads as ±∞ in both.)
            diff.numbers(
                &at("<limit> (absent: urdf-rs's default)"),
                &[0.0; 4],
                &oracle_limit,
            );
        } else {
            diff.numbers(
                &at("<limit lower upper effort velocity>"),
                &ribbon_limit,
                &oracle_limit,
            );
            coverage.count("limit lower upper", nonzero(&ribbon_limit[..2]));
            coverage.count("limit effort velocity", nonzero(&ribbon_limit[2..]));
        }

        let (damping, friction) = other
            .dynamics
            .as_ref()
            .map_or((0.0, 0.0), |d| (d.damping, d.friction));
        diff.numbers(
            &at("<dynamics damping friction>"),
            &[joint.damping, joint.friction],
            &[damping, friction],
        );
        coverage.count("damping", joint.damping != 0.0);
        coverage.count("friction", joint.friction != 0.0);

        match (&joint.mimic, &other.mimic) {
            (None, None) => {}
            (Some(mimic), Some(o)) => {
                diff.text(&at("<mimic joint>"), &mimic.joint, &o.joint);
                diff.numbers(
                    &at("<mimic multiplier offset>"),
                    &[mimic.multiplier, mimic.offset],
                    &[o.multiplier.unwrap_or(1.0), o.offset.unwrap_or(0.0)],
                );
                coverage.count("mimic multiplier", mimic.multiplier != 1.0);
                coverage.count("mimic offset", mimic.offset != 0.0);
            }
            (a, b) => diff.text(
                &at("<mimic>"),
                &format!("{:?}", a.as_ref().map(|m| &m.joint)),
                &format!("{:?}", b.as_ref().map(|m| &m.joint)),
            ),
        }
    }
    diff.found
}

/// The first line of an error message, with the file's path taken out (`FILE`).
fn first_line(message: &str, path: &Path) -> String {
    message
        .replace(&path.display().to_string(), "FILE")
        .lines()
        .next()
        .unwrap_or("")
        .to_string()
}

/// Fields the corpus must exercise with non-default values (see [`Coverage`]). The corpus has no
/// `floating` joint: that type name is compared by the same code as the others.
const REQUIRED_COVERAGE: &[&str] = &[
    "mass",
    "inertial xyz",
    "inertial rpy",
    "inertia",
    "type revolute",
    "type continuous",
    "type prismatic",
    "type fixed",
    "joint xyz",
    "joint rpy",
    "axis",
    "axis not unit",
    "limit lower upper",
    "limit effort velocity",
    "damping",
    "friction",
    "mimic multiplier",
    "mimic offset",
];

#[test]
fn ribbon_reads_every_value_urdf_rs_reads_bit_for_bit() {
    let files = all_urdfs();
    let mut compared = 0;
    let mut coverage = Coverage::default();
    let mut mismatches = Vec::new();
    let mut urdf_rs_refused: BTreeMap<String, (String, Ribbon)> = BTreeMap::new();
    let mut ribbon_refused: BTreeMap<String, String> = BTreeMap::new();
    let (mut links, mut joints) = (0, 0);
    for (name, path) in &files {
        let ribbon = read_description(path);
        let oracle = urdf_rs::read_file(path);
        match (ribbon, oracle) {
            (Ok(ribbon), Ok(oracle)) => {
                compared += 1;
                links += ribbon.links.len();
                joints += ribbon.joints.len();
                mismatches.extend(compare(name, &ribbon, &oracle, &mut coverage));
            }
            (ribbon, Err(e)) => {
                let verdict = if ribbon.is_ok() {
                    Ribbon::Loads
                } else {
                    Ribbon::Refuses
                };
                urdf_rs_refused.insert(name.clone(), (first_line(&e.to_string(), path), verdict));
            }
            (Err(e), Ok(_)) => {
                ribbon_refused.insert(name.clone(), first_line(&e.to_string(), path));
            }
        }
    }

    let mut report = String::new();
    writeln!(
        report,
        "{} URDFs: {compared} read by both and compared ({links} links, {joints} joints), {} refused by urdf-rs, {} refused by ribbon alone, {} mismatches",
        files.len(),
        urdf_rs_refused.len(),
        ribbon_refused.len(),
        mismatches.len()
    )
    .unwrap();
    let counts: Vec<String> = coverage
        .0
        .iter()
        .map(|(field, n)| format!("{field} {n}"))
        .collect();
    writeln!(
        report,
        "  non-default values compared: {}",
        counts.join(", ")
    )
    .unwrap();
    for (file, (why, verdict)) in &urdf_rs_refused {
        writeln!(
            report,
            "  urdf-rs refuses {file} (ribbon {verdict:?}): {why}"
        )
        .unwrap();
    }
    for (file, why) in &ribbon_refused {
        writeln!(report, "  ribbon refuses {file}: {why}").unwrap();
    }
    for m in &mismatches {
        writeln!(report, "  MISMATCH {m}").unwrap();
    }
    println!("{report}");

    let mut problems = Vec::new();
    for &(file, reason, verdict) in URDF_RS_REFUSES {
        match urdf_rs_refused.remove(file) {
            None => problems.push(format!(
                "{file}: listed as refused by urdf-rs, but it loaded (or the file is gone)"
            )),
            Some((why, seen)) => {
                if !why.starts_with(reason) {
                    problems.push(format!("{file}: urdf-rs's reason changed: expected it to start with {reason:?}, got {why:?}"));
                }
                if seen != verdict {
                    problems.push(format!(
                        "{file}: ribbon was expected to do {verdict:?}, did {seen:?}"
                    ));
                }
            }
        }
    }
    for (file, (why, _)) in urdf_rs_refused {
        problems.push(format!(
            "{file}: urdf-rs refuses it, but URDF_RS_REFUSES does not list it: {why}"
        ));
    }
    for &(file, reason) in RIBBON_REFUSES {
        match ribbon_refused.remove(file) {
            None => problems.push(format!(
                "{file}: listed as refused by ribbon alone, but it is not"
            )),
            Some(why) => {
                if !why.starts_with(&format!("FILE{reason}")) {
                    problems.push(format!(
                        "{file}: ribbon's reason changed: expected FILE{reason}…, got {why:?}"
                    ));
                }
            }
        }
    }
    for (file, why) in ribbon_refused {
        problems.push(format!("{file}: ribbon refuses it where urdf-rs loads it, and RIBBON_REFUSES does not list it: {why}"));
    }
    for field in REQUIRED_COVERAGE {
        if coverage.0.get(field).copied().unwrap_or(0) == 0 {
            problems.push(format!("no file compares a non-default value of {field}"));
        }
    }
    assert!(
        problems.is_empty(),
        "the refusal lists or the coverage changed:\n  {}\n{report}",
        problems.join("\n  ")
    );
    assert!(
        mismatches.is_empty(),
        "ribbon and urdf-rs read different values:\n{report}"
    );
}

/// A robot that gives every compared field a non-default value, in decimal forms both readers
/// must read alike (exponents, a leading `+`, a bare `.5`, a trailing `.`, `-0`).
const EVERY_FIELD: &str = r#"<?xml version="1.0"?>
<robot name="every_field">
  <link name="base"/>
  <link name="arm">
    <inertial>
      <origin xyz="1e-3 -0 +.5" rpy="0.1 -2.5E-1 3."/>
      <mass value="2.5"/>
      <inertia ixx="0.1" ixy="-1e-5" ixz="2E-6" iyy="0.2" iyz="-0.0" izz="0.30000000000000004"/>
    </inertial>
  </link>
  <link name="finger"/>
  <joint name="shoulder" type="revolute">
    <origin xyz="0 0.1 0.2" rpy="1.5707963267948966 0 -3.141592653589793"/>
    <parent link="base"/>
    <child link="arm"/>
    <axis xyz="0 0.6 0.8000000000000002"/>
    <limit lower="-1.5" upper="2.25" effort="87" velocity="2.175"/>
    <dynamics damping="0.5" friction="0.125"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="arm"/>
    <child link="finger"/>
    <axis xyz="0 0 -2"/>
    <limit lower="-0.01" upper="0.04" effort="20" velocity="0.2"/>
    <mimic joint="shoulder" multiplier="-0.5" offset="0.01"/>
  </joint>
</robot>
"#;

/// Both readers on `text`.
fn read_both(text: &str) -> (Description, urdf_rs::Robot) {
    let ribbon = ribbon::model::parse_description(text, "every_field.urdf")
        .unwrap_or_else(|e| panic!("ribbon refuses the test robot: {e}"));
    let oracle = urdf_rs::read_from_string(text)
        .unwrap_or_else(|e| panic!("urdf-rs refuses the test robot: {e}"));
    (ribbon, oracle)
}

/// The next larger `f64` (one unit in the last place): the smallest change a reading bug makes.
fn next_up(x: f64) -> f64 {
    if x == 0.0 {
        f64::from_bits(1)
    } else if x > 0.0 {
        f64::from_bits(x.to_bits() + 1)
    } else {
        f64::from_bits(x.to_bits() - 1)
    }
}

/// The comparison can fail: a robot read alike by both gives no difference, and changing any one
/// compared value of ribbon's reading by one unit in the last place (or one name) gives exactly
/// one difference, naming that field (three for a link's name, which two joints name too).
#[test]
fn the_comparison_catches_a_one_ulp_change_in_every_field() {
    let (ribbon, oracle) = read_both(EVERY_FIELD);
    let mut coverage = Coverage::default();
    let found = compare("every_field", &ribbon, &oracle, &mut coverage);
    assert!(found.is_empty(), "{found:#?}");

    type Change = fn(&mut Description);
    let changes: &[(&str, Change)] = &[
        ("robot name", |d| d.robot_name.push('x')),
        ("links", |d| d.links[1].name.push('x')),
        ("link 'arm' <mass value>", |d| {
            d.links[1].inertial.mass = next_up(d.links[1].inertial.mass)
        }),
        ("link 'arm' <inertial><origin xyz>", |d| {
            d.links[1].inertial.com[1] = next_up(d.links[1].inertial.com[1])
        }),
        ("link 'arm' <inertial><origin rpy>", |d| {
            d.links[1].inertial.rpy[2] = next_up(d.links[1].inertial.rpy[2])
        }),
        ("link 'arm' <inertia>", |d| {
            d.links[1].inertial.inertia[4] = next_up(d.links[1].inertial.inertia[4])
        }),
        ("joints", |d| d.joints[0].name.push('x')),
        ("joint 'shoulder' type", |d| {
            d.joints[0].joint_type = UrdfJointType::Continuous
        }),
        ("joint 'shoulder' <parent link>", |d| d.joints[0].parent = 2),
        ("joint 'shoulder' <child link>", |d| d.joints[0].child = 2),
        ("joint 'shoulder' <origin xyz>", |d| {
            d.joints[0].origin[0] = next_up(d.joints[0].origin[0])
        }),
        ("joint 'shoulder' <origin rpy>", |d| {
            d.joints[0].origin[5] = next_up(d.joints[0].origin[5])
        }),
        ("joint 'slide' <axis xyz>", |d| {
            d.joints[1].axis[2] = next_up(d.joints[1].axis[2])
        }),
        (
            "joint 'shoulder' <limit lower upper effort velocity>",
            |d| d.joints[0].limits[0] = next_up(d.joints[0].limits[0]),
        ),
        (
            "joint 'shoulder' <limit lower upper effort velocity>",
            |d| d.joints[0].effort_velocity[1] = next_up(d.joints[0].effort_velocity[1]),
        ),
        (
            "joint 'shoulder' <limit> (absent: urdf-rs's default)",
            |d| {
                d.joints[0].limits = [f64::NEG_INFINITY, f64::INFINITY];
                d.joints[0].effort_velocity = [f64::INFINITY; 2];
            },
        ),
        ("joint 'shoulder' <dynamics damping friction>", |d| {
            d.joints[0].damping = next_up(d.joints[0].damping)
        }),
        ("joint 'slide' <dynamics damping friction>", |d| {
            d.joints[1].friction = next_up(d.joints[1].friction)
        }),
        ("joint 'slide' <mimic joint>", |d| {
            if let Some(m) = &mut d.joints[1].mimic {
                m.joint.push('x')
            }
        }),
        ("joint 'slide' <mimic multiplier offset>", |d| {
            if let Some(m) = &mut d.joints[1].mimic {
                m.offset = next_up(m.offset)
            }
        }),
        ("joint 'slide' <mimic>", |d| d.joints[1].mimic = None),
    ];
    for (field, change) in changes {
        let mut changed = ribbon.clone();
        change(&mut changed);
        let found = compare("every_field", &changed, &oracle, &mut coverage);
        // A renamed link is also a different <parent>/<child> of the two joints at it.
        let expected = if *field == "links" { 3 } else { 1 };
        assert!(
            found.len() == expected && found[0].starts_with(&format!("every_field: {field}: ")),
            "changing {field} should give one difference naming it, got {found:#?}"
        );
    }
}

/// Whitespace around single numbers, which urdfdom, urdf-rs and ribbon all read.
#[test]
fn padded_numbers_read_alike() {
    let padded = EVERY_FIELD
        .replace("value=\"2.5\"", "value=\" 2.5 \"")
        .replace("effort=\"87\"", "effort=\"\t87\"")
        .replace("multiplier=\"-0.5\"", "multiplier=\"-0.5 \"");
    assert_ne!(padded, EVERY_FIELD);
    let (ribbon, oracle) = read_both(&padded);
    let found = compare("padded", &ribbon, &oracle, &mut Coverage::default());
    assert!(found.is_empty(), "{found:#?}");
}

/// `EVERY_FIELD` as a URDF 1.2 file: a continuous joint with `<limit effort>` only (lower and
/// upper ∓∞, velocity ∞ in both readers) and a prismatic one without effort and velocity.
#[test]
fn urdf_1_2_limits_read_alike() {
    let text = EVERY_FIELD
        .replace(
            "<robot name=\"every_field\">",
            "<robot name=\"every_field\" version=\"1.2\">",
        )
        .replace("type=\"revolute\"", "type=\"continuous\"")
        .replace(
            "lower=\"-1.5\" upper=\"2.25\" effort=\"87\" velocity=\"2.175\"",
            "effort=\"87\"",
        )
        .replace(" effort=\"20\" velocity=\"0.2\"", "");
    let (ribbon, oracle) = read_both(&text);
    assert_eq!(ribbon.joints[0].limits, [f64::NEG_INFINITY, f64::INFINITY]);
    assert_eq!(ribbon.joints[1].effort_velocity, [f64::INFINITY; 2]);
    let found = compare("urdf_1_2", &ribbon, &oracle, &mut Coverage::default());
    assert!(found.is_empty(), "{found:#?}");
}

/// The rotations of ribbon's and urdf-rs's rpy for one orientation differ by at most this much
/// per matrix entry: both turn `quat_xyzw` into roll, pitch, yaw, by different formulas (urdf-rs
/// follows urdfdom's, with `asin`), so the angles agree to rounding, not to the bit.
const QUATERNION_ROTATION_TOLERANCE: f64 = 1e-14;

/// URDF 1.1 `quat_xyzw` orientations (joint and inertial origins, unnormalised too) give the same
/// rotation in both readers; every other field agrees bit for bit.
#[test]
fn urdf_1_1_quaternions_give_the_same_rotation() {
    let quaternions = [
        "0 0 0.7071067811865476 0.7071067811865476",
        "0.3 0.7 -0.2 0.6",
        "0 0 1 1",
        "1 0 0 0",
        "0.1 -0.2 0.3 -0.9",
    ];
    for quaternion in quaternions {
        let text = EVERY_FIELD
            .replace(
                "<robot name=\"every_field\">",
                "<robot name=\"every_field\" version=\"1.1\">",
            )
            .replace(
                "rpy=\"1.5707963267948966 0 -3.141592653589793\"",
                &format!("quat_xyzw=\"{quaternion}\""),
            )
            .replace(
                "rpy=\"0.1 -2.5E-1 3.\"",
                &format!("quat_xyzw=\"{quaternion}\""),
            );
        let (mut ribbon, oracle) = read_both(&text);
        let rotation = |rpy: &[f64]| ribbon::spatial::rotation_from_rpy(rpy[0], rpy[1], rpy[2]);
        let pairs = [
            (
                &ribbon.joints[0].origin[3..],
                &oracle.joints[0].origin.rpy.0[..],
            ),
            (
                &ribbon.links[1].inertial.rpy[..],
                &oracle.links[1].inertial.origin.rpy.0[..],
            ),
        ];
        for (ours, theirs) in pairs {
            let gap = (rotation(ours) - rotation(theirs)).abs().max();
            assert!(
                gap <= QUATERNION_ROTATION_TOLERANCE,
                "quat_xyzw=\"{quaternion}\": ribbon rpy {ours:?}, urdf-rs rpy {theirs:?}: rotations differ by {gap:e}"
            );
        }
        // The rest, bit for bit (the rpy compared above are set to urdf-rs's).
        ribbon.joints[0].origin[3..].copy_from_slice(&oracle.joints[0].origin.rpy.0);
        ribbon.links[1].inertial.rpy = oracle.links[1].inertial.origin.rpy.0;
        let found = compare("urdf_1_1", &ribbon, &oracle, &mut Coverage::default());
        assert!(found.is_empty(), "{found:#?}");
    }
}
