//! [`BatchStepper`]: up to [`LANES`] samples of one robot advanced by one HHT-I3 grid step together,
//! their mass matrices and inverse dynamics evaluated by the batched kernels
//! ([`crate::dynamics::batch`]) in one walk of the tree per chunk (docs/batch.md §5).
//!
//! Every lane keeps its own [`RobotSystem`] (its sample's model and effects) and its own
//! [`HhtIntegrator`]; the integrator does all of a step's arithmetic except the two kernels, which
//! it takes from the batch (`HhtIntegrator::begin_plain_step` and what follows). Since a batched
//! kernel gives each lane the bits of the scalar kernel, and the residual is completed by the same
//! function as the scalar path's ([`RobotSystem::finish_dynamics_residual`]), every lane's step has
//! the bits of [`HhtIntegrator::step`] on its own system. A lane whose step is not plain (see
//! `src/integrate/hht/plain.rs`) or gives up on its first Newton matrix is stepped by
//! [`HhtIntegrator::step`] itself, from the same state.
//!
//! A lane that converges waits, masked, for the others of its chunk: its arithmetic is part of the
//! same vector instructions, so it costs nothing extra (docs/batch.md §5).

use super::RobotSystem;
use crate::dynamics::batch::{self, BatchData, BatchError, BatchModel, BatchVectors, LANES};
use crate::integrate::{
    DenseSolver, HhtIntegrator, HhtSettings, IntegrateError, PlainProgress, PlainStep,
    ReportedVelocity,
};
use crate::linalg::cholesky::NonPositivePivot;
use nalgebra::DVector;

/// From this many coordinates on, the lanes whose Newton matrix was factorised in the batch also
/// solve their Newton systems there (`batch::cholesky_solve`, the scalar solve's operations lane by
/// lane) instead of each with its own copy of the factor, however many lanes there are. Per sample
/// step of a lock-step fall (callgrind, benches/README.md): the quadruped's 14 coordinates
/// 14 807 → 14 329 instructions. Below it they solve there when [`BATCHED_SOLVE_FROM_LANES`] lanes
/// or more were factorised in the batch.
pub const BATCHED_SOLVE_FROM: usize = 12;

/// Below [`BATCHED_SOLVE_FROM`] coordinates, the lanes factorised in the batch solve there when
/// at least this many were. A triangular solve is a chain of dependent divisions: a lane's solve
/// waits on their latency alone or in a vector, so four lanes in one vector chain take about the
/// time of one. In instructions the hand-out and hand-back cost more than the vectors save (the
/// ur5's 6 coordinates: 10 119 → 10 418 per sample step), which is why small robots had kept their
/// own solves; in time they gain (`hht_batch --no-mujoco`, the builds alternating three times,
/// 2026-11-30): ribbon-ur5 batches of 32 0.85–0.86 → 0.80–0.81 µs per sample step, erd-ur5
/// 0.62–0.64 → 0.59–0.61; the d = 72 study's simulation took 0.91 of its time (median of eight
/// runs side by side, one per core). A lone lane has nothing to overlap and only pays the copies
/// (erd-ur5, a batch of 1 solving there: 1.30–1.33 → 1.38–1.50 µs), hence two.
pub const BATCHED_SOLVE_FROM_LANES: usize = 2;

/// How the lanes' grid steps were taken since the stepper was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BatchStepCounts {
    /// Lane steps driven with the batched kernels.
    pub batched: u64,
    /// Lane steps run by the scalar integrator (not plain, or abandoned by the batched attempt).
    pub scalar: u64,
}

/// Where one lane stands within a grid step. (A few hundred bytes per lane, kept inline: a step
/// allocates nothing.)
#[derive(Clone, Copy, Debug)]
#[allow(clippy::large_enum_variant)]
enum LaneState {
    /// Not stepped (inactive, finished, or failed).
    Idle,
    /// In a plain step driven with the batched kernels.
    Plain(PlainStep),
    /// Converged; its velocity projection waits for `M` at the converged iterate.
    Projecting(PlainStep),
    /// To be stepped by the scalar integrator.
    Scalar,
}

/// Up to [`LANES`] samples of one robot, each with its own system and integrator, stepped together
/// with the batched kernels.
pub struct BatchStepper {
    systems: Vec<RobotSystem>,
    integrators: Vec<Option<HhtIntegrator>>,
    batch_model: BatchModel<LANES>,
    batch_data: BatchData<LANES>,
    q: BatchVectors<LANES>,
    v: BatchVectors<LANES>,
    qdd: BatchVectors<LANES>,
    /// The Newton systems' right-hand sides, then their solutions, of the lanes whose factor is
    /// the batch's (`factor_in_batch`).
    newton_rhs: BatchVectors<LANES>,
    /// Per lane: its plain step's Newton matrix was factorised in the batch (and is still there,
    /// in `batch_data.mass_matrix`), so its Newton systems are solved there too.
    factor_in_batch: [bool; LANES],
    states: Vec<LaneState>,
    errors: Vec<Option<IntegrateError>>,
    /// One lane's `M` (nv²) or `τ` (nv).
    scratch: Vec<f64>,
    counts: BatchStepCounts,
}

impl BatchStepper {
    /// Whether a study of `system` with `settings` gains from the batched step: no contacts and no
    /// reuse of the Newton matrix (fixed or adaptive step control, joint limits allowed: a step
    /// that crosses one is the scalar step's). (Any
    /// system steps correctly through a [`BatchStepper`], falling back to the scalar step where it
    /// must; this says whether it would ever take the batched path.)
    pub fn suits(system: &RobotSystem, settings: &HhtSettings) -> bool {
        !settings.reuse_newton_matrix && !system.effects.has_contacts()
    }

    /// `lanes` (1 to [`LANES`]) copies of `template`, without integrators yet
    /// ([`BatchStepper::start_lane`]).
    ///
    /// Errors: [`BatchError::Empty`] for 0 lanes, [`BatchError::NoSuchSample`] for more than
    /// [`LANES`].
    pub fn new(template: &RobotSystem, lanes: usize) -> Result<Self, BatchError> {
        if lanes > LANES {
            return Err(BatchError::NoSuchSample {
                sample: lanes - 1,
                size: LANES,
            });
        }
        let samples: Vec<(&crate::model::Model, &crate::spatial::Vec3)> = (0..lanes)
            .map(|_| (&template.model, &template.environment.gravity))
            .collect();
        let batch_model = BatchModel::from_models(&samples)?;
        let batch_data = BatchData::new(&batch_model);
        let (nq, nv) = (template.model.nq, template.model.nv);
        Ok(Self {
            systems: vec![template.clone(); lanes],
            integrators: (0..lanes).map(|_| None).collect(),
            batch_model,
            batch_data,
            q: BatchVectors::zeros(nq, lanes),
            v: BatchVectors::zeros(nv, lanes),
            qdd: BatchVectors::zeros(nv, lanes),
            newton_rhs: BatchVectors::zeros(nv, lanes),
            factor_in_batch: [false; LANES],
            states: vec![LaneState::Idle; lanes],
            errors: (0..lanes).map(|_| None).collect(),
            scratch: vec![0.0; nv * nv],
            counts: BatchStepCounts::default(),
        })
    }

    /// Number of lanes.
    pub fn lanes(&self) -> usize {
        self.systems.len()
    }

    /// Lane `lane`'s system, to write a sample's parameter values into its model and environment; call
    /// [`BatchStepper::sync_lane`] afterwards.
    pub fn system_mut(&mut self, lane: usize) -> &mut RobotSystem {
        &mut self.systems[lane]
    }

    /// Lane `lane`'s system and integrator (`None` before [`BatchStepper::start_lane`]).
    pub fn lane_mut(&mut self, lane: usize) -> (&mut RobotSystem, Option<&mut HhtIntegrator>) {
        (&mut self.systems[lane], self.integrators[lane].as_mut())
    }

    /// Copies lane `lane`'s model and gravity values into the batch (after they changed).
    pub fn sync_lane(&mut self, lane: usize) -> Result<(), BatchError> {
        let system = &self.systems[lane];
        self.batch_model
            .set_sample(lane, &system.model, &system.environment.gravity)
    }

    /// Makes lane `lane`'s integrator, if it has none, with a consistent start of its system from
    /// `(0, q0, v0)` (a workspace for the trajectories swapped in later).
    pub fn start_lane(
        &mut self,
        lane: usize,
        settings: HhtSettings,
        q0: &DVector<f64>,
        v0: &DVector<f64>,
    ) -> Result<&mut HhtIntegrator, IntegrateError> {
        let integrator = &mut self.integrators[lane];
        if integrator.is_none() {
            *integrator = Some(HhtIntegrator::new(
                &mut self.systems[lane],
                settings,
                0.0,
                q0,
                v0,
            )?);
        }
        Ok(integrator.as_mut().expect("made just above"))
    }

    /// How the lanes' steps were taken so far.
    pub fn counts(&self) -> BatchStepCounts {
        self.counts
    }

    /// Advances every lane with `active[lane]` (and an integrator) by one grid step, bitwise as
    /// [`HhtIntegrator::advance`] with `report` on the lane's system would (a study leaves the
    /// reported velocity out between its record times). Returns each lane's error (`None`: the
    /// step succeeded or the lane was not active); a failed lane's state is where `advance` leaves
    /// it.
    pub fn step(
        &mut self,
        active: &[bool],
        report: ReportedVelocity,
    ) -> &mut [Option<IntegrateError>] {
        let lanes = self.lanes();
        let mut any_plain = false;
        self.factor_in_batch = [false; LANES];
        for lane in 0..lanes {
            self.errors[lane] = None;
            self.states[lane] = LaneState::Idle;
            let Some(integrator) = self.integrators[lane].as_mut() else {
                continue;
            };
            if !active.get(lane).copied().unwrap_or(false) {
                continue;
            }
            self.states[lane] = match integrator.begin_plain_step(&mut self.systems[lane], report) {
                Some(plain) => {
                    write_lane(&mut self.q, lane, integrator.plain_iterate().0.as_slice());
                    any_plain = true;
                    LaneState::Plain(plain)
                }
                None => LaneState::Scalar,
            };
        }
        if any_plain {
            batch::crba(&self.batch_model, &mut self.batch_data, &self.q);
            self.factorise_plain_lanes();
        }
        // The first round's iterates are the CRBA's configurations: its placements stand.
        self.iterate_plain_lanes(any_plain);
        self.project_lanes();
        for lane in 0..lanes {
            if !matches!(self.states[lane], LaneState::Scalar) {
                continue;
            }
            self.states[lane] = LaneState::Idle;
            let Some(integrator) = self.integrators[lane].as_mut() else {
                continue;
            };
            self.counts.scalar += 1;
            if let Err(error) = integrator.advance(&mut self.systems[lane], report) {
                self.errors[lane] = Some(error);
            }
        }
        &mut self.errors
    }

    /// Newton iterations of the plain lanes, one batched inverse dynamics per round, until every
    /// lane has converged, been abandoned (to the scalar step) or failed. `placements_current`:
    /// the batch's joint placements are those of the lanes' current iterates (the CRBA just ran
    /// there), so the first round need not compute them again.
    fn iterate_plain_lanes(&mut self, mut placements_current: bool) {
        let nv = self.batch_model.nv;
        loop {
            let mut pending = false;
            for lane in 0..self.lanes() {
                if !matches!(self.states[lane], LaneState::Plain(_)) {
                    continue;
                }
                let Some(integrator) = self.integrators[lane].as_ref() else {
                    continue;
                };
                let (q, v, qdd) = integrator.plain_iterate();
                if !placements_current {
                    // Else the CRBA's configurations, written for it: the iterates' own.
                    write_lane(&mut self.q, lane, q.as_slice());
                }
                write_lane(&mut self.v, lane, v.as_slice());
                write_lane(&mut self.qdd, lane, qdd.as_slice());
                pending = true;
            }
            if !pending {
                return;
            }
            if placements_current {
                batch::rnea_at_placements(
                    &self.batch_model,
                    &mut self.batch_data,
                    &self.v,
                    &self.qdd,
                );
                placements_current = false;
            } else {
                batch::rnea(
                    &self.batch_model,
                    &mut self.batch_data,
                    &self.q,
                    &self.v,
                    &self.qdd,
                );
            }
            // Per lane: the residual, then the correction. A lane whose factor is the batch's
            // has its system solved with the others' below (the scalar solve's operations, lane
            // by lane: the same bits); the others solve their own.
            let mut solved_in_batch: [Option<f64>; LANES] = [None; LANES];
            let lanes = self.lanes();
            for (lane, solved_in_batch) in solved_in_batch.iter_mut().enumerate().take(lanes) {
                let LaneState::Plain(plain) = &mut self.states[lane] else {
                    continue;
                };
                let Some(integrator) = self.integrators[lane].as_mut() else {
                    continue;
                };
                let system = &mut self.systems[lane];
                let (q, v, residual) = integrator.plain_residual_buffers();
                // The stepper's lanes are one chunk (at most LANES): lane `lane` of each entry.
                for (r, t) in residual.as_mut_slice()[..nv]
                    .iter_mut()
                    .zip(self.batch_data.tau.chunk(0))
                {
                    *r = t.0[lane];
                }
                system.finish_dynamics_residual(
                    q.as_slice(),
                    v.as_slice(),
                    residual.as_mut_slice(),
                );
                if self.factor_in_batch[lane] {
                    match integrator.plain_newton_rhs(system, plain) {
                        Some(residual_inf) => {
                            write_lane(
                                &mut self.newton_rhs,
                                lane,
                                integrator.plain_newton_rhs_mut(),
                            );
                            *solved_in_batch = Some(residual_inf);
                        }
                        None => self.states[lane] = LaneState::Scalar,
                    }
                    continue;
                }
                let progress = integrator.plain_correct(system, plain);
                self.settle(lane, progress);
            }
            if solved_in_batch.iter().all(Option::is_none) {
                continue;
            }
            batch::cholesky_solve(
                self.batch_model.isa,
                &self.batch_data.mass_matrix,
                nv,
                &mut self.newton_rhs,
            );
            for (lane, residual_inf) in solved_in_batch.into_iter().enumerate() {
                let Some(residual_inf) = residual_inf else {
                    continue;
                };
                let LaneState::Plain(plain) = &mut self.states[lane] else {
                    continue;
                };
                let Some(integrator) = self.integrators[lane].as_mut() else {
                    continue;
                };
                self.newton_rhs
                    .copy_sample(lane, integrator.plain_newton_rhs_mut());
                let progress =
                    integrator.plain_correct_solved(&mut self.systems[lane], plain, residual_inf);
                self.settle(lane, progress);
            }
        }
    }

    /// Lane `lane`'s state after a Newton correction of its plain step that returned `progress`.
    #[inline(always)]
    fn settle(&mut self, lane: usize, progress: Result<PlainProgress, IntegrateError>) {
        match progress {
            Ok(PlainProgress::Iterate) => {}
            Ok(PlainProgress::Done) => {
                self.counts.batched += 1;
                self.states[lane] = LaneState::Idle;
            }
            Ok(PlainProgress::NeedsProjectionMass) => {
                if let LaneState::Plain(plain) = self.states[lane] {
                    self.states[lane] = LaneState::Projecting(plain);
                }
            }
            Ok(PlainProgress::Abandoned) => self.states[lane] = LaneState::Scalar,
            Err(error) => {
                self.errors[lane] = Some(error);
                self.states[lane] = LaneState::Idle;
            }
        }
    }
}

impl BatchStepper {
    /// The plain lanes' Newton matrices at their first iterates, from the batched CRBA's `M`.
    /// Without constraint rows each is the Cholesky factorisation of `M + diag`: those are
    /// formed and factorised together in place of the batch's `M` (which nothing reads after),
    /// lane by lane the integrator's own operations and pivot test
    /// (`batch::cholesky_factor_with_min_pivots`, the threshold of `DenseSolver::cholesky_min_pivot`
    /// from each lane's largest diagonal entry), and handed in; a lane whose matrix that test
    /// refuses abandons its plain step, and the scalar step, repeating it, refuses the same matrix.
    /// With rows, each lane factorises its own from a copy of its `M`.
    fn factorise_plain_lanes(&mut self) {
        let nv = self.batch_model.nv;
        let n2 = nv * nv;
        let mut batched = [false; LANES];
        let lanes = self.lanes();
        for (lane, lane_batched) in batched.iter_mut().enumerate().take(lanes) {
            let LaneState::Plain(plain) = &mut self.states[lane] else {
                continue;
            };
            let Some(integrator) = self.integrators[lane].as_mut() else {
                continue;
            };
            let system = &mut self.systems[lane];
            if !integrator.plain_factor_is_cholesky() {
                let mass = &mut self.scratch[..n2];
                self.batch_data.mass_matrix.copy_sample(lane, mass);
                if !integrator.plain_factorise(system, plain, mass) {
                    self.states[lane] = LaneState::Scalar;
                }
                continue;
            }
            match integrator.plain_newton_diagonal(system, plain) {
                None => self.states[lane] = LaneState::Scalar,
                Some(diagonal) => {
                    // The stepper's lanes are one chunk (at most LANES).
                    if let Some(diagonal) = diagonal {
                        for (j, d) in diagonal.iter().enumerate() {
                            self.batch_data.mass_matrix.chunks[j * nv + j].0[lane] += d;
                        }
                    }
                    *lane_batched = true;
                }
            }
        }
        if !batched.contains(&true) {
            return;
        }
        // Each lane's largest diagonal entry, as `dense_solver::largest_diagonal_entry` takes it
        // for `DenseSolver::cholesky_min_pivot` (NaN skipped).
        let mut largest = [0.0_f64; LANES];
        for j in 0..nv {
            for (m, x) in largest
                .iter_mut()
                .zip(self.batch_data.mass_matrix.chunks[j * nv + j].0)
            {
                let magnitude = x.abs();
                if magnitude > *m {
                    *m = magnitude;
                }
            }
        }
        let mut min_pivots = [0.0; LANES];
        let mut failures: [Option<NonPositivePivot>; LANES] = [None; LANES];
        for lane in 0..LANES {
            match DenseSolver::cholesky_min_pivot(largest[lane]) {
                Some(min_pivot) => min_pivots[lane] = min_pivot,
                // A zero matrix: refused outright (by the integrator below).
                None => {
                    failures[lane] = Some(NonPositivePivot {
                        index: 0,
                        pivot: 0.0,
                    })
                }
            }
        }
        let mut refused = failures;
        let solve_in_batch = nv >= BATCHED_SOLVE_FROM
            || batched.iter().filter(|&&b| b).count() >= BATCHED_SOLVE_FROM_LANES;
        batch::cholesky_factor_with_min_pivots(
            self.batch_model.isa,
            &mut self.batch_data.mass_matrix,
            nv,
            &min_pivots,
            &mut failures,
        );
        for lane in 0..self.lanes() {
            refused[lane] = refused[lane].or(failures[lane]);
            if !batched[lane] {
                continue;
            }
            let LaneState::Plain(plain) = &mut self.states[lane] else {
                continue;
            };
            let Some(integrator) = self.integrators[lane].as_mut() else {
                continue;
            };
            let system = &mut self.systems[lane];
            if refused[lane].is_some() {
                // The scalar step repeats the attempt and refuses the same matrix.
                integrator.plain_abandon(plain);
                self.states[lane] = LaneState::Scalar;
                continue;
            }
            let factors = &self.batch_data.mass_matrix;
            integrator.plain_install_factor(system, plain, |out| factors.copy_sample(lane, out));
            self.factor_in_batch[lane] = solve_in_batch;
        }
    }

    /// The velocity projections of the lanes that converged with constraint rows: one batched CRBA
    /// at their `q_{n+1}`, then each lane accepts its step.
    fn project_lanes(&mut self) {
        let nv = self.batch_model.nv;
        let mut any = false;
        for lane in 0..self.lanes() {
            if let (LaneState::Projecting(_), Some(integrator)) =
                (&self.states[lane], self.integrators[lane].as_ref())
            {
                write_lane(&mut self.q, lane, integrator.plain_iterate().0.as_slice());
                any = true;
            }
        }
        if !any {
            return;
        }
        batch::crba(&self.batch_model, &mut self.batch_data, &self.q);
        for lane in 0..self.lanes() {
            let LaneState::Projecting(plain) = &mut self.states[lane] else {
                continue;
            };
            let Some(integrator) = self.integrators[lane].as_mut() else {
                continue;
            };
            let mass = &mut self.scratch[..nv * nv];
            self.batch_data.mass_matrix.copy_sample(lane, mass);
            match integrator.plain_accept_with_projection_mass(&mut self.systems[lane], plain, mass)
            {
                Ok(()) => self.counts.batched += 1,
                Err(error) => self.errors[lane] = Some(error),
            }
            self.states[lane] = LaneState::Idle;
        }
    }
}

/// Writes one lane's vector into a batch (dimensions fixed at construction).
fn write_lane(batch: &mut BatchVectors<LANES>, lane: usize, values: &[f64]) {
    let dim = batch.dim;
    let (chunk, l) = (lane / LANES, lane % LANES);
    for (entry, value) in batch.chunks[chunk * dim..(chunk + 1) * dim]
        .iter_mut()
        .zip(values)
    {
        entry.0[l] = *value;
    }
}
