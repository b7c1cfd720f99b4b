//! The batched dynamics kernels (`ribbon::dynamics::batch`) give, in every lane, **the same bits**
//! as the scalar kernels on the scalar model of that lane's sample: forward kinematics (every
//! body's `parent_from_body` and `world_from_body`), RNEA, the bias forces and CRBA.
//!
//! Each lane has its own parameter values (masses, centres of mass and inertias of every link, joint
//! origins and axes, gravity) and its own state, so a kernel that mixed up lanes, dropped a
//! per-lane value, or summed in another order than the scalar path would show here. Robots: the
//! shipped ur5, quadruped (floating base), four-bar and slider-crank trees and double pendulum;
//! example-robot-data's ur5 and panda (prismatic fingers, a mimic joint); random trees (proptest:
//! revolute, continuous, prismatic and fixed joints, optional floating base). Batch sizes 1, 3, 4,
//! 8 and 32 at the default width of 4 lanes (sizes that are not a multiple of 4 exercise the tail
//! lanes), widths 2 and 8 too, and both instruction sets when the CPU has AVX2. The per-sample
//! Cholesky factorisation and solve complete forward dynamics: `M⁻¹ (τ − b)` per lane has the bits
//! of the scalar `forward_dynamics`, and a singular lane reports the scalar function's pivot.

mod common;

use proptest::prelude::*;
use ribbon::dynamics::batch::{
    self, lane_transform, BatchData, BatchError, BatchModel, BatchVectors, Isa,
};
use ribbon::dynamics::{
    cholesky_factor_in_place, crba, forward_dynamics, forward_kinematics, nonlinear_effects, rnea,
    Data,
};
use ribbon::model::{JointKind, LoadOptions, Model, UrdfJointType};
use ribbon::spatial::{Transform, Vec3};
use std::path::Path;

const SIZES: [usize; 5] = [1, 3, 4, 8, 32];

/// A smooth pseudo-random number in [−1, 1] for sample `sample` and slot `k`: every lane and every
/// value gets its own.
fn wiggle(sample: usize, k: usize, salt: f64) -> f64 {
    (1.3 * sample as f64 + 0.71 * k as f64 + salt).sin()
}

/// `base` with sample `sample`'s values: every link's mass ±5 %, centre of mass ±1 cm, inertia
/// diagonal ±3 %, every joint origin ±1 cm and ±0.01 rad, every moving axis tilted by ~0.02 (its
/// gravity is [`sample_gravity`]).
fn sample_model(base: &Model, sample: usize) -> Model {
    sample_model_with_axes(base, sample, true)
}

/// [`sample_model`], with the axes and the joint origins' orientations moved only when
/// `tilt_axes` (else as in the URDF: a joint about a coordinate axis of its frame stays on it, and
/// the kernels take their aligned path).
fn sample_model_with_axes(base: &Model, sample: usize, tilt_axes: bool) -> Model {
    let mut model = base.clone();
    for (k, link) in model.description.links.iter_mut().enumerate() {
        let inertial = &mut link.inertial;
        if inertial.mass > 0.0 {
            inertial.mass *= 1.0 + 0.05 * wiggle(sample, k, 0.1);
            for (c, com) in inertial.com.iter_mut().enumerate() {
                *com += 0.01 * wiggle(sample, 3 * k + c, 0.2);
            }
            for d in [0, 3, 5] {
                inertial.inertia[d] *= 1.0 + 0.03 * wiggle(sample, 6 * k + d, 0.3);
            }
        }
    }
    for (k, joint) in model.description.joints.iter_mut().enumerate() {
        // Without the tilt the origins keep their URDF orientation too, and with it its exact
        // zeros (whose signs the aligned formulas must keep).
        let moved = if tilt_axes { 6 } else { 3 };
        for (c, value) in joint.origin.iter_mut().enumerate().take(moved) {
            *value += 0.01 * wiggle(sample, 6 * k + c, 0.4);
        }
        if tilt_axes && joint.joint_type != UrdfJointType::Fixed {
            for (c, value) in joint.axis.iter_mut().enumerate() {
                *value += 0.02 * wiggle(sample, 3 * k + c, 0.5);
            }
        }
    }
    model.refresh();
    model
}

/// Sample `sample`'s gravity: tilted and scaled by ±1 %.
fn sample_gravity(sample: usize) -> Vec3 {
    Vec3::new(
        0.1 * wiggle(sample, 0, 0.6),
        0.1 * wiggle(sample, 1, 0.6),
        -9.81 * (1.0 + 0.01 * wiggle(sample, 2, 0.6)),
    )
}

/// Sample `sample`'s state `(q, v, q̈)`: angles within ±3 rad (every quadrant, so that sines and
/// cosines of both signs meet the zeros of the joint frames), prismatic offsets the same
/// numbers in metres, speeds within ±2 (every fifth sample at rest: zero products whose signs the
/// kernels must keep), accelerations within ±3; a floating base's quaternion normalised.
fn sample_state(model: &Model, sample: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut q: Vec<f64> = (0..model.nq)
        .map(|i| 3.0 * wiggle(sample, i, 0.7))
        .collect();
    for joint in &model.joints {
        if joint.kind == JointKind::Floating {
            let quaternion = &mut q[joint.q_index + 3..joint.q_index + 7];
            quaternion[3] += 2.0;
            let norm = quaternion.iter().map(|x| x * x).sum::<f64>().sqrt();
            quaternion.iter_mut().for_each(|x| *x /= norm);
        }
    }
    let at_rest = if sample % 5 == 2 { 0.0 } else { 1.0 };
    let v = (0..model.nv)
        .map(|i| at_rest * 2.0 * wiggle(sample, i, 0.8))
        .collect();
    let qdd = (0..model.nv)
        .map(|i| 3.0 * wiggle(sample, i, 0.9))
        .collect();
    (q, v, qdd)
}

/// The first entry whose bits differ, with both values, or `None`.
fn first_bit_difference(batched: &[f64], scalar: &[f64]) -> Option<(usize, f64, f64)> {
    assert_eq!(batched.len(), scalar.len());
    batched
        .iter()
        .zip(scalar)
        .enumerate()
        .find(|(_, (a, b))| a.to_bits() != b.to_bits())
        .map(|(k, (a, b))| (k, *a, *b))
}

fn transform_entries(t: &Transform) -> Vec<f64> {
    t.rotation
        .iter()
        .chain(t.translation.iter())
        .copied()
        .collect()
}

/// Runs every batched kernel on `models` (one per sample) and compares every lane with the scalar
/// kernels on that sample's model; returns a description of the first difference.
fn compare<const W: usize>(models: &[Model], isa: Isa) -> Result<(), String> {
    let gravities: Vec<Vec3> = (0..models.len()).map(sample_gravity).collect();
    let refs: Vec<(&Model, &Vec3)> = models.iter().zip(&gravities).collect();
    let mut batch_model = BatchModel::<W>::from_models(&refs).map_err(|e| e.to_string())?;
    batch_model.isa = isa;
    let size = models.len();
    let (nq, nv) = (models[0].nq, models[0].nv);
    let nb = models[0].joints.len();
    let mut q = BatchVectors::<W>::zeros(nq, size);
    let mut v = BatchVectors::<W>::zeros(nv, size);
    let mut qdd = BatchVectors::<W>::zeros(nv, size);
    let states: Vec<_> = models
        .iter()
        .enumerate()
        .map(|(s, m)| sample_state(m, s))
        .collect();
    for (s, (qs, vs, qdds)) in states.iter().enumerate() {
        q.set_sample(s, qs).map_err(|e| e.to_string())?;
        v.set_sample(s, vs).map_err(|e| e.to_string())?;
        qdd.set_sample(s, qdds).map_err(|e| e.to_string())?;
    }
    let mut data = BatchData::new(&batch_model);
    let label = |s: usize, what: &str, k: usize, a: f64, b: f64| {
        format!(
            "{} ({} lanes, {}): sample {s} of {size}, {what}[{k}]: batched {a:e} ({:#x}), scalar {b:e} ({:#x})",
            models[0].name(),
            W,
            isa.name(),
            a.to_bits(),
            b.to_bits()
        )
    };

    batch::forward_kinematics(&batch_model, &mut data, &q);
    for (s, model) in models.iter().enumerate() {
        let mut scalar = Data::new(model);
        forward_kinematics(model, &mut scalar, &states[s].0);
        for i in 0..nb {
            let at = (s / W) * nb + i;
            for (what, batched, reference) in [
                (
                    "world_from_body",
                    &data.world_from_body[at],
                    &scalar.world_from_body[i],
                ),
                (
                    "parent_from_body",
                    &data.parent_from_body[at],
                    &scalar.parent_from_body[i],
                ),
            ] {
                let batched = transform_entries(&lane_transform(batched, s % W));
                if let Some((k, a, b)) =
                    first_bit_difference(&batched, &transform_entries(reference))
                {
                    return Err(label(s, &format!("{what} of body {i}, entry"), k, a, b));
                }
            }
        }
    }

    batch::rnea(&batch_model, &mut data, &q, &v, &qdd);
    batch::crba(&batch_model, &mut data, &q);
    let mass = data.mass_matrix.clone();
    batch::nonlinear_effects(&batch_model, &mut data, &q, &v);
    for (s, model) in models.iter().enumerate() {
        let (qs, vs, qdds) = &states[s];
        let mut scalar = Data::new(model);
        let tau = rnea(model, &gravities[s], &mut scalar, qs, vs, qdds).to_vec();
        if let Some((k, a, b)) = first_bit_difference(&data.tau.sample(s), &tau) {
            return Err(label(s, "rnea tau", k, a, b));
        }
        let bias = nonlinear_effects(model, &gravities[s], &mut scalar, qs, vs).to_vec();
        if let Some((k, a, b)) = first_bit_difference(&data.bias.sample(s), &bias) {
            return Err(label(s, "nonlinear_effects bias", k, a, b));
        }
        let m = crba(model, &mut scalar, qs).as_slice().to_vec();
        if let Some((k, a, b)) = first_bit_difference(&mass.sample(s), &m) {
            return Err(label(s, "crba M (column-major)", k, a, b));
        }
    }

    // Forward dynamics from the pieces: q̈ = M⁻¹ (τ − b), with τ := the state's q̈ values.
    let mut factors = mass;
    let mut failures = vec![None; size];
    if !batch::cholesky_factor(isa, &mut factors, nv, &mut failures) {
        return Err(format!(
            "a positive-definite mass matrix failed: {failures:?}"
        ));
    }
    let mut rhs = BatchVectors::<W>::zeros(nv, size);
    for (s, (_, _, taus)) in states.iter().enumerate() {
        let difference: Vec<f64> = taus
            .iter()
            .zip(data.bias.sample(s))
            .map(|(tau, bias)| tau - bias)
            .collect();
        rhs.set_sample(s, &difference).map_err(|e| e.to_string())?;
    }
    batch::cholesky_solve(isa, &factors, nv, &mut rhs);
    for (s, model) in models.iter().enumerate() {
        let (qs, vs, taus) = &states[s];
        let mut scalar = Data::new(model);
        let qdd = forward_dynamics(model, &gravities[s], &mut scalar, qs, vs, taus)
            .map_err(|e| e.to_string())?
            .to_vec();
        if let Some((k, a, b)) = first_bit_difference(&rhs.sample(s), &qdd) {
            return Err(label(
                s,
                "forward dynamics q̈ via the batched Cholesky",
                k,
                a,
                b,
            ));
        }
        let lower = |m: &[f64]| -> Vec<f64> {
            (0..nv)
                .flat_map(|j| (j..nv).map(move |i| (i, j)))
                .map(|(i, j)| m[i + j * nv])
                .collect()
        };
        if let Some((k, a, b)) = first_bit_difference(
            &lower(&factors.sample(s)),
            &lower(scalar.mass_matrix.as_slice()),
        ) {
            return Err(label(
                s,
                "Cholesky factor L (lower triangle, by columns)",
                k,
                a,
                b,
            ));
        }
    }
    Ok(())
}

/// Every instruction set this CPU can run.
fn instruction_sets() -> Vec<Isa> {
    let mut sets = vec![Isa::baseline()];
    sets.extend(Isa::avx2());
    sets
}

/// Checks `base` at every batch size of [`SIZES`] (4 lanes), sizes 3 and 8 at widths 2 and 8, with
/// every instruction set, for three populations of samples: every axis tilted (the kernels'
/// general path), every axis as in the URDF (the aligned path wherever the URDF puts an axis on
/// `x`, `y` or `z`), and every third sample as in the URDF among tilted ones (chunks that mix
/// both, docs/batch.md §7).
fn check_robot(base: &Model) {
    let tilted: Vec<Model> = (0..32).map(|s| sample_model(base, s)).collect();
    let as_in_urdf: Vec<Model> = (0..32)
        .map(|s| sample_model_with_axes(base, s, false))
        .collect();
    let mixed: Vec<Model> = (0..32)
        .map(|s| sample_model_with_axes(base, s, s % 3 != 0))
        .collect();
    for models in [&tilted, &as_in_urdf, &mixed] {
        for isa in instruction_sets() {
            for size in SIZES {
                compare::<4>(&models[..size], isa).unwrap_or_else(|e| panic!("{e}"));
            }
            for size in [3, 8] {
                compare::<2>(&models[..size], isa).unwrap_or_else(|e| panic!("{e}"));
                compare::<8>(&models[..size], isa).unwrap_or_else(|e| panic!("{e}"));
            }
        }
    }
}

fn load(path: &Path, floating_base: bool) -> Model {
    Model::from_urdf_file(path, LoadOptions { floating_base })
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn ur5_lanes_match_the_scalar_kernels_bit_for_bit() {
    let ur5 = load(&common::manifest("robots/ur5/ur5.urdf"), false);
    // Every ur5 joint turns about z: the untilted population runs the aligned path throughout.
    assert!(ur5
        .joints
        .iter()
        .all(|j| j.revolute_coordinate_axis() == Some(2)));
    check_robot(&ur5);
}

#[test]
fn floating_base_quadruped_lanes_match_bit_for_bit() {
    let model = load(&common::manifest("robots/quadruped/quadruped.urdf"), true);
    assert_eq!(model.joints[0].kind, JointKind::Floating);
    check_robot(&model);
}

#[test]
fn four_bar_slider_crank_and_pendulum_trees_match_bit_for_bit() {
    for path in [
        "robots/four_bar/four_bar.urdf",
        "robots/slider_crank/slider_crank.urdf",
        "robots/double_pendulum/double_pendulum.urdf",
    ] {
        check_robot(&load(&common::manifest(path), false));
    }
}

#[test]
fn example_robot_data_ur5_and_panda_match_bit_for_bit() {
    let dir = common::example_robot_data_dir();
    let ur5 = load(&dir.join("ur_description/urdf/ur5_robot.urdf"), false);
    check_robot(&ur5);
    let panda = load(&dir.join("panda_description/urdf/panda.urdf"), false);
    assert!(
        panda.joints.iter().any(|j| j.kind == JointKind::Prismatic)
            && panda.joints.iter().any(|j| j.mimic.is_some()),
        "the panda should have prismatic fingers, one mimicking the other"
    );
    check_robot(&panda);
}

#[test]
fn a_singular_lane_reports_the_scalar_pivot_and_the_others_factorise() {
    // Sample 1 is the singular [[1, 1], [1, 1]]; samples 0 and 2 are positive definite.
    let matrices = [
        [4.0, 2.0, 2.0, 5.0],
        [1.0, 1.0, 1.0, 1.0],
        [2.0, -0.5, -0.5, 3.0],
    ];
    for isa in instruction_sets() {
        let mut batched = BatchVectors::<4>::zeros(4, 3);
        for (s, m) in matrices.iter().enumerate() {
            batched.set_sample(s, m).unwrap();
        }
        let mut failures = vec![
            Some(ribbon::linalg::cholesky::NonPositivePivot {
                index: 9,
                pivot: 9.0
            });
            3
        ];
        assert!(!batch::cholesky_factor(isa, &mut batched, 2, &mut failures));
        for (s, m) in matrices.iter().enumerate() {
            let mut scalar = nalgebra::DMatrix::from_column_slice(2, 2, m);
            let expected = cholesky_factor_in_place(&mut scalar).err();
            assert_eq!(failures[s], expected, "sample {s} ({})", isa.name());
            if expected.is_none() {
                assert_eq!(batched.sample(s), scalar.as_slice(), "sample {s}");
            }
        }
        assert_eq!(failures[1].map(|f| f.index), Some(1));
    }
}

/// The integrator's lock-step factorises its lanes' Newton matrices with their own smallest
/// pivots (`cholesky_factor_with_min_pivots`): every lane must get the bits and the verdict of
/// `linalg::cholesky::factor_in_place` with the same threshold — for 14 × 14 matrices (the
/// quadruped's Newton matrix; the scalar kernel compiled for that size), five samples over two
/// chunks, one refused by its threshold and one with a NaN.
#[test]
fn lanes_with_their_own_minimum_pivots_match_the_scalar_factorisation() {
    let n = 14;
    let samples = 5;
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let matrices: Vec<Vec<f64>> = (0..samples)
        .map(|s| {
            let j = nalgebra::DMatrix::<f64>::from_fn(n, n, |_, _| uniform());
            let mut a = j.transpose() * &j;
            for k in 0..n {
                a[(k, k)] += 0.1;
            }
            if s == 4 {
                a[(6, 6)] = f64::NAN;
            }
            a.as_slice().to_vec()
        })
        .collect();
    // Sample 2's threshold is above its own diagonal entries: refused at pivot 0.
    let min_pivots = [1e-12, 1e-9, 1e6, 0.0, 1e-12];
    for isa in instruction_sets() {
        let mut batched = BatchVectors::<4>::zeros(n * n, samples);
        for (s, m) in matrices.iter().enumerate() {
            batched.set_sample(s, m).unwrap();
        }
        let mut failures = vec![None; samples];
        assert!(!batch::cholesky_factor_with_min_pivots(
            isa,
            &mut batched,
            n,
            &min_pivots,
            &mut failures
        ));
        for (s, m) in matrices.iter().enumerate() {
            let mut scalar = m.clone();
            let expected =
                ribbon::linalg::cholesky::factor_in_place(&mut scalar, n, min_pivots[s]).err();
            assert_eq!(
                failures[s].map(|f| f.index),
                expected.map(|f| f.index),
                "sample {s} ({})",
                isa.name()
            );
            if expected.is_none() {
                let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&batched.sample(s)), bits(&scalar), "sample {s}");
            }
        }
        assert_eq!(failures[2].map(|f| f.index), Some(0));
        assert_eq!(failures[4].map(|f| f.index), Some(6));
        assert!(failures[0].is_none() && failures[1].is_none() && failures[3].is_none());
    }
}

#[test]
fn the_default_instruction_set_is_the_best_available() {
    let model = load(&common::manifest("robots/ur5/ur5.urdf"), false);
    let gravity = sample_gravity(0);
    let batch = BatchModel::<4>::from_models(&[(&model, &gravity)]).unwrap();
    assert_eq!(batch.isa, Isa::best());
    assert_eq!(Isa::best() == Isa::baseline(), Isa::avx2().is_none());
}

#[test]
fn set_sample_replaces_one_lane_only() {
    let base = load(&common::manifest("robots/ur5/ur5.urdf"), false);
    let models: Vec<Model> = (0..5).map(|s| sample_model(&base, s)).collect();
    let gravities: Vec<Vec3> = (0..5).map(sample_gravity).collect();
    let refs: Vec<(&Model, &Vec3)> = models.iter().zip(&gravities).collect();
    let mut batch = BatchModel::<4>::from_models(&refs).unwrap();
    let replacement = (sample_model(&base, 17), sample_gravity(17));
    batch.set_sample(4, &replacement.0, &replacement.1).unwrap();
    let mut expected = models.clone();
    let mut expected_gravities = gravities.clone();
    expected[4] = replacement.0;
    expected_gravities[4] = replacement.1;
    let refs: Vec<(&Model, &Vec3)> = expected.iter().zip(&expected_gravities).collect();
    let fresh = BatchModel::<4>::from_models(&refs).unwrap();
    // Lane 4 is lane 0 of chunk 1; the tail lanes 1–3 of chunk 1 hold sample 0's values in both.
    for (a, b) in batch.chunks.iter().zip(&fresh.chunks) {
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
    assert_eq!(
        batch.set_sample(5, &base, &gravities[0]).unwrap_err(),
        BatchError::NoSuchSample { sample: 5, size: 5 }
    );
}

#[test]
fn models_of_different_trees_are_refused_with_the_joint_named() {
    let ur5 = load(&common::manifest("robots/ur5/ur5.urdf"), false);
    let pendulum = load(
        &common::manifest("robots/double_pendulum/double_pendulum.urdf"),
        false,
    );
    let g = sample_gravity(0);
    let error = BatchModel::<4>::from_models(&[(&ur5, &g), (&pendulum, &g)]).unwrap_err();
    assert!(
        matches!(error, BatchError::DifferentTree { sample: 1, .. }),
        "{error}"
    );
    assert!(
        error.to_string().contains("number of moving joints"),
        "{error}"
    );
    let mut other = ur5.clone();
    other.joints[2].parent = Some(0);
    let error = BatchModel::<4>::from_models(&[(&ur5, &g), (&other, &g)]).unwrap_err();
    let name = &ur5.joints[2].name;
    assert!(
        error.to_string().contains(&format!("joint '{name}'")),
        "{error}"
    );
    assert_eq!(
        BatchModel::<4>::from_models(&[]).unwrap_err(),
        BatchError::Empty
    );
    let mut q = BatchVectors::<4>::zeros(ur5.nq, 2);
    let error = q.set_sample(1, &[0.0; 3]).unwrap_err();
    assert_eq!(
        error,
        BatchError::WrongLength {
            sample: 1,
            expected: ur5.nq,
            got: 3
        }
    );
    assert!(
        error.to_string().contains("has 3 entries, expected 6"),
        "{error}"
    );
}

/// One random link: parent index (mod its position), joint type, joint origin (xyz rpy), axis,
/// mass, centre of mass.
type RandomLink<'a> = (usize, &'a str, [f64; 6], [f64; 3], f64, [f64; 3]);

// Random trees: the generator of tests/properties.rs, in short.
fn random_urdf(links: &[RandomLink<'_>]) -> String {
    let mut text = String::from(
        "<robot name=\"random\">\n<link name=\"l0\"><inertial><mass value=\"2\"/>\
         <inertia ixx=\"0.02\" ixy=\"0\" ixz=\"0\" iyy=\"0.03\" iyz=\"0\" izz=\"0.04\"/></inertial></link>\n",
    );
    for (k, (parent, joint, o, axis, mass, com)) in links.iter().enumerate() {
        let k = k + 1;
        text += &format!(
            "<link name=\"l{k}\"><inertial><origin xyz=\"{} {} {}\" rpy=\"0.3 -0.2 0.1\"/><mass value=\"{mass}\"/>\
             <inertia ixx=\"0.05\" ixy=\"0.001\" ixz=\"0\" iyy=\"0.04\" iyz=\"0\" izz=\"0.03\"/></inertial></link>\n\
             <joint name=\"j{k}\" type=\"{joint}\"><parent link=\"l{}\"/><child link=\"l{k}\"/>\
             <origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><axis xyz=\"{} {} {}\"/>\
             <limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/></joint>\n",
            com[0], com[1], com[2], parent % k, o[0], o[1], o[2], o[3], o[4], o[5],
            axis[0], axis[1], axis[2]
        );
    }
    text + "</robot>\n"
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|c| c.parse().ok()).unwrap_or(48),
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_trees_match_bit_for_bit(
        links in prop::collection::vec(
            (
                any::<prop::sample::Index>(),
                prop::sample::select(vec!["revolute", "continuous", "prismatic", "fixed"]),
                prop::array::uniform6(-0.6f64..0.6),
                prop::array::uniform3(-1.0f64..1.0)
                    .prop_filter("a usable axis", |a| a.iter().map(|x| x * x).sum::<f64>() > 0.04),
                0.5f64..5.0,
                prop::array::uniform3(-0.2f64..0.2),
            ),
            1..=6,
        ),
        floating_base in any::<bool>(),
        size in prop::sample::select(vec![1usize, 3, 4, 8, 32]),
    ) {
        let links: Vec<_> = links
            .into_iter()
            .map(|(p, j, o, a, m, c)| (p.index(usize::MAX), j, o, a, m, c))
            .collect();
        let base = Model::from_urdf_str(&random_urdf(&links), "random.urdf", LoadOptions { floating_base });
        prop_assume!(base.as_ref().is_ok_and(|m| m.nv > 0));
        let base = base.unwrap();
        let models: Vec<Model> = (0..size).map(|s| sample_model(&base, s)).collect();
        for isa in instruction_sets() {
            prop_assert_eq!(compare::<4>(&models, isa), Ok(()));
        }
    }
}
