//! Linear joint spring-dampers of `[[scene.spring]]`: `τ_j = −k (q_j − rest) − c q̇_j` (with `c`, a PD
//! position controller).

use crate::model::Model;
use crate::scene::JointSpring;

#[derive(Clone, Copy, Debug)]
struct Spring {
    q_index: usize,
    v_index: usize,
    stiffness: f64,
    rest: f64,
    damping: f64,
}

/// The scene's springs.
#[derive(Clone, Debug, Default)]
pub struct JointSprings {
    springs: Vec<Spring>,
}

impl JointSprings {
    pub(super) fn new(model: &Model, springs: &[JointSpring]) -> Self {
        Self {
            springs: springs
                .iter()
                .map(|s| Spring {
                    q_index: model.joints[s.joint].q_index,
                    v_index: model.joints[s.joint].v_index,
                    stiffness: s.stiffness,
                    rest: s.rest,
                    damping: s.damping,
                })
                .collect(),
        }
    }

    pub(super) fn add_forces(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for s in &self.springs {
            out[s.v_index] -= s.stiffness * (q[s.q_index] - s.rest) + s.damping * v[s.v_index];
        }
    }

    pub(super) fn add_diagonal(&self, stiffness: &mut [f64], damping: &mut [f64]) {
        for s in &self.springs {
            stiffness[s.v_index] += s.stiffness;
            damping[s.v_index] += s.damping;
        }
    }
}
