//! Derivatives of dynamics quantities that the forward sensitivities need (docs/sensitivities.md §3,
//! §7):
//!
//! - [`link_inertia_derivative`]: how a link's spatial inertia (mass, first moment, inertia about the
//!   link origin) moves with one URDF `<inertial>` value — the chain rule from the URDF's mass, COM
//!   and inertia about the COM to the additive form RNEA is linear in;
//! - [`rnea_inertia_derivative`]: `∂τ/∂I_b · δI` of inverse dynamics along an inertia change `δI` of
//!   one body, from the kinematics of the last [`rnea`](super::rnea) (one column of the
//!   inertial-parameter regressor, Atkeson, An & Hollerbach 1986);
//! - [`link_origin_jacobian`]: `∂x/∂q` of a URDF link's origin in the world frame, along the tangent
//!   space.
//!
//! Nothing here allocates.

use super::{frame_placements, Data};
use crate::model::{InertialSpec, Model};
use crate::spatial::{rotation_from_rpy, Force, Inertia, Mat3, Vec3};
use nalgebra::DMatrix;

/// One value of a URDF `<inertial>`: what [`link_inertia_derivative`] differentiates by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InertialField {
    /// `<mass value>`, kg.
    Mass,
    /// Component 0, 1, 2 (x, y, z) of `<origin xyz>` (the centre of mass in the link frame), m.
    Com(usize),
    /// Component 0..6 (ixx, ixy, ixz, iyy, iyz, izz) of `<inertia>` about the COM in the inertial
    /// frame, kg·m².
    Inertia(usize),
}

/// Row and column of each `<inertia>` component in the symmetric tensor.
const INERTIA_ENTRIES: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// The derivative of [`crate::model::link_inertia`] (the link's spatial inertia about its origin, in
/// the link frame) with respect to one `<inertial>` value `field`, at `inertial`
/// (docs/sensitivities.md §3). With `m` the mass, `c` the COM, `R` the inertial frame's rotation and
/// `I_c` the inertia about the COM, the link inertia is `(m, m c, R I_c Rᵀ + m (|c|² 1 − c cᵀ))`, so
///
/// ```text
/// ∂/∂m   = (1, c, |c|² 1 − c cᵀ)
/// ∂/∂c_i = (0, m e_i, m (2 c_i 1 − e_i cᵀ − c e_iᵀ))
/// ∂/∂I_ab = (0, 0, R E_ab Rᵀ)          E_ab: the symmetric unit matrix of entry (a, b)
/// ```
///
/// Units: per kg, per m or per kg·m² of the field. An out-of-range component index gives zero.
pub fn link_inertia_derivative(inertial: &InertialSpec, field: InertialField) -> Inertia {
    let mass = inertial.mass;
    let com = Vec3::new(inertial.com[0], inertial.com[1], inertial.com[2]);
    match field {
        InertialField::Mass => Inertia {
            mass: 1.0,
            first_moment: com,
            rotational: Mat3::from_diagonal_element(com.norm_squared()) - com * com.transpose(),
        },
        InertialField::Com(i) if i < 3 => {
            let e = Vec3::ith(i, 1.0);
            Inertia {
                mass: 0.0,
                first_moment: e * mass,
                rotational: (Mat3::from_diagonal_element(2.0 * com[i])
                    - e * com.transpose()
                    - com * e.transpose())
                    * mass,
            }
        }
        InertialField::Inertia(i) if i < 6 => {
            let (a, b) = INERTIA_ENTRIES[i];
            let mut unit = Mat3::zeros();
            unit[(a, b)] = 1.0;
            unit[(b, a)] = 1.0;
            let rotation = rotation_from_rpy(inertial.rpy[0], inertial.rpy[1], inertial.rpy[2]);
            Inertia {
                mass: 0.0,
                first_moment: Vec3::zeros(),
                rotational: rotation * unit * rotation.transpose(),
            }
        }
        _ => Inertia::zero(),
    }
}

/// Adds `∂τ/∂I_body · d_inertia` to `tau_out` (dim `nv`): the change of the inverse-dynamics torques
/// when body `body`'s spatial inertia (about its origin, body frame) changes by `d_inertia`, at the
/// state of the last [`rnea`](super::rnea) call on `data` (docs/sensitivities.md §3). RNEA is linear
/// in each body's inertia: the body's own force changes by
/// `δf = δI a_b + v_b ×* (δI v_b)` (gravity included in `a_b` as a base acceleration) and
/// propagates to the root like any body force; no other body's force changes.
///
/// Reads `data.velocity`, `data.acceleration`, `data.parent_from_body` (written by `rnea` or
/// `nonlinear_effects`); overwrites nothing in `data`. Cost: one force transform per ancestor.
pub fn rnea_inertia_derivative(
    model: &Model,
    data: &Data,
    body: usize,
    d_inertia: &Inertia,
    tau_out: &mut [f64],
) {
    let velocity = &data.velocity[body];
    let mut force: Force = d_inertia.apply(&data.acceleration[body])
        + velocity.cross_force(&d_inertia.apply(velocity));
    let mut projected = [0.0; 6];
    let mut current = body;
    loop {
        let joint = &model.joints[current];
        let nv = joint.nv();
        joint.project_force(&force, &mut projected[..nv]);
        for (out, value) in tau_out[joint.v_index..joint.v_index + nv]
            .iter_mut()
            .zip(&projected[..nv])
        {
            *out += value;
        }
        match joint.parent {
            Some(parent) => {
                force = data.parent_from_body[current].act_force(&force);
                current = parent;
            }
            None => break,
        }
    }
}

/// `out = ∂x/∂q` (`3 × nv`, overwritten) of URDF link `link`'s origin `x` in the world frame, along
/// the tangent space (column `i`: the origin's velocity for a unit velocity of coordinate `i`), from
/// the placements of the last [`forward_kinematics`](super::forward_kinematics) on `data`
/// (docs/sensitivities.md §7). A link fixed to the world gives zeros.
pub fn link_origin_jacobian(model: &Model, data: &Data, link: usize, out: &mut DMatrix<f64>) {
    out.fill(0.0);
    let point = frame_placements(model, data, link).translation;
    let mut current = model.links[link].body;
    while let Some(body) = current {
        let joint = &model.joints[body];
        for k in 0..joint.nv() {
            let column = data.world_from_body[body].act_motion(&joint.subspace_column(k));
            let velocity = column.linear + column.angular.cross(&point);
            for axis in 0..3 {
                out[(axis, joint.v_index + k)] = velocity[axis];
            }
        }
        current = joint.parent;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, rnea};
    use crate::model::{link_inertia, parse_description, LoadOptions};

    /// Central differences below are exact to ~1e-10 relative (step 1e-6, smooth functions).
    const FD_AGREEMENT: f64 = 1e-8;

    const ARM: &str = r#"<robot name="arm"><link name="base"/>
      <link name="a"><inertial><origin xyz="0.1 0.02 0.3" rpy="0.3 -0.2 0.5"/><mass value="2"/>
        <inertia ixx="0.05" ixy="0.002" ixz="-0.001" iyy="0.04" iyz="0.003" izz="0.03"/></inertial></link>
      <link name="b"><inertial><origin xyz="0.2 -0.05 0.01" rpy="0 0.4 0"/><mass value="1.2"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
      <link name="tip"><inertial><origin xyz="0.05 0 0"/><mass value="0.3"/>
        <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><origin xyz="0 0 0.1" rpy="0.1 0 0"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.4 0 0.05" rpy="0 0.3 0"/>
        <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <joint name="fix" type="fixed"><parent link="b"/><child link="tip"/><origin xyz="0.3 0.01 0" rpy="0 0 0.2"/></joint>
    </robot>"#;

    fn arm() -> Model {
        let description = parse_description(ARM, "arm.urdf").unwrap();
        Model::from_description(description, LoadOptions::default(), "arm.urdf").unwrap()
    }

    fn fields() -> Vec<InertialField> {
        let mut all = vec![InertialField::Mass];
        all.extend((0..3).map(InertialField::Com));
        all.extend((0..6).map(InertialField::Inertia));
        all
    }

    fn set(inertial: &mut InertialSpec, field: InertialField, value: f64) {
        match field {
            InertialField::Mass => inertial.mass = value,
            InertialField::Com(i) => inertial.com[i] = value,
            InertialField::Inertia(i) => inertial.inertia[i] = value,
        }
    }

    fn get(inertial: &InertialSpec, field: InertialField) -> f64 {
        match field {
            InertialField::Mass => inertial.mass,
            InertialField::Com(i) => inertial.com[i],
            InertialField::Inertia(i) => inertial.inertia[i],
        }
    }

    #[test]
    fn link_inertia_derivative_matches_central_differences() {
        let model = arm();
        let inertial = model.description.links[1].inertial;
        let h = 1e-6;
        for field in fields() {
            let exact = link_inertia_derivative(&inertial, field);
            let (mut plus, mut minus) = (inertial, inertial);
            set(&mut plus, field, get(&inertial, field) + h);
            set(&mut minus, field, get(&inertial, field) - h);
            let (a, b) = (link_inertia(&plus), link_inertia(&minus));
            let mass = (a.mass - b.mass) / (2.0 * h);
            let first = (a.first_moment - b.first_moment) / (2.0 * h);
            let rot = (a.rotational - b.rotational) / (2.0 * h);
            assert!((mass - exact.mass).abs() < FD_AGREEMENT, "{field:?}");
            assert!(
                (first - exact.first_moment).norm() < FD_AGREEMENT,
                "{field:?}"
            );
            assert!((rot - exact.rotational).norm() < FD_AGREEMENT, "{field:?}");
        }
    }

    /// Every inertial value of every link, merged link included: the regressor column equals a central
    /// difference of RNEA with the model refreshed.
    #[test]
    fn rnea_inertia_derivative_matches_central_differences() {
        let mut model = arm();
        model.gravity = Vec3::new(0.3, -1.0, -9.81);
        let mut data = Data::new(&model);
        let (q, v, qdd) = ([0.4, -0.9], [1.3, -0.7], [0.5, 2.0]);
        let h = 1e-6;
        for link in 1..model.description.links.len() {
            for field in fields() {
                rnea(&model, &mut data, &q, &v, &qdd);
                let body = model.links[link].body.unwrap();
                let d_link =
                    link_inertia_derivative(&model.description.links[link].inertial, field);
                let d_body = model.links[link].body_from_link.act_inertia(&d_link);
                let mut exact = [0.0; 2];
                rnea_inertia_derivative(&model, &data, body, &d_body, &mut exact);
                let value = get(&model.description.links[link].inertial, field);
                let mut taus = [[0.0; 2]; 2];
                for (tau, sign) in taus.iter_mut().zip([1.0, -1.0]) {
                    set(
                        &mut model.description.links[link].inertial,
                        field,
                        value + sign * h,
                    );
                    model.refresh();
                    tau.copy_from_slice(rnea(&model, &mut data, &q, &v, &qdd));
                }
                set(&mut model.description.links[link].inertial, field, value);
                model.refresh();
                for i in 0..2 {
                    let numeric = (taus[0][i] - taus[1][i]) / (2.0 * h);
                    assert!(
                        (numeric - exact[i]).abs() < FD_AGREEMENT * numeric.abs().max(1.0),
                        "link {link} {field:?} τ{i}: {} vs {numeric}",
                        exact[i]
                    );
                }
            }
        }
    }

    #[test]
    fn link_origin_jacobian_matches_central_differences() {
        let model = arm();
        let mut data = Data::new(&model);
        let q = [0.4, -0.9];
        let h = 1e-6;
        let mut jacobian = DMatrix::zeros(3, 2);
        for link in 0..model.description.links.len() {
            forward_kinematics(&model, &mut data, &q);
            link_origin_jacobian(&model, &data, link, &mut jacobian);
            for i in 0..2 {
                let mut positions = [Vec3::zeros(); 2];
                for (position, sign) in positions.iter_mut().zip([1.0, -1.0]) {
                    let mut moved = q;
                    moved[i] += sign * h;
                    forward_kinematics(&model, &mut data, &moved);
                    *position = frame_placements(&model, &data, link).translation;
                }
                let numeric = (positions[0] - positions[1]) / (2.0 * h);
                for axis in 0..3 {
                    assert!(
                        (numeric[axis] - jacobian[(axis, i)]).abs() < FD_AGREEMENT,
                        "link {link} coordinate {i}"
                    );
                }
            }
        }
    }
}
