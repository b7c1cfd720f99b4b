//! Property tests (proptest): identities that must hold for every input, not just the examples the
//! unit tests pick.
//!
//! - Spatial algebra: transform composition and inverse, `act`/`inv_act` of motions and forces,
//!   invariance of power, inertia transforms (mass kept, inertia about the COM stays PSD, momentum
//!   transforms like a force).
//! - Dynamics on random consistent trees (revolute, continuous, prismatic and fixed joints; each
//!   link a solid box of random size, mass, centre and orientation; optional floating base): `M`
//!   symmetric positive definite, `RNEA(q, v, ABA(q, v, τ)) = τ`, `M q̈ + b = RNEA(q, v, q̈)`, and
//!   the energy balance of damped passive motion over a short RK4 integration.
//! - The `[bind]` expression parser: random expression trees printed with the fewest parentheses
//!   the documented grammar allows (precedence, right-associative `^`, `-a^b = -(a^b)`), parsed and
//!   evaluated, against a reference evaluator of the tree.
//!
//! Case counts are modest (CI time: about a second in release); `PROPTEST_CASES` raises them.

use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use ribbon::dynamics::{crba, forward_dynamics, forward_kinematics, nonlinear_effects, rnea, Data};
use ribbon::environment::DEFAULT_GRAVITY;
use ribbon::model::{LoadOptions, Model};
use ribbon::spatial::{rotation_from_rpy, Force, Inertia, Mat3, Motion, Transform, Vec3};
use ribbon::uncertainty::Expression;

/// The gravity every dynamics property here is checked under (m/s²).
fn standard_gravity() -> Vec3 {
    Vec3::from(DEFAULT_GRAVITY)
}

/// Identities of the spatial algebra hold to round-off: a few operations on values of order 1–10.
const SPATIAL_TOLERANCE: f64 = 1e-11;
/// Dynamics identities, relative to the size of the quantities (`max(‖·‖∞, 1)`): recursive
/// algorithms on ≤ 6 bodies, and a Cholesky solve of a matrix whose condition the box sizes bound.
const DYNAMICS_TOLERANCE: f64 = 1e-9;
/// Energy balance over the RK4 integration, relative to `max(|E|, 1)`: RK4's global error at
/// `ENERGY_STEP_S` over `ENERGY_DURATION_S` on these bodies (smallest principal moment ~ 4e-4 kg·m²,
/// speeds of a few rad/s) is ~1e-9; 1e-6 leaves margin and still catches a wrong term, which shows
/// at ≥ 1e-3.
const ENERGY_TOLERANCE: f64 = 1e-6;
const ENERGY_STEP_S: f64 = 1e-3;
const ENERGY_DURATION_S: f64 = 0.2;

/// `cases`, or `PROPTEST_CASES` from the environment when set (for longer runs by hand).
fn config(cases: u32) -> ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(cases);
    ProptestConfig {
        cases,
        ..ProptestConfig::default()
    }
}

fn vec3(range: f64) -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-range..range).prop_map(Vec3::from)
}

fn transform() -> impl Strategy<Value = Transform> {
    (prop::array::uniform3(-3.2f64..3.2), vec3(2.0))
        .prop_map(|(rpy, t)| Transform::new(rotation_from_rpy(rpy[0], rpy[1], rpy[2]), t))
}

fn motion() -> impl Strategy<Value = Motion> {
    (vec3(5.0), vec3(5.0)).prop_map(|(l, a)| Motion::new(l, a))
}

fn force() -> impl Strategy<Value = Force> {
    (vec3(5.0), vec3(5.0)).prop_map(|(l, a)| Force::new(l, a))
}

/// A solid box: mass, half extents' squares give principal moments that satisfy the triangle
/// inequality, turned by a random rotation and centred at a random point.
fn inertia() -> impl Strategy<Value = Inertia> {
    (
        0.1f64..10.0,
        prop::array::uniform3(0.05f64..1.0),
        prop::array::uniform3(-3.2f64..3.2),
        vec3(1.0),
    )
        .prop_map(|(mass, size, rpy, com)| {
            let [a, b, c] = size.map(|s| s * s);
            let principal = Mat3::from_diagonal(&Vec3::new(b + c, a + c, a + b)) * (mass / 12.0);
            let r = rotation_from_rpy(rpy[0], rpy[1], rpy[2]);
            Inertia::from_com(mass, com, r * principal * r.transpose())
        })
}

fn close(a: &[f64], b: &[f64], tolerance: f64) -> bool {
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= tolerance * scale)
}

fn m6(m: &Motion) -> [f64; 6] {
    [
        m.linear.x,
        m.linear.y,
        m.linear.z,
        m.angular.x,
        m.angular.y,
        m.angular.z,
    ]
}

fn f6(f: &Force) -> [f64; 6] {
    [
        f.linear.x,
        f.linear.y,
        f.linear.z,
        f.angular.x,
        f.angular.y,
        f.angular.z,
    ]
}

fn t12(t: &Transform) -> Vec<f64> {
    t.rotation
        .iter()
        .chain(t.translation.iter())
        .copied()
        .collect()
}

proptest! {
    #![proptest_config(config(256))]

    #[test]
    fn composition_is_associative_and_inverse_cancels(a in transform(), b in transform(), c in transform()) {
        let left = a.compose(&b).compose(&c);
        let right = a.compose(&b.compose(&c));
        prop_assert!(close(&t12(&left), &t12(&right), SPATIAL_TOLERANCE));
        let identity = t12(&Transform::identity());
        prop_assert!(close(&t12(&a.compose(&a.inverse())), &identity, SPATIAL_TOLERANCE));
        prop_assert!(close(&t12(&a.inverse().compose(&a)), &identity, SPATIAL_TOLERANCE));
    }

    #[test]
    fn act_and_inv_act_are_inverse_and_compose(a in transform(), b in transform(), m in motion(), f in force()) {
        prop_assert!(close(&m6(&a.inv_act_motion(&a.act_motion(&m))), &m6(&m), SPATIAL_TOLERANCE));
        prop_assert!(close(&f6(&a.inv_act_force(&a.act_force(&f))), &f6(&f), SPATIAL_TOLERANCE));
        let ab = a.compose(&b);
        prop_assert!(close(&m6(&ab.act_motion(&m)), &m6(&a.act_motion(&b.act_motion(&m))), SPATIAL_TOLERANCE));
        prop_assert!(close(&f6(&ab.act_force(&f)), &f6(&a.act_force(&b.act_force(&f))), SPATIAL_TOLERANCE));
        prop_assert!(close(&m6(&a.inverse().act_motion(&m)), &m6(&a.inv_act_motion(&m)), SPATIAL_TOLERANCE));
        // Power does not depend on the frame it is computed in.
        let power = m.dot(&f);
        let moved = a.act_motion(&m).dot(&a.act_force(&f));
        prop_assert!((power - moved).abs() <= SPATIAL_TOLERANCE * power.abs().max(1.0) * 10.0);
    }

    #[test]
    fn inertia_transforms_keep_mass_and_physical_shape(x in transform(), inertia in inertia(), m in motion()) {
        let moved = x.act_inertia(&inertia);
        prop_assert_eq!(moved.mass, inertia.mass);
        // About its COM the moved inertia is the original rotated: PSD with the same spectrum.
        let about_com = moved.inertia_about_com().unwrap();
        let mut eigen: Vec<f64> = about_com.symmetric_eigenvalues().iter().copied().collect();
        let mut original: Vec<f64> = inertia.inertia_about_com().unwrap().symmetric_eigenvalues().iter().copied().collect();
        eigen.sort_by(f64::total_cmp);
        original.sort_by(f64::total_cmp);
        prop_assert!(eigen[0] >= -SPATIAL_TOLERANCE, "{eigen:?}");
        prop_assert!(close(&eigen, &original, 1e-10));
        // Momentum is a force: X (I m) = (X I)(X m).
        let direct = x.act_force(&inertia.apply(&m));
        let via = moved.apply(&x.act_motion(&m));
        prop_assert!(close(&f6(&via), &f6(&direct), SPATIAL_TOLERANCE * 10.0));
        // The kinetic energy ½ m·(I m) is ≥ 0 and frame-independent.
        let energy = m.dot(&inertia.apply(&m));
        prop_assert!(energy >= -SPATIAL_TOLERANCE);
        let moved_energy = x.act_motion(&m).dot(&via);
        prop_assert!((energy - moved_energy).abs() <= 1e-10 * energy.abs().max(1.0));
    }
}

// ---------------------------------------------------------------------------------------------
// Random robots.

/// One link of a random tree: its parent among the earlier links, its joint and its box.
#[derive(Clone, Debug)]
struct LinkSpec {
    parent: usize,
    joint: &'static str,
    origin: [f64; 6],
    axis: [f64; 3],
    mass: f64,
    size: [f64; 3],
    com: [f64; 3],
    rpy: [f64; 3],
    damping: f64,
}

fn link_spec() -> impl Strategy<Value = LinkSpec> {
    (
        any::<prop::sample::Index>(),
        prop::sample::select(vec!["revolute", "continuous", "prismatic", "fixed"]),
        prop::array::uniform6(-0.6f64..0.6),
        prop::array::uniform3(-1.0f64..1.0).prop_filter("a usable axis", |a| {
            a.iter().map(|x| x * x).sum::<f64>() > 0.04
        }),
        0.5f64..5.0,
        prop::array::uniform3(0.1f64..0.5),
        prop::array::uniform3(-0.2f64..0.2),
        prop::array::uniform3(-3.2f64..3.2),
        0.0f64..0.5,
    )
        .prop_map(
            |(parent, joint, origin, axis, mass, size, com, rpy, damping)| LinkSpec {
                parent: parent.index(usize::MAX),
                joint,
                origin,
                axis,
                mass,
                size,
                com,
                rpy,
                damping,
            },
        )
}

/// URDF text of a tree: link 0 is the root, link k hangs from an earlier link.
fn robot_urdf(links: &[LinkSpec]) -> String {
    // The root is a body too, so that a floating base is a consistent model (a massless floating
    // root makes M singular, which ribbon refuses by design — tested in src/model/singular.rs).
    let mut text = String::from(
        "<robot name=\"random\">\n<link name=\"l0\"><inertial><mass value=\"2\"/>\
         <inertia ixx=\"0.02\" ixy=\"0\" ixz=\"0\" iyy=\"0.03\" iyz=\"0\" izz=\"0.04\"/></inertial></link>\n",
    );
    for (k, l) in links.iter().enumerate() {
        let k = k + 1;
        let [a, b, c] = l.size.map(|s| s * s);
        let m = l.mass;
        text += &format!(
            "<link name=\"l{k}\"><inertial><origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><mass value=\"{m}\"/>\
             <inertia ixx=\"{}\" ixy=\"0\" ixz=\"0\" iyy=\"{}\" iyz=\"0\" izz=\"{}\"/></inertial></link>\n",
            l.com[0], l.com[1], l.com[2], l.rpy[0], l.rpy[1], l.rpy[2],
            m * (b + c) / 12.0, m * (a + c) / 12.0, m * (a + b) / 12.0
        );
        let o = l.origin;
        text += &format!(
            "<joint name=\"j{k}\" type=\"{}\"><parent link=\"l{}\"/><child link=\"l{k}\"/>\
             <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><axis xyz=\"{} {} {}\"/>\
             <limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/><dynamics damping=\"{}\"/></joint>\n",
            l.joint, l.parent % k, o[0], o[1], o[2], o[3], o[4], o[5], l.axis[0], l.axis[1], l.axis[2], l.damping
        );
    }
    text + "</robot>\n"
}

/// A model (1–6 links), a state and a torque, all of consistent sizes.
fn robot_and_state() -> impl Strategy<Value = (Model, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>)> {
    (prop::collection::vec(link_spec(), 1..=6), any::<bool>())
        .prop_filter_map("a model that moves", |(links, floating_base)| {
            let model = Model::from_urdf_str(
                &robot_urdf(&links),
                "random.urdf",
                LoadOptions { floating_base },
            )
            .ok()?;
            (model.nv > 0).then_some(model)
        })
        .prop_flat_map(|model| {
            let (nq, nv) = (model.nq, model.nv);
            (
                Just(model),
                prop::collection::vec(-3.0f64..3.0, nq),
                prop::collection::vec(-2.0f64..2.0, nv),
                prop::collection::vec(-5.0f64..5.0, nv),
                prop::collection::vec(-5.0f64..5.0, nv),
            )
        })
        .prop_map(|(model, mut q, v, tau, qdd)| {
            // A floating base's quaternion must be a unit quaternion.
            for joint in model.joints.iter().filter(|j| j.nq() == 7) {
                let quaternion = &mut q[joint.q_index + 3..joint.q_index + 7];
                let norm = quaternion
                    .iter()
                    .map(|x| x * x)
                    .sum::<f64>()
                    .sqrt()
                    .max(1e-3);
                quaternion.iter_mut().for_each(|x| *x /= norm);
                if norm <= 1e-3 {
                    quaternion.copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
                }
            }
            (model, q, v, tau, qdd)
        })
}

proptest! {
    #![proptest_config(config(64))]

    #[test]
    fn mass_matrix_is_symmetric_positive_definite((model, q, _v, _tau, _qdd) in robot_and_state()) {
        let mut data = Data::new(&model);
        let m: DMatrix<f64> = crba(&model, &mut data, &q).clone();
        let scale = m.abs().max().max(1.0);
        prop_assert!((&m - m.transpose()).abs().max() <= DYNAMICS_TOLERANCE * scale);
        let smallest = m.clone().symmetric_eigen().eigenvalues.min();
        prop_assert!(smallest > 0.0, "smallest eigenvalue {smallest} of\n{m}");
    }

    #[test]
    fn inverse_dynamics_inverts_forward_dynamics((model, q, v, tau, qdd) in robot_and_state()) {
        let mut data = Data::new(&model);
        let accelerations = forward_dynamics(&model, &standard_gravity(), &mut data, &q, &v, &tau).unwrap().to_vec();
        let torques = rnea(&model, &standard_gravity(), &mut data, &q, &v, &accelerations).to_vec();
        prop_assert!(close(&torques, &tau, DYNAMICS_TOLERANCE), "{torques:?} vs {tau:?}");
        // M q̈ + b = RNEA(q, v, q̈) for any q̈.
        let m = crba(&model, &mut data, &q).clone();
        let b = DVector::from_column_slice(nonlinear_effects(&model, &standard_gravity(), &mut data, &q, &v));
        let expected = &m * DVector::from_column_slice(&qdd) + b;
        let torques = rnea(&model, &standard_gravity(), &mut data, &q, &v, &qdd).to_vec();
        prop_assert!(close(&torques, expected.as_slice(), DYNAMICS_TOLERANCE));
    }
}

/// Kinetic plus potential energy (J) of a fixed-base model at (q, v).
fn energy(model: &Model, data: &mut Data, q: &[f64], v: &[f64]) -> f64 {
    let m = crba(model, data, q).clone();
    let v = DVector::from_column_slice(v);
    let kinetic = 0.5 * v.dot(&(&m * &v));
    forward_kinematics(model, data, q);
    let potential: f64 = model
        .bodies
        .iter()
        .zip(&data.world_from_body)
        .map(|(body, world_from_body)| {
            let h = world_from_body.rotation * body.inertia.first_moment
                + world_from_body.translation * body.inertia.mass;
            -standard_gravity().dot(&h)
        })
        .sum();
    kinetic + potential
}

/// `[q̇, q̈, power of the damping torques]` for a fixed-base model with joint damping `d`.
fn passive(
    model: &Model,
    data: &mut Data,
    damping: &[f64],
    q: &[f64],
    v: &[f64],
) -> (Vec<f64>, f64) {
    let tau: Vec<f64> = damping.iter().zip(v).map(|(d, v)| -d * v).collect();
    let power = tau.iter().zip(v).map(|(t, v)| t * v).sum();
    (
        forward_dynamics(model, &standard_gravity(), data, q, v, &tau)
            .unwrap()
            .to_vec(),
        power,
    )
}

proptest! {
    #![proptest_config(config(16))]

    #[test]
    fn damped_passive_motion_balances_energy(
        links in prop::collection::vec(link_spec(), 1..=4),
        seed_v in prop::collection::vec(-2.0f64..2.0, 4),
    ) {
        let model = Model::from_urdf_str(&robot_urdf(&links), "random.urdf", LoadOptions::default()).unwrap();
        prop_assume!(model.nv > 0);
        let damping: Vec<f64> = model
            .joints
            .iter()
            .map(|j| model.description.joints[j.source.unwrap()].damping)
            .collect();
        let mut data = Data::new(&model);
        let mut q = vec![0.0; model.nq];
        let mut v: Vec<f64> = seed_v.iter().cycle().take(model.nv).copied().collect();
        let start = energy(&model, &mut data, &q, &v);
        let mut dissipated = 0.0;
        let h = ENERGY_STEP_S;
        let steps = (ENERGY_DURATION_S / h).round() as usize;
        let add = |x: &[f64], k: &[f64], s: f64| x.iter().zip(k).map(|(a, b)| a + s * b).collect::<Vec<f64>>();
        for _ in 0..steps {
            // RK4 on (q, v, W) with q̇ = v (no floating base here), v̇ = ABA, Ẇ = damping power.
            let (a1, p1) = passive(&model, &mut data, &damping, &q, &v);
            let (q2, v2) = (add(&q, &v, h / 2.0), add(&v, &a1, h / 2.0));
            let (a2, p2) = passive(&model, &mut data, &damping, &q2, &v2);
            let (q3, v3) = (add(&q, &v2, h / 2.0), add(&v, &a2, h / 2.0));
            let (a3, p3) = passive(&model, &mut data, &damping, &q3, &v3);
            let (q4, v4) = (add(&q, &v3, h), add(&v, &a3, h));
            let (a4, p4) = passive(&model, &mut data, &damping, &q4, &v4);
            for i in 0..model.nv {
                q[i] += h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
                v[i] += h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
            }
            dissipated += h / 6.0 * (p1 + 2.0 * p2 + 2.0 * p3 + p4);
        }
        let end = energy(&model, &mut data, &q, &v);
        let balance = end - start - dissipated;
        prop_assert!(
            balance.abs() <= ENERGY_TOLERANCE * start.abs().max(1.0),
            "E0 = {start}, E1 = {end}, damping work {dissipated}: imbalance {balance:e}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// The [bind] expression parser.

#[derive(Clone, Debug)]
enum Tree {
    Number(f64),
    Symbol(usize),
    Neg(Box<Tree>),
    Add(Box<Tree>, Box<Tree>),
    Sub(Box<Tree>, Box<Tree>),
    Mul(Box<Tree>, Box<Tree>),
    Div(Box<Tree>, Box<Tree>),
    Pow(Box<Tree>, Box<Tree>),
    Sqrt(Box<Tree>),
}

const SYMBOLS: [&str; 3] = ["l1", "mass", "x_2"];

fn tree() -> impl Strategy<Value = Tree> {
    let leaf = prop_oneof![
        (0u32..1000, 0u32..3)
            .prop_map(|(n, scale)| Tree::Number(f64::from(n) / 10f64.powi(scale as i32))),
        (0usize..SYMBOLS.len()).prop_map(Tree::Symbol),
    ];
    leaf.prop_recursive(5, 40, 2, |inner| {
        prop_oneof![
            inner.clone().prop_map(|a| Tree::Neg(Box::new(a))),
            inner.clone().prop_map(|a| Tree::Sqrt(Box::new(a))),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| Tree::Add(Box::new(a), Box::new(b))),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| Tree::Sub(Box::new(a), Box::new(b))),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| Tree::Mul(Box::new(a), Box::new(b))),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| Tree::Div(Box::new(a), Box::new(b))),
            (inner.clone(), inner).prop_map(|(a, b)| Tree::Pow(Box::new(a), Box::new(b))),
        ]
    })
}

impl Tree {
    /// The reference evaluator: the mathematics of the tree, in f64.
    fn eval(&self, values: &[f64]) -> f64 {
        match self {
            Tree::Number(x) => *x,
            Tree::Symbol(k) => values[*k],
            Tree::Neg(a) => -a.eval(values),
            Tree::Add(a, b) => a.eval(values) + b.eval(values),
            Tree::Sub(a, b) => a.eval(values) - b.eval(values),
            Tree::Mul(a, b) => a.eval(values) * b.eval(values),
            Tree::Div(a, b) => a.eval(values) / b.eval(values),
            Tree::Pow(a, b) => {
                // The documented rule (src/uncertainty/expression.rs): integer exponents up to 64
                // by repeated multiplication (`l^2 == l*l` exactly), others by `powf`.
                let (a, b) = (a.eval(values), b.eval(values));
                if b == b.trunc() && b.abs() <= 64.0 {
                    a.powi(b as i32)
                } else {
                    a.powf(b)
                }
            }
            Tree::Sqrt(a) => a.eval(values).sqrt(),
        }
    }

    /// Binding strength of the printed form: 1 sum, 2 product, 3 unary, 4 power, 5 primary.
    fn strength(&self) -> u8 {
        match self {
            Tree::Add(..) | Tree::Sub(..) => 1,
            Tree::Mul(..) | Tree::Div(..) => 2,
            Tree::Neg(_) => 3,
            Tree::Pow(..) => 4,
            Tree::Number(_) | Tree::Symbol(_) | Tree::Sqrt(_) => 5,
        }
    }

    /// Printed with parentheses only where the grammar needs them.
    fn print(&self) -> String {
        let at_least = |t: &Tree, s: u8| {
            if t.strength() >= s {
                t.print()
            } else {
                format!("({})", t.print())
            }
        };
        match self {
            Tree::Number(x) => format!("{x}"),
            Tree::Symbol(k) => SYMBOLS[*k].to_string(),
            Tree::Neg(a) => format!("-{}", at_least(a, 3)),
            Tree::Sqrt(a) => format!("sqrt({})", a.print()),
            Tree::Add(a, b) => format!("{} + {}", at_least(a, 1), at_least(b, 2)),
            Tree::Sub(a, b) => format!("{} - {}", at_least(a, 1), at_least(b, 2)),
            Tree::Mul(a, b) => format!("{} * {}", at_least(a, 2), at_least(b, 3)),
            Tree::Div(a, b) => format!("{} / {}", at_least(a, 2), at_least(b, 3)),
            // The base is a primary; the exponent a unary (right-associative: 2^3^2 = 2^(3^2)).
            Tree::Pow(a, b) => format!("{}^{}", at_least(a, 5), at_least(b, 3)),
        }
    }
}

proptest! {
    #![proptest_config(config(512))]

    #[test]
    fn printed_expressions_parse_back_to_the_same_value(
        tree in tree(),
        values in prop::array::uniform3(-3.0f64..3.0),
    ) {
        let text = tree.print();
        let parsed = Expression::parse(&text, &SYMBOLS)
            .map_err(|e| TestCaseError::fail(format!("{text}: {e}")))?;
        let (got, expected) = (parsed.eval_with(&values), tree.eval(&values));
        prop_assert!(
            got.to_bits() == expected.to_bits() || (got.is_nan() && expected.is_nan()),
            "{text} at {values:?}: parser {got}, reference {expected}"
        );
    }
}
