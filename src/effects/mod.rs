//! Generalised forces of the scene's declared effects, assembled once per run: a scene that does not
//! declare an effect never evaluates it. One file per effect.
//!
//! `(q, v) ⇒ Q_effects` (added to the right-hand side `Q`), and the diagonal stiffness and damping the
//! modified Newton matrix of the integrator needs (docs/method.md §5: `+β'h² k_j`, `+γ'h c_j`).
//!
//! Gravity is not here: it enters the rigid-body bias as a base acceleration in RNEA through the
//! environment's gravity ([`crate::environment::Environment`], an argument of the dynamics; zero
//! when the scene does not declare it). Values that parameters can change (URDF damping, friction,
//! limits; the contact material) are read from the model (and the environment, for the material,
//! an argument of the calls that reach contacts) at each evaluation, so a sample's parameter values take effect without re-assembly. The joint limits'
//! penalty constants are the exception: they are tuned once, at assembly, to the joints' inertias
//! of the model assembled with (a study's nominal model), and every sample shares them.

mod contact;
mod damping;
mod friction;
mod limits;
mod springs;

pub use contact::{contact_force, ContactForce, ContactState, ContactStats};
pub use friction::FRICTION_SMOOTHING_VELOCITY;
pub use limits::{
    limit_penalty, LimitEvent, LimitSide, JOINT_LIMIT_DAMPING_DEPTH, JOINT_LIMIT_DAMPING_RATIO,
    JOINT_LIMIT_FREQUENCY,
};

use crate::dynamics::Data;
use crate::environment::Environment;
use crate::model::{JointKind, Model};
use crate::scene::Scene;
use nalgebra::DMatrix;

/// The diagonal `M_jj` of the mass matrix of `model` at `q` (dim nv): the inertia each coordinate
/// moves with every other one held, kg·m² or kg.
fn inertia_diagonal(model: &Model, q: &[f64]) -> Vec<f64> {
    let mut data = Data::new(model);
    crate::dynamics::crba(model, &mut data, q)
        .diagonal()
        .as_slice()
        .to_vec()
}

/// A 1-dof joint an effect acts on: its coordinates and its URDF joint.
#[derive(Clone, Copy, Debug, PartialEq)]
struct JointSlot {
    q_index: usize,
    v_index: usize,
    source: usize,
}

/// Every 1-dof joint that comes from the URDF.
fn one_dof_joints(model: &Model) -> Vec<JointSlot> {
    model
        .joints
        .iter()
        .filter(|j| j.kind != JointKind::Floating)
        .filter_map(|j| {
            j.source.map(|source| JointSlot {
                q_index: j.q_index,
                v_index: j.v_index,
                source,
            })
        })
        .collect()
}

/// The assembled effects of one scene.
#[derive(Clone, Debug, Default)]
pub struct Effects {
    damping: Option<damping::JointDamping>,
    friction: Option<friction::JointFriction>,
    springs: Option<springs::JointSprings>,
    limits: Option<limits::JointLimits>,
    contacts: Option<contact::Contacts>,
}

impl Effects {
    /// Assembles the effects `scene` declares for `model`.
    pub fn assemble(model: &Model, scene: &Scene) -> Effects {
        let joints = one_dof_joints(model);
        let e = &scene.effects;
        Effects {
            damping: e.joint_damping.then(|| damping::JointDamping::new(&joints)),
            friction: e
                .joint_friction
                .then(|| friction::JointFriction::new(&joints)),
            springs: e
                .joint_springs
                .then(|| springs::JointSprings::new(model, &scene.springs)),
            limits: e.joint_limits.then(|| {
                limits::JointLimits::new(
                    model,
                    &joints,
                    &inertia_diagonal(model, &scene.initial_q),
                    scene.limit_restitution,
                )
            }),
            contacts: scene
                .contact
                .as_ref()
                .map(|c| contact::Contacts::new(model, c.geometry.clone())),
        }
    }

    /// Whether some effect is declared (else [`Effects::add_forces`] adds nothing).
    #[inline]
    pub fn has_forces(&self) -> bool {
        self.has_newton_diagonal() || self.has_contacts()
    }

    /// Whether the scene declares contacts (then the generalised forces couple joints: see
    /// [`Effects::add_newton_matrices`]).
    pub fn has_contacts(&self) -> bool {
        self.contacts.is_some()
    }

    /// Whether [`Effects::add_newton_matrices`] would add anything now: contacts are declared and
    /// some pair passed its bounding-sphere test at the last force evaluation (docs/contacts.md §4).
    /// Changes from step to step.
    pub fn has_contact_coupling(&self) -> bool {
        self.contacts.as_ref().is_some_and(|c| c.coupling_active())
    }

    /// The contact state of a run that has not started (`None` without contacts).
    pub fn fresh_contact_state(&self) -> Option<ContactState> {
        self.contacts.as_ref().map(|c| c.fresh_state())
    }

    /// Exchanges the contact run state (counters, which pairs touch, whether the Newton coupling is
    /// on) with `state`, which must come from [`Effects::fresh_contact_state`] of the same scene.
    /// Nothing without contacts.
    pub fn swap_contact_state(&mut self, state: &mut ContactState) {
        if let Some(c) = &mut self.contacts {
            c.swap_state(state);
        }
    }

    /// Whether [`Effects::newton_update_fraction`] may limit Newton corrections now: a contact
    /// with friction touched at the last force evaluation (docs/contacts.md §4).
    pub fn limits_newton_updates(&self) -> bool {
        self.contacts
            .as_ref()
            .is_some_and(|c| c.limits_newton_updates())
    }

    /// The fraction in `(0, 1]` of a Newton correction to apply at `(q, v)`, whose full correction
    /// changes the joint velocities by `dv`: below 1 when it would carry a sliding contact's
    /// tangential velocity across the stiction band (docs/contacts.md §4). 1 without contacts.
    pub fn newton_update_fraction(
        &self,
        environment: &Environment,
        q: &[f64],
        v: &[f64],
        dv: &[f64],
    ) -> f64 {
        self.contacts
            .as_ref()
            .map_or(1.0, |c| c.newton_update_fraction(environment, q, v, dv))
    }

    /// The contact counters so far (`None` without contacts).
    pub fn contact_stats(&self) -> Option<ContactStats> {
        self.contacts.as_ref().map(|c| c.stats())
    }

    /// The normal force of every declared contact pair at `(q, v)`, N, in pair order (empty without
    /// contacts; docs/contacts.md); with `signed`, a pair apart reads `−k·gap^e` instead of 0
    /// (docs/contacts.md §7, "The signed force"; `max(0, ·)` of each is the normal force). Not
    /// counted in [`Effects::contact_stats`]; overwrites the kinematic buffers of `data`.
    pub fn contact_normal_forces(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        signed: bool,
    ) -> &[f64] {
        match &mut self.contacts {
            Some(c) => c.normal_forces(model, environment, data, q, v, signed),
            None => &[],
        }
    }

    /// The declared contact geometry (`None` without contacts).
    pub fn contact_geometry(&self) -> Option<&crate::geometry::GeometryModel> {
        self.contacts.as_ref().map(|c| c.geometry())
    }

    /// At an accepted state: counts contacts made and broken since the last call and returns the
    /// deepest penetration, m (0 without contacts). Overwrites the kinematic buffers of `data`.
    pub fn observe_contacts(
        &mut self,
        model: &Model,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
    ) -> f64 {
        self.contacts
            .as_mut()
            .map_or(0.0, |c| c.observe(model, data, q, v))
    }

    /// The deepest penetration over the declared pairs at `q`, m (0 without contacts).
    pub fn deepest_penetration(&mut self, model: &Model, data: &mut Data, q: &[f64]) -> f64 {
        self.contacts
            .as_mut()
            .map_or(0.0, |c| c.deepest_penetration(model, data, q))
    }

    /// Adds the coupling terms of the effects that act on several joints at once — contacts:
    /// `Jᵀ K J` to `stiffness` and `Jᵀ C J` to `damping` (nv × nv; docs/contacts.md §4). Nothing
    /// without contacts. Overwrites the kinematic buffers of `data`.
    pub fn add_newton_matrices(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        (q, v): (&[f64], &[f64]),
        stiffness: &mut DMatrix<f64>,
        damping: &mut DMatrix<f64>,
    ) {
        if let Some(c) = &mut self.contacts {
            c.add_newton_matrices(model, environment, data, (q, v), stiffness, damping);
        }
    }

    /// Whether no effect besides gravity is simulated.
    pub fn is_empty(&self) -> bool {
        self.damping.is_none()
            && self.friction.is_none()
            && self.springs.is_none()
            && self.limits.is_none()
            && self.contacts.is_none()
    }

    /// Number of unilateral limit events (two per joint with finite limits when `joint_limits` is
    /// declared, else 0).
    pub fn n_limit_events(&self) -> usize {
        self.limits.as_ref().map_or(0, |l| l.n_events())
    }

    /// Limit event `k` (`0..n_limit_events()`) at the model's current limit values.
    pub fn limit_event(&self, model: &Model, k: usize) -> Option<LimitEvent> {
        self.limits.as_ref().and_then(|l| l.event(model, k))
    }

    /// Gaps (allowed side ≥ 0, rad or m) and rates of every limit event (`q: dim nq`, `v: dim nv`,
    /// `gaps`, `rates`: dim `n_limit_events()`, overwritten).
    pub fn limit_gaps(
        &self,
        model: &Model,
        q: &[f64],
        v: &[f64],
        gaps: &mut [f64],
        rates: &mut [f64],
    ) {
        if let Some(l) = &self.limits {
            l.gaps(model, q, v, gaps, rates);
        }
    }

    /// Adds the effects' generalised forces to `out` (`q: dim nq`, `v, out: dim nv`). With contacts,
    /// `data` must hold RNEA's kinematics at `(q, v)` (call [`crate::dynamics::rnea`] or
    /// [`crate::dynamics::nonlinear_effects`] at the same `q`, `v` just before, as every residual
    /// does); contacts overwrite `data.world_from_body`.
    #[inline]
    pub fn add_forces(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        if self.has_forces() {
            self.add_declared_forces(model, environment, data, q, v, out);
        }
    }

    /// [`Effects::add_forces`] once some effect is declared.
    fn add_declared_forces(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        if let Some(e) = &self.damping {
            e.add_forces(model, v, out);
        }
        if let Some(e) = &self.friction {
            e.add_forces(model, v, out);
        }
        if let Some(e) = &self.springs {
            e.add_forces(q, v, out);
        }
        if let Some(e) = &self.limits {
            e.add_forces(model, q, v, out);
        }
        if let Some(e) = &mut self.contacts {
            e.add_forces(model, environment, data, q, v, out);
        }
    }

    /// Which joints are beyond a limit at `q` (a bit per limited joint; 0 without the
    /// `joint_limits` effect): the regime of the piecewise penalty law, whose Newton diagonal
    /// switches with it (see [`crate::integrate::DaeSystem::newton_regime`]).
    pub fn newton_regime(&self, model: &Model, q: &[f64]) -> u64 {
        self.limits.as_ref().map_or(0, |l| l.regime(model, q))
    }

    /// Whether [`Effects::add_newton_diagonal`] adds anything: damping, friction, springs or
    /// limits are declared.
    pub fn has_newton_diagonal(&self) -> bool {
        self.damping.is_some()
            || self.friction.is_some()
            || self.springs.is_some()
            || self.limits.is_some()
    }

    /// Adds the effects' diagonal stiffness `k_j = −∂Q_j/∂q_j` and damping `c_j = −∂Q_j/∂q̇_j` to
    /// `stiffness` and `damping` (`dim nv`).
    pub fn add_newton_diagonal(
        &self,
        model: &Model,
        q: &[f64],
        v: &[f64],
        stiffness: &mut [f64],
        damping: &mut [f64],
    ) {
        if let Some(e) = &self.damping {
            e.add_diagonal(model, damping);
        }
        if let Some(e) = &self.friction {
            e.add_diagonal(model, v, damping);
        }
        if let Some(e) = &self.springs {
            e.add_diagonal(stiffness, damping);
        }
        if let Some(e) = &self.limits {
            e.add_diagonal(model, q, v, stiffness, damping);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{parse_description, LoadOptions};
    use crate::scene::{parse_sidecar, SceneOverrides};

    fn setup(sidecar: &str) -> (Model, Scene) {
        let text = r#"<robot name="p"><link name="w"/>
          <link name="bar"><inertial><origin xyz="0.5 0 0"/><mass value="1"/>
          <inertia ixx="0" ixy="0" ixz="0" iyy="0.08" iyz="0" izz="0.08"/></inertial></link>
          <joint name="hinge" type="revolute"><parent link="w"/><child link="bar"/><axis xyz="0 0 1"/>
          <limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="0.5" friction="0.2"/></joint></robot>"#;
        let model = Model::from_description(
            parse_description(text, "p.urdf").unwrap(),
            LoadOptions::default(),
            "p.urdf",
        )
        .unwrap();
        let scene = Scene::resolve(
            &parse_sidecar(sidecar).unwrap(),
            &model,
            "s.toml",
            SceneOverrides::default(),
        )
        .unwrap();
        (model, scene)
    }

    /// Central difference of the effects' force with respect to q (or v) at coordinate 0.
    fn numeric_derivative(
        effects: &mut Effects,
        model: &Model,
        q: f64,
        v: f64,
        of_velocity: bool,
    ) -> f64 {
        let h = 1e-7;
        let mut eval = |dq: f64, dv: f64| {
            let mut out = [0.0];
            let mut data = Data::new(model);
            effects.add_forces(
                model,
                &Environment::default(),
                &mut data,
                &[q + dq],
                &[v + dv],
                &mut out,
            );
            out[0]
        };
        if of_velocity {
            -(eval(0.0, h) - eval(0.0, -h)) / (2.0 * h)
        } else {
            -(eval(h, 0.0) - eval(-h, 0.0)) / (2.0 * h)
        }
    }

    #[test]
    fn only_declared_effects_are_assembled() {
        let (model, scene) = setup("");
        assert!(Effects::assemble(&model, &scene).is_empty());
        let (model, scene) = setup("[scene]\neffects = []");
        assert!(!scene.effects.gravity);
        assert!(Effects::assemble(&model, &scene).is_empty());
    }

    #[test]
    fn diagonal_terms_match_the_forces_derivatives() {
        let sidecar = "[scene]\neffects = [\"joint_damping\", \"joint_friction\", \"joint_springs\", \"joint_limits\"]\n\
                       [[scene.spring]]\njoint = \"hinge\"\nstiffness = 30.0\nrest = 0.2\ndamping = 1.5";
        let (model, scene) = setup(sidecar);
        let mut effects = Effects::assemble(&model, &scene);
        // Inside the limits and beyond the upper one; slow and fast.
        for (q, v) in [(0.3, 0.004), (1.05, 0.5), (-1.2, -2.0)] {
            let (mut k, mut c) = ([0.0], [0.0]);
            effects.add_newton_diagonal(&model, &[q], &[v], &mut k, &mut c);
            let k_numeric = numeric_derivative(&mut effects, &model, q, v, false);
            let c_numeric = numeric_derivative(&mut effects, &model, q, v, true);
            assert!(
                (k[0] - k_numeric).abs() <= 1e-5 * k_numeric.abs().max(1.0),
                "k at {q}: {} vs {k_numeric}",
                k[0]
            );
            assert!(
                (c[0] - c_numeric).abs() <= 1e-5 * c_numeric.abs().max(1.0),
                "c at {q},{v}: {} vs {c_numeric}",
                c[0]
            );
        }
    }
}
