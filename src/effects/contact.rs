//! Compliant contact between declared shape pairs (docs/contacts.md §2–§4): a Hunt–Crossley
//! normal force `f_n = k δ^e (1 + d δ̇)` (never pulling) and regularised Coulomb friction
//! `f_t = −μ f_n v_t / √(|v_t|² + v_s²)`, applied at the contact point as external wrenches on the
//! bodies and turned into generalised forces by RNEA's backward pass
//! ([`crate::dynamics::add_external_forces`]).
//!
//! The material is read from the environment (`Environment::contact`, an argument) at every
//! evaluation (parameters `scene.contact.*`),
//! the sizes from `model.description` (parameters `link.NAME.collision.K.*`). Only the declared
//! pairs are tested, each first by bounding spheres; the counters say how many tests and parry
//! queries ran.

use crate::dynamics::{add_external_forces, drift_kinematics, Data};
use crate::environment::Environment;
use crate::geometry::{
    contact_between, ContactMaterial, ContactPoint, ContactPoints, GeometryModel, PairTest,
};
use crate::model::Model;
use crate::spatial::{Force, Mat3, Vec3};
use nalgebra::DMatrix;

/// Counters of the contact effect over a run (summary `stats.contacts`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ContactStats {
    /// Pair tests (bounding spheres), one per declared shape pair per evaluation.
    pub pair_tests: u64,
    /// parry contact queries (pair tests whose bounding spheres overlapped).
    pub narrow_queries: u64,
    /// Pairs that started touching between two steps (a pair touches when any of its points does),
    /// judged at the last force evaluation of each step (docs/contacts.md §4, "Counters").
    pub made: u64,
    /// Pairs that stopped touching between two steps, judged like `made`.
    pub broken: u64,
    /// The deepest penetration seen at the last force evaluation of a step, m.
    pub max_depth_m: f64,
}

impl ContactStats {
    /// Adds the counters of `other` (maxima for the depth).
    pub fn merge(&mut self, other: &ContactStats) {
        self.pair_tests += other.pair_tests;
        self.narrow_queries += other.narrow_queries;
        self.made += other.made;
        self.broken += other.broken;
        self.max_depth_m = self.max_depth_m.max(other.max_depth_m);
    }
}

/// What the contact effect carries from step to step of one run: the counters, which pairs touched
/// at the last accepted step, and whether any pair was near at the last force evaluation (which
/// decides whether the Newton matrix gets the contact coupling). A study that steps many samples
/// through one system swaps each sample's state in and out ([`crate::effects::Effects::swap_contact_state`]),
/// so that a sample's run does not depend on which samples ran before it on the same thread.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactState {
    stats: ContactStats,
    touching: Vec<bool>,
    near: bool,
}

impl ContactState {
    /// The counters of this run so far.
    pub fn stats(&self) -> ContactStats {
        self.stats
    }
}

/// The force of one contact and its derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactForce {
    /// The force on shape `a` (world frame), N.
    pub force: Vec3,
    /// `∂f_n/∂δ`, N/m.
    pub normal_stiffness: f64,
    /// `∂f_n/∂δ̇`, N·s/m.
    pub normal_damping: f64,
    /// `∂(−f_t)/∂v_rel` (world frame, 3 × 3, symmetric positive semi-definite), N·s/m.
    pub friction_damping: Mat3,
}

/// The contact force on `a` for penetration `contact` and relative velocity `velocity = v_a − v_b`
/// of the contact point (world frame, m/s) (docs/contacts.md §2–§3).
pub fn contact_force(
    material: &ContactMaterial,
    contact: &ContactPoint,
    velocity: &Vec3,
) -> ContactForce {
    let n = contact.normal;
    let depth = contact.depth.max(0.0);
    let normal_velocity = n.dot(velocity);
    let rate = -normal_velocity;
    let power = depth.powf(material.exponent);
    let factor = 1.0 + material.damping * rate;
    let zero = ContactForce {
        force: Vec3::zeros(),
        normal_stiffness: 0.0,
        normal_damping: 0.0,
        friction_damping: Mat3::zeros(),
    };
    if !(factor > 0.0 && power > 0.0) {
        // Separating faster than 1/d: Hunt–Crossley would pull; the force is zero instead.
        return zero;
    }
    let normal_force = material.stiffness * power * factor;
    if !normal_force.is_finite() {
        return zero;
    }
    let tangential = velocity - normal_velocity * n;
    let vs = material.stiction_velocity;
    let s = (tangential.norm_squared() + vs * vs).sqrt();
    let mu_fn = material.friction * normal_force;
    let friction = -mu_fn / s * tangential;
    let projector = Mat3::identity() - n * n.transpose();
    let friction_damping = mu_fn / s * (projector - tangential * tangential.transpose() / (s * s));
    ContactForce {
        force: normal_force * n + friction,
        normal_stiffness: material.stiffness
            * material.exponent
            * depth.powf(material.exponent - 1.0)
            * factor,
        normal_damping: material.stiffness * material.damping * power,
        friction_damping,
    }
}

/// The scene's contacts.
#[derive(Clone, Debug)]
pub struct Contacts {
    geometry: GeometryModel,
    /// External wrench per body (body frame), work buffer of one evaluation.
    external: Vec<Force>,
    /// Linear Jacobian of the contact point, 3 × nv, work buffer.
    point_jacobian: DMatrix<f64>,
    stats: ContactStats,
    /// Whether each pair touched at the last accepted step.
    touching: Vec<bool>,
    /// Whether each pair touched at the last force evaluation ([`Contacts::add_forces`]): what
    /// [`Contacts::observe`] counts.
    touching_now: Vec<bool>,
    /// The deepest penetration at the last force evaluation, m.
    deepest_now: f64,
    /// Whether each pair has a contact point at the recorded state
    /// ([`Contacts::normal_forces`]' buffer; not the step's [`Contacts::touching_now`]).
    touching_recorded: Vec<bool>,
    /// Whether a force evaluation ran since the last [`Contacts::observe`] (else `observe` tests
    /// the pairs itself).
    evaluated: bool,
    /// The normal force of each pair, N, work buffer of [`Contacts::normal_forces`].
    normal_forces: Vec<f64>,
    /// Whether any pair passed the bounding-sphere test at the last force evaluation: when none
    /// did, the Newton coupling is zero and is not computed.
    near: bool,
    /// What [`Contacts::newton_update_fraction`] needs of the last force evaluation.
    sliding: SlidingContacts,
}

/// The touching contacts of the last force evaluation, for limiting Newton corrections across the
/// stiction band (docs/contacts.md §4, "Newton across the stiction band"): at which `(q, v)` they
/// were evaluated, and per contact the normal, the tangential velocity and the velocity Jacobian.
#[derive(Clone, Debug, Default)]
struct SlidingContacts {
    q: Vec<f64>,
    v: Vec<f64>,
    /// Per touching contact: normal (3), tangential relative velocity (3), then the relative point
    /// velocity Jacobian (3 × nv, row-major).
    entries: Vec<f64>,
    count: usize,
}

impl Contacts {
    pub(super) fn new(model: &Model, geometry: GeometryModel) -> Self {
        let n_pairs = geometry.pairs.len();
        Self {
            geometry,
            external: vec![Force::zero(); model.bodies.len()],
            point_jacobian: DMatrix::zeros(3, model.nv),
            stats: ContactStats::default(),
            touching: vec![false; n_pairs],
            touching_now: vec![false; n_pairs],
            touching_recorded: vec![false; n_pairs],
            deepest_now: 0.0,
            evaluated: false,
            normal_forces: vec![0.0; n_pairs],
            near: true,
            sliding: SlidingContacts::default(),
        }
    }

    /// The normal force `f · n ≥ 0` of every declared pair at `(q, v)`, N (0 while apart), in pair
    /// order: what the `contact.A.B.normal` outputs record. With `signed`, continued below zero
    /// for the pairs that do not touch: a pair with no contact point reads `−k·gap^e` (the force
    /// law of its material at the pair's distance, with the sign turned), so that across the box
    /// the value passes smoothly through the touch-down that the force itself only meets with a
    /// kink; `max(0, ·)` of it is the normal force (docs/contacts.md §7, "The signed force"). A
    /// pair parry cannot measure a distance for reads 0, as the force does. Not counted in the
    /// stats (recording is not simulating); overwrites the kinematic buffers of `data`.
    pub(super) fn normal_forces(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        signed: bool,
    ) -> &[f64] {
        let Self {
            geometry,
            normal_forces,
            touching_recorded,
            ..
        } = self;
        normal_forces.fill(0.0);
        touching_recorded.fill(false);
        let mut uncounted = ContactStats::default();
        Self::for_each_contact(
            geometry,
            &mut uncounted,
            model,
            environment,
            data,
            q,
            v,
            false,
            |_, k, contact, _, force| {
                normal_forces[k] += force.force.dot(&contact.normal);
                touching_recorded[k] = true;
            },
        );
        let material = match environment.contact {
            Some(material) if signed => material,
            _ => return &self.normal_forces,
        };
        for (k, pair) in geometry.pairs.iter().enumerate() {
            if touching_recorded[k] {
                continue;
            }
            let Ok([(shape_a, world_from_a), (shape_b, world_from_b)]) =
                geometry.placed_pair(model, &data.world_from_body, pair)
            else {
                continue;
            };
            if let Some(gap) =
                crate::geometry::separation(&shape_a, &world_from_a, &shape_b, &world_from_b)
            {
                normal_forces[k] = -material.stiffness * gap.powf(material.exponent);
            }
        }
        &self.normal_forces
    }

    /// Whether the Newton coupling is non-zero: some pair passed its bounding-sphere test at the
    /// last force evaluation (or none has run yet). When `false`,
    /// [`Contacts::add_newton_matrices`] would add only zeros.
    pub(super) fn coupling_active(&self) -> bool {
        self.near
    }

    /// The state of a run that has not started: no counts, nothing touching, coupling on.
    pub(super) fn fresh_state(&self) -> ContactState {
        ContactState {
            stats: ContactStats::default(),
            touching: vec![false; self.geometry.pairs.len()],
            near: true,
        }
    }

    /// Exchanges the run state with `state` (made by [`Contacts::fresh_state`] of this scene).
    pub(super) fn swap_state(&mut self, state: &mut ContactState) {
        std::mem::swap(&mut self.stats, &mut state.stats);
        std::mem::swap(&mut self.touching, &mut state.touching);
        std::mem::swap(&mut self.near, &mut state.near);
    }

    /// The counters so far.
    pub(super) fn stats(&self) -> ContactStats {
        self.stats
    }

    /// The declared geometry.
    pub(super) fn geometry(&self) -> &GeometryModel {
        &self.geometry
    }

    /// Tests pair `k` at the placements in `data` (counted).
    #[inline]
    fn test_pair(
        geometry: &GeometryModel,
        stats: &mut ContactStats,
        model: &Model,
        data: &Data,
        k: usize,
    ) -> Option<ContactPoints> {
        let pair = &geometry.pairs[k];
        stats.pair_tests += 1;
        if geometry.provably_apart(model, &data.world_from_body, pair) {
            // The bounding-sphere test of `contact_between` would answer `Apart` (docs/contacts.md
            // §4): the same result, without building both placements.
            return None;
        }
        let Ok([(shape_a, world_from_a), (shape_b, world_from_b)]) =
            geometry.placed_pair(model, &data.world_from_body, pair)
        else {
            // Sizes moved outside the valid range by a parameter: no contact (the parameter
            // check refuses such boxes before a run; this keeps a stray evaluation from panicking).
            return None;
        };
        let result = contact_between(&shape_a, &world_from_a, &shape_b, &world_from_b);
        if result != PairTest::Apart {
            stats.narrow_queries += 1;
        }
        match result {
            PairTest::Touching(points) => Some(points),
            _ => None,
        }
    }

    /// World velocity of the point `point` (world) riding on `body` (`None`: fixed).
    fn point_velocity(data: &Data, body: Option<usize>, point: &Vec3) -> Vec3 {
        let Some(b) = body else {
            return Vec3::zeros();
        };
        let world_from_body = &data.world_from_body[b];
        let in_body = world_from_body.inverse().transform_point(point);
        let twist = &data.velocity[b];
        world_from_body.rotation * (twist.linear + twist.angular.cross(&in_body))
    }

    /// Adds the wrench of `force` (world frame) at `point` (world) to `body`'s external wrench.
    fn add_wrench(data: &Data, external: &mut [Force], body: usize, point: &Vec3, force: &Vec3) {
        let world_from_body = &data.world_from_body[body];
        let in_body = world_from_body.inverse().transform_point(point);
        let f = world_from_body.rotation.transpose() * force;
        external[body] += Force::new(f, in_body.cross(&f));
    }

    /// The active contacts at `(q, v)`: calls `visit(data, pair, contact, velocity, force)` for each
    /// contact point of each touching pair (a pair may give several points, docs/contacts.md §1);
    /// `velocity` is the point's relative velocity `v_a − v_b` (world frame, m/s).
    /// With `from_rnea`, `data` already holds RNEA's `parent_from_body` and body velocities at
    /// `(q, v)` and only the world placements are composed from them (cheap); otherwise a
    /// kinematics pass computes everything.
    #[allow(clippy::too_many_arguments)]
    fn for_each_contact(
        geometry: &GeometryModel,
        stats: &mut ContactStats,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        from_rnea: bool,
        mut visit: impl FnMut(&Data, usize, &ContactPoint, &Vec3, &ContactForce),
    ) {
        let Some(material) = environment.contact else {
            return;
        };
        if from_rnea {
            for (i, joint) in model.joints.iter().enumerate() {
                data.world_from_body[i] = match joint.parent {
                    Some(p) => data.world_from_body[p].compose(&data.parent_from_body[i]),
                    None => data.parent_from_body[i],
                };
            }
        } else {
            drift_kinematics(model, data, q, v);
        }
        for k in 0..geometry.pairs.len() {
            let Some(points) = Self::test_pair(geometry, stats, model, data, k) else {
                continue;
            };
            let pair = geometry.pairs[k];
            let body_a = GeometryModel::body_of(model, pair.a);
            let body_b = GeometryModel::body_of(model, pair.b);
            for contact in points.as_slice() {
                let velocity = Self::point_velocity(data, body_a, &contact.point)
                    - Self::point_velocity(data, body_b, &contact.point);
                let force = contact_force(&material, contact, &velocity);
                visit(data, k, contact, &velocity, &force);
            }
        }
    }

    /// Adds the contacts' generalised forces to `out` (`q: dim nq`, `v, out: dim nv`). `data` must
    /// hold RNEA's kinematics at `(q, v)` (`rnea` or `nonlinear_effects` just before, as every
    /// residual does); overwrites `data.world_from_body`.
    pub(super) fn add_forces(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        q: &[f64],
        v: &[f64],
        out: &mut [f64],
    ) {
        let Self {
            geometry,
            stats,
            external,
            near,
            sliding,
            touching_now,
            deepest_now,
            evaluated,
            ..
        } = self;
        let narrow_before = stats.narrow_queries;
        external.fill(Force::zero());
        touching_now.fill(false);
        *deepest_now = 0.0;
        *evaluated = true;
        let mut any = false;
        let with_friction = environment.contact.is_some_and(|m| m.friction > 0.0);
        sliding.begin(q, v);
        Self::for_each_contact(
            geometry,
            stats,
            model,
            environment,
            data,
            q,
            v,
            true,
            |data, k, contact, velocity, force| {
                touching_now[k] = true;
                *deepest_now = deepest_now.max(contact.depth);
                let pair = geometry.pairs[k];
                let body_a = GeometryModel::body_of(model, pair.a);
                let body_b = GeometryModel::body_of(model, pair.b);
                if let Some(a) = body_a {
                    Self::add_wrench(data, external, a, &contact.point, &force.force);
                    any = true;
                }
                if let Some(b) = body_b {
                    Self::add_wrench(data, external, b, &contact.point, &(-force.force));
                    any = true;
                }
                if with_friction && force.force != Vec3::zeros() {
                    sliding.push(model, data, body_a, body_b, contact, velocity);
                }
            },
        );
        *near = stats.narrow_queries > narrow_before;
        if any {
            add_external_forces(model, &data.parent_from_body, external, out);
        }
    }

    /// Fills `jacobian` (3 × nv) with the linear velocity Jacobian of the world point `point`
    /// riding on `body`, with `sign` (+1 or −1), added to what it holds.
    fn add_point_jacobian(
        model: &Model,
        data: &Data,
        body: usize,
        point: &Vec3,
        sign: f64,
        jacobian: &mut DMatrix<f64>,
    ) {
        Self::for_each_point_jacobian_column(model, data, body, point, |index, column| {
            for r in 0..3 {
                jacobian[(r, index)] += sign * column[r];
            }
        });
    }

    /// Calls `visit(v_index, column)` with each non-zero column (world frame) of the linear
    /// velocity Jacobian of the world point `point` riding on `body`, root-ward from `body`.
    fn for_each_point_jacobian_column(
        model: &Model,
        data: &Data,
        body: usize,
        point: &Vec3,
        mut visit: impl FnMut(usize, Vec3),
    ) {
        let mut current = Some(body);
        while let Some(i) = current {
            let joint = &model.joints[i];
            for k in 0..joint.nv() {
                let motion = data.world_from_body[i].act_motion(&joint.subspace_column(k));
                visit(
                    joint.v_index + k,
                    motion.linear + motion.angular.cross(point),
                );
            }
            current = joint.parent;
        }
    }

    /// Adds `Jᵀ K J` and `Jᵀ C J` of every active contact to `stiffness` and `damping` (nv × nv):
    /// `K = (∂f_n/∂δ) n nᵀ`, `C = (∂f_n/∂δ̇) n nᵀ + ∂(−f_t)/∂v` (docs/contacts.md §4).
    pub(super) fn add_newton_matrices(
        &mut self,
        model: &Model,
        environment: &Environment,
        data: &mut Data,
        (q, v): (&[f64], &[f64]),
        stiffness: &mut DMatrix<f64>,
        damping: &mut DMatrix<f64>,
    ) {
        if !self.near {
            // No pair was within its bounding spheres at the last force evaluation (the previous
            // iterate): the coupling is zero there, and a touch-down since then is caught by the
            // refresh of a failing Newton pass, which evaluates forces first.
            return;
        }
        let Self {
            geometry,
            stats,
            point_jacobian: jacobian,
            ..
        } = self;
        Self::for_each_contact(
            geometry,
            stats,
            model,
            environment,
            data,
            q,
            v,
            false,
            |data, k, contact, _, force| {
                let pair = geometry.pairs[k];
                jacobian.fill(0.0);
                if let Some(a) = GeometryModel::body_of(model, pair.a) {
                    Self::add_point_jacobian(model, data, a, &contact.point, 1.0, jacobian);
                }
                if let Some(b) = GeometryModel::body_of(model, pair.b) {
                    Self::add_point_jacobian(model, data, b, &contact.point, -1.0, jacobian);
                }
                let n = contact.normal;
                let k_world = force.normal_stiffness * n * n.transpose();
                let c_world = force.normal_damping * n * n.transpose() + force.friction_damping;
                let nv = model.nv;
                // Only the columns of joints that move the pair are non-zero.
                for col in 0..nv {
                    let jc = Vec3::new(jacobian[(0, col)], jacobian[(1, col)], jacobian[(2, col)]);
                    if jc == Vec3::zeros() {
                        continue;
                    }
                    let kc = k_world * jc;
                    let cc = c_world * jc;
                    for row in 0..nv {
                        let jr =
                            Vec3::new(jacobian[(0, row)], jacobian[(1, row)], jacobian[(2, row)]);
                        stiffness[(row, col)] += jr.dot(&kc);
                        damping[(row, col)] += jr.dot(&cc);
                    }
                }
            },
        );
    }

    /// Whether [`Contacts::newton_update_fraction`] may limit a correction now: a contact with
    /// friction touched at the last force evaluation.
    pub(super) fn limits_newton_updates(&self) -> bool {
        self.sliding.count > 0
    }

    /// The fraction of a Newton correction to apply at the iterate `(q, v)` whose full correction
    /// changes the joint velocities by `dv` (docs/contacts.md §4, "Newton across the stiction
    /// band"): for every contact that slides faster than the stiction velocity `v_s` at the iterate
    /// and whose tangential velocity the full correction would carry through the band
    /// `|v_t| ≤ v_s` and out on the other side, the fraction that stops at the point of the
    /// correction nearest to `v_t = 0`; the smallest over the contacts, 1 when none crosses. 1 when
    /// the last force evaluation was not at this iterate.
    pub(super) fn newton_update_fraction(
        &self,
        environment: &Environment,
        q: &[f64],
        v: &[f64],
        dv: &[f64],
    ) -> f64 {
        let sliding = &self.sliding;
        let Some(material) = environment.contact else {
            return 1.0;
        };
        if sliding.q != q || sliding.v != v {
            return 1.0;
        }
        let vs = material.stiction_velocity;
        let nv = dv.len();
        let stride = 6 + 3 * nv;
        let mut fraction = 1.0_f64;
        for entry in sliding.entries.chunks_exact(stride).take(sliding.count) {
            let n = Vec3::new(entry[0], entry[1], entry[2]);
            let tangential = Vec3::new(entry[3], entry[4], entry[5]);
            if tangential.norm() <= vs {
                continue;
            }
            let jacobian = &entry[6..];
            let mut change = Vec3::zeros();
            for r in 0..3 {
                change[r] = jacobian[r * nv..(r + 1) * nv]
                    .iter()
                    .zip(dv)
                    .map(|(j, d)| j * d)
                    .sum();
            }
            let change = change - n.dot(&change) * n;
            let length_squared = change.norm_squared();
            if length_squared == 0.0 {
                continue;
            }
            let nearest = -tangential.dot(&change) / length_squared;
            if !(nearest > 0.0 && nearest < 1.0) {
                continue;
            }
            let passes_through = (tangential + nearest * change).norm() <= vs;
            let leaves = (tangential + change).norm() > vs;
            if passes_through && leaves {
                fraction = fraction.min(nearest);
            }
        }
        fraction
    }

    /// After an accepted step ending at `(q, v)`: counts pairs that started or stopped touching
    /// since the last call and returns the deepest penetration (m, 0 when none), as seen by the
    /// last force evaluation of the step — the residual of its last Newton iteration, which the
    /// integrator evaluated anyway (docs/contacts.md §4, "Counters"). Only when no force
    /// evaluation ran since the last call are the pairs tested here, at `q` (a kinematics pass;
    /// overwrites the kinematic buffers of `data`).
    pub(super) fn observe(&mut self, model: &Model, data: &mut Data, q: &[f64], v: &[f64]) -> f64 {
        let Self {
            geometry,
            stats,
            touching,
            touching_now,
            deepest_now,
            evaluated,
            ..
        } = self;
        let _ = v;
        if !*evaluated {
            touching_now.fill(false);
            *deepest_now = 0.0;
            crate::dynamics::forward_kinematics(model, data, q);
            for (k, now) in touching_now.iter_mut().enumerate() {
                if let Some(points) = Self::test_pair(geometry, stats, model, data, k) {
                    *now = true;
                    *deepest_now = deepest_now.max(points.deepest());
                }
            }
        }
        *evaluated = false;
        for (before, after) in touching.iter_mut().zip(touching_now.iter()) {
            match (*before, *after) {
                (false, true) => stats.made += 1,
                (true, false) => stats.broken += 1,
                _ => {}
            }
            *before = *after;
        }
        stats.max_depth_m = stats.max_depth_m.max(*deepest_now);
        *deepest_now
    }

    /// The deepest penetration over all pairs at `q` (m; 0 when nothing touches), counted as
    /// pair tests.
    pub(super) fn deepest_penetration(&mut self, model: &Model, data: &mut Data, q: &[f64]) -> f64 {
        crate::dynamics::forward_kinematics(model, data, q);
        let Self {
            geometry, stats, ..
        } = self;
        (0..geometry.pairs.len())
            .filter_map(|k| Self::test_pair(geometry, stats, model, data, k))
            .map(|points| points.deepest())
            .fold(0.0, f64::max)
    }
}

impl SlidingContacts {
    /// Starts a force evaluation at `(q, v)`: forgets the contacts of the last one.
    fn begin(&mut self, q: &[f64], v: &[f64]) {
        self.q.clear();
        self.q.extend_from_slice(q);
        self.v.clear();
        self.v.extend_from_slice(v);
        self.count = 0;
    }

    /// Records a touching contact: its normal, the tangential part of `velocity` (`v_a − v_b` at
    /// the contact point, world) and the Jacobian of that relative velocity.
    fn push(
        &mut self,
        model: &Model,
        data: &Data,
        body_a: Option<usize>,
        body_b: Option<usize>,
        contact: &ContactPoint,
        velocity: &Vec3,
    ) {
        let nv = model.nv;
        let stride = 6 + 3 * nv;
        let start = self.count * stride;
        if self.entries.len() < start + stride {
            self.entries.resize(start + stride, 0.0);
        }
        let entry = &mut self.entries[start..start + stride];
        let n = contact.normal;
        let tangential = velocity - n.dot(velocity) * n;
        entry[..3].copy_from_slice(n.as_slice());
        entry[3..6].copy_from_slice(tangential.as_slice());
        let jacobian = &mut entry[6..];
        jacobian.fill(0.0);
        for (body, sign) in [(body_a, 1.0), (body_b, -1.0)] {
            if let Some(body) = body {
                Contacts::for_each_point_jacobian_column(
                    model,
                    data,
                    body,
                    &contact.point,
                    |index, column| {
                        for r in 0..3 {
                            jacobian[r * nv + index] += sign * column[r];
                        }
                    },
                );
            }
        }
        self.count += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touching(depth: f64) -> ContactPoint {
        ContactPoint {
            point: Vec3::zeros(),
            normal: Vec3::z(),
            depth,
        }
    }

    #[test]
    fn hunt_crossley_force_and_its_derivatives() {
        let material = ContactMaterial {
            stiffness: 2e5,
            exponent: 1.5,
            damping: 0.8,
            friction: 0.5,
            stiction_velocity: 1e-3,
        };
        let force_at = |depth: f64, v: Vec3| contact_force(&material, &touching(depth), &v);
        let (depth, v) = (2e-3, Vec3::new(0.3, -0.1, -0.4));
        let f = force_at(depth, v);
        let fn_expected = 2e5 * depth.powf(1.5) * (1.0 + 0.8 * 0.4);
        assert!((f.force.z - fn_expected).abs() < 1e-12 * fn_expected);
        // Friction opposes the sliding direction with μ f_n (sliding far above v_s).
        let ft = Vec3::new(f.force.x, f.force.y, 0.0);
        assert!((ft.norm() / fn_expected - 0.5).abs() < 1e-4);
        assert!(ft.dot(&Vec3::new(0.3, -0.1, 0.0)) < 0.0);
        // Derivatives against central differences.
        let h = 1e-8;
        let dk = (force_at(depth + h, v).force.z - force_at(depth - h, v).force.z) / (2.0 * h);
        assert!(
            (f.normal_stiffness - dk).abs() < 1e-5 * dk.abs(),
            "{} vs {dk}",
            f.normal_stiffness
        );
        let dv = Vec3::new(0.0, 0.0, h);
        let dc = -(force_at(depth, v + dv).force.z - force_at(depth, v - dv).force.z) / (2.0 * h);
        assert!((f.normal_damping - dc).abs() < 1e-5 * dc.abs());
        for axis in 0..2 {
            let mut e = Vec3::zeros();
            e[axis] = h;
            let column = -(force_at(depth, v + e).force - force_at(depth, v - e).force) / (2.0 * h);
            for r in 0..2 {
                let exact = f.friction_damping[(r, axis)];
                assert!(
                    (exact - column[r]).abs() < 1e-5 * (1.0 + exact.abs()),
                    "{r},{axis}"
                );
            }
        }
        // Never pulling, never NaN: separating fast, no depth, an absurd impact speed.
        assert_eq!(
            force_at(depth, Vec3::new(0.0, 0.0, 5.0)).force,
            Vec3::zeros()
        );
        assert_eq!(force_at(0.0, v).force, Vec3::zeros());
        let hard = force_at(0.5, Vec3::new(0.0, 0.0, -1e6));
        assert!(hard.force.iter().all(|x| x.is_finite()) && hard.force.z > 0.0);
    }
}
