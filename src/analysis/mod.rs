//! Studies: interval parameters of the sidecar propagated through HHT-I3 into bound envelopes.
//!
//! `plan (sample points ξ) ⇒ lock-step simulation in blocks of record times (rayon over samples)
//! ⇒ fit and bound each block (the samples' records are then dropped) ⇒ true-model runs at the
//! predicted extremisers (the a-posteriori check) widen the envelopes ⇒ sinks (MCAP, summary, CSV)`
//!
//! Memory holds one block of records for all samples, never whole trajectories: peak memory does not
//! grow with horizon × samples. Results are bitwise identical for any thread count: each sample's
//! trajectory depends only on its parameters, and fits read samples in plan order.
//!
//! Where things are: what a study is asked and will do in `study_plan.rs`; the phase driver in
//! `study.rs`, each phase in its own `*_phase.rs` over the `PhaseContext` of `phase.rs`; what a
//! study hands back in `report.rs` and `envelope.rs` (with `bounded_block.rs`, what bounding a
//! block hands back); its errors in `error.rs`. No file here imports one that imports it.

mod accumulator;
mod adaptive;
mod adaptive_phase;
mod auto;
mod bound_clock;
mod bounded_block;
mod bounds;
mod check;
mod check_phase;
mod design_part;
mod design_phase;
mod element_round;
mod elements;
mod elements_phase;
mod engine;
mod envelope;
mod error;
mod horizon_phase;
mod lyapunov;
mod method;
mod nested_design;
mod phase;
mod plan;
mod reference;
mod refine_phase;
mod report;
mod scan_refinement;
mod scanned_leaf;
mod schedule;
mod screening;
mod screening_phase;
mod sobol_indices;
mod sparse;
mod sparse_bounds;
mod stages;
mod study;
mod study_plan;

pub use adaptive::{
    AdaptiveSet, Term, ADAPTIVE_BATCH_FRACTION, ADAPTIVE_MAX_DEGREE, ADAPTIVE_MIN_BATCH,
    ADAPTIVE_TOLERANCE, LOOK_AHEAD,
};
pub use adaptive_phase::ADAPTIVE_NOISE_FLOOR;
pub use auto::{
    adaptive_choice, binomial, choose as choose_auto, screened_choice, screened_terms,
    total_degree_terms, AutoChoice, AutoDesign, ADAPTIVE_VALUE_BUDGET, AUTO_TENSOR_MAX_DIM,
    BASE_ORDER, DEFAULT_MAX_RUNS,
};
pub use bounded_block::{BoundedBlock, Extremes};
pub use check::{
    automatic_check_runs, output_resolution, trust_verdict, untrusted_advice, CheckCandidates,
    CheckPlan, TrustVerdict, CHECK_POINT_TOLERANCE, CHECK_RUNS_FRACTION, MIN_CHECK_RUNS,
    SEPARATION_ADVICE_AMPLIFICATION, TRUST_RELATIVE_MISFIT, TRUST_RESOLUTION_FACTOR,
};
pub use design_part::{DesignPartRequest, PartSink};
pub use elements::ELEMENT_TENSOR_MAX_DIM;
pub use elements::{
    ElementsOptions, DEFAULT_MAX_ELEMENTS, MAX_SPLIT_DIMS, MIN_ELEMENT_HALF_WIDTH,
    MIN_ELEMENT_ORDER, SPLIT_SHARE,
};
pub use engine::{BlockOutcome, LockStep, RecordSource};
pub use envelope::{widest_index, widest_record, Envelope, EnvelopePoint, OuterBounds, Side};
pub use error::{ForeignError, StudyError};
pub use lyapunov::{
    estimate_lyapunov, LyapunovEstimate, CHAOS_AMPLIFICATION, COLLAPSED_SEPARATION, MAX_PULL,
    RENORMALISATION_INTERVAL_S, SHADOW_SEPARATION, VELOCITY_TIME_SCALE_S,
};
pub use method::{CheckMisfit, Method, METHODS};
pub use plan::{Plan, SplitMix64, MAX_RUNS, TAYLOR_STEP};
pub use reference::{VertexReferenceOptions, MAX_FLIP_ROUNDS, MAX_VERTEX_RUNS};
pub use report::{
    AdaptiveReport, BlockView, CheckReport, CheckSkipped, DesignPart, ElementSummary,
    ElementsReport, HorizonCheck, PendingStage, PhaseSeconds, Progress, RefinedExtreme,
    RefinementReport, SampleFailure, SampleRetry, StudyReport,
};
pub use schedule::{RecordSchedule, BLOCK_VALUE_BUDGET, MAX_BLOCK_RECORDS};
pub use screening::{DimensionScreening, Screening};
pub use sobol_indices::{
    has_sobol_indices, sobol_values_per_record, SobolBlock, SobolSeries, TABLE_SOBOL_CONTRIBUTORS,
};
pub use sparse::{screened_set, SparseDesign, REGRESSION_OVERSAMPLING, REGRESSION_SEED};
pub use sparse_bounds::{DESIGN_STARTS_PER_SIDE, FRESH_DESIGN_STARTS_PER_SIDE};
pub use stages::{FirstStage, SimulateHere, StageRecords, StageRequest, StageSource};
pub use study::Study;
pub use study_plan::{DesignKind, StudyOptions, StudyPlan};
