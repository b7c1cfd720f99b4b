//! The parameters `p_k` a [`RobotSystem`](super::RobotSystem) is differentiated by
//! (docs/sensitivities.md §3): each is a **direction** in the model's values, a list of
//! `(ParamTarget, ∂θ_t/∂p_k)` — for a study, `p_k = ξ_k` and the list is the chain from the box's
//! dimension `k` to the model values it moves.
//!
//! What it computes, at the model's current values:
//! - `∂r/∂p_k` of the residual `r = M q̈ + Φ_qᵀ λ − Q`: inertial targets (mass, COM, inertia of a
//!   link on a moving body) exactly, as one regressor column of RNEA per body they touch; every
//!   other target (joint origins and axes, damping, friction, gravity) by a central difference of
//!   the residual with the model moved along the direction by [`ParameterDirections::step`]: a
//!   4-point stencil at relative change [`THETA_FD_RELATIVE_STEP`] when the system has constraint
//!   rows, a 2-point one at [`THETA_FD_RELATIVE_STEP_UNCONSTRAINED`] when it has none; moving a
//!   value recomputes only what depends on it (a moving joint's placement; nothing for damping,
//!   friction, gravity; the full [`Model::refresh`] otherwise);
//! - `∂Φ/∂p_k` likewise (inertial targets do not move `Φ`);
//! - moving the model along one direction by an offset (for central differences of whole
//!   computations), and back exactly.
//!
//! Nothing here allocates after [`ParameterDirections::new`].

use crate::constraints::ConstraintSet;
use crate::dynamics::{
    link_inertia_derivative, rnea, rnea_inertia_derivative, Data, InertialField,
};
use crate::effects::Effects;
use crate::environment::Environment;
use crate::model::{joint_origin, Model};
use crate::params::{self, ParamTarget};
use crate::spatial::Inertia;
use nalgebra::{DMatrix, DVector};

/// Relative change of the model values in the 4-point central differences
/// `[−f(2ε) + 8 f(ε) − 8 f(−ε) + f(−2ε)] / 12ε` of the residual, the constraints and frame positions
/// along a direction (docs/sensitivities.md §3): the largest change of any target is this fraction
/// of its scale (`max(|θ|, floor)`, floors in [`target_scale`]). Geometry is nonlinear on the scale
/// of the values themselves, so the truncation error is ~ε⁴/30 ≈ 3e-14 relative (zero for
/// constraints and frames in origin translations, which enter them linearly).
///
/// Why so large a step: index-3 rows turn an error `e` in `∂Φ/∂p` into an error `e/(β'h²)` in
/// `∂q̈/∂p` at every step (4e6·e at h = 1 ms), so `∂Φ/∂p` must be good to the rounding of `Φ`
/// itself, ~1e-16 m. The rounding of a difference is ~u·|x|/ε: at 1e-6 (2-point) it was 1e-10 per
/// m, measured as a 6e-7 relative error of the slider-crank's `∂q̈/∂l` and 4e-6 of its `∂λ/∂l`; at
/// 1e-3 it is ~1e-13 per m.
pub const THETA_FD_RELATIVE_STEP: f64 = 1e-3;

/// Relative change of the model values in the 2-point central differences of the residual of a
/// system without constraint rows (docs/sensitivities.md §3): no constraint row amplifies the
/// error of `∂r/∂p` there, and a small step keeps the truncation at ~1e-12 while rounding costs
/// ~u·|terms|/(1e-6·scale) ≈ 1e-10 of the derivative (residual terms of ~50 N·m, derivatives of
/// ~50 N·m per m); half the evaluations of the 4-point stencil.
pub const THETA_FD_RELATIVE_STEP_UNCONSTRAINED: f64 = 1e-6;

/// The 4-point central-difference stencil: `(offset in steps, weight / 12)`.
const STENCIL: [(f64, f64); 4] = [(2.0, -1.0), (1.0, 8.0), (-1.0, -8.0), (-2.0, 1.0)];

/// The 2-point central-difference stencil in the same form.
const STENCIL_2: [(f64, f64); 2] = [(1.0, 6.0), (-1.0, -6.0)];

/// What must be recomputed after writing some targets (docs/sensitivities.md §3): the full
/// [`Model::refresh`] (it recomputes every link placement and body inertia), only the placement and
/// axis of some moving joints, or nothing (damping, friction and gravity are read where used).
#[derive(Clone, Debug, PartialEq)]
enum Refresh {
    Nothing,
    Joints(Vec<usize>),
    Full,
}

impl Refresh {
    /// The refresh writing `moves` needs.
    fn of(model: &Model, moves: &[TargetMove]) -> Refresh {
        let mut joints = Vec::new();
        for m in moves {
            let urdf_joint = match m.target {
                ParamTarget::JointDamping(_)
                | ParamTarget::JointFriction(_)
                | ParamTarget::Gravity(_)
                | ParamTarget::Contact(_)
                | ParamTarget::CollisionSize(..) => continue,
                ParamTarget::JointOrigin(j, _) | ParamTarget::JointAxis(j, _) => j,
                ParamTarget::LinkMass(_)
                | ParamTarget::LinkCom(..)
                | ParamTarget::LinkInertia(..)
                | ParamTarget::LinkScale(_) => return Refresh::Full,
            };
            // A fixed joint's origin places links (and their inertia) in a body: full refresh.
            match model
                .joints
                .iter()
                .position(|j| j.source == Some(urdf_joint))
            {
                Some(k) => {
                    if !joints.contains(&k) {
                        joints.push(k);
                    }
                }
                None => return Refresh::Full,
            }
        }
        if joints.is_empty() {
            Refresh::Nothing
        } else {
            Refresh::Joints(joints)
        }
    }

    fn apply(&self, model: &mut Model) {
        match self {
            Refresh::Nothing => {}
            Refresh::Joints(joints) => {
                for &k in joints {
                    refresh_joint(model, k);
                }
            }
            Refresh::Full => model.refresh(),
        }
    }
}

/// The part of [`Model::refresh`] that depends on moving joint `k`'s URDF origin and axis: its
/// `parent_from_joint` and unit axis, by the same expressions (a unit test checks the result is
/// bitwise the full refresh's). Nothing else reads a moving joint's origin or axis.
fn refresh_joint(model: &mut Model, k: usize) {
    let Some(source) = model.joints[k].source else {
        return;
    };
    let spec = &model.description.joints[source];
    let parent_from_joint = model.links[spec.parent]
        .body_from_link
        .compose(&joint_origin(spec));
    let axis = crate::spatial::Vec3::from(spec.axis);
    let norm = axis.norm();
    let joint = &mut model.joints[k];
    joint.parent_from_joint = parent_from_joint;
    if norm > 0.0 {
        joint.set_axis(axis / norm);
    }
}

/// The scale a target's central-difference step is measured against: `max(|value|, floor)`, with
/// floors on the scale on which the dynamics are nonlinear in the value: 0.1 m for joint-origin
/// translations and centres of mass (a link length), 1 rad for origin angles, 1 for axis
/// components, damping, friction and gravity (the last three enter linearly: any step is exact),
/// 0.1 kg for masses and 1e-3 kg·m² for inertia entries (a light link's share of a joint's
/// inertia).
pub fn target_scale(target: ParamTarget, value: f64) -> f64 {
    let floor = match target {
        ParamTarget::JointOrigin(_, c) if c < 3 => 0.1,
        ParamTarget::LinkCom(..) => 0.1,
        ParamTarget::LinkMass(_) => 0.1,
        ParamTarget::LinkInertia(..) => 1e-3,
        ParamTarget::LinkScale(_) => 1.0,
        // Contact values: relative to their own size (a stiffness of 1e6 N/m^1.5), with a 1 mm
        // floor for collision sizes.
        ParamTarget::Contact(_) => 1e-12,
        ParamTarget::CollisionSize(..) => 1e-3,
        ParamTarget::JointOrigin(..)
        | ParamTarget::JointAxis(..)
        | ParamTarget::JointDamping(_)
        | ParamTarget::JointFriction(_)
        | ParamTarget::Gravity(_) => 1.0,
    };
    value.abs().max(floor)
}

/// `relative · min_t scale_t / |∂θ_t/∂p|` over `moves`: the step in `p` that changes no value by
/// more than that fraction of its scale (0 for no moves).
fn relative_step(moves: &[TargetMove], relative: f64) -> f64 {
    let step = moves
        .iter()
        .map(|m| relative * target_scale(m.target, m.base) / m.derivative.abs())
        .fold(f64::INFINITY, f64::min);
    if step.is_finite() {
        step
    } else {
        0.0
    }
}

/// The `<inertial>` field a target writes, when it is one.
fn inertial_field(target: ParamTarget) -> Option<(usize, InertialField)> {
    match target {
        ParamTarget::LinkMass(l) => Some((l, InertialField::Mass)),
        ParamTarget::LinkCom(l, c) => Some((l, InertialField::Com(c))),
        ParamTarget::LinkInertia(l, c) => Some((l, InertialField::Inertia(c))),
        ParamTarget::LinkScale(l) => Some((l, InertialField::Scale)),
        ParamTarget::JointOrigin(..)
        | ParamTarget::JointAxis(..)
        | ParamTarget::JointDamping(_)
        | ParamTarget::JointFriction(_)
        | ParamTarget::Gravity(_)
        | ParamTarget::Contact(_)
        | ParamTarget::CollisionSize(..) => None,
    }
}

/// Whether a target moves link frames (and so frame outputs and loop points).
fn moves_frames(target: ParamTarget) -> bool {
    match target {
        ParamTarget::JointOrigin(..) | ParamTarget::JointAxis(..) => true,
        ParamTarget::LinkMass(_)
        | ParamTarget::LinkCom(..)
        | ParamTarget::LinkInertia(..)
        | ParamTarget::LinkScale(_)
        | ParamTarget::JointDamping(_)
        | ParamTarget::JointFriction(_)
        | ParamTarget::Gravity(_)
        | ParamTarget::Contact(_)
        | ParamTarget::CollisionSize(..) => false,
    }
}

/// One model value moved by a direction.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TargetMove {
    target: ParamTarget,
    /// `∂θ_t/∂p_k`.
    derivative: f64,
    /// The value at `p = 0`.
    base: f64,
}

/// What one direction does, prepared at the model's values.
#[derive(Clone, Debug)]
struct Direction {
    /// Every target with a non-zero derivative.
    moves: Vec<TargetMove>,
    /// The exact part: `∂I_body/∂p_k` per body (in the body frame, about its origin).
    inertial: Vec<(usize, Inertia)>,
    /// Targets differentiated by central differences.
    differenced: Vec<TargetMove>,
    /// Step in `p_k` of those central differences.
    step: f64,
    /// Step in `p_k` changing no moved value by more than [`THETA_FD_RELATIVE_STEP`] of its scale.
    natural_step: f64,
    /// Whether a differenced target moves link frames.
    moves_frames: bool,
    /// What writing the differenced targets needs recomputed.
    refresh_differenced: Refresh,
    /// What writing every target needs recomputed.
    refresh_all: Refresh,
}

/// The parameter directions `p_k` of a robot system and their work buffers (docs/sensitivities.md
/// §3): each direction is a list of model values with `∂θ_t/∂p_k`; inertial values are
/// differentiated exactly (RNEA regressor columns), every other value by central differences of
/// the residual with the model moved. Built by
/// [`RobotSystem::set_parameter_directions`](super::RobotSystem::set_parameter_directions).
#[derive(Clone, Debug, Default)]
pub struct ParameterDirections {
    directions: Vec<Direction>,
    /// The direction whose targets are currently moved by [`ParameterDirections::set_offset`].
    offset: Option<usize>,
    /// Whether the system has constraint rows (the 4-point stencil at the larger step), or not
    /// (the 2-point stencil at [`THETA_FD_RELATIVE_STEP_UNCONSTRAINED`]).
    constrained: bool,
    /// Residual at one point of the stencil, dim nv.
    residual: DVector<f64>,
    /// Φ at one point of the stencil, dim m.
    phi: DVector<f64>,
    /// Φ_q, m × nv.
    phi_q: DMatrix<f64>,
}

impl ParameterDirections {
    /// Prepares `directions` (direction `k`: the targets it moves and `∂θ_t/∂p_k`) at `model`'s
    /// and `environment`'s current values, for a system with `m` constraint rows. Zero derivatives are dropped; a target
    /// listed twice in one direction has its derivatives added.
    pub fn new(
        model: &Model,
        environment: &Environment,
        m: usize,
        directions: &[Vec<(ParamTarget, f64)>],
    ) -> Self {
        let prepared = directions
            .iter()
            .map(|list| Self::prepare(model, environment, m > 0, list))
            .collect();
        Self {
            directions: prepared,
            offset: None,
            constrained: m > 0,
            residual: DVector::zeros(model.nv),
            phi: DVector::zeros(m),
            phi_q: DMatrix::zeros(m, model.nv),
        }
    }

    fn prepare(
        model: &Model,
        environment: &Environment,
        constrained: bool,
        list: &[(ParamTarget, f64)],
    ) -> Direction {
        let mut moves: Vec<TargetMove> = Vec::new();
        for &(target, derivative) in list {
            match moves.iter_mut().find(|m| m.target == target) {
                Some(existing) => existing.derivative += derivative,
                None => moves.push(TargetMove {
                    target,
                    derivative,
                    base: params::get(model, environment, target),
                }),
            }
        }
        moves.retain(|m| m.derivative != 0.0);
        let mut inertial: Vec<(usize, Inertia)> = Vec::new();
        let mut differenced = Vec::new();
        for m in &moves {
            match inertial_field(m.target) {
                Some((link, field)) => {
                    // A link fixed to the world moves no body: derivative 0.
                    let Some(body) = model.links[link].body else {
                        continue;
                    };
                    let d = link_inertia_derivative(&model.description.links[link].inertial, field);
                    // The effective inertia is scale × the URDF one (link.NAME.scale).
                    let factor = if field == InertialField::Scale {
                        m.derivative
                    } else {
                        m.derivative * model.inertial_scales[link]
                    };
                    let scaled = Inertia {
                        mass: d.mass * factor,
                        first_moment: d.first_moment * factor,
                        rotational: d.rotational * factor,
                    };
                    let in_body = model.links[link].body_from_link.act_inertia(&scaled);
                    match inertial.iter_mut().find(|(b, _)| *b == body) {
                        Some((_, sum)) => *sum += in_body,
                        None => inertial.push((body, in_body)),
                    }
                }
                None => differenced.push(*m),
            }
        }
        let differenced_step = if constrained {
            THETA_FD_RELATIVE_STEP
        } else {
            THETA_FD_RELATIVE_STEP_UNCONSTRAINED
        };
        Direction {
            moves_frames: differenced.iter().any(|m| moves_frames(m.target)),
            step: relative_step(&differenced, differenced_step),
            natural_step: relative_step(&moves, THETA_FD_RELATIVE_STEP),
            refresh_differenced: Refresh::of(model, &differenced),
            refresh_all: Refresh::of(model, &moves),
            moves,
            inertial,
            differenced,
        }
    }

    /// Number of directions `P`.
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }

    /// The central-difference step ε in `p_k` of direction `k` (0 when it has no differenced target):
    /// with constraint rows its 4-point stencil evaluates `p_k = ±ε, ±2ε` (relative change
    /// [`THETA_FD_RELATIVE_STEP`]), without them the 2-point stencil `±ε` (relative change
    /// [`THETA_FD_RELATIVE_STEP_UNCONSTRAINED`]).
    pub fn step(&self, k: usize) -> f64 {
        self.directions[k].step
    }

    /// A step in `p_k` for central differences of whole computations along direction `k`: no model
    /// value it moves changes by more than [`THETA_FD_RELATIVE_STEP`] of its scale
    /// ([`target_scale`]); 1e-3 for a direction that moves nothing.
    pub fn natural_step(&self, k: usize) -> f64 {
        let step = self.directions[k].natural_step;
        if step > 0.0 {
            step
        } else {
            crate::integrate::PARAMETER_FD_STEP
        }
    }

    /// Whether direction `k` moves link frames (joint origins or axes), so that frame outputs depend
    /// on it directly and not only through `q`.
    pub fn moves_frames(&self, k: usize) -> bool {
        self.directions[k].moves_frames
    }

    /// Writes `base + scale · derivative` into every target of direction `k` (`differenced_only`:
    /// only its differenced targets), then recomputes what they change in the model.
    fn move_targets(
        &self,
        model: &mut Model,
        environment: &mut Environment,
        k: usize,
        scale: f64,
        differenced_only: bool,
    ) {
        let direction = &self.directions[k];
        let (moves, refresh) = if differenced_only {
            (&direction.differenced, &direction.refresh_differenced)
        } else {
            (&direction.moves, &direction.refresh_all)
        };
        for m in moves {
            params::set(model, environment, m.target, m.base + scale * m.derivative);
        }
        refresh.apply(model);
    }

    /// Moves `model` and `environment` to `p = offset · e_k` (see [`Parameters::set_parameter_offset`]); `offset = 0`
    /// restores the values exactly. Each call first undoes the previous offset.
    ///
    /// [`Parameters::set_parameter_offset`]: crate::integrate::Parameters::set_parameter_offset
    pub fn set_offset(
        &mut self,
        model: &mut Model,
        environment: &mut Environment,
        k: usize,
        offset: f64,
    ) {
        if let Some(previous) = self.offset.take() {
            self.move_targets(model, environment, previous, 0.0, false);
        }
        if offset != 0.0 {
            self.move_targets(model, environment, k, offset, false);
            self.offset = Some(k);
        }
    }

    /// `r = M q̈ + Φ_qᵀ λ − Q` at the model's current values into `out` (dim nv).
    #[allow(clippy::too_many_arguments)]
    fn residual(
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        effects: &mut Effects,
        constraints: &ConstraintSet,
        q: &[f64],
        v: &[f64],
        qdd: &[f64],
        lambda: &DVector<f64>,
        phi_q: &mut DMatrix<f64>,
        out: &mut DVector<f64>,
    ) {
        let tau = rnea(model, &environment.gravity, data, q, v, qdd);
        for (o, t) in out.iter_mut().zip(tau) {
            *o = -t;
        }
        effects.add_forces(model, environment, data, q, v, out.as_mut_slice());
        out.neg_mut();
        if !lambda.is_empty() {
            constraints.jacobian(model, data, q, phi_q);
            out.gemv_tr(1.0, phi_q, lambda, 1.0);
        }
    }

    /// `dynamics_out[:, k] = ∂r/∂p_k` (nv × P) and `constraints_out[:, k] = ∂Φ/∂p_k` (m × P) at
    /// `(t, q, q̇, q̈, λ)`, both overwritten (docs/sensitivities.md §3). The model must be at `p = 0`
    /// (no offset); it is left bitwise as it was.
    #[allow(clippy::too_many_arguments)]
    pub fn jacobians(
        &mut self,
        model: &mut Model,
        environment: &mut Environment,
        data: &mut Data,
        effects: &mut Effects,
        constraints: &ConstraintSet,
        t: f64,
        q: &[f64],
        v: &[f64],
        qdd: &[f64],
        lambda: &DVector<f64>,
        dynamics_out: &mut DMatrix<f64>,
        constraints_out: &mut DMatrix<f64>,
    ) {
        let nv = model.nv;
        dynamics_out.fill(0.0);
        constraints_out.fill(0.0);
        if self.directions.iter().any(|d| !d.inertial.is_empty()) {
            // The kinematics (velocities, accelerations with gravity) every regressor column reads.
            rnea(model, &environment.gravity, data, q, v, qdd);
            for (k, direction) in self.directions.iter().enumerate() {
                let column = &mut dynamics_out.as_mut_slice()[k * nv..(k + 1) * nv];
                for (body, d_inertia) in &direction.inertial {
                    rnea_inertia_derivative(model, data, *body, d_inertia, column);
                }
            }
        }
        for k in 0..self.directions.len() {
            if self.directions[k].differenced.is_empty() {
                continue;
            }
            let step = self.directions[k].step;
            let stencil: &[(f64, f64)] = if self.constrained {
                &STENCIL
            } else {
                &STENCIL_2
            };
            for &(offset, weight) in stencil {
                self.move_targets(model, environment, k, offset * step, true);
                Self::residual(
                    model,
                    environment,
                    data,
                    effects,
                    constraints,
                    q,
                    v,
                    qdd,
                    lambda,
                    &mut self.phi_q,
                    &mut self.residual,
                );
                let w = weight / (12.0 * step);
                for i in 0..nv {
                    dynamics_out[(i, k)] += w * self.residual[i];
                }
                if !constraints.is_empty() {
                    constraints.evaluate(model, data, t, q, &mut self.phi);
                    for j in 0..constraints.len() {
                        constraints_out[(j, k)] += w * self.phi[j];
                    }
                }
            }
            self.move_targets(model, environment, k, 0.0, true);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::LoadOptions;

    /// Moving a joint's origin or axis and recomputing only that joint gives bitwise the model a
    /// full refresh gives, for every moving joint's every origin and axis component.
    #[test]
    fn joint_refresh_is_the_full_refresh() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5/ur5.urdf");
        let base = Model::from_urdf_file(&path, LoadOptions::default()).unwrap();
        let mut environment = Environment::default();
        for (k, joint) in base.joints.iter().enumerate() {
            let source = joint.source.unwrap();
            let targets = (0..6)
                .map(|c| ParamTarget::JointOrigin(source, c))
                .chain((0..3).map(|c| ParamTarget::JointAxis(source, c)));
            for target in targets {
                let moves = [TargetMove {
                    target,
                    derivative: 1.0,
                    base: params::get(&base, &environment, target),
                }];
                assert_eq!(Refresh::of(&base, &moves), Refresh::Joints(vec![k]));
                let value = params::get(&base, &environment, target) + 0.0123;
                let (mut local, mut full) = (base.clone(), base.clone());
                params::set(&mut local, &mut environment, target, value);
                refresh_joint(&mut local, k);
                params::set(&mut full, &mut environment, target, value);
                full.refresh();
                for (a, b) in local.joints.iter().zip(&full.joints) {
                    assert_eq!(a.parent_from_joint, b.parent_from_joint, "{target:?}");
                    assert_eq!(a.axis(), b.axis(), "{target:?}");
                }
                for (a, b) in local.links.iter().zip(&full.links) {
                    assert_eq!(a.body_from_link, b.body_from_link, "{target:?}");
                }
                for (a, b) in local.bodies.iter().zip(&full.bodies) {
                    assert_eq!(a.inertia, b.inertia, "{target:?}");
                }
            }
        }
        // A fixed joint's origin places a link in its body: that needs the full refresh.
        let fixed = base
            .description
            .joints
            .iter()
            .position(|j| j.joint_type == crate::model::UrdfJointType::Fixed)
            .unwrap();
        let moves = [TargetMove {
            target: ParamTarget::JointOrigin(fixed, 2),
            derivative: 1.0,
            base: 0.0,
        }];
        assert_eq!(Refresh::of(&base, &moves), Refresh::Full);
    }
}
