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

/// Explains a null direction `direction` of `M` (`dim model.nv`, any scale): which joints move
/// together without moving inertia, which link is massless, and what to do. The words match the
/// load-time warning of [`Model`] for a massless floating body.
pub fn explain_null_motion(model: &Model, direction: &[f64]) -> String {
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
    let names = |joints: &[usize]| {
        joints
            .iter()
            .map(|&j| format!("'{}'", model.joints[j].name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let link_of = |b: usize| model.description.links[model.bodies[b].link].name.as_str();
    // Joints come in depth-first order, so the first massless body moved is the one nearest the
    // root: the cause, whatever hangs below it.
    let massless = involved.iter().copied().find(|&b| is_massless(model, b));
    match (involved.as_slice(), massless) {
        ([], _) => "no joint moves any inertia (the robot has no mass at all?)".to_string(),
        ([j], Some(_)) => format!(
            "joint '{}' moves link '{}', which has no mass or inertia, and nothing below it (a massless leaf); give '{}' an <inertial> or make the joint fixed",
            model.joints[*j].name,
            link_of(*j),
            link_of(*j)
        ),
        ([j], None) => format!(
            "joint '{}' moves link '{}' (and what hangs below it) without inertia along its motion — e.g. a point mass on the axis of a revolute joint; give '{}' a rotational inertia",
            model.joints[*j].name,
            link_of(*j),
            link_of(*j)
        ),
        (joints, Some(b)) if model.joints[b].kind == JointKind::Floating => format!(
            "link '{}' is on the floating joint '{}' but has no mass or inertia, so joints {} can move the rest of the robot while '{}' moves the other way at no cost (a massless floating base); give '{}' an <inertial> (its real mass) or load it with a fixed base",
            link_of(b),
            model.joints[b].name,
            names(joints),
            link_of(b),
            link_of(b)
        ),
        (joints, Some(b)) => format!(
            "joints {} together move nothing with inertia: link '{}' (moved by '{}') has no mass or inertia, so the joints below it can turn against it at no cost; give '{}' an <inertial>",
            names(joints),
            link_of(b),
            model.joints[b].name,
            link_of(b)
        ),
        (joints, None) => format!(
            "joints {} together move nothing with inertia (their links are point masses or slender bars aligned with the motion); give those links rotational inertia",
            names(joints)
        ),
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
        match forward_dynamics(&model, &mut data, &q, &zeros, &zeros) {
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
            msg.contains("link 'base' is on the floating joint 'root_joint' but has no mass"),
            "{msg}"
        );
        assert!(msg.contains("a massless floating base"), "{msg}");
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
            msg.contains("joint 'wrist' moves link 'hand', which has no mass or inertia"),
            "{msg}"
        );
    }

    #[test]
    fn a_point_mass_on_the_axis_is_named() {
        let point = r#"<inertial><mass value="0.5"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>"#;
        let (msg, _) = cause(&ARM.replace("HAND", point), false);
        assert!(
            msg.contains(
                "joint 'wrist' moves link 'hand' (and what hangs below it) without inertia"
            ),
            "{msg}"
        );
    }
}
