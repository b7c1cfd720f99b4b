//! [`RobotSystem`]: a robot tree plus its scene's effects and constraint rows (loops, mimic joints,
//! drives), seen by the integrator through [`DaeSystem`]. A tree without rows pays nothing for them.
//! Its full residual Jacobians are in `system/residual_jacobians.rs`, its joint limits as events
//! and impacts in `system/joint_limits.rs`, its tests in `system/tests.rs`.

use super::lie;
use super::parameters::ParameterDirections;
use crate::constraints::ConstraintSet;
use crate::dynamics::{crba, nonlinear_effects, rnea, rnea_at_placements, Data};
use crate::effects::Effects;
use crate::environment::Environment;
use crate::integrate::{
    Constraints, DaeState, DaeSystem, InverseDynamics, NewtonCoupling, NewtonDiagonal,
    NewtonUpdateLimit, Parameters, PositionGroup, PositionScale, ResidualJacobians, SystemError,
    UnilateralLimits,
};
use crate::model::{JointKind, Model};
use crate::params::ParamTarget;
use crate::scene::Scene;
use crate::spatial::quaternion::{unit_quaternion_from_xyzw, write_xyzw};
use crate::spatial::{Transform, Vec3};
use nalgebra::{DMatrix, DVector};
use residual_jacobians::JacobianBuffers;

mod joint_limits;
mod residual_jacobians;

/// A robot with its effects and constraint rows as the index-3 DAE
/// `M(q) q̈ + Φ_qᵀ λ = Q(t, q, q̇)`, `Φ(q, t) = 0`.
#[derive(Clone, Debug)]
pub struct RobotSystem {
    /// The model.
    pub model: Model,
    /// The environment the model is simulated in: the scene's gravity (zero when the scene does
    /// not declare it) and contact material, with parameters' values written in.
    pub environment: Environment,
    /// Work buffers of the dynamics algorithms.
    pub data: Data,
    /// The scene's assembled effects.
    pub effects: Effects,
    /// The scene's constraint rows.
    pub constraints: ConstraintSet,
    has_floating_joint: bool,
    /// Some coordinate is a translation (a prismatic joint or a floating base): the Newton test's
    /// position scale is not all zeros ([`PositionScale::position_scale`]).
    has_translation_coordinate: bool,
    /// Adaptive step: the largest growth of the deepest contact penetration over one sub-step, m
    /// (∞ without contacts or with the fixed step).
    max_penetration_m: f64,
    /// The parameters `p_k` of the forward sensitivities (none unless
    /// [`RobotSystem::set_parameter_directions`] was called).
    parameters: ParameterDirections,
    /// Work buffers of [`ResidualJacobians::residual_jacobians`], made on first use (taken out while in
    /// use).
    jacobians: Option<Box<JacobianBuffers>>,
    /// What the last [`DaeSystem::mass_matrix`] call computed that the next residual may reuse.
    mass_matrix_kinematics: MassMatrixKinematics,
}

/// The configuration of the last [`DaeSystem::mass_matrix`] call and the joint placements its
/// CRBA computed there, held aside for [`InverseDynamics::dynamics_residual_after_mass_matrix`] (other
/// calls reuse `data`). The placements move by swapping buffers with `data.parent_from_body`, never
/// by copying: while they are held here, `data.parent_from_body` holds an old set, which every
/// kernel that reads it overwrites first (RNEA and CRBA from `q`, forward kinematics), except RNEA
/// at given placements, which only the hand-back below precedes.
#[derive(Clone, Debug)]
struct MassMatrixKinematics {
    q: Vec<f64>,
    placements: Vec<Transform>,
    /// `placements` are the CRBA's at `q` (else they are an old set of `data`'s).
    holds: bool,
}

impl MassMatrixKinematics {
    /// Buffers for a model of `bodies` bodies (as many placements as `data.parent_from_body`).
    fn new(bodies: usize) -> Self {
        Self {
            q: Vec::new(),
            placements: vec![Transform::identity(); bodies],
            holds: false,
        }
    }

    /// Takes the placements the CRBA has just written into `data_placements` at `q`, leaving an
    /// old set there in exchange.
    fn take(&mut self, q: &[f64], data_placements: &mut Vec<Transform>) {
        self.q.clear();
        self.q.extend_from_slice(q);
        std::mem::swap(&mut self.placements, data_placements);
        self.holds = true;
    }

    /// Hands the held placements back into `data_placements` when `q` is bit for bit the
    /// configuration they were taken at; returns whether it did.
    fn give_back(&mut self, q: &[f64], data_placements: &mut Vec<Transform>) -> bool {
        let same = self.holds
            && self.q.len() == q.len()
            && self
                .q
                .iter()
                .zip(q)
                .all(|(a, b)| a.to_bits() == b.to_bits());
        if same {
            std::mem::swap(&mut self.placements, data_placements);
            self.holds = false;
        }
        same
    }
}

impl RobotSystem {
    /// Assembles `model` in `environment` with the effects `scene` declares. The environment keeps
    /// its gravity (the scene's, [`Scene::environment`], which parameters may override) unless the
    /// scene does not declare the `gravity` effect: then it is zero.
    pub fn new(model: Model, mut environment: Environment, scene: &Scene) -> Self {
        if !scene.effects.gravity {
            environment.gravity = Vec3::zeros();
        }
        let data = Data::new(&model);
        let data_bodies = data.parent_from_body.len();
        let effects = Effects::assemble(&model, scene);
        let has_floating_joint = model.joints.iter().any(|j| j.kind == JointKind::Floating);
        let has_translation_coordinate = model
            .joints
            .iter()
            .any(|j| matches!(j.kind, JointKind::Floating | JointKind::Prismatic));
        Self {
            model,
            environment,
            data,
            effects,
            constraints: scene.constraints.clone(),
            has_floating_joint,
            has_translation_coordinate,
            max_penetration_m: match (&scene.contact, scene.step_control) {
                (Some(c), crate::integrate::StepControl::Adaptive) => c.max_penetration_m,
                _ => f64::INFINITY,
            },
            parameters: ParameterDirections::default(),
            jacobians: None,
            mass_matrix_kinematics: MassMatrixKinematics::new(data_bodies),
        }
    }

    /// Declares the parameters `p_k` the system is differentiated by (docs/sensitivities.md §3):
    /// direction `k` moves each listed model value `θ_t` by `∂θ_t/∂p_k` per unit `p_k`, from the
    /// model's and environment's **current** values (call it after writing the parameter point into
    /// `self.model` and `self.environment`).
    /// For a study, `p_k = ξ_k` and the list is [`ParameterSpace`]'s chain from dimension `k` to the
    /// model values (see [`crate::uncertainty::ParameterSpace::target_derivatives`]). Replaces any previous declaration.
    ///
    /// [`ParameterSpace`]: crate::uncertainty::ParameterSpace
    pub fn set_parameter_directions(&mut self, directions: &[Vec<(ParamTarget, f64)>]) {
        self.parameters = ParameterDirections::new(
            &self.model,
            &self.environment,
            self.constraints.len(),
            directions,
        );
    }

    /// The declared parameter directions.
    pub fn parameter_directions(&self) -> &ParameterDirections {
        &self.parameters
    }

    /// Completes the dynamics residual `M q̈ + C q̇ + g − Q_effects` from the inverse dynamics:
    /// `out` holds `τ_rnea(q, q̇, q̈)` on entry (dim nv) and the residual on return, computed as
    /// `−(−τ_rnea + Q_effects)`; without effects that is `τ_rnea` itself, bit for bit (negation is
    /// exact), and `out` is left as it is. [`InverseDynamics::dynamics_residual`] and the batched step
    /// (which computes `τ_rnea` for many samples at once, bitwise the same) share it.
    pub(crate) fn finish_dynamics_residual(&mut self, q: &[f64], v: &[f64], out: &mut [f64]) {
        if !self.effects.has_forces() {
            return;
        }
        for o in out.iter_mut() {
            *o = -*o;
        }
        self.effects
            .add_forces(&self.model, &self.environment, &mut self.data, q, v, out);
        for o in out.iter_mut() {
            *o = -*o;
        }
    }

    /// [`PositionGroup::integrate_position`] of a model with a floating joint (`q ⊕ δ = q · exp(δ)` for
    /// it, `q + δ` for the others), kept out of line so that the common case stays small.
    #[inline(never)]
    fn integrate_position_with_floating_joint(&self, q: &[f64], dq: &[f64], out: &mut [f64]) {
        for joint in &self.model.joints {
            let (qi, vi) = (joint.q_index, joint.v_index);
            if joint.kind != JointKind::Floating {
                out[qi] = q[qi] + dq[vi];
                continue;
            }
            // q ⊕ δ = q · exp(δ): the twist δ = (v, ω) is in the body frame.
            let position = Vec3::new(q[qi], q[qi + 1], q[qi + 2]);
            let orientation = unit_quaternion_from_xyzw(&q[qi + 3..qi + 7]);
            let linear = Vec3::new(dq[vi], dq[vi + 1], dq[vi + 2]);
            let angular = Vec3::new(dq[vi + 3], dq[vi + 4], dq[vi + 5]);
            let (translation, increment) = se3_exp(&linear, &angular);
            let new_position = position + orientation * translation;
            let new_orientation = orientation * increment;
            let quaternion = new_orientation.quaternion().normalize();
            out[qi] = new_position.x;
            out[qi + 1] = new_position.y;
            out[qi + 2] = new_position.z;
            write_xyzw(&quaternion, &mut out[qi + 3..qi + 7]);
        }
    }

    /// `out = M q̈ − Q` from RNEA: with `placements_given`, RNEA reads the joint placements
    /// already in `data.parent_from_body` (which must be those at `q`) instead of computing them.
    fn inverse_dynamics_residual(
        &mut self,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        placements_given: bool,
        out: &mut DVector<f64>,
    ) {
        let tau = if placements_given {
            rnea_at_placements(
                &self.model,
                &self.environment.gravity,
                &mut self.data,
                v.as_slice(),
                qdd.as_slice(),
            )
        } else {
            rnea(
                &self.model,
                &self.environment.gravity,
                &mut self.data,
                q.as_slice(),
                v.as_slice(),
                qdd.as_slice(),
            )
        };
        out.as_mut_slice().copy_from_slice(tau);
        self.finish_dynamics_residual(q.as_slice(), v.as_slice(), out.as_mut_slice());
    }
}

/// Below this rotation angle (rad) [`se3_exp`] uses the series of its coefficients: the closed
/// forms lose digits to cancellation (`1 − cos θ`, `θ − sin θ`).
const SE3_EXP_SERIES_BELOW: f64 = 1e-4;

/// `exp` of the body twist `(v, ω)` as the translation `V(ω) v` and the rotation, the unit
/// quaternion `(cos(θ/2), sin(θ/2) ω/θ)` with `θ = |ω|`, from one `sin_cos(θ/2)`:
/// `V(ω) v = v + b ω × v + c ω × (ω × v)` with `b = (1 − cos θ)/θ² = 2 sin²(θ/2)/θ²` and
/// `c = (θ − sin θ)/θ³`, `sin θ = 2 sin(θ/2) cos(θ/2)` (docs/method.md §5). Built as the quaternion
/// itself rather than as a rotation matrix converted back (benches/README.md).
fn se3_exp(linear: &Vec3, angular: &Vec3) -> (Vec3, nalgebra::UnitQuaternion<f64>) {
    let theta = angular.norm();
    let t2 = theta * theta;
    let (cos_half, sin_half_over_theta, b, c) = if theta < SE3_EXP_SERIES_BELOW {
        (
            1.0 - t2 / 8.0,
            0.5 - t2 / 48.0,
            0.5 - t2 / 24.0,
            1.0 / 6.0 - t2 / 120.0,
        )
    } else {
        let (sin_half, cos_half) = crate::spatial::trig::sin_cos(0.5 * theta);
        (
            cos_half,
            sin_half / theta,
            2.0 * sin_half * sin_half / t2,
            (theta - 2.0 * sin_half * cos_half) / (t2 * theta),
        )
    };
    let first = angular.cross(linear);
    let translation = linear + first * b + angular.cross(&first) * c;
    let vector = angular * sin_half_over_theta;
    let rotation = nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
        cos_half, vector.x, vector.y, vector.z,
    ));
    (translation, rotation)
}

impl DaeSystem for RobotSystem {
    fn nq(&self) -> usize {
        self.model.nq
    }

    fn nv(&self) -> usize {
        self.model.nv
    }

    fn mass_matrix(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        out.as_mut_slice()
            .copy_from_slice(crba(&self.model, &mut self.data, q.as_slice()).as_slice());
        self.mass_matrix_kinematics
            .take(q.as_slice(), &mut self.data.parent_from_body);
        Ok(())
    }

    fn forces(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let bias = nonlinear_effects(
            &self.model,
            &self.environment.gravity,
            &mut self.data,
            q.as_slice(),
            v.as_slice(),
        );
        for (o, b) in out.iter_mut().zip(bias) {
            *o = -b;
        }
        self.effects.add_forces(
            &self.model,
            &self.environment,
            &mut self.data,
            q.as_slice(),
            v.as_slice(),
            out.as_mut_slice(),
        );
        Ok(())
    }

    fn as_inverse_dynamics(&mut self) -> Option<&mut dyn InverseDynamics> {
        Some(self)
    }

    fn newton_regime(&self, q: &DVector<f64>) -> u64 {
        self.effects.newton_regime(&self.model, q.as_slice())
    }

    /// Not with contacts: touch-downs and stick-slip transitions are kinks within a step.
    fn smooth_between_steps(&self) -> bool {
        !self.effects.has_contacts()
    }

    /// How much deeper the deepest contact got over the sub-step, over `[scene.contact]
    /// max_penetration` (adaptive step only; 0 otherwise). Growth, not depth: a contact resting
    /// deep under a heavy load is not a reason to shorten steps, a fast touch-down is.
    fn state_rejection(
        &mut self,
        _t: f64,
        q_start: &DVector<f64>,
        q_end: &DVector<f64>,
    ) -> Result<f64, SystemError> {
        if !self.max_penetration_m.is_finite() {
            return Ok(0.0);
        }
        let before =
            self.effects
                .deepest_penetration(&self.model, &mut self.data, q_start.as_slice());
        let after = self
            .effects
            .deepest_penetration(&self.model, &mut self.data, q_end.as_slice());
        Ok((after - before).max(0.0) / self.max_penetration_m)
    }

    /// Not with contacts: their Jacobians here would leave out the geometric terms (the normal
    /// and the contact point move with `q`; docs/contacts.md §4), so users such as the forward
    /// sensitivities form the exact Jacobians by central differences of the residual instead.
    fn as_residual_jacobians(&mut self) -> Option<&mut dyn ResidualJacobians> {
        if !self.effects.has_contacts() {
            Some(self)
        } else {
            None
        }
    }

    fn as_constraints(&mut self) -> Option<&mut dyn Constraints> {
        Some(self)
    }

    /// A floating joint's quaternion: `q ⊕ δ = q · Exp(δ)` on SE(3); without one, addition.
    fn as_position_group(&self) -> Option<&dyn PositionGroup> {
        if self.has_floating_joint {
            Some(self)
        } else {
            None
        }
    }

    /// Without translation coordinates every scale is zero (`None`).
    fn as_position_scale(&self) -> Option<&dyn PositionScale> {
        if self.has_translation_coordinate {
            Some(self)
        } else {
            None
        }
    }

    fn as_newton_diagonal(&mut self) -> Option<&mut dyn NewtonDiagonal> {
        if self.effects.has_newton_diagonal() {
            Some(self)
        } else {
            None
        }
    }

    /// Contacts, and only while some pair is near (passed its bounding-sphere test at the last force
    /// evaluation): otherwise the coupling is zero, and not adding it keeps the Newton matrix
    /// bitwise that of the same scene without contacts (docs/contacts.md §4).
    fn as_newton_coupling(&mut self) -> Option<&mut dyn NewtonCoupling> {
        if self.effects.has_contact_coupling() {
            Some(self)
        } else {
            None
        }
    }

    /// Contacts with friction, while one touches (docs/contacts.md §4, "Newton across the
    /// stiction band").
    fn as_newton_update_limit(&mut self) -> Option<&mut dyn NewtonUpdateLimit> {
        if self.effects.limits_newton_updates() {
            Some(self)
        } else {
            None
        }
    }

    fn as_unilateral_limits(&mut self) -> Option<&mut dyn UnilateralLimits> {
        Some(self)
    }

    fn as_parameters(&mut self) -> Option<&mut dyn Parameters> {
        Some(self)
    }
}

impl Constraints for RobotSystem {
    fn n_constraints(&self) -> usize {
        self.constraints.len()
    }

    fn constraints(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.constraints
            .evaluate(&self.model, &mut self.data, t, q.as_slice(), out);
        Ok(())
    }

    fn constraint_jacobian(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        self.constraints
            .jacobian(&self.model, &mut self.data, q.as_slice(), out);
        Ok(())
    }

    fn constraints_and_jacobian(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        phi: &mut DVector<f64>,
        phi_q: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        self.constraints.evaluate_with_jacobian(
            &self.model,
            &mut self.data,
            t,
            q.as_slice(),
            phi,
            phi_q,
        );
        Ok(())
    }

    fn constraints_are_scleronomic(&self) -> bool {
        self.constraints.is_scleronomic()
    }

    fn constraint_time_derivative(
        &mut self,
        t: f64,
        _q: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.constraints.time_derivative(t, out);
        Ok(())
    }

    fn constraint_acceleration_bias(
        &mut self,
        t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.constraints.acceleration_bias(
            &self.model,
            &mut self.data,
            t,
            q.as_slice(),
            v.as_slice(),
            out,
        );
        Ok(())
    }
}

impl PositionGroup for RobotSystem {
    fn integrate_position(
        &self,
        q: &DVector<f64>,
        dq: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        if !self.has_floating_joint {
            for ((x, q), dq) in out
                .as_mut_slice()
                .iter_mut()
                .zip(q.as_slice())
                .zip(dq.as_slice())
            {
                *x = q + dq;
            }
            return Ok(());
        }
        self.integrate_position_with_floating_joint(
            q.as_slice(),
            dq.as_slice(),
            out.as_mut_slice(),
        );
        Ok(())
    }

    /// Identity blocks for 1-dof joints; for a floating joint (`q ⊕ δ = q · Exp(δ)` on SE(3)) the
    /// blocks `Ad(Exp(−dq))` and `J_r(dq)` (docs/sensitivities.md §4).
    fn integrate_position_jacobians(
        &self,
        _q: &DVector<f64>,
        dq: &DVector<f64>,
        wrt_q_out: &mut DMatrix<f64>,
        wrt_dq_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        wrt_q_out.fill_with_identity();
        wrt_dq_out.fill_with_identity();
        for joint in &self.model.joints {
            if joint.kind != JointKind::Floating {
                continue;
            }
            let vi = joint.v_index;
            let linear = Vec3::new(dq[vi], dq[vi + 1], dq[vi + 2]);
            let angular = Vec3::new(dq[vi + 3], dq[vi + 4], dq[vi + 5]);
            let (adjoint, jacobian) = lie::exp_jacobians(&linear, &angular)
                .map_err(|message| format!("joint '{}': {message}", joint.name))?;
            wrt_q_out.view_mut((vi, vi), (6, 6)).copy_from(&adjoint);
            wrt_dq_out.view_mut((vi, vi), (6, 6)).copy_from(&jacobian);
        }
        Ok(())
    }

    /// `q1 ⊖ q0`: differences for 1-dof joints, the SE(3) logarithm of `q0⁻¹ q1` for a floating
    /// joint (docs/sensitivities.md §4).
    fn difference_position(
        &self,
        q0: &DVector<f64>,
        q1: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        for joint in &self.model.joints {
            let (qi, vi) = (joint.q_index, joint.v_index);
            if joint.kind != JointKind::Floating {
                out[vi] = q1[qi] - q0[qi];
                continue;
            }
            let pose = |q: &DVector<f64>| {
                (
                    Vec3::new(q[qi], q[qi + 1], q[qi + 2]),
                    unit_quaternion_from_xyzw(&q.as_slice()[qi + 3..qi + 7]),
                )
            };
            let ((p0, r0), (p1, r1)) = (pose(q0), pose(q1));
            let (linear, angular) = lie::log_between(&p0, &r0, &p1, &r1).ok_or_else(|| {
                format!(
                    "joint '{}': the two configurations differ by a rotation whose SE(3) logarithm \
                     is not defined",
                    joint.name
                )
            })?;
            for k in 0..3 {
                out[vi + k] = linear[k];
                out[vi + 3 + k] = angular[k];
            }
        }
        Ok(())
    }
}

impl PositionScale for RobotSystem {
    /// Scale of each coordinate for the Newton test's relative tolerance. An angle's size says
    /// nothing about its precision (a spinning wrist reaches 50 rad; `reltol · 50` would loosen the
    /// test 10⁵-fold), so revolute joints and base rotations use the absolute tolerance alone;
    /// translations scale with their size.
    fn position_scale(&self, q: &DVector<f64>, out: &mut DVector<f64>) {
        if !self.has_translation_coordinate {
            out.as_mut_slice().fill(0.0);
            return;
        }
        for joint in &self.model.joints {
            let (qi, vi) = (joint.q_index, joint.v_index);
            if joint.kind == JointKind::Floating {
                for k in 0..3 {
                    out[vi + k] = q[qi + k].abs();
                    out[vi + 3 + k] = 0.0;
                }
            } else if joint.kind == JointKind::Prismatic {
                out[vi] = q[qi].abs();
            } else {
                out[vi] = 0.0;
            }
        }
    }
}

impl NewtonDiagonal for RobotSystem {
    fn newton_diagonal(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        stiffness_out: &mut DVector<f64>,
        damping_out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        stiffness_out.as_mut_slice().fill(0.0);
        damping_out.as_mut_slice().fill(0.0);
        self.effects.add_newton_diagonal(
            &self.model,
            q.as_slice(),
            v.as_slice(),
            stiffness_out.as_mut_slice(),
            damping_out.as_mut_slice(),
        );
        Ok(())
    }
}

impl NewtonCoupling for RobotSystem {
    /// Contacts: `Jᵀ K J` and `Jᵀ C J` over the touching pairs (docs/contacts.md §4).
    fn newton_coupling(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        stiffness_out: &mut DMatrix<f64>,
        damping_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        stiffness_out.fill(0.0);
        damping_out.fill(0.0);
        self.effects.add_newton_matrices(
            &self.model,
            &self.environment,
            &mut self.data,
            (q.as_slice(), v.as_slice()),
            stiffness_out,
            damping_out,
        );
        Ok(())
    }
}

impl NewtonUpdateLimit for RobotSystem {
    fn newton_update_fraction(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        dv: &DVector<f64>,
    ) -> Result<f64, SystemError> {
        Ok(self.effects.newton_update_fraction(
            &self.environment,
            q.as_slice(),
            v.as_slice(),
            dv.as_slice(),
        ))
    }
}

impl Parameters for RobotSystem {
    fn n_parameters(&self) -> usize {
        self.parameters.len()
    }

    /// Inertial targets exactly (RNEA regressor columns), everything else by central differences of
    /// the residual with the model moved (docs/sensitivities.md §3).
    fn parameter_jacobians(
        &mut self,
        state: &DaeState<'_>,
        dynamics_out: &mut DMatrix<f64>,
        constraints_out: &mut DMatrix<f64>,
    ) -> Result<(), SystemError> {
        let DaeState {
            t,
            q,
            v,
            qdd,
            lambda,
        } = *state;
        self.parameters.jacobians(
            &mut self.model,
            &mut self.environment,
            &mut self.data,
            &mut self.effects,
            &self.constraints,
            t,
            q.as_slice(),
            v.as_slice(),
            qdd.as_slice(),
            lambda,
            dynamics_out,
            constraints_out,
        );
        Ok(())
    }

    /// The direction's natural step: no model value moves by more than
    /// [`THETA_FD_RELATIVE_STEP`](super::THETA_FD_RELATIVE_STEP) of its scale.
    fn parameter_difference_step(&self, k: usize) -> f64 {
        self.parameters.natural_step(k)
    }

    fn set_parameter_offset(&mut self, k: usize, offset: f64) -> Result<(), SystemError> {
        if k >= self.parameters.len() {
            return Err(format!(
                "parameter {k} does not exist: the system has {} parameter directions",
                self.parameters.len()
            )
            .into());
        }
        self.parameters
            .set_offset(&mut self.model, &mut self.environment, k, offset);
        Ok(())
    }
}

impl InverseDynamics for RobotSystem {
    fn dynamics_residual(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        self.inverse_dynamics_residual(q, v, qdd, false, out);
        Ok(())
    }

    /// Reuses the joint placements of the last `mass_matrix` call when `q` is bit for bit its
    /// configuration (else the plain [`InverseDynamics::dynamics_residual`]): the same bits, one
    /// placement pass (a `sin_cos` and a 3 × 3 product per revolute joint) fewer.
    fn dynamics_residual_after_mass_matrix(
        &mut self,
        _t: f64,
        q: &DVector<f64>,
        v: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<(), SystemError> {
        let reuse = self
            .mass_matrix_kinematics
            .give_back(q.as_slice(), &mut self.data.parent_from_body);
        self.inverse_dynamics_residual(q, v, qdd, reuse, out);
        Ok(())
    }
}

#[cfg(test)]
mod tests;
