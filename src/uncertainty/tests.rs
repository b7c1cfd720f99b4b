//! Tests of the parameter space and the box check on small inline robots.

use super::*;
use crate::environment::Environment;
use crate::model::{parse_description, LoadOptions, Model};
use crate::params::{self, ParamTarget};
use crate::sidecar::parse_sidecar;

/// Two bars and a link whose URDF inertia violates the triangle inequality (0.1 + 0.1 < 0.3).
const ROBOT: &str = r#"<robot name="t">
  <link name="world"/>
  <link name="bar1"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="bar2"><inertial><origin xyz="0 0 0"/><mass value="1"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.15" iyz="0" izz="0.2"/></inertial></link>
  <link name="bad"><inertial><mass value="1"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.3"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="world"/><child link="bar1"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="bar1"/><child link="bar2"/>
    <origin xyz="1 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j3" type="continuous"><parent link="bar2"/><child link="bad"/></joint>
</robot>"#;

const FILE: &str = "t.uncertainty.toml";

fn model() -> Model {
    Model::from_description(
        parse_description(ROBOT, "t.urdf").unwrap(),
        LoadOptions::default(),
        "t.urdf",
    )
    .unwrap()
}

fn space(sidecar: &str) -> Result<ParameterSpace, UncertaintyError> {
    let file = parse_sidecar(sidecar).unwrap();
    ParameterSpace::from_sidecar(&file, &model(), &Environment::default(), FILE)
}

fn error(sidecar: &str) -> String {
    let message = space(sidecar).unwrap_err().to_string();
    assert!(message.starts_with(FILE), "{message}");
    message
}

const ALL_FORMS: &str = r#"
[parameters]
"link.bar1.mass"    = [1.0, 2.5]
"joint.j1.origin.z" = { rel = 0.1 }
"link.bar2.com.y"   = { abs = 0.002 }
l1                  = [0.99, 1.01]
[bind]
"joint.j2.origin.x" = "l1"
"link.bar1.com.x"   = "l1 / 2"
"#;

#[test]
fn all_forms_parse_in_order_of_appearance() {
    let s = space(ALL_FORMS).unwrap();
    let names: Vec<&str> = s.dimensions().iter().map(|d| d.name.as_str()).collect();
    // Not alphabetical ("joint" < "link"): the file's order.
    assert_eq!(
        names,
        [
            "link.bar1.mass",
            "joint.j1.origin.z",
            "link.bar2.com.y",
            "l1"
        ]
    );
    let d = s.dimensions();
    assert_eq!((d[0].lower, d[0].upper, d[0].nominal), (1.0, 2.5, 2.0));
    assert_eq!(d[0].kind, DimensionKind::Path(ParamTarget::LinkMass(1)));
    assert!((d[1].lower - 0.45).abs() < 1e-15 && (d[1].upper - 0.55).abs() < 1e-15);
    assert_eq!(d[1].nominal, 0.5);
    assert_eq!((d[2].lower, d[2].upper, d[2].nominal), (-0.002, 0.002, 0.0));
    assert_eq!((d[3].lower, d[3].upper), (0.99, 1.01));
    assert!((d[3].nominal - 1.0).abs() < 1e-15);
    assert_eq!(d[3].kind, DimensionKind::Symbol);
    let bound: Vec<(&str, &str)> = s
        .bindings()
        .iter()
        .map(|b| (b.path.as_str(), b.expression.source()))
        .collect();
    assert_eq!(
        bound,
        [("joint.j2.origin.x", "l1"), ("link.bar1.com.x", "l1 / 2")]
    );
    assert!(s.warnings().is_empty(), "{:?}", s.warnings());
}

#[test]
fn nominal_xi_and_values_at() {
    let s = space(ALL_FORMS).unwrap();
    let xi = s.nominal_xi();
    // Mass: URDF 2 in [1, 2.5]: c = 1.75, r = 0.75, ξ = 1/3. The others are centred.
    assert!((xi[0] - 1.0 / 3.0).abs() < 1e-15, "{xi:?}");
    assert_eq!(&xi[1..], &[0.0, 0.0, 0.0]);
    let values = s.values_at(&xi);
    for (value, d) in values.iter().zip(s.dimensions()) {
        assert!((value - d.nominal).abs() <= 1e-15 * d.nominal.abs().max(1.0));
    }
    // Bounds are hit exactly at ξ = ±1.
    assert_eq!(s.values_at(&[-1.0; 4])[0], 1.0);
    assert_eq!(s.values_at(&[1.0; 4])[2], 0.002);
}

#[test]
fn apply_writes_direct_and_bound_values() {
    let s = space(ALL_FORMS).unwrap();
    let mut m = model();
    s.apply(&mut m, &mut Environment::default(), &[1.0, -1.0, 0.5, 1.0]);
    let get = |m: &Model, path: &str| {
        params::get(
            m,
            &Environment::default(),
            params::resolve(m, &Environment::default(), path).unwrap(),
        )
    };
    assert_eq!(get(&m, "link.bar1.mass"), 2.5);
    assert!((get(&m, "joint.j1.origin.z") - 0.45).abs() < 1e-15);
    assert!((get(&m, "link.bar2.com.y") - 0.001).abs() < 1e-15);
    assert_eq!(get(&m, "joint.j2.origin.x"), 1.01);
    assert!((get(&m, "link.bar1.com.x") - 0.505).abs() < 1e-15);
    // The derived tree follows (refresh): body 0 is bar1, body 1 is bar2.
    let bar1 = &m.bodies[0].inertia;
    assert_eq!(bar1.mass, 2.5);
    assert!((bar1.com().unwrap().x - 0.505).abs() < 1e-15);
    assert!((m.joints[1].parent_from_joint.translation.x - 1.01).abs() < 1e-15);
    assert!((m.joints[0].parent_from_joint.translation.z - 0.45).abs() < 1e-15);
    // Back to the nominal point: the URDF values again.
    s.apply(&mut m, &mut Environment::default(), &s.nominal_xi());
    assert!((get(&m, "link.bar1.mass") - 2.0).abs() < 1e-15);
    assert!((get(&m, "joint.j2.origin.x") - 1.0).abs() < 1e-15);
}

#[test]
fn inertia_values_written_by_apply_reach_the_body() {
    let s = space(
        r#"[parameters]
        "link.bar2.inertia.izz" = [0.18, 0.22]"#,
    )
    .unwrap();
    let mut m = model();
    s.apply(&mut m, &mut Environment::default(), &[1.0]);
    let about_com = m.bodies[1].inertia.inertia_about_com().unwrap();
    // bar2 merges no fixed child, and `bad` is on its own moving joint.
    assert!((about_com[(2, 2)] - 0.22).abs() < 1e-15);
}

#[test]
fn bind_at_midpoints_differing_from_urdf_warns() {
    let s = space(
        r#"[parameters]
        l1 = [0.99, 1.01]
        [bind]
        "link.bar1.com.x" = "l1 / 3""#,
    )
    .unwrap();
    let w = s.warnings().join("\n");
    assert!(
        w.contains("[bind] \"link.bar1.com.x\"")
            && w.contains("URDF value is 0.5")
            && w.contains("0.333"),
        "{w}"
    );
}

#[test]
fn unused_symbol_warns() {
    let s = space("[parameters]\nl9 = [1, 2]\n").unwrap();
    assert!(s.warnings()[0].contains("[parameters] \"l9\": the free symbol is used by no [bind]"));
    // Integer bounds are numbers too.
    assert_eq!(
        (s.dimensions()[0].lower, s.dimensions()[0].upper),
        (1.0, 2.0)
    );
}

#[test]
fn unknown_symbol_names_it_and_the_path() {
    let msg = error(
        r#"[parameters]
        l1 = [0.99, 1.01]
        [bind]
        "joint.j2.origin.x" = "2 * l2""#,
    );
    assert!(
        msg.contains("[bind] \"joint.j2.origin.x\" = \"2 * l2\"")
            && msg.contains("unknown symbol 'l2'")
            && msg.contains("did you mean 'l1'")
            && msg.contains("declared symbols: l1"),
        "{msg}"
    );
    // A path dimension is not a symbol.
    let msg = error(
        r#"[parameters]
        "link.bar1.mass" = [1, 3]
        [bind]
        "joint.j2.origin.x" = "mass""#,
    );
    assert!(msg.contains("declared symbols: none"), "{msg}");
}

#[test]
fn expression_syntax_errors_name_the_key() {
    let msg = error(
        r#"[parameters]
        l1 = [0.99, 1.01]
        [bind]
        "joint.j2.origin.x" = "l1 *""#,
    );
    assert!(
        msg.contains("[bind] \"joint.j2.origin.x\" = \"l1 *\": expected a number"),
        "{msg}"
    );
    let msg = error("[bind]\n\"joint.j2.origin.x\" = 1.0\n");
    assert!(
        msg.contains("a binding is an expression in quotes"),
        "{msg}"
    );
}

#[test]
fn path_in_both_tables_is_refused() {
    let msg = error(
        r#"[parameters]
        "joint.j2.origin.x" = [0.9, 1.1]
        l1 = [0.9, 1.1]
        [bind]
        "joint.j2.origin.x" = "l1""#,
    );
    assert!(
        msg.contains("[bind] \"joint.j2.origin.x\": [parameters] \"joint.j2.origin.x\" already declares this value"),
        "{msg}"
    );
}

#[test]
fn relative_interval_of_a_zero_value_is_refused() {
    let msg = error("[parameters]\n\"link.bar2.com.y\" = { rel = 0.1 }\n");
    assert!(
        msg.contains("[parameters] \"link.bar2.com.y\"")
            && msg.contains("URDF value is 0")
            && msg.contains("abs"),
        "{msg}"
    );
}

#[test]
fn urdf_value_outside_the_interval_is_refused() {
    let msg = error("[parameters]\n\"link.bar1.mass\" = [2.1, 2.5]\n");
    assert!(
        msg.contains(
            "[parameters] \"link.bar1.mass\" = [2.1, 2.5] does not contain the URDF value 2"
        ),
        "{msg}"
    );
}

#[test]
fn unknown_keys_get_suggestions() {
    let msg = error("[parameters]\n\"link.bar1.mas\" = [1, 3]\n");
    assert!(
        msg.contains("[parameters] \"link.bar1.mas\"")
            && msg.contains("did you mean 'link.bar1.mass'"),
        "{msg}"
    );
    let msg = error("[parameters]\n\"2x\" = [1, 3]\n");
    assert!(msg.contains("a free symbol name"), "{msg}");
    let msg = error("[parameters]\nl1 = [1, 2]\n[bind]\nl2 = \"l1\"\n");
    assert!(msg.contains("a [bind] key is a parameter path"), "{msg}");
    let msg = error("[parameters]\nsqrt = [1, 2]\n");
    assert!(msg.contains("'sqrt' is the square-root function"), "{msg}");
}

#[test]
fn bad_intervals_are_refused() {
    let cases = [
        (
            "\"link.bar1.mass\" = { abs = 0 }",
            "abs must be a finite amount > 0",
        ),
        (
            "\"link.bar1.mass\" = { rel = -0.1 }",
            "rel must be a finite fraction > 0",
        ),
        ("\"link.bar1.mass\" = [2.5, 1.0]", "write [1, 2.5]"),
        ("\"link.bar1.mass\" = [2.0, 2.0]", "zero width"),
        ("\"link.bar1.mass\" = [1.0, inf]", "finite"),
        ("\"link.bar1.mass\" = [1, 2, 3]", "two bounds, not 3"),
        (
            "\"link.bar1.mass\" = { rel = 0.1, abs = 0.1 }",
            "exactly one key",
        ),
        ("\"link.bar1.mass\" = \"2\"", "write [lower, upper]"),
        ("l1 = { rel = 0.1 }", "explicit bounds only"),
        ("\"link.bar1.mass\" = [-1, 3]", "a mass must be ≥ 0"),
        ("\"joint.j1.damping\" = { abs = 1 }", "damping must be ≥ 0"),
    ];
    for (line, expected) in cases {
        let msg = error(&format!("[parameters]\n{line}\n"));
        assert!(msg.contains(expected), "{line}: {msg}");
    }
}

#[test]
fn box_creating_a_triangle_violation_is_refused_at_a_corner() {
    // bar2: ixx 0.1, iyy 0.15, izz 0.2. At ixx = 0.05, izz = 0.3: 0.05 + 0.15 < 0.3.
    let msg = error(
        r#"[parameters]
        "link.bar2.inertia.ixx" = [0.05, 0.1]
        "link.bar2.inertia.izz" = [0.15, 0.3]"#,
    );
    assert!(
        msg.contains(
            "at the corner \"link.bar2.inertia.ixx\" = 0.05, \"link.bar2.inertia.izz\" = 0.3"
        ) && msg.contains("link 'bar2'")
            && msg.contains("triangle inequality"),
        "{msg}"
    );
    // A box whose corners are all physical passes (affine: the corners prove it).
    let s = space(
        r#"[parameters]
        "link.bar2.inertia.ixx" = [0.09, 0.1]
        "link.bar2.inertia.izz" = [0.19, 0.21]
        "link.bar2.mass" = [0.5, 1.5]"#,
    )
    .unwrap();
    assert!(s.warnings().is_empty(), "{:?}", s.warnings());
}

#[test]
fn off_diagonal_inertia_is_checked_on_principal_moments() {
    // A product of inertia large enough to break the triangle inequality of principal moments while
    // the diagonal alone passes.
    let msg = error("[parameters]\n\"link.bar2.inertia.ixy\" = [-0.1, 0.1]\n");
    assert!(msg.contains("link 'bar2'"), "{msg}");
}

#[test]
fn nominal_violation_only_warns() {
    let s = space("[parameters]\n\"link.bad.inertia.izz\" = [0.29, 0.31]\n").unwrap();
    let w = s.warnings().join("\n");
    assert!(
        w.contains("the URDF inertia of link 'bad' violates the triangle inequality")
            && w.contains("[parameters] \"link.bad.inertia.izz\""),
        "{w}"
    );
}

#[test]
fn nonlinear_bind_violation_is_found_by_the_grid() {
    // izz = 0.2 at s = -1, 0, 1 (corners and midpoint fine), 0.275 at s = ±0.5 > 0.1 + 0.15.
    let msg = error(
        r#"[parameters]
        s = [-1, 1]
        [bind]
        "link.bar2.inertia.izz" = "0.2 + 0.4 * s^2 * (1 - s^2)""#,
    );
    assert!(
        msg.contains("at the grid point s = -0.5 (giving \"link.bar2.inertia.izz\" = 0.275")
            && msg.contains("link 'bar2'"),
        "{msg}"
    );
}

#[test]
fn bound_values_are_validated_over_the_box() {
    let msg = error(
        r#"[parameters]
        l1 = [0.5, 3.5]
        [bind]
        "link.bar1.mass" = "l1 - 1""#,
    );
    assert!(
        msg.contains("[bind] \"link.bar1.mass\" = \"l1 - 1\" is -0.5 at l1 = 0.5")
            && msg.contains("a mass must be ≥ 0"),
        "{msg}"
    );
}

#[test]
fn no_parameters_is_an_empty_space() {
    let s = space("").unwrap();
    assert!(s.is_empty() && s.nominal_xi().is_empty() && s.warnings().is_empty());
    let mut m = model();
    s.apply(&mut m, &mut Environment::default(), &[]);
    assert_eq!(m.bodies[0].inertia.mass, 2.0);
}

#[test]
fn symbol_names() {
    assert!(is_symbol_name("l1") && is_symbol_name("_a") && is_symbol_name("L_2b"));
    assert!(!is_symbol_name("1l") && !is_symbol_name("a.b") && !is_symbol_name(""));
    assert!(!is_symbol_name("a-b"));
}

#[test]
fn a_space_is_shared_between_threads() {
    fn shareable<T: Send + Sync>() {}
    shareable::<ParameterSpace>();
}

#[test]
fn a_constant_binding_is_validated_too() {
    let msg = error("[bind]\n\"link.bar1.mass\" = \"-1/2\"\n");
    assert!(
        msg.contains("[bind] \"link.bar1.mass\" = \"-1/2\" is -0.5 at every point of the box"),
        "{msg}"
    );
}

// ---- patterns, groups, scale, derivatives (issue 11 §1) ----

fn ur5() -> Model {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5/ur5.urdf");
    Model::from_urdf_file(&path, LoadOptions::default()).unwrap()
}

fn ur5_space(sidecar: &str) -> Result<ParameterSpace, UncertaintyError> {
    let file = parse_sidecar(sidecar).unwrap();
    ParameterSpace::from_sidecar(&file, &ur5(), &Environment::default(), "ur5.test.toml")
}

fn value(m: &Model, path: &str) -> f64 {
    params::get(
        m,
        &Environment::default(),
        params::resolve(m, &Environment::default(), path).unwrap(),
    )
}

#[test]
fn dimensions_carry_their_source_and_unit() {
    let s = ur5_space(
        r#"[parameters]
        "link.*.mass" = { rel = 0.03 }
        "joint.*.origin.z" = { abs = 0.0005, shared = true }
        "link.*.scale" = { rel = 0.05 }
        s1 = [0.9, 1.1]
        [bind]
        "joint.wrist_1_joint.damping" = "s1""#,
    )
    .unwrap();
    let d = s.dimensions();
    assert_eq!(s.len(), 6 + 1 + 6 + 1);
    assert_eq!(
        (d[0].name.as_str(), d[0].source.as_str(), d[0].unit),
        ("link.shoulder_link.mass", "link.*.mass", "kg")
    );
    assert_eq!(
        (d[0].lower, d[0].upper),
        (3.7 - 0.03 * 3.7, 3.7 + 0.03 * 3.7)
    );
    assert_eq!(
        (d[6].name.as_str(), d[6].source.as_str(), d[6].unit),
        ("joint.*.origin.z", "joint.*.origin.z", "m")
    );
    assert_eq!(
        (d[6].lower, d[6].nominal, d[6].upper),
        (-0.0005, 0.0, 0.0005)
    );
    assert_eq!(d[6].kind, DimensionKind::Group(0));
    assert_eq!(
        (d[7].name.as_str(), d[7].unit, d[7].nominal),
        ("link.shoulder_link.scale", "", 1.0)
    );
    assert_eq!((d[13].source.as_str(), d[13].unit), ("s1", ""));
    assert_eq!(s.nominal_xi()[6], 0.0);
}

#[test]
fn a_shared_group_moves_every_match_together() {
    let s = ur5_space(
        r#"[parameters]
        "link.*.mass" = { rel = 0.1, shared = true }
        "joint.*.origin.z" = { abs = 0.001, shared = true }"#,
    )
    .unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(s.groups()[0].members.len(), 6);
    let nominal = ur5();
    let mut m = ur5();
    for xi in [-1.0, 1.0, 0.0, 0.25] {
        s.apply(&mut m, &mut Environment::default(), &[xi, xi]);
        for link in MOVING_LINKS {
            let path = format!("link.{link}.mass");
            let expected = value(&nominal, &path) * (1.0 + 0.1 * xi);
            assert_eq!(value(&m, &path), expected, "{path} at ξ = {xi}");
        }
        for joint in &nominal.description.joints {
            let path = format!("joint.{}.origin.z", joint.name);
            let expected = value(&nominal, &path) + 0.001 * xi;
            assert_eq!(value(&m, &path), expected, "{path} at ξ = {xi}");
        }
        // Values no dimension moves stay put.
        assert_eq!(
            value(&m, "link.base_link.mass"),
            value(&nominal, "link.base_link.mass")
        );
    }
    // ξ = 0 gives the URDF values bitwise, so the nominal run is the URDF robot.
    s.apply(&mut m, &mut Environment::default(), &[0.0, 0.0]);
    assert_eq!(
        m.description, nominal.description,
        "the nominal point must reproduce the URDF"
    );
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
fn groups_cannot_make_a_mass_negative() {
    // wrist_3_link weighs 0.1879 kg: an offset of ±0.5 kg makes it negative at ξ = −1.
    let message = ur5_space("[parameters]\n\"link.*.mass\" = { abs = 0.5, shared = true }\n")
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("[parameters] \"link.*.mass\": a bound is impossible: parameter 'link.wrist_3_link.mass' cannot be -0.3121")
            && message.contains("a mass must be ≥ 0"),
        "{message}"
    );
    // Per match too.
    let message = ur5_space("[parameters]\n\"link.*.mass\" = { abs = 0.5 }\n")
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("[parameters] \"link.*.mass\" (match \"link.wrist_3_link.mass\"): a bound is impossible"),
        "{message}"
    );
    // A relative interval beyond 100 % would too.
    let message = ur5_space("[parameters]\n\"link.*.mass\" = { rel = 1.5, shared = true }\n")
        .unwrap_err()
        .to_string();
    assert!(message.contains("a mass must be ≥ 0"), "{message}");
}

#[test]
fn scale_multiplies_mass_and_inertia_and_combines_with_a_mass_interval() {
    let s = space(
        r#"[parameters]
        "link.bar1.mass" = [1.0, 2.5]
        "link.bar1.scale" = { rel = 0.1 }"#,
    )
    .unwrap();
    assert_eq!(s.dimensions()[1].unit, "");
    let mut m = model();
    let com_before = m.bodies[0].inertia.com().unwrap();
    s.apply(&mut m, &mut Environment::default(), &[1.0, 1.0]);
    let body = &m.bodies[0].inertia;
    assert_eq!(body.mass, 2.5 * 1.1);
    // COM unchanged; the rotational inertia about the COM scaled by the same factor.
    assert!((body.com().unwrap() - com_before).norm() < 1e-15);
    let about_com = body.inertia_about_com().unwrap();
    assert!((about_com[(1, 1)] - 0.1 * 1.1).abs() < 1e-15, "{about_com}");
    // The description keeps the declared mass; the scale lives beside it.
    assert_eq!(m.description.links[1].inertial.mass, 2.5);
    assert_eq!(m.inertial_scales[1], 1.1);
    assert_eq!(m.effective_inertial(1).mass, 2.5 * 1.1);
    // A scale ≤ 0 is refused.
    let message = error("[parameters]\n\"link.bar1.scale\" = [-0.5, 1.5]\n");
    assert!(message.contains("a scale must be > 0"), "{message}");
}

/// Central differences of `apply` in ξ_j against `target_derivatives`: every value the model
/// exposes through the registry is read back.
fn check_target_derivatives(s: &ParameterSpace, m0: &Model, xi: &[f64], tolerance: f64) {
    // Step of the check's own central difference (in ξ); the values are affine or smooth.
    const STEP: f64 = 1e-4;
    let registry = params::list(m0, &Environment::default());
    let mut derivatives = Vec::new();
    for j in 0..s.len() {
        s.target_derivatives(xi, j, &mut derivatives);
        assert!(!derivatives.is_empty(), "dimension {j} moves nothing");
        let mut plus = (m0.clone(), Environment::default());
        let mut minus = (m0.clone(), Environment::default());
        let mut at = xi.to_vec();
        at[j] = xi[j] + STEP;
        s.apply(&mut plus.0, &mut plus.1, &at);
        at[j] = xi[j] - STEP;
        s.apply(&mut minus.0, &mut minus.1, &at);
        for info in &registry {
            let difference = (params::get(&plus.0, &plus.1, info.target)
                - params::get(&minus.0, &minus.1, info.target))
                / (2.0 * STEP);
            let claimed = derivatives
                .iter()
                .find(|(t, _)| *t == info.target)
                .map_or(0.0, |(_, v)| *v);
            let scale = claimed.abs().max(1e-300);
            assert!(
                (difference - claimed).abs() <= tolerance * scale.max(difference.abs()),
                "dimension {} ({}), {}: central difference {difference:e}, target_derivatives {claimed:e}",
                j,
                s.dimensions()[j].name,
                info.path
            );
        }
    }
}

#[test]
fn target_derivatives_match_central_differences_of_apply() {
    // Path, pattern match, group (factor and offset) and bound-symbol dimensions.
    let s = ur5_space(
        r#"[parameters]
        "link.forearm_link.mass" = [2.0, 2.5]
        "link.*.scale" = { rel = 0.05 }
        "link.*.com.x" = { abs = 0.002, shared = true }
        "joint.*.origin.z" = { rel = 0.01, shared = true }
        l = [0.42, 0.43]
        c = [0.9, 1.1]
        [bind]
        "joint.elbow_joint.origin.x" = "-l"
        "link.upper_arm_link.com.z" = "c * c * 0.11336"
        "link.upper_arm_link.inertia.iyy" = "sqrt(l) * c / 4.86""#,
    )
    .unwrap();
    let m0 = ur5();
    let d = s.len();
    // Relative agreement: the affine values are exact up to rounding of the check's own
    // difference (1e-4 step: ~1e-12 relative); the nonlinear bindings to its truncation error
    // (step² · f'''/6 ≈ 1e-9 relative here).
    const TOLERANCE: f64 = 1e-7;
    let interior: Vec<f64> = (0..d).map(|k| 0.3 - 0.1 * k as f64 % 0.7).collect();
    check_target_derivatives(&s, &m0, &interior, TOLERANCE);
    check_target_derivatives(&s, &m0, &s.nominal_xi(), TOLERANCE);
    // On a face of the box the one-sided difference is used for symbols.
    let mut face = interior.clone();
    let symbol = s.dimensions().iter().position(|x| x.name == "c").unwrap();
    face[symbol] = 1.0;
    let mut derivatives = Vec::new();
    s.target_derivatives(&face, symbol, &mut derivatives);
    // "c * c * 0.11336": ∂/∂ξ = 2 c r 0.11336 with c = 1.1 and r = 0.1.
    let (_, com_z) = derivatives
        .iter()
        .find(|(t, _)| {
            *t == params::resolve(&m0, &Environment::default(), "link.upper_arm_link.com.z")
                .unwrap()
        })
        .copied()
        .unwrap();
    let exact = 2.0 * 1.1 * 0.1 * 0.11336;
    assert!((com_z - exact).abs() <= 1e-9 * exact, "{com_z} vs {exact}");
    // Sizes: a group lists every member, a symbol every binding that uses it.
    s.target_derivatives(&interior, 7, &mut derivatives);
    assert_eq!(s.dimensions()[7].name, "link.*.com.x");
    assert_eq!(derivatives.len(), 6);
    s.target_derivatives(&interior, symbol - 1, &mut derivatives);
    assert_eq!(derivatives.len(), 2, "l is used by two bindings");
}

#[test]
fn a_box_of_more_than_100_dimensions_is_checked_link_by_link() {
    let sidecar = r#"[parameters]
        "link.*.mass" = { rel = 0.03 }
        "link.*.com.*" = { abs = 0.002 }
        "link.*.inertia.*" = { abs = 1e-5 }
        "link.*.inertia.ixx" = { rel = 0.01, shared = true }
        "link.*.scale" = { rel = 0.05 }
        "joint.*.origin.*" = { abs = 0.0005 }"#;
    let file = parse_sidecar(sidecar).unwrap();
    let m0 = ur5();
    let start = std::time::Instant::now();
    let s =
        ParameterSpace::from_sidecar(&file, &m0, &Environment::default(), "ur5.test.toml").unwrap();
    let elapsed = start.elapsed();
    // 6 masses, 18 COM, 6 × 5 own inertia entries + 1 shared ixx, 6 scales, 7 × 6 origins.
    assert_eq!(s.len(), 6 + 18 + 30 + 1 + 6 + 42);
    assert!(s.len() >= 100);
    let summary = s.box_check();
    // Each of the 6 moving links depends on its 5 own inertia entries and the shared ixx group:
    // 2^6 corners each, and nothing else is visited (no bindings).
    assert_eq!(
        summary,
        BoxCheckSummary {
            links: 6,
            inertia_points: 6 * 64,
            binding_points: 0,
        }
    );
    assert!(s.warnings().is_empty(), "{:?}", s.warnings());
    // Timing for the report only (printed, never asserted: the machine is shared).
    let mut m = ur5();
    let xi: Vec<f64> = (0..s.len()).map(|k| (k as f64 * 0.61).sin()).collect();
    const APPLIES: u32 = 10_000;
    let start = std::time::Instant::now();
    for _ in 0..APPLIES {
        s.apply(
            &mut m,
            &mut Environment::default(),
            std::hint::black_box(&xi),
        );
    }
    let per_apply = start.elapsed() / APPLIES;
    println!(
        "d = {}: box check visited {} inertia points on {} links; building the space took {:.2} ms; apply took {:.2} µs",
        s.len(),
        summary.inertia_points,
        summary.links,
        elapsed.as_secs_f64() * 1e3,
        per_apply.as_secs_f64() * 1e6
    );
}

#[test]
fn a_shared_inertia_group_that_breaks_one_link_is_refused() {
    // One factor on every link's izz: bar1 (ixx 0.01, iyy 0.1, izz 0.1) breaks its triangle
    // inequality at the lower corner (0.01 + 0.07 < 0.1), bar2 (0.1, 0.15, 0.2) at the upper one
    // (0.1 + 0.15 < 0.26). Links are checked in order, so bar1's corner is named.
    let message = error(
        r#"[parameters]
        "link.*.inertia.izz" = { rel = 0.3, shared = true }"#,
    );
    assert!(
        message.contains("link 'bar1'") && message.contains("corner \"link.*.inertia.izz\" = 0.7"),
        "{message}"
    );
    // Narrow enough for bar1 but not for bar2: bar2's upper corner is named.
    let message = error(
        r#"[parameters]
        "link.bar2.inertia.izz" = { rel = 0.3 }"#,
    );
    assert!(
        message.contains("link 'bar2'") && message.contains("\"link.bar2.inertia.izz\" = 0.26"),
        "{message}"
    );
}

#[test]
fn apply_allocates_nothing_with_groups_scales_and_bindings() {
    use crate::integrate::tests::alloc_counter::allocations;
    let s = ur5_space(
        r#"[parameters]
        "link.*.mass" = { rel = 0.03 }
        "link.*.com.*" = { abs = 0.002 }
        "link.*.scale" = { rel = 0.05 }
        "joint.*.origin.*" = { abs = 0.0005 }
        "link.*.inertia.ixx" = { rel = 0.01, shared = true }
        l = [0.42, 0.43]
        [bind]
        "joint.elbow_joint.origin.x" = "-l""#,
    )
    .unwrap();
    let mut m = ur5();
    let xi: Vec<f64> = (0..s.len()).map(|k| (k as f64 * 0.37).sin()).collect();
    let mut derivatives = Vec::with_capacity(16);
    s.target_derivatives(&xi, 0, &mut derivatives);
    let before = allocations();
    s.apply(&mut m, &mut Environment::default(), &xi);
    let checked = s.check_bound_values(&m, &xi);
    for j in 0..s.len() {
        s.target_derivatives(&xi, j, &mut derivatives);
    }
    assert_eq!(
        allocations() - before,
        0,
        "apply, check_bound_values or target_derivatives allocated"
    );
    assert!(checked.is_ok(), "{checked:?}");
}
