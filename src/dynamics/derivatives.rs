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
//!   space;
//! - [`rnea_derivatives`]: the full Jacobians `∂τ/∂q` (tangent space) and `∂τ/∂q̇` of inverse
//!   dynamics, analytically (docs/sensitivities.md §2).
//!
//! Nothing here allocates after [`RneaDerivatives::new`].

use super::{forward_kinematics, rnea, world_from_link, Data};
use crate::model::{InertialSpec, Model};
use crate::spatial::{rotation_from_rpy, Force, Inertia, Mat3, Motion, Vec3};
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
    /// `link.NAME.scale`: one factor on the mass and the whole inertia tensor, COM unchanged.
    Scale,
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
/// ∂/∂s   = the whole link inertia        (scale: every part is linear in it)
/// ```
///
/// These are derivatives of the *unscaled* inertia; with a `link.NAME.scale` factor `s` the
/// effective inertia is `s` times it, so the mass, COM and inertia derivatives are multiplied by `s`
/// by the caller.
///
/// Units: per kg, per m or per kg·m² of the field. An out-of-range component index gives zero.
pub fn link_inertia_derivative(inertial: &InertialSpec, field: InertialField) -> Inertia {
    if field == InertialField::Scale {
        // The link inertia is linear in the scale: its derivative is the unscaled inertia.
        return crate::model::link_inertia(inertial);
    }
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
    let point = world_from_link(model, data, link).translation;
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

/// Work buffers of [`rnea_derivatives`] for one model (world-frame quantities per body and per
/// velocity coordinate).
#[derive(Clone, Debug)]
pub struct RneaDerivatives {
    /// Body velocities, world frame.
    velocity: Vec<Motion>,
    /// Body accelerations (gravity included), world frame.
    acceleration: Vec<Motion>,
    /// Body inertias, world frame.
    inertia: Vec<Inertia>,
    /// Forces transmitted to each body's subtree (`F_i = Σ_{k ⪰ i} f_k`), world frame.
    subtree_force: Vec<Force>,
    /// `I_i v_i`, world frame.
    momentum: Vec<Force>,
    /// Motion subspace column of each velocity coordinate, world frame.
    column: Vec<Motion>,
    /// Body of each velocity coordinate.
    body_of: Vec<usize>,
    /// One past the last body of each body's subtree (bodies are in depth-first order).
    subtree_end: Vec<usize>,
    /// Subtree sums of the position correction terms, per body.
    sum_q: Vec<Force>,
    /// Subtree sums of the velocity terms, per body.
    sum_v: Vec<Force>,
}

impl RneaDerivatives {
    /// Buffers for `model` (the only allocation).
    pub fn new(model: &Model) -> Self {
        let nb = model.bodies.len();
        let mut body_of = vec![0; model.nv];
        for (b, joint) in model.joints.iter().enumerate() {
            for k in 0..joint.nv() {
                body_of[joint.v_index + k] = b;
            }
        }
        let mut subtree_end: Vec<usize> = (1..=nb).collect();
        for b in (0..nb).rev() {
            if let Some(p) = model.joints[b].parent {
                subtree_end[p] = subtree_end[p].max(subtree_end[b]);
            }
        }
        Self {
            velocity: vec![Motion::zero(); nb],
            acceleration: vec![Motion::zero(); nb],
            inertia: vec![Inertia::zero(); nb],
            subtree_force: vec![Force::zero(); nb],
            momentum: vec![Force::zero(); nb],
            column: vec![Motion::zero(); model.nv],
            body_of,
            subtree_end,
            sum_q: vec![Force::zero(); nb],
            sum_v: vec![Force::zero(); nb],
        }
    }
}

/// `dq_out = ∂τ/∂q` (along the tangent space: column `c` is the derivative along `q ⊕ ε e_c`) and
/// `dv_out = ∂τ/∂q̇` (both `nv × nv`, overwritten) of inverse dynamics
/// `τ = M(q) q̈ + C(q, q̇) q̇ + g(q)` at `(q, q̇, q̈)`, rigid-body terms only (docs/sensitivities.md
/// §2; the world-frame recursions of Carpentier & Mansard 2018, written here as one pass per
/// coordinate over its subtree).
///
/// In the world frame, moving coordinate `c` of joint `j` (world-frame column `S`) turns every
/// quantity of `j`'s subtree by `S`, except that velocities and accelerations keep their parent's
/// part: `∂v_i = S × (v_i − v_λ)`, `∂a_i = S × (a_i − a_λ) − (S × v_λ) × (v_i − v_λ)` (`λ` = `j`'s
/// parent). So each body force changes by the rigid turn `S ×* f_i` plus
///
/// ```text
/// g_i = I_i (u' + u × (v_i − v_λ)) + u ×* I_i v_i + v_i ×* I_i u,    u = −S × v_λ,  u' = −S × a_λ
/// ```
///
/// and `∂τ_r/∂q_c = S_rᵀ Σ_{i ⪰ k} g_i` for a coordinate `r` of a joint `k` in `j`'s subtree (the rigid
/// turn of the force and of `S_r` cancel), `S_rᵀ (S ×* F_j + Σ_{i ⪰ j} g_i)` for an ancestor. For
/// velocities `∂v_i/∂q̇_c = S`, `∂a_i/∂q̇_c = S × v_i + (v_λ + v_j) × S`, and
/// `∂f_i/∂q̇_c = I_i ∂a_i + S ×* I_i v_i + v_i ×* I_i S`, summed over subtrees the same way.
///
/// Overwrites `data` as [`rnea`] and [`forward_kinematics`] do and `work`. Cost: one RNEA, then
/// `nv` passes over subtrees (O(nv · bodies)).
#[allow(clippy::too_many_arguments)]
pub fn rnea_derivatives(
    model: &Model,
    gravity: &Vec3,
    data: &mut Data,
    work: &mut RneaDerivatives,
    q: &[f64],
    v: &[f64],
    qdd: &[f64],
    dq_out: &mut DMatrix<f64>,
    dv_out: &mut DMatrix<f64>,
) {
    rnea(model, gravity, data, q, v, qdd);
    forward_kinematics(model, data, q);
    let nb = model.bodies.len();
    for i in 0..nb {
        let x = &data.world_from_body[i];
        work.velocity[i] = x.act_motion(&data.velocity[i]);
        work.acceleration[i] = x.act_motion(&data.acceleration[i]);
        work.inertia[i] = x.act_inertia(&model.bodies[i].inertia);
        // After RNEA's backward pass `data.force[i]` holds the whole subtree's force.
        work.subtree_force[i] = x.act_force(&data.force[i]);
        work.momentum[i] = work.inertia[i].apply(&work.velocity[i]);
    }
    for (i, joint) in model.joints.iter().enumerate() {
        for k in 0..joint.nv() {
            work.column[joint.v_index + k] =
                data.world_from_body[i].act_motion(&joint.subspace_column(k));
        }
    }
    let gravity = Motion::new(-gravity, Vec3::zeros());
    dq_out.fill(0.0);
    dv_out.fill(0.0);
    for c in 0..model.nv {
        let j = work.body_of[c];
        let s = work.column[c];
        let (v_parent, a_parent) = match model.joints[j].parent {
            Some(p) => (work.velocity[p], work.acceleration[p]),
            None => (Motion::zero(), gravity),
        };
        let u = -s.cross_motion(&v_parent);
        let u_acc = -s.cross_motion(&a_parent);
        let e = (v_parent + work.velocity[j]).cross_motion(&s);
        let end = work.subtree_end[j];
        for i in (j..end).rev() {
            let inertia = &work.inertia[i];
            let vi = work.velocity[i];
            let relative = vi - v_parent;
            let g_q = inertia.apply(&(u_acc + u.cross_motion(&relative)))
                + u.cross_force(&work.momentum[i])
                + vi.cross_force(&inertia.apply(&u));
            let g_v = inertia.apply(&(s.cross_motion(&vi) + e))
                + s.cross_force(&work.momentum[i])
                + vi.cross_force(&inertia.apply(&s));
            work.sum_q[i] = g_q;
            work.sum_v[i] = g_v;
        }
        // Subtree sums: children come after their parents in depth-first order.
        for i in (j + 1..end).rev() {
            if let Some(p) = model.joints[i].parent {
                let (fq, fv) = (work.sum_q[i], work.sum_v[i]);
                work.sum_q[p] += fq;
                work.sum_v[p] += fv;
            }
        }
        let ancestor_q = s.cross_force(&work.subtree_force[j]) + work.sum_q[j];
        for r in 0..model.nv {
            let k = work.body_of[r];
            let column = &work.column[r];
            if (j..end).contains(&k) {
                dq_out[(r, c)] = column.dot(&work.sum_q[k]);
                dv_out[(r, c)] = column.dot(&work.sum_v[k]);
            } else if (k..work.subtree_end[k]).contains(&j) {
                dq_out[(r, c)] = column.dot(&ancestor_q);
                dv_out[(r, c)] = column.dot(&work.sum_v[j]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, rnea};
    use crate::model::{link_inertia, parse_description, LoadOptions};
    use crate::spatial::quaternion::{unit_quaternion_from_xyzw, write_xyzw};

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
            InertialField::Scale => unreachable!("the scale is not a value of the URDF spec"),
        }
    }

    fn get(inertial: &InertialSpec, field: InertialField) -> f64 {
        match field {
            InertialField::Mass => inertial.mass,
            InertialField::Com(i) => inertial.com[i],
            InertialField::Inertia(i) => inertial.inertia[i],
            InertialField::Scale => unreachable!("the scale is not a value of the URDF spec"),
        }
    }

    #[test]
    fn the_scale_derivative_is_the_unscaled_link_inertia() {
        let model = arm();
        let inertial = model.description.links[1].inertial;
        let d = link_inertia_derivative(&inertial, InertialField::Scale);
        let full = crate::model::link_inertia(&inertial);
        assert_eq!(d.mass, full.mass);
        assert_eq!(d.first_moment, full.first_moment);
        assert_eq!(d.rotational, full.rotational);
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
        let gravity = Vec3::new(0.3, -1.0, -9.81);
        let mut data = Data::new(&model);
        let (q, v, qdd) = ([0.4, -0.9], [1.3, -0.7], [0.5, 2.0]);
        let h = 1e-6;
        for link in 1..model.description.links.len() {
            for field in fields() {
                rnea(&model, &gravity, &mut data, &q, &v, &qdd);
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
                    tau.copy_from_slice(rnea(&model, &gravity, &mut data, &q, &v, &qdd));
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

    /// The analytic Jacobians of RNEA against central differences along the tangent space, on the
    /// arm (a merged link, tilted axes) and on a floating ur5 (a 6-dof root).
    #[test]
    fn rnea_derivatives_match_central_differences() {
        let ur5 = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5/ur5.urdf");
        let floating = Model::from_urdf_file(
            &ur5,
            LoadOptions {
                floating_base: true,
            },
        )
        .unwrap();
        let tilted_gravity = Vec3::new(0.3, -1.0, -9.81);
        let default_gravity = Vec3::from(crate::environment::DEFAULT_GRAVITY);
        for (model, gravity) in [(arm(), tilted_gravity), (floating, default_gravity)] {
            let (nq, nv) = (model.nq, model.nv);
            let mut q: Vec<f64> = (0..nq).map(|i| 0.3 + 0.41 * i as f64).collect();
            if model.floating_base {
                let n = (q[3] * q[3] + q[4] * q[4] + q[5] * q[5] + q[6] * q[6]).sqrt();
                for x in &mut q[3..7] {
                    *x /= n;
                }
            }
            let v: Vec<f64> = (0..nv).map(|i| 0.7 - 0.33 * i as f64).collect();
            let qdd: Vec<f64> = (0..nv).map(|i| -0.4 + 0.27 * i as f64).collect();
            let mut data = Data::new(&model);
            let mut work = RneaDerivatives::new(&model);
            let (mut dq, mut dv) = (DMatrix::zeros(nv, nv), DMatrix::zeros(nv, nv));
            rnea_derivatives(
                &model, &gravity, &mut data, &mut work, &q, &v, &qdd, &mut dq, &mut dv,
            );
            let h = 1e-6;
            let mut system_q = nalgebra::DVector::from_column_slice(&q);
            for c in 0..nv {
                let mut taus = [vec![0.0; nv], vec![0.0; nv], vec![0.0; nv], vec![0.0; nv]];
                for (n, sign) in [1.0, -1.0].into_iter().enumerate() {
                    let mut tangent = nalgebra::DVector::zeros(nv);
                    tangent[c] = sign * h;
                    let moved = integrate(&model, &system_q, &tangent);
                    taus[n].copy_from_slice(rnea(
                        &model,
                        &gravity,
                        &mut data,
                        moved.as_slice(),
                        &v,
                        &qdd,
                    ));
                    let mut vv = v.clone();
                    vv[c] += sign * h;
                    taus[2 + n].copy_from_slice(rnea(&model, &gravity, &mut data, &q, &vv, &qdd));
                }
                for r in 0..nv {
                    let numeric_q = (taus[0][r] - taus[1][r]) / (2.0 * h);
                    let numeric_v = (taus[2][r] - taus[3][r]) / (2.0 * h);
                    let scale = numeric_q.abs().max(1.0);
                    assert!(
                        (numeric_q - dq[(r, c)]).abs() < 1e-7 * scale,
                        "{} ∂τ{r}/∂q{c}: {} vs {numeric_q}",
                        model.name(),
                        dq[(r, c)]
                    );
                    assert!(
                        (numeric_v - dv[(r, c)]).abs() < 1e-7 * numeric_v.abs().max(1.0),
                        "{} ∂τ{r}/∂v{c}: {} vs {numeric_v}",
                        model.name(),
                        dv[(r, c)]
                    );
                }
            }
            system_q.fill(0.0);
        }
    }

    /// `q ⊕ δ` as the integrator does it: additive, and `q · Exp(δ)` for the floating root.
    fn integrate(
        model: &Model,
        q: &nalgebra::DVector<f64>,
        tangent: &nalgebra::DVector<f64>,
    ) -> nalgebra::DVector<f64> {
        let mut out = q.clone();
        for joint in &model.joints {
            let (qi, vi) = (joint.q_index, joint.v_index);
            if joint.nv() == 1 {
                out[qi] += tangent[vi];
                continue;
            }
            let rotation = unit_quaternion_from_xyzw(&q.as_slice()[qi + 3..qi + 7]);
            let linear = Vec3::new(tangent[vi], tangent[vi + 1], tangent[vi + 2]);
            let angular = Vec3::new(tangent[vi + 3], tangent[vi + 4], tangent[vi + 5]);
            // First order in the step suffices for a central difference: Exp(δ) ≈ (1 + ω×, v).
            let turn = nalgebra::UnitQuaternion::from_scaled_axis(angular);
            let position = Vec3::new(q[qi], q[qi + 1], q[qi + 2]) + rotation * linear;
            let quaternion = (rotation * turn).into_inner();
            out[qi] = position.x;
            out[qi + 1] = position.y;
            out[qi + 2] = position.z;
            write_xyzw(&quaternion, &mut out.as_mut_slice()[qi + 3..qi + 7]);
        }
        out
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
                    *position = world_from_link(&model, &data, link).translation;
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
