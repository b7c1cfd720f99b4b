//! Constraint rows `Φ(q, t) = 0` of the index-3 formulation: loop closures (`[[scene.loop]]`), URDF
//! mimic joints and drives (`[[scene.drive]]`). Row order: loops (in declaration order, their
//! components in order), then mimic joints, then drives.
//!
//! For each row the set provides `Φ`, the Jacobian `Φ_q` (along the tangent space, `m × nv`), `Φ_t`
//! and the acceleration right-hand side `−(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt` the consistent start needs.
//! Multiplier signs follow `M q̈ + Φ_qᵀ λ = Q`: a drive's effort is `−λ` (= Pinocchio's `rnea`
//! torque), a loop's reaction force on the child along its direction `i` is `−λ_i`.

mod loops;
mod profile;

pub use loops::{LoopClosure, LoopKind};
pub use profile::{Profile, Spline};

use crate::dynamics::{drift_kinematics, world_placements, Data};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// A prescribed joint motion `q_j = f(t)`.
#[derive(Clone, Debug)]
pub struct Drive {
    /// Name (output `effort.NAME`).
    pub name: String,
    /// The driven coordinate.
    pub q_index: usize,
    /// Its velocity coordinate.
    pub v_index: usize,
    /// `f(t)`.
    pub profile: Profile,
}

/// A URDF mimic joint as a row: `q_follower = multiplier · q_leader + offset`.
#[derive(Clone, Debug)]
pub struct Mimic {
    /// The following joint's name (output `lambda.mimic.NAME`).
    pub joint: String,
    /// Follower coordinates.
    pub follower: (usize, usize),
    /// Leader coordinates.
    pub leader: (usize, usize),
    /// Multiplier.
    pub multiplier: f64,
    /// Offset (rad or m).
    pub offset: f64,
}

/// All constraint rows of a run.
#[derive(Clone, Debug, Default)]
pub struct ConstraintSet {
    /// Loop closures.
    pub loops: Vec<LoopClosure>,
    /// Mimic rows.
    pub mimics: Vec<Mimic>,
    /// Drives.
    pub drives: Vec<Drive>,
    row_names: Vec<String>,
}

impl ConstraintSet {
    /// Collects the rows; `row_name(i)` then names row `i` for messages.
    pub fn new(loops: Vec<LoopClosure>, mimics: Vec<Mimic>, drives: Vec<Drive>) -> Self {
        let mut row_names = Vec::new();
        for l in &loops {
            for i in 0..l.rows() {
                row_names.push(format!("loop '{}' row {i}", l.name));
            }
        }
        row_names.extend(mimics.iter().map(|m| format!("mimic joint '{}'", m.joint)));
        row_names.extend(drives.iter().map(|d| format!("drive '{}'", d.name)));
        Self {
            loops,
            mimics,
            drives,
            row_names,
        }
    }

    /// The mimic rows of every URDF mimic joint of `model`.
    pub fn mimics_of(model: &Model) -> Vec<Mimic> {
        model
            .joints
            .iter()
            .filter_map(|j| {
                j.mimic.map(|(leader, multiplier, offset)| Mimic {
                    joint: j.name.clone(),
                    follower: (j.q_index, j.v_index),
                    leader: (model.joints[leader].q_index, model.joints[leader].v_index),
                    multiplier,
                    offset,
                })
            })
            .collect()
    }

    /// Number of rows `m`.
    pub fn len(&self) -> usize {
        self.row_names.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.row_names.is_empty()
    }

    /// What row `i` is, e.g. `loop 'closure' row 1`.
    pub fn row_name(&self, i: usize) -> &str {
        self.row_names.get(i).map_or("?", String::as_str)
    }

    /// First row of each loop, then of the mimic rows, then of the drives.
    fn offsets(&self) -> (usize, usize) {
        let loop_rows: usize = self.loops.iter().map(LoopClosure::rows).sum();
        (loop_rows, loop_rows + self.mimics.len())
    }

    /// `out = Φ(q, t)` (`dim m`). Writes the world placements `data.world_from_body`
    /// ([`world_placements`]) when there are loops.
    pub fn evaluate(
        &self,
        model: &Model,
        data: &mut Data,
        t: f64,
        q: &[f64],
        out: &mut DVector<f64>,
    ) {
        if !self.loops.is_empty() {
            world_placements(model, data, q);
            let mut row = 0;
            for l in &self.loops {
                l.evaluate(model, data, &mut out.as_mut_slice()[row..row + l.rows()]);
                row += l.rows();
            }
        }
        self.non_loop_values(t, q, out);
    }

    /// The mimic and drive rows of `Φ(q, t)` into `out`.
    #[inline]
    fn non_loop_values(&self, t: f64, q: &[f64], out: &mut DVector<f64>) {
        if self.mimics.is_empty() && self.drives.is_empty() {
            return;
        }
        let (mimic_start, drive_start) = self.offsets();
        for (i, m) in self.mimics.iter().enumerate() {
            out[mimic_start + i] = q[m.follower.0] - m.multiplier * q[m.leader.0] - m.offset;
        }
        for (i, d) in self.drives.iter().enumerate() {
            out[drive_start + i] = q[d.q_index] - d.profile.evaluate(t).0;
        }
    }

    /// `out = Φ_q` (`m × nv`). Writes the world placements `data.world_from_body`
    /// ([`world_placements`]) when there are loops.
    pub fn jacobian(&self, model: &Model, data: &mut Data, q: &[f64], out: &mut DMatrix<f64>) {
        if !self.loops.is_empty() {
            world_placements(model, data, q);
        }
        self.jacobian_at_kinematics(model, data, out);
    }

    /// `out = Φ_q` with the loops' chains read from the placements already in `data` (a
    /// [`world_placements`] pass at the configuration of interest; the other rows do not
    /// depend on it).
    fn jacobian_at_kinematics(&self, model: &Model, data: &Data, out: &mut DMatrix<f64>) {
        out.as_mut_slice().fill(0.0);
        let mut row = 0;
        for l in &self.loops {
            l.jacobian(model, data, row, out);
            row += l.rows();
        }
        self.non_loop_jacobian(out);
    }

    /// Adds the mimic rows' entries of `Φ_q` into `out` and writes the drive rows' (after the
    /// loops' rows: the entries of different rows never meet).
    #[inline]
    fn non_loop_jacobian(&self, out: &mut DMatrix<f64>) {
        if self.mimics.is_empty() && self.drives.is_empty() {
            return;
        }
        let (mimic_start, drive_start) = self.offsets();
        for (i, m) in self.mimics.iter().enumerate() {
            out[(mimic_start + i, m.follower.1)] += 1.0;
            out[(mimic_start + i, m.leader.1)] -= m.multiplier;
        }
        for (i, d) in self.drives.iter().enumerate() {
            out[(drive_start + i, d.v_index)] = 1.0;
        }
    }

    /// `phi = Φ(q, t)` and `phi_q = Φ_q` with one pass of world placements: the same bits as
    /// [`evaluate`](Self::evaluate) then [`jacobian`](Self::jacobian) (both read the placements
    /// of that pass).
    pub fn evaluate_with_jacobian(
        &self,
        model: &Model,
        data: &mut Data,
        t: f64,
        q: &[f64],
        phi: &mut DVector<f64>,
        phi_q: &mut DMatrix<f64>,
    ) {
        phi_q.as_mut_slice().fill(0.0);
        if !self.loops.is_empty() {
            world_placements(model, data, q);
            let mut row = 0;
            for l in &self.loops {
                let values = &mut phi.as_mut_slice()[row..row + l.rows()];
                l.evaluate_with_jacobian(model, data, values, row, phi_q);
                row += l.rows();
            }
        }
        self.non_loop_values(t, q, phi);
        self.non_loop_jacobian(phi_q);
    }

    /// Whether no row depends on time explicitly (no drives): [`Self::time_derivative`] is then
    /// `+0` in every row.
    pub fn is_scleronomic(&self) -> bool {
        self.drives.is_empty()
    }

    /// `out = Φ_t` (`dim m`): only drives depend on time explicitly.
    pub fn time_derivative(&self, t: f64, out: &mut DVector<f64>) {
        out.fill(0.0);
        let (_, drive_start) = self.offsets();
        for (i, d) in self.drives.iter().enumerate() {
            out[drive_start + i] = -d.profile.evaluate(t).1;
        }
    }

    /// `out = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt` (`dim m`), the right-hand side of `Φ_q q̈`.
    pub fn acceleration_bias(
        &self,
        model: &Model,
        data: &mut Data,
        t: f64,
        q: &[f64],
        v: &[f64],
        out: &mut DVector<f64>,
    ) {
        out.fill(0.0);
        let (_, drive_start) = self.offsets();
        if !self.loops.is_empty() {
            drift_kinematics(model, data, q, v);
            let mut row = 0;
            for l in &self.loops {
                l.acceleration_bias(model, data, &mut out.as_mut_slice()[row..row + l.rows()]);
                row += l.rows();
            }
        }
        for (i, d) in self.drives.iter().enumerate() {
            out[drive_start + i] = d.profile.evaluate(t).2;
        }
    }
}
