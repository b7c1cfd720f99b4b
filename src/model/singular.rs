//! Why a mass matrix is singular, said in terms of joints and links.
//!
//! `M(q)` is singular when some joint velocity `v ≠ 0` moves nothing that has inertia: the kinetic
//! energy `½ vᵀ M v` is zero. The Cholesky factorisation stops at the first coordinate where this
//! shows, which is not necessarily the joint at fault: with a massless floating root, turning a
//! child joint one way while the root turns the other way leaves every massive body at rest, and
//! the pivot vanishes at the *child* joint. So the explanation starts from the null direction `v`
//! itself (computed by the caller) and looks for the massless bodies it moves.

use super::{JointKind, Model};

/// A component of a null direction smaller than this fraction of its largest component does not
/// involve its joint (the direction comes from an eigen-solver; its round-off is ~1e-15).
pub const NULL_DIRECTION_RELATIVE_THRESHOLD: f64 = 1e-6;

/// Whether body `b` has neither mass nor rotational inertia.
pub fn is_massless(model: &Model, b: usize) -> bool {
    let inertia = &model.bodies[b].inertia;
    inertia.mass == 0.0 && inertia.rotational.abs().max() == 0.0
}

/// The first moving joint whose parent is body `b`, if any.
pub fn first_moving_child(model: &Model, b: usize) -> Option<usize> {
    model.joints.iter().position(|j| j.parent == Some(b))
}

/// How a moving body lacks inertia, for messages.
fn lack(model: &Model, b: usize) -> &'static str {
    let inertia = &model.bodies[b].inertia;
    if is_massless(model, b) {
        "has no mass or inertia"
    } else if inertia.mass == 0.0 {
        "has no mass"
    } else {
        "has no inertia for that motion (a point mass or a slender bar along it)"
    }
}

/// Explains a null direction `direction` of `M` (`dim model.nv`, any scale) given the speed
/// `body_speeds[b]` (`dim model.bodies.len()`, the norm of body `b`'s twist under that direction):
/// the joints that move together, the links that move without inertia while everything with
/// inertia stays at rest, and what to do. The words match the load-time warning of [`Model`] for a
/// floating body without inertia.
pub fn explain_null_motion(model: &Model, direction: &[f64], body_speeds: &[f64]) -> String {
    let largest = direction.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let involved: Vec<usize> = model
        .joints
        .iter()
        .enumerate()
        .filter(|(_, j)| {
            direction[j.v_index..j.v_index + j.nv()]
                .iter()
                .any(|x| x.abs() > NULL_DIRECTION_RELATIVE_THRESHOLD * largest)
        })
        .map(|(i, _)| i)
        .collect();
    let fastest = body_speeds.iter().fold(0.0f64, |m, x| m.max(*x));
    let moving: Vec<usize> = (0..model.bodies.len())
        .filter(|&b| body_speeds[b] > NULL_DIRECTION_RELATIVE_THRESHOLD * fastest)
        .collect();
    let joint_names = format!(
        "{} {}",
        if involved.len() == 1 {
            "joint"
        } else {
            "joints"
        },
        involved
            .iter()
            .map(|&j| format!("'{}'", model.joints[j].name))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let link_of = |b: usize| model.description.links[model.bodies[b].link].name.as_str();
    let link_names = moving
        .iter()
        .map(|&b| format!("'{}'", link_of(b)))
        .collect::<Vec<_>>()
        .join(", ");
    // Bodies come in depth-first order: the first moving one is nearest the root, the cause.
    let Some(&first) = moving.first() else {
        return format!("{joint_names} move nothing with inertia");
    };
    let what = lack(model, first);
    let link = link_of(first);
    if model.joints[first].kind == JointKind::Floating {
        format!(
            "link '{link}' (on the floating joint '{}') {what}: {joint_names} can move it while every body with inertia stays at rest — a floating base without inertia; give '{link}' an <inertial> (its real mass and inertia) or load it with a fixed base",
            model.joints[first].name
        )
    } else if involved.len() == 1 && moving.len() == 1 {
        let fix = if model.bodies[first].inertia.mass == 0.0 {
            "an <inertial> or make the joint fixed"
        } else {
            "its rotational inertia"
        };
        format!("{joint_names} moves only link '{link}', which {what}; give '{link}' {fix}")
    } else {
        format!(
            "{joint_names} together move only the links {link_names}, and link '{link}' {what}; give it an <inertial>"
        )
    }
}

#[cfg(test)]
mod tests {
    use crate::dynamics::{forward_dynamics, Data, DynamicsError};
    use crate::model::{LoadOptions, Model};

    const ARM: &str = r#"<robot name="m">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0 0 0.5"/><mass value="1"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.01"/></inertial></link>
  <link name="hand">HAND</link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
  <joint name="wrist" type="revolute"><parent link="arm"/><child link="hand"/><origin xyz="0 0 1"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
</robot>"#;
    const HAND: &str = r#"<inertial><origin xyz="0 0 0.1"/><mass value="0.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"#;

    fn cause(text: &str, floating_base: bool) -> (String, Vec<String>) {
        let model = Model::from_urdf_str(text, "m.urdf", LoadOptions { floating_base }).unwrap();
        let mut data = Data::new(&model);
        let q = model.neutral_configuration();
        let zeros = vec![0.0; model.nv];
        let gravity = crate::spatial::Vec3::from(crate::environment::DEFAULT_GRAVITY);
        match forward_dynamics(&model, &gravity, &mut data, &q, &zeros, &zeros) {
            Err(e @ DynamicsError::SingularMassMatrix { .. }) => (e.to_string(), model.warnings),
            other => panic!("expected a singular mass matrix, got {other:?}"),
        }
    }

    #[test]
    fn a_massless_floating_root_is_blamed_not_the_child_joint() {
        let (msg, warnings) = cause(&ARM.replace("HAND", HAND), true);
        // The pivot vanishes at the shoulder; the cause is the root.
        assert!(msg.contains("at coordinate 6, joint 'shoulder'"), "{msg}");
        assert!(
            msg.contains("link 'base' (on the floating joint 'root_joint') has no mass or inertia: joints 'root_joint', 'shoulder' can move it"),
            "{msg}"
        );
        assert!(
            warnings.iter().any(|w| w
                .starts_with("m.urdf:2: link 'base' is on the floating joint 'root_joint'")
                && w.contains("joint 'shoulder' can move the rest of the robot")),
            "{warnings:?}"
        );
    }

    #[test]
    fn a_massless_leaf_is_blamed_on_its_joint() {
        let (msg, _) = cause(&ARM.replace("HAND", ""), false);
        assert!(
            msg.contains("joint 'wrist' moves only link 'hand', which has no mass or inertia"),
            "{msg}"
        );
    }

    #[test]
    fn a_point_mass_on_the_axis_is_named() {
        let point = r#"<inertial><mass value="0.5"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>"#;
        let (msg, _) = cause(&ARM.replace("HAND", point), false);
        assert!(
            msg.contains("joint 'wrist' moves only link 'hand', which has no inertia for that motion (a point mass or a slender bar along it); give 'hand' its rotational inertia"),
            "{msg}"
        );
    }
}
