//! One study, in phases over the same record times:
//!
//! ```text
//! before:  the screening (star design ⇒ ranking ⇒ the design built on it) or the adaptive
//!          rounds (⇒ their interpolation grid and values), where the plan has no fixed design
//! design:  lock-step simulation of the design's samples and the nominal run, block by block
//!          ⇒ fit and bound each block ⇒ envelopes (kept) and predicted extremisers (deduplicated)
//! check:   true-model runs at a budgeted selection of the predicted extremisers
//!          ⇒ envelopes widened to contain them, misfits recorded (|true − predicted| for the
//!          scans, the excess past the envelope for outer and approximate methods)
//! chaos:   the largest Lyapunov exponent of the nominal motion (two runs)
//! sinks:   the finished envelopes, block by block
//! ```
//!
//! This file only drives: [`Study::run_stages`] calls each phase in order — a function of the
//! [`PhaseContext`] and what the phases before it left (`screening_phase.rs`, `adaptive_phase.rs`,
//! `design_phase.rs`, `check_phase.rs`) — and stops early, keeping what was done, when one is
//! interrupted. What a study is asked and will do is `study_plan.rs`; what it hands back is
//! `report.rs`.
//!
//! Memory holds one block of records of one phase's samples plus the envelopes (a few numbers per
//! output per record time) and the nominal configurations: it does not grow with samples × horizon.
//! Every envelope contains every model run the study made, in every phase.

use super::accumulator::Accumulator;
use super::adaptive_phase::{adapt, Adapted};
use super::auto::AutoDesign;
use super::check::automatic_check_runs;
use super::check_phase::check;
use super::design_phase::{bound_design, Bounded, Design};
use super::elements_phase::{split_into_elements, RootDesign};
use super::engine::LockStep;
use super::envelope::EnvelopePoint;
use super::error::{ForeignError, StudyError};
use super::horizon_phase::verify_horizon_of_one_surrogate;
use super::lyapunov::estimate_lyapunov;
use super::method::Method;
use super::phase::{lockstep, PhaseContext};
use super::plan::Plan;
use super::report::{BlockView, CheckSkipped, Progress, StudyReport};
use super::schedule::RecordSchedule;
use super::screening_phase::screen;
use super::sparse::SparseDesign;
use super::stages::{SimulateHere, StageCursor, StageRecords};
use super::study_plan::{StudyOptions, StudyPlan};
use crate::environment::Environment;
use crate::model::Model;
use crate::scene::Scene;
use crate::uncertainty::ParameterSpace;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

/// A study ready to run.
pub struct Study<'a> {
    /// The nominal model.
    pub model: Model,
    /// The scene's environment (gravity, contact material; [`Scene::environment`]).
    pub environment: Environment,
    /// The scene.
    pub scene: &'a Scene,
    /// The interval parameters.
    pub space: &'a ParameterSpace,
    /// The options.
    pub options: StudyOptions,
}

impl<'a> Study<'a> {
    /// The study of `space` on `scene` with a copy of the nominal `model` in `environment` (the
    /// scene's): the one way every command (`plan`, `run`, `merge`, `analyze`, `compare`) builds
    /// it.
    pub fn new(
        model: &Model,
        environment: &Environment,
        scene: &'a Scene,
        space: &'a ParameterSpace,
        options: StudyOptions,
    ) -> Self {
        Study {
            model: model.clone(),
            environment: *environment,
            scene,
            space,
            options,
        }
    }
}

impl Study<'_> {
    /// The design, its runs and the check budget ([`StudyPlan::new`]); errors for plans that
    /// cannot run.
    pub fn plan(&self) -> Result<StudyPlan, StudyError> {
        let values_per_run = self.scene.outputs.len() * RecordSchedule::of(self.scene).len();
        StudyPlan::new(&self.options, self.space.len(), values_per_run)
    }

    /// The worker threads of `options.threads`.
    pub fn thread_pool(&self) -> Result<rayon::ThreadPool, StudyError> {
        let threads = self.options.threads;
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| StudyError::Threads {
                threads,
                message: e.to_string(),
            })
    }

    /// A report with no runs and empty envelopes over the scene's outputs.
    pub(super) fn empty_report(&self, threads: &rayon::ThreadPool) -> StudyReport {
        StudyReport::empty(
            self.scene.outputs.clone(),
            threads.current_num_threads(),
            self.options.method,
        )
    }

    /// The context every phase of one run of this study shares (see [`PhaseContext`]).
    pub(super) fn phase_context<'c>(
        &'c self,
        threads: &'c rayon::ThreadPool,
        interrupt: &'c AtomicBool,
        started: Instant,
        report: &'c mut StudyReport,
        progress: &'c mut dyn FnMut(Progress),
    ) -> PhaseContext<'c> {
        PhaseContext {
            model: &self.model,
            environment: &self.environment,
            scene: self.scene,
            space: self.space,
            options: &self.options,
            threads,
            interrupt,
            started,
            report,
            progress,
        }
    }

    /// The lock-step simulation of `points` (row-major `n × d`) and, when given, the nominal run
    /// after them, with this study's model, scene and box.
    pub fn lockstep(&self, points: &[f64], nominal_xi: Option<&[f64]>) -> LockStep<'_> {
        lockstep(
            &self.model,
            &self.environment,
            self.scene,
            self.space,
            points,
            nominal_xi,
        )
    }

    /// The design's sample points (row-major `runs × d`, the nominal run not included) when the
    /// plan fixes them before any run; `None` for designs that depend on runs (screened,
    /// adaptive).
    pub fn design_points(&self, study_plan: &StudyPlan) -> Option<Vec<f64>> {
        study_plan
            .plan
            .as_ref()
            .map(|plan| plan.points(self.space.len()))
    }

    /// Runs the study: `progress` after each block of each phase, then `sink` with each block of
    /// the finished envelopes. Stops at the next step when `interrupt` is set (the report is then
    /// `partial` and covers the records finished before).
    pub fn run(
        &self,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        let study_plan = self.plan()?;
        self.run_planned(study_plan, interrupt, progress, sink)
    }

    /// [`Study::run`] with the plan already made (the caller printed it; planning a regression
    /// design costs seconds at large d, so it is not done twice).
    pub fn run_planned(
        &self,
        study_plan: StudyPlan,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        self.run_stages(study_plan, &mut SimulateHere, interrupt, progress, sink)
    }

    /// The study's phases — screening or adaptive rounds where the design has them, design, fit
    /// and bound, the a-posteriori check, the chaos estimate, the sinks — with the records of
    /// each *stage* (a phase of runs planned before it runs: the design, the screening, each
    /// adaptive round; docs/distributed.md §7) from `stages`: simulated here
    /// ([`SimulateHere`]: `analyze`) or read from the record blocks of shards that simulated
    /// them elsewhere (`merge`). Either way the values reach the fits in the same order, so the
    /// decisions between stages and the results are the same bit for bit. A stage whose records
    /// do not exist yet ends the study with [`StudyError::StageNeeded`] naming its points.
    pub fn run_stages(
        &self,
        study_plan: StudyPlan,
        stages: &mut dyn StageRecords,
        interrupt: &AtomicBool,
        progress: &mut dyn FnMut(Progress),
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        let started = Instant::now();
        let threads = self.thread_pool()?;
        let n_outputs = self.scene.outputs.len();
        let schedule = RecordSchedule::of(self.scene);
        let mut report = StudyReport {
            runs: 0,
            block_records: schedule.block_records(study_plan.design_runs, n_outputs),
            method: study_plan.method,
            design: study_plan.design_name,
            auto: study_plan.auto.clone(),
            ..self.empty_report(&threads)
        };
        let mut accumulator = Accumulator::new(n_outputs, schedule.len())
            .with_known_ranges(&super::design_phase::known_ranges(self.scene));
        let mut stages = StageCursor::new(stages, self.space.len());
        let mut context = self.phase_context(&threads, interrupt, started, &mut report, progress);
        run_phases(&mut context, study_plan, &mut stages, &mut accumulator)?;
        self.finish(report, accumulator, sink)
    }

    /// The sinks: moves the accumulated envelopes into the report and hands them to `sink` block
    /// by block (with the hull of true runs where the report shows it,
    /// [`StudyReport::shows_runs_hull`]).
    fn finish(
        &self,
        mut report: StudyReport,
        accumulator: Accumulator,
        sink: &mut dyn FnMut(&BlockView) -> Result<(), ForeignError>,
    ) -> Result<StudyReport, StudyError> {
        let n_outputs = accumulator.n_outputs;
        let n_done = accumulator.times.len();
        let nq = self.model.nq;
        accumulator.fill(&mut report.envelope);
        let shows_runs_hull = report.shows_runs_hull();
        let block = report.block_records.max(1);
        let mut first = 0;
        while first < n_done {
            let count = block.min(n_done - first);
            let values = first * n_outputs..(first + count) * n_outputs;
            let positions = (first * nq).min(accumulator.nominal_positions.len())
                ..((first + count) * nq).min(accumulator.nominal_positions.len());
            sink(&BlockView {
                first_record: first,
                times: &accumulator.times[first..first + count],
                points: &accumulator.points[values.clone()],
                nominal: &accumulator.nominal[values],
                nominal_positions: &accumulator.nominal_positions[positions],
                sobol: report.sobol.as_ref().and_then(|s| s.block(first, count)),
                runs_hull: shows_runs_hull
                    .then(|| accumulator.run_hulls(first..first + count))
                    .flatten(),
            })
            .map_err(StudyError::Sink)?;
            first += count;
        }
        Ok(report)
    }
}

/// The phases from the first run to the chaos estimate, in order (module documentation); each
/// leaves its results in `context.report` and `accumulator`. Returns early, with what was done,
/// when a phase before the design was interrupted.
fn run_phases(
    context: &mut PhaseContext<'_>,
    mut study_plan: StudyPlan,
    stages: &mut StageCursor,
    accumulator: &mut Accumulator,
) -> Result<(), StudyError> {
    let fixed = study_plan.plan.take();
    let Some(mut design) = design_of(context, fixed, &study_plan, stages, accumulator)? else {
        return Ok(());
    };
    let locates_extremes = study_plan.check_runs > 0;
    let Bounded {
        complete,
        candidates,
        runs,
    } = bound_design(
        context,
        stages,
        &mut design,
        study_plan.method,
        locates_extremes,
        accumulator,
    )?;

    // The a-posteriori check: true runs where the surrogates put their extremes. An adaptive
    // design that stopped early is checked in proportion to the runs it made.
    let check_budget = match (&context.report.adaptive, context.options.check_runs) {
        (Some(adaptive), None) => automatic_check_runs(adaptive.runs),
        _ => study_plan.check_runs,
    };
    if complete && locates_extremes {
        let t_select = Instant::now();
        let check_plan = candidates.select(check_budget);
        context.report.phase_seconds.check_selection += t_select.elapsed().as_secs_f64();
        let outcome = check(context, &check_plan, accumulator)?;
        // Where the surrogate is not trusted: elements (sub-boxes with their own surrogates),
        // whose last step is the horizon check; without them the horizon check alone.
        if context.options.elements.enabled && study_plan.method == Method::LegendreScan {
            context.report.check = Some(outcome.report);
            let root = RootDesign {
                plan: &design.plan,
                runs,
                misfit: outcome.misfit,
                candidates,
            };
            split_into_elements(context, stages, root, accumulator)?;
        } else {
            let verdict =
                verify_horizon_of_one_surrogate(context, &candidates, outcome, accumulator)?;
            context.report.check = Some(verdict);
        }
    } else if study_plan.method.is_checked() && context.options.check_runs == Some(0) {
        context.report.check_skipped = Some(CheckSkipped::TurnedOff);
    }
    // Is the nominal motion chaotic? Two runs, after the design so that an interruption
    // still saves the envelopes.
    if !context.report.partial {
        chaos(context);
    }
    Ok(())
}

/// The design the study bounds: the plan's `fixed` design, or the one the phases before it make —
/// the adaptive rounds (whose values the design phase then bounds) or the screening (whose
/// ranking chooses the terms, and whose runs the envelopes contain). `None` when such a phase was
/// interrupted: nothing more runs.
fn design_of(
    context: &mut PhaseContext<'_>,
    fixed: Option<Plan>,
    study_plan: &StudyPlan,
    stages: &mut StageCursor,
    accumulator: &mut Accumulator,
) -> Result<Option<Design>, StudyError> {
    let d = context.space.len();
    let design_runs = study_plan.design_runs;
    let mut screen_hull: Vec<EnvelopePoint> = Vec::new();
    let mut adapted = None;
    let mut last_stage = None;
    let plan = match fixed {
        Some(plan) => {
            context.report.runs += design_runs;
            plan
        }
        None => {
            let Some(choice) = &study_plan.auto else {
                return Err(StudyError::BadOptions(
                    "internal: a plan without design or auto choice".to_string(),
                ));
            };
            if let AutoDesign::Adaptive { budget } = choice.design {
                // The adaptive design runs its rounds here and keeps their values; the design
                // phase then bounds from them.
                let nominal_xi = context.space.nominal_xi();
                let Some(rounds) = adapt(context, stages, budget, &nominal_xi, accumulator)? else {
                    return Ok(None);
                };
                let n_outputs = context.scene.outputs.len();
                let schedule = RecordSchedule::of(context.scene);
                match rounds {
                    Adapted::Done(grid, outcome) => {
                        context.report.adaptive = Some(outcome.report.clone());
                        context.report.block_records =
                            schedule.block_records(grid.n_points() + 1, n_outputs);
                        adapted = Some(outcome);
                        Plan::Sparse(Arc::new(SparseDesign::Grid(grid)))
                    }
                    // Its last stage runs in the design phase, beside its bounding.
                    Adapted::LastStage(last) => {
                        let design = last.design().clone();
                        context.report.block_records =
                            schedule.block_records(design.n_points() + 1, n_outputs);
                        last_stage = Some(Box::new(last));
                        Plan::Sparse(design)
                    }
                }
            } else {
                // Screening (auto above the budget of a full total-degree set): the star design
                // ranks the parameters, and the design is built from the ranking.
                let (screening, complete) = screen(context, stages, &mut screen_hull)?;
                let t_choice = Instant::now();
                let ranking = screening.ranking();
                context.report.screening = Some(screening);
                context.report.ranking = Some(ranking.clone());
                if !complete {
                    return Ok(None);
                }
                context.report.runs += design_runs;
                let design = SparseDesign::screened(d, &choice.design, &ranking)?;
                context.report.phase_seconds.design_choice += t_choice.elapsed().as_secs_f64();
                Plan::Sparse(Arc::new(design))
            }
        }
    };
    Ok(Some(Design {
        plan,
        adapted,
        last_stage,
        screen_hull,
    }))
}

/// The chaos estimate: the largest Lyapunov exponent of the nominal motion (two runs: the
/// nominal parameters and a shadow with a perturbed state).
fn chaos(context: &mut PhaseContext<'_>) {
    let mut nominal_model = context.model.clone();
    let mut nominal_environment = *context.environment;
    context.space.apply(
        &mut nominal_model,
        &mut nominal_environment,
        &context.space.nominal_xi(),
    );
    let t_lyapunov = Instant::now();
    context.report.lyapunov = estimate_lyapunov(
        &nominal_model,
        &nominal_environment,
        context.scene,
        context.interrupt,
    );
    context.report.simulate_seconds += t_lyapunov.elapsed().as_secs_f64();
}
