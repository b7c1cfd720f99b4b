//! The dimension-adaptive design (docs/method.md §11) as a study runs it: rounds of lock-step runs,
//! bounded from the stored values. Here on the ur5 with eight link values uncertain and a run budget
//! small enough that the total-degree-4 set (495 runs) does not fit, so `auto` must choose it.

use ribbon::analysis::{DesignKind, Method, Progress, Study, StudyOptions, StudyReport};
use ribbon::model::{LoadOptions, Model};
use ribbon::scene::{read_sidecar, Scene, SceneOverrides};
use ribbon::uncertainty::ParameterSpace;
use ribbon::uq::Truncation;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// The sidecar: eight values of the shipped all-values box, 0.3 s.
const SIDECAR: &str = r#"
[parameters]
"link.upper_arm_link.mass" = { rel = 0.03 }
"link.forearm_link.mass" = { rel = 0.03 }
"link.wrist_3_link.mass" = [0.15, 1.2]
"link.wrist_3_link.com.z" = [-0.002, 0.04]
"link.upper_arm_link.com.x" = { abs = 0.002 }
"link.forearm_link.com.x" = { abs = 0.002 }
"joint.elbow_joint.origin.z" = { abs = 0.0005 }
"joint.wrist_1_joint.origin.y" = { abs = 0.0005 }

[scene]
duration = 0.3
step = 0.001
gravity = [0.0, 0.0, -9.81]
initial.q = { shoulder_lift_joint = -1.2, elbow_joint = 1.0, wrist_1_joint = -0.5 }
"#;

/// Budget: below C(8 + 4, 4) = 495 runs with the check, above the 9-run start.
const MAX_RUNS: usize = 300;

/// The model, scene and box; `test` names the sidecar file (tests run in parallel, and a file
/// rewritten while another test reads it would be read empty).
fn study_parts(test: &str) -> (Model, Scene, ParameterSpace) {
    study_parts_of(test, SIDECAR)
}

/// [`study_parts`] of the sidecar `text`.
fn study_parts_of(test: &str, text: &str) -> (Model, Scene, ParameterSpace) {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("adaptive_design");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{test}.toml"));
    std::fs::write(&path, text).unwrap();
    let urdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/ur5/ur5.urdf");
    let (sidecar, _) = read_sidecar(&path).unwrap();
    let model = Model::from_urdf_file(&urdf, LoadOptions::default()).unwrap();
    let scene =
        Scene::resolve(&sidecar, &model, "test sidecar", SceneOverrides::default()).unwrap();
    let environment = scene.environment();
    let space =
        ParameterSpace::from_sidecar(&sidecar, &model, &environment, "test sidecar").unwrap();
    (model, scene, space)
}

fn options(threads: usize, max_runs: usize) -> StudyOptions {
    StudyOptions {
        method: Method::Auto,
        order: 4,
        truncation: Truncation::Tensor,
        grid: 21,
        scan_grid: None,
        samples: 0,
        seed: 0,
        threads,
        keep_going: false,
        check_runs: None,
        elements: ribbon::analysis::ElementsOptions::default(),
        design: DesignKind::Tensor,
        max_runs,
    }
}

fn run(study: &Study, interrupt: &AtomicBool, progress: &mut dyn FnMut(Progress)) -> StudyReport {
    study.run(interrupt, progress, &mut |_| Ok(())).unwrap()
}

#[test]
fn auto_chooses_the_adaptive_design_and_its_envelopes_do_not_depend_on_threads() {
    let (model, scene, space) = study_parts("threads");
    assert_eq!(space.len(), 8);
    let interrupt = AtomicBool::new(false);
    let mut reports = Vec::new();
    for threads in [1, 2] {
        let study = Study {
            model: model.clone(),
            environment: scene.environment(),
            scene: &scene,
            space: &space,
            options: options(threads, MAX_RUNS),
        };
        reports.push(run(&study, &interrupt, &mut |_| {}));
    }
    let report = &reports[0];
    assert_eq!(report.design, "sparse-adaptive");
    let adaptive = report.adaptive.as_ref().expect("an adaptive report");
    assert!(adaptive.rounds >= 2, "{adaptive:?}");
    assert!(adaptive.runs <= adaptive.budget, "{adaptive:?}");
    assert!(report.runs <= MAX_RUNS, "{} runs", report.runs);
    assert!(!report.partial);
    // Every envelope contains the nominal run.
    let e = &report.envelope;
    for o in 0..e.outputs.len() {
        for k in 0..e.times.len() {
            assert!(e.lower[o][k] <= e.nominal[o][k] && e.nominal[o][k] <= e.upper[o][k]);
        }
    }
    // Bitwise the same with one thread and two.
    assert_eq!(reports[0].envelope.lower, reports[1].envelope.lower);
    assert_eq!(reports[0].envelope.upper, reports[1].envelope.upper);
    assert_eq!(reports[0].adaptive, reports[1].adaptive);
    // The check ran, in proportion to the runs the design made.
    let check = report.check.as_ref().expect("a check");
    assert!(
        check.runs <= adaptive.runs.max(80) / 10 + 1,
        "{} check runs",
        check.runs
    );
}

#[test]
fn an_interrupted_adaptive_study_keeps_the_rounds_it_finished() {
    let (model, scene, space) = study_parts("interrupted");
    let study = Study {
        model,
        environment: scene.environment(),
        scene: &scene,
        space: &space,
        options: options(0, MAX_RUNS),
    };
    let interrupt = AtomicBool::new(false);
    // Interrupt as soon as the first round (the start) has finished: the second round stops at
    // its first step.
    let report = run(&study, &interrupt, &mut |p: Progress| {
        if p.phase == "adaptive" && p.records_done == p.records_total {
            interrupt.store(true, Ordering::SeqCst);
        }
    });
    assert!(report.partial);
    let adaptive = report.adaptive.as_ref().expect("an adaptive report");
    assert_eq!(adaptive.stop, "interrupted");
    // The envelopes cover the whole horizon, from the first round's runs (centre + one point per
    // parameter), and no check ran on a partial study.
    assert_eq!(adaptive.runs, space.len() + 1);
    assert_eq!(
        report.envelope.times.len(),
        scene.n_steps.div_ceil(scene.record_every) + 1
    );
    assert!(report.check.is_none());
    let e = &report.envelope;
    for o in 0..e.outputs.len() {
        for k in 0..e.times.len() {
            assert!(e.lower[o][k].is_finite() && e.upper[o][k].is_finite());
            assert!(e.lower[o][k] <= e.nominal[o][k] && e.nominal[o][k] <= e.upper[o][k]);
        }
    }
}

/// The last stage (the one the budget makes last) runs beside its bounding: each block's records
/// are fitted and bounded while the next block is simulated. Interrupted after its first block,
/// the study keeps the stages before it, as an interruption of an earlier stage does: what that
/// block's bounding put into the envelopes is dropped, and the envelopes come from the stage
/// before's fit. The same with one thread and two, bit for bit.
#[test]
fn an_adaptive_study_interrupted_in_its_last_stage_keeps_the_stages_before() {
    // 151 record times: the last stage runs in several blocks.
    let text = format!("{SIDECAR}\n[outputs]\nrate = 500.0\n");
    let (model, scene, space) = study_parts_of("interrupted_last", &text);
    // A budget the rounds reach before they converge.
    let study = |threads| Study {
        model: model.clone(),
        environment: scene.environment(),
        scene: &scene,
        space: &space,
        options: options(threads, 100),
    };
    let interrupt = AtomicBool::new(false);
    // The stages' runs, from a study that is not interrupted.
    let mut stage_runs = Vec::new();
    let mut blocks_of_last = 0;
    let full = run(&study(1), &interrupt, &mut |p: Progress| {
        if p.phase == "adaptive" && p.records_done == p.records_total {
            stage_runs.push(p.runs);
        }
    });
    let full_adaptive = full.adaptive.clone().expect("an adaptive report");
    assert_eq!(full_adaptive.stop, "budget");
    assert_eq!(full_adaptive.stages, stage_runs.len());
    assert!(stage_runs.len() >= 2, "{stage_runs:?}");
    let last_runs = *stage_runs.last().expect("a stage");
    let mut reports = Vec::new();
    for threads in [1, 2] {
        let interrupt = AtomicBool::new(false);
        let mut stages_done = 0;
        let report = run(&study(threads), &interrupt, &mut |p: Progress| {
            if p.phase != "adaptive" {
                return;
            }
            if p.records_done == p.records_total {
                stages_done += 1;
            } else if stages_done + 1 == stage_runs.len() {
                // The last stage's first block is in; its bounding runs beside the next block,
                // which the interrupt stops at its first step.
                blocks_of_last += 1;
                interrupt.store(true, Ordering::SeqCst);
            }
        });
        assert!(report.partial);
        let adaptive = report.adaptive.as_ref().expect("an adaptive report");
        assert_eq!(adaptive.stop, "interrupted");
        assert_eq!(adaptive.stages, full_adaptive.stages);
        assert_eq!(adaptive.runs, full_adaptive.runs - last_runs);
        assert!(report.check.is_none());
        assert_eq!(
            report.envelope.times.len(),
            scene.n_steps.div_ceil(scene.record_every) + 1
        );
        let e = &report.envelope;
        for o in 0..e.outputs.len() {
            for k in 0..e.times.len() {
                assert!(e.lower[o][k].is_finite() && e.upper[o][k].is_finite());
                assert!(e.lower[o][k] <= e.nominal[o][k] && e.nominal[o][k] <= e.upper[o][k]);
            }
        }
        reports.push(report);
    }
    assert_eq!(
        blocks_of_last, 2,
        "the last stage's first block, once per study"
    );
    assert_eq!(reports[0].envelope.lower, reports[1].envelope.lower);
    assert_eq!(reports[0].envelope.upper, reports[1].envelope.upper);
    // Interrupted before the last stage's first step instead (nothing of it bounded): the same
    // envelopes and report, so the dropped bounding left nothing behind.
    let interrupt = AtomicBool::new(false);
    let mut stages_done = 0;
    let at_start = run(&study(1), &interrupt, &mut |p: Progress| {
        if p.phase == "adaptive" && p.records_done == p.records_total {
            stages_done += 1;
            if stages_done + 1 == stage_runs.len() {
                interrupt.store(true, Ordering::SeqCst);
            }
        }
    });
    assert_eq!(at_start.adaptive, reports[0].adaptive);
    assert_eq!(at_start.envelope.lower, reports[0].envelope.lower);
    assert_eq!(at_start.envelope.upper, reports[0].envelope.upper);
    assert_ne!(at_start.envelope.upper, full.envelope.upper);
}

#[test]
fn a_budget_too_small_for_the_rounds_still_runs_the_start() {
    // 12 runs cannot hold the start (d + 1 = 9), the nominal run and the least check (8): the
    // design still runs its start, and stops there.
    let (model, scene, space) = study_parts("tiny_budget");
    let study = Study {
        model,
        environment: scene.environment(),
        scene: &scene,
        space: &space,
        options: options(0, 12),
    };
    let plan = study.plan().unwrap();
    assert_eq!(plan.design_name, "sparse-adaptive");
    let reason = &plan.auto.as_ref().expect("auto's choice").reason;
    assert!(
        reason.contains("--max-runs 12 cannot hold it") && reason.contains("18 runs in all"),
        "{reason}"
    );
    let report = run(&study, &AtomicBool::new(false), &mut |_| {});
    let adaptive = report.adaptive.expect("an adaptive report");
    assert_eq!(adaptive.runs, space.len() + 1);
    assert_eq!(adaptive.stop, "budget");
}
