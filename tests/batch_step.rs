//! The batched HHT-I3 step (`BatchStepper`, docs/batch.md §5) against the scalar integrator: every
//! lane, at its own parameter point, must take exactly the steps `HhtIntegrator::step` takes on the
//! lane's own system — state, counters and errors compared bit for bit at every step — whether the
//! lane's step ran with the batched kernels, fell back to the scalar step, or failed.

mod common;

use nalgebra::DVector;
use ribbon::analysis::{BlockOutcome, LockStep};
use ribbon::integrate::{HhtIntegrator, HhtSettings, HhtState, ReportedVelocity, StepControl};
use ribbon::setup::Setup;
use ribbon::simulate::{hht_settings, BatchStepper, RobotSystem};
use std::sync::atomic::AtomicBool;

/// Bits of a state, for exact comparison (signed zeros included).
fn state_bits(state: &HhtState) -> Vec<u64> {
    let mut bits = vec![state.t.to_bits(), state.step];
    for vector in [&state.q, &state.v, &state.a, &state.qdd, &state.lambda] {
        bits.extend(vector.iter().map(|x| x.to_bits()));
    }
    bits
}

/// Parameter points in standard coordinates, one per lane, spread over the box (corners and
/// interior, different for every lane).
fn lane_points(d: usize, lanes: usize) -> Vec<Vec<f64>> {
    (0..lanes)
        .map(|lane| {
            (0..d)
                .map(|k| {
                    let phase = (lane * 7 + k * 3) % 5;
                    [-1.0, -0.37, 0.0, 0.61, 1.0][phase]
                })
                .collect()
        })
        .collect()
}

/// What one run produced: per step, the state's bits and the counters, and the error if any.
#[derive(Debug, PartialEq)]
struct Run {
    states: Vec<Vec<u64>>,
    stats: Vec<String>,
    error: Option<String>,
    /// Limit impacts over the run.
    impacts: u64,
}

/// Every step computes the reported velocity (`HhtIntegrator::step`).
fn every_step(_step: usize) -> ReportedVelocity {
    ReportedVelocity::Computed
}

/// A study's pattern at 100 Hz records and 1 ms steps: only every tenth step (1-based) computes the
/// reported velocity.
fn every_tenth_step(step: usize) -> ReportedVelocity {
    if step.is_multiple_of(10) {
        ReportedVelocity::Computed
    } else {
        ReportedVelocity::Skipped
    }
}

/// Steps `settings.len()` samples of `setup` (lane `i` with `settings[i]`) for `steps` steps with
/// the batched stepper and, separately, each sample with its own scalar integrator, step `k`
/// (1-based) reporting its velocity as `report(k)` says; returns both, and the stepper's counts.
fn run_both(
    setup: &Setup,
    settings: &[HhtSettings],
    steps: usize,
    report: fn(usize) -> ReportedVelocity,
) -> (Vec<Run>, Vec<Run>, ribbon::simulate::BatchStepCounts) {
    let scene = &setup.scene;
    let template = RobotSystem::new(setup.model.clone(), setup.environment, scene);
    let q0 = DVector::from_column_slice(&scene.initial_q);
    let v0 = DVector::from_column_slice(&scene.initial_v);
    let lanes = settings.len();
    let points = lane_points(setup.space.len(), lanes);

    let mut scalar_runs = Vec::new();
    for (xi, lane_settings) in points.iter().zip(settings) {
        let mut system = template.clone();
        setup
            .space
            .apply(&mut system.model, &mut system.environment, xi);
        let mut hht = HhtIntegrator::new(&mut system, *lane_settings, 0.0, &q0, &v0)
            .expect("the scalar start succeeds");
        let mut run = Run {
            states: Vec::new(),
            stats: Vec::new(),
            error: None,
            impacts: 0,
        };
        for k in 1..=steps {
            if let Err(error) = hht.advance(&mut system, report(k)) {
                run.error = Some(error.to_string());
                run.states.push(state_bits(hht.state()));
                run.stats.push(format!("{:?}", hht.stats()));
                break;
            }
            run.states.push(state_bits(hht.state()));
            run.stats.push(format!("{:?}", hht.stats()));
        }
        run.impacts = hht.stats().impacts;
        scalar_runs.push(run);
    }

    let mut stepper = BatchStepper::new(&template, lanes).expect("a stepper of 1–4 lanes");
    for (lane, xi) in points.iter().enumerate() {
        let system = stepper.system_mut(lane);
        setup
            .space
            .apply(&mut system.model, &mut system.environment, xi);
        stepper.sync_lane(lane).expect("same tree");
        stepper
            .start_lane(lane, settings[lane], &q0, &v0)
            .expect("the batched lane's start succeeds");
    }
    let mut batched_runs: Vec<Run> = (0..lanes)
        .map(|_| Run {
            states: Vec::new(),
            stats: Vec::new(),
            error: None,
            impacts: 0,
        })
        .collect();
    let mut active = vec![true; lanes];
    for k in 1..=steps {
        let errors: Vec<Option<String>> = stepper
            .step(&active, report(k))
            .iter()
            .map(|e| e.as_ref().map(|e| e.to_string()))
            .collect();
        for lane in 0..lanes {
            if !active[lane] {
                continue;
            }
            let (_, integrator) = stepper.lane_mut(lane);
            let integrator = integrator.expect("started");
            let run = &mut batched_runs[lane];
            run.states.push(state_bits(integrator.state()));
            run.stats.push(format!("{:?}", integrator.stats()));
            run.impacts = integrator.stats().impacts;
            if let Some(error) = &errors[lane] {
                run.error = Some(error.clone());
                active[lane] = false;
            }
        }
    }
    (scalar_runs, batched_runs, stepper.counts())
}

fn assert_lanes_match(what: &str, scalar: &[Run], batched: &[Run]) {
    for (lane, (s, b)) in scalar.iter().zip(batched).enumerate() {
        assert_eq!(s.error, b.error, "{what}, lane {lane}: errors differ");
        assert_eq!(
            s.states.len(),
            b.states.len(),
            "{what}, lane {lane}: steps differ"
        );
        for (k, (x, y)) in s.states.iter().zip(&b.states).enumerate() {
            assert_eq!(
                x,
                y,
                "{what}, lane {lane}: state bits differ after step {}",
                k + 1
            );
        }
        assert_eq!(s.stats, b.stats, "{what}, lane {lane}: counters differ");
    }
}

#[test]
fn every_lane_steps_bit_for_bit_as_the_scalar_integrator_on_the_shipped_robots() {
    let cases = [
        (
            "robots/ur5/ur5.urdf",
            "robots/ur5/ur5.uncertainty.toml",
            600,
        ),
        (
            "robots/ur5/ur5.urdf",
            "robots/ur5/ur5.all-values.uncertainty.toml",
            300,
        ),
        (
            "robots/double_pendulum/double_pendulum.urdf",
            "robots/double_pendulum/double_pendulum.uncertainty.toml",
            600,
        ),
        // Closed loops: constraint rows, evaluated per lane, and the velocity projection.
        (
            "robots/four_bar/four_bar.urdf",
            "robots/four_bar/four_bar.uncertainty.toml",
            400,
        ),
        (
            "robots/slider_crank/slider_crank.urdf",
            "robots/slider_crank/slider_crank.uncertainty.toml",
            400,
        ),
    ];
    for (urdf, sidecar, steps) in cases {
        let setup = common::shipped_setup(urdf, sidecar, steps as f64 * 1e-3);
        let settings = hht_settings(&setup.scene);
        for lanes in [1, 3, 4] {
            let what = format!("{sidecar}, {lanes} lanes");
            let (scalar, batched, counts) =
                run_both(&setup, &vec![settings; lanes], steps, every_step);
            assert!(
                scalar.iter().all(|r| r.error.is_none()),
                "{what}: the scalar runs are expected to succeed"
            );
            assert_lanes_match(&what, &scalar, &batched);
            let total = (lanes * steps) as u64;
            assert_eq!(counts.batched + counts.scalar, total, "{what}: {counts:?}");
            // The batched path must actually carry these plain scenes, not the fallback.
            assert!(
                counts.batched * 100 >= total * 95,
                "{what}: only {} of {total} lane steps were batched",
                counts.batched
            );
        }
    }
}

/// A branched tree: the shipped quadruped without its contacts (a floating base falling with its
/// legs on PD springs; contacts are not plain steps). Its mass matrix has entries that couple
/// different legs, zero in every configuration: the batched CRBA zeroes only those, and the
/// lock-step factorises in place of its `M`, so every lane must still be the scalar integrator's
/// bit for bit over many steps.
#[test]
fn every_lane_steps_bit_for_bit_as_the_scalar_integrator_on_a_branched_tree() {
    let shipped = std::fs::read_to_string(common::manifest(
        "robots/quadruped/quadruped.uncertainty.toml",
    ))
    .expect("read the quadruped's sidecar");
    let (before_contact, after_contact) = shipped
        .split_once("[scene.contact]")
        .expect("the quadruped's sidecar declares contacts");
    let outputs = &after_contact[after_contact.find("[outputs]").expect("an [outputs] table")..];
    let without_contacts: String = format!("{before_contact}{outputs}")
        .lines()
        .filter(|line| {
            !["contact", "r_foot", "step_control"]
                .iter()
                .any(|word| line.contains(word))
        })
        .map(|line| format!("{line}\n"))
        .collect();
    let sidecar = common::scratch_file("batch_step", "quadruped_without_contacts.toml");
    std::fs::write(&sidecar, without_contacts).expect("write the sidecar");
    let steps = 300;
    let setup = common::shipped_setup(
        "robots/quadruped/quadruped.urdf",
        sidecar.to_str().expect("a UTF-8 path"),
        steps as f64 * 1e-3,
    );
    assert!(setup.scene.contact.is_none(), "contacts left in the scene");
    let settings = hht_settings(&setup.scene);
    for lanes in [1, 4] {
        let what = format!("quadruped without contacts, {lanes} lanes");
        let (scalar, batched, counts) = run_both(&setup, &vec![settings; lanes], steps, every_step);
        assert!(
            scalar.iter().all(|r| r.error.is_none()),
            "{what}: the scalar runs are expected to succeed"
        );
        assert_lanes_match(&what, &scalar, &batched);
        let total = (lanes * steps) as u64;
        assert!(
            counts.batched * 100 >= total * 95,
            "{what}: only {} of {total} lane steps were batched",
            counts.batched
        );
    }
}

/// A study leaves the reported velocity out between its records (`ReportedVelocity::Skipped`):
/// on the closed loops (constraint rows, the velocity projection) the batched lanes must still be
/// the scalar integrator's at every step, and every step that computes it must have the bits of
/// stepping with it every time — `q`, `q̈`, `λ`, `a` at every step, the reported `v` at every
/// tenth, the Newton counters throughout. Between records `v` is the Newmark velocity.
#[test]
fn leaving_the_reported_velocity_out_between_records_changes_no_record() {
    for (urdf, sidecar) in [
        (
            "robots/four_bar/four_bar.urdf",
            "robots/four_bar/four_bar.uncertainty.toml",
        ),
        (
            "robots/slider_crank/slider_crank.urdf",
            "robots/slider_crank/slider_crank.uncertainty.toml",
        ),
    ] {
        let steps = 400;
        let setup = common::shipped_setup(urdf, sidecar, steps as f64 * 1e-3);
        let settings = [hht_settings(&setup.scene); 4];
        let (every, _, _) = run_both(&setup, &settings, steps, every_step);
        let (scalar, batched, counts) = run_both(&setup, &settings, steps, every_tenth_step);
        assert_lanes_match(&format!("{sidecar}, every tenth step"), &scalar, &batched);
        let total = (settings.len() * steps) as u64;
        assert!(counts.batched * 100 >= total * 95, "{sidecar}: {counts:?}");
        let nv = setup.model.nv;
        let nq = setup.model.nq;
        // state_bits: t, step, q (nq), v (nv), then a, q̈, λ.
        let v_range = 2 + nq..2 + nq + nv;
        let mut projections_differ = false;
        for (lane, (full, sparse)) in every.iter().zip(&scalar).enumerate() {
            assert!(full.error.is_none() && sparse.error.is_none());
            for (k, (x, y)) in full.states.iter().zip(&sparse.states).enumerate() {
                let step = k + 1;
                if every_tenth_step(step) == ReportedVelocity::Computed {
                    assert_eq!(x, y, "{sidecar}, lane {lane}: record after step {step}");
                } else {
                    assert_eq!(
                        x[..v_range.start],
                        y[..v_range.start],
                        "{sidecar} step {step}"
                    );
                    assert_eq!(x[v_range.end..], y[v_range.end..], "{sidecar} step {step}");
                    projections_differ |= x[v_range.clone()] != y[v_range.clone()];
                }
            }
            let iterations = |stats: &String| {
                stats
                    .split("newton_iterations: ")
                    .nth(1)
                    .and_then(|rest| rest.split(',').next())
                    .map(str::to_string)
            };
            assert_eq!(
                full.stats.iter().map(iterations).collect::<Vec<_>>(),
                sparse.stats.iter().map(iterations).collect::<Vec<_>>(),
                "{sidecar}, lane {lane}: Newton iterations differ"
            );
        }
        // Had nothing been left out, this test would prove nothing: between records the reported
        // velocity must really be the unprojected one.
        assert!(
            projections_differ,
            "{sidecar}: no skipped step differs in v"
        );
    }
}

/// With one Newton iteration allowed per pass, many first passes give up: those lanes fall back to
/// the scalar step (which refreshes the matrix) and the others go on batched. One lane has a
/// position tolerance no iterate can meet and fails in its first step while the others go on.
/// Every lane must still be the scalar integrator's, errors included.
#[test]
fn lanes_that_fall_back_or_fail_stay_the_scalar_integrators() {
    let setup = common::shipped_setup(
        "robots/ur5/ur5.urdf",
        "robots/ur5/ur5.uncertainty.toml",
        0.4,
    );
    let one_iteration = HhtSettings {
        max_newton_iterations: 1,
        ..hht_settings(&setup.scene)
    };
    let unreachable = HhtSettings {
        abstol_position: 1e-13,
        ..one_iteration
    };
    let settings = [one_iteration, one_iteration, unreachable, one_iteration];
    let (scalar, batched, counts) = run_both(&setup, &settings, 400, every_step);
    assert_lanes_match("ur5, one iteration per pass", &scalar, &batched);
    let failed: Vec<bool> = scalar.iter().map(|r| r.error.is_some()).collect();
    assert_eq!(failed, [false, false, true, false], "{scalar:?}");
    assert!(
        counts.scalar > 0 && counts.batched > 0,
        "both paths must be exercised: {counts:?}"
    );
}

/// Adaptive step control: a grid step whose one attempt the controller accepts is driven batched;
/// one it rejects (then sub-stepped) falls back to the scalar step. With a tight tolerance both
/// happen; every lane must still be the scalar integrator's.
#[test]
fn adaptive_lanes_stay_the_scalar_integrators() {
    let setup = common::shipped_setup(
        "robots/ur5/ur5.urdf",
        "robots/ur5/ur5.uncertainty.toml",
        0.4,
    );
    for tolerance in [1e-5, 1e-8] {
        let settings = HhtSettings {
            step_control: StepControl::Adaptive,
            tolerance,
            ..hht_settings(&setup.scene)
        };
        let (scalar, batched, counts) = run_both(&setup, &[settings; 4], 400, every_step);
        let what = format!("ur5, adaptive, tolerance {tolerance:e}");
        assert!(scalar.iter().all(|r| r.error.is_none()), "{what}");
        assert_lanes_match(&what, &scalar, &batched);
        assert!(counts.batched > 0, "{what}: {counts:?}");
        if tolerance < 1e-6 {
            assert!(
                counts.scalar > 0,
                "{what}: expected rejected steps: {counts:?}"
            );
        }
    }
}

/// Joint limits: the shipped double pendulum with its elbow limited to ±0.4 rad (restitution 0.5)
/// folds onto the limits under gravity. A step that crosses a limit is located and resolved by the
/// scalar step; the others go batched; every lane must be the scalar integrator's.
#[test]
fn lanes_hitting_joint_limits_stay_the_scalar_integrators() {
    let urdf = std::fs::read_to_string(common::manifest(
        "robots/double_pendulum/double_pendulum.urdf",
    ))
    .expect("shipped URDF");
    let limited = urdf.replacen(
        "<joint name=\"j2\" type=\"continuous\">",
        "<joint name=\"j2\" type=\"revolute\">\n    <limit lower=\"-0.4\" upper=\"0.4\" effort=\"1\" velocity=\"10\"/>",
        1,
    );
    assert_ne!(limited, urdf, "the elbow joint is found");
    let sidecar = std::fs::read_to_string(common::manifest(
        "robots/double_pendulum/double_pendulum.uncertainty.toml",
    ))
    .expect("shipped sidecar")
    .replacen(
        "[scene]\n",
        "[scene]\neffects = [\"gravity\", \"joint_limits\"]\nlimit_restitution = 0.5\n",
        1,
    );
    let dir = common::fresh_test_scratch_dir("batch_step", "limits");
    let (urdf_path, sidecar_path) = (
        dir.join("limited.urdf"),
        dir.join("limited.uncertainty.toml"),
    );
    std::fs::write(&urdf_path, limited).expect("scratch URDF");
    std::fs::write(&sidecar_path, sidecar).expect("scratch sidecar");
    let setup = common::shipped_setup(
        urdf_path.to_str().expect("UTF-8 path"),
        sidecar_path.to_str().expect("UTF-8 path"),
        1.5,
    );
    let settings = hht_settings(&setup.scene);
    let (scalar, batched, counts) = run_both(&setup, &[settings; 4], 1500, every_tenth_step);
    assert!(scalar.iter().all(|r| r.error.is_none()));
    assert!(
        scalar.iter().all(|r| r.impacts >= 2),
        "every lane is expected to hit the limits: {:?}",
        scalar.iter().map(|r| r.impacts).collect::<Vec<_>>()
    );
    assert_lanes_match("double pendulum with elbow limits", &scalar, &batched);
    assert!(
        counts.batched > 0 && counts.scalar > 0,
        "both paths must be exercised: {counts:?}"
    );
}

/// Everything a study reads from its lock-step engine, block by block: every sample's records (as
/// bits), the nominal run's configurations, the failures and the counters.
fn study_records(
    setup: &Setup,
    settings: HhtSettings,
    points: &[f64],
    batched: bool,
    threads: usize,
) -> (Vec<u64>, String, (u64, u64)) {
    let template = RobotSystem::new(setup.model.clone(), setup.environment, &setup.scene);
    let nominal = vec![0.0; setup.space.len()];
    let mut lockstep = LockStep::new(
        template,
        &setup.space,
        &setup.scene,
        settings,
        points,
        Some(&nominal),
    );
    assert!(
        lockstep.batched(),
        "the shipped ur5 scene suits the batched path"
    );
    if !batched {
        lockstep.disable_batching();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let interrupt = AtomicBool::new(false);
    let records = setup.scene.record_count() as usize;
    let mut bits = Vec::new();
    let block = 7;
    let mut first = 0;
    while first < records {
        let count = block.min(records - first);
        let outcome = lockstep.advance(first, count, &pool, &interrupt);
        assert_eq!(outcome, BlockOutcome::Complete);
        for i in 0..lockstep.len() {
            for r in 0..count {
                if !lockstep.failed(i) {
                    bits.extend(lockstep.record(i, r).iter().map(|x| x.to_bits()));
                }
            }
        }
        for r in 0..count {
            bits.extend(lockstep.nominal_positions(r).iter().map(|x| x.to_bits()));
        }
        first += count;
    }
    (
        bits,
        format!("{:?}", lockstep.failures()),
        lockstep.counters(),
    )
}

/// A study's lock-step engine gives the same records, failures and counters with the batched path
/// as with every sample stepped alone, for 1 and 2 threads: 13 samples (three groups of four and a
/// group of one, plus the nominal run) of the shipped ur5, one of them outside the box with a
/// negative payload mass, whose start fails; and with one Newton iteration per pass, so that
/// lanes fall back to the scalar step within groups.
#[test]
fn a_study_records_the_same_bits_batched_and_unbatched() {
    let setup = common::shipped_setup(
        "robots/ur5/ur5.urdf",
        "robots/ur5/ur5.uncertainty.toml",
        0.3,
    );
    let d = setup.space.len();
    let mut points: Vec<f64> = lane_points(d, 13).concat();
    // Sample 5: the payload mass (dimension 1, [0.15, 1.2] kg) at ξ = −30, i.e. −15 kg.
    points[5 * d + 1] = -30.0;
    let default = hht_settings(&setup.scene);
    let one_iteration = HhtSettings {
        max_newton_iterations: 1,
        ..default
    };
    for (what, settings) in [("default", default), ("one iteration", one_iteration)] {
        let reference = study_records(&setup, settings, &points, false, 1);
        assert!(
            reference.1.contains("index: 5,"),
            "{what}: the out-of-box sample is expected to fail: {}",
            reference.1
        );
        assert!(
            !reference.1.contains("index: 4,"),
            "{what}: only sample 5 is expected to fail"
        );
        for threads in [1, 2] {
            let batched = study_records(&setup, settings, &points, true, threads);
            assert_eq!(
                reference.1, batched.1,
                "{what}, {threads} threads: failures differ"
            );
            assert_eq!(
                reference.2, batched.2,
                "{what}, {threads} threads: counters differ"
            );
            assert!(
                reference.0 == batched.0,
                "{what}, {threads} threads: records differ"
            );
        }
    }
}

/// A study that moves joint axes: its nominal sample keeps them exactly on `z` (the kernels'
/// aligned path, docs/batch.md §7) while the other samples of its chunks tilt them, so the batch
/// mixes aligned and general lanes. The records are the same bits batched and unbatched.
#[test]
fn a_study_that_tilts_joint_axes_records_the_same_bits_batched_and_unbatched() {
    let shipped = std::fs::read_to_string(common::manifest("robots/ur5/ur5.uncertainty.toml"))
        .expect("the shipped ur5 sidecar reads");
    let sidecar = shipped.replacen(
        "[parameters]\n",
        "[parameters]\n\"joint.wrist_2_joint.axis.x\" = [-0.02, 0.02]\n\
         \"joint.wrist_3_joint.axis.y\" = [-0.02, 0.02]\n",
        1,
    );
    assert_ne!(sidecar, shipped, "the axis parameters are added");
    let path = common::scratch_file("batch_step", "ur5_tilted_axes.uncertainty.toml");
    std::fs::write(&path, sidecar).expect("scratch sidecar writes");
    let setup = common::shipped_setup(
        "robots/ur5/ur5.urdf",
        path.to_str().expect("UTF-8 scratch path"),
        0.3,
    );
    let d = setup.space.len();
    let axes: Vec<usize> = (0..d)
        .filter(|&k| setup.space.dimensions()[k].name.contains(".axis."))
        .collect();
    assert_eq!(axes.len(), 2, "two axis parameters in {d}");
    let mut points: Vec<f64> = lane_points(d, 9).concat();
    // Samples 1 and 6 with both axes exactly as in the URDF (ξ = 0), the others tilted: mixed
    // chunks. (The nominal run, ξ = 0 throughout, is aligned too.)
    for sample in 0..9 {
        for &k in &axes {
            let value = &mut points[sample * d + k];
            *value = if sample == 1 || sample == 6 {
                0.0
            } else if *value == 0.0 {
                0.5
            } else {
                *value
            };
        }
    }
    let settings = hht_settings(&setup.scene);
    let reference = study_records(&setup, settings, &points, false, 1);
    assert_eq!(reference.1, "[]", "no sample is expected to fail");
    let batched = study_records(&setup, settings, &points, true, 2);
    assert_eq!(reference.2, batched.2, "counters differ");
    assert!(reference.0 == batched.0, "records differ");
}
