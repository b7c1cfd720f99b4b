//! From the values of every sample at one record time to each output's envelope there.
//!
//! - surrogate methods: fit all outputs at once ([`Projector::fit_into`]), then bound each output's
//!   surrogate by scanning (inner), interval arithmetic or its Bernstein form (outer); the error
//!   estimate is the magnitude of the top-order coefficients;
//! - `taylor`: first-order inclusion from the central differences;
//! - `scan`, `monte-carlo`: min and max over the runs.
//!
//! Every method the a-posteriori check follows ([`Method::is_checked`]) also says where its
//! approximation takes each output's extremes ([`Extremes`]): the scans where they found them;
//! the outer methods by scanning the same surrogate beside their bound (the tensor [`Scanner`],
//! the sparse design's [`BoxOptimizer`]); `taylor` at the sign vertices of its linearisation.
//!
//! Every envelope also contains every model run made at that time (the design points and the
//! nominal run are true responses inside the box), so a surrogate's misfit never puts a real run
//! outside its own envelope.

use super::bound_clock::{BoundClock, BoundPhase};
use super::bounded_block::{BoundedBlock, Extremes};
// Re-exported: the path by which elements_phase.rs, scanned_leaf.rs and check_phase.rs name it.
pub(super) use super::envelope::EnvelopePoint;
use super::plan::Plan;
use super::report::PhaseSeconds;
use super::sparse_bounds::{RecordFits, SparseBounds};
use super::Method;
use crate::uq::{
    chebyshev_inclusion, interval_bound, BernsteinBounder, Bound, BoundKind, CoefficientMatrix,
    Projector, RangeMode, ScanOptions, ScanOutcome, Scanner, SobolIndices, Surrogate,
    TaylorStencil, UqError,
};
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// One record's bounds, as a worker computes them.
struct RecordBounds {
    points: Vec<EnvelopePoint>,
    extremes: Vec<Option<Extremes>>,
    /// `outputs × d` main indices, then as many total indices, then `outputs` variances (empty
    /// for methods without a surrogate).
    main_indices: Vec<f64>,
    total_indices: Vec<f64>,
    variances: Vec<f64>,
}

/// Bounds record times for one method; cheap to share across threads.
pub struct Bounder {
    method: Method,
    projector: Option<Projector>,
    stencil: Option<TaylorStencil>,
    scan_options: ScanOptions,
    dim: usize,
    order: usize,
    /// The sparse design's bounds (`None` for other designs).
    sparse: Option<SparseBounds>,
    /// Locate the extremes for the check also where the bound does not need them (outer methods
    /// and `taylor`); the scans always locate them.
    locate_extremes: bool,
    /// The time the workers spent per phase.
    clock: BoundClock,
    /// Record times the sparse design bounds per block when given more at once
    /// ([`Bounder::with_block_records`]).
    block_records: usize,
}

impl Bounder {
    /// A bounder for `method` with the study's `plan`; `scan_grid` overrides the surrogate scan's
    /// points per dimension; `locate_extremes` (a check will run) makes the outer methods and
    /// `taylor` say where their approximation takes its extremes as well.
    pub fn new(
        method: Method,
        plan: &Plan,
        dim: usize,
        order: usize,
        scan_grid: Option<usize>,
        locate_extremes: bool,
    ) -> Result<Bounder, UqError> {
        let mut scan_options = ScanOptions::for_dim(dim);
        if let Some(points) = scan_grid {
            scan_options.points_per_dim = points;
        }
        let (projector, stencil) = match plan {
            Plan::Surrogate(design) => (Some(Projector::new(design.clone())?), None),
            Plan::Taylor(stencil) => (None, Some(*stencil)),
            _ => (None, None),
        };
        let locate_extremes = locate_extremes && method.is_checked();
        let sparse = match plan {
            Plan::Sparse(design) => Some(SparseBounds::new(
                Arc::clone(design),
                method == Method::LegendreIa,
                locate_extremes,
            )),
            _ => None,
        };
        if let (Some(projector), true) = (&projector, method.scans_surrogate() || locate_extremes) {
            // Validate the scan options once, here, rather than in every worker.
            Scanner::new(projector.design().family(), dim, order, scan_options)?;
        }
        Ok(Bounder {
            method,
            projector,
            stencil,
            scan_options,
            dim,
            order,
            sparse,
            locate_extremes,
            clock: BoundClock::default(),
            block_records: usize::MAX,
        })
    }

    /// The same bounder, bounding a sparse design's records `block_records` at a time when
    /// [`Bounder::bound_records`] is given more (all by default): two blocks' values and fits are
    /// in memory at once, and the next block's fits fill the threads while the last side of
    /// this block's inner bound runs (`sparse_bounds.rs`). The results do not depend on it.
    pub fn with_block_records(mut self, block_records: usize) -> Bounder {
        self.block_records = block_records.max(1);
        self
    }

    /// The seconds the workers have spent so far fitting, bounding and computing Sobol' indices
    /// with this bounder, summed over the threads ([`PhaseSeconds`]: only those four phases).
    pub fn phase_seconds(&self) -> PhaseSeconds {
        self.clock.seconds()
    }

    /// Envelopes of `n_outputs` outputs at each of `records` record times. `values(r)` gives record
    /// `r`'s values of the plan's samples (row-major `samples × outputs`), `excluded(i)` whether
    /// sample `i` is left out (only `scan` and `monte-carlo` can leave samples out); `given_fits(r)`,
    /// when given, record `r`'s coefficients of a sparse design's fit, which a caller that has
    /// fitted them already hands over instead of the sparse bounds fitting them again. Returns
    /// `records × outputs` points, record-major, with the predicted extremes.
    pub fn bound_records(
        &self,
        records: usize,
        n_outputs: usize,
        values: &(dyn Fn(usize) -> Vec<f64> + Sync),
        excluded: &(dyn Fn(usize) -> bool + Sync),
        given_fits: Option<&RecordFits<'_>>,
        threads: &rayon::ThreadPool,
    ) -> Result<BoundedBlock, UqError> {
        if let Some(sparse) = &self.sparse {
            return sparse.bound(
                records,
                n_outputs,
                values,
                excluded,
                given_fits,
                self.block_records,
                &self.clock,
                threads,
            );
        }
        let per_record: Vec<Result<RecordBounds, UqError>> = threads.install(|| {
            (0..records)
                .into_par_iter()
                .map_init(
                    || self.workspace(n_outputs),
                    |workspace, r| self.bound_one(&values(r), n_outputs, excluded, workspace),
                )
                .collect()
        });
        let mut out = BoundedBlock {
            points: Vec::with_capacity(records * n_outputs),
            extremes: Vec::with_capacity(records * n_outputs),
            ..BoundedBlock::default()
        };
        for record in per_record {
            let record = record?;
            out.points.extend(record.points);
            out.extremes.extend(record.extremes);
            out.main_indices.extend(record.main_indices);
            out.total_indices.extend(record.total_indices);
            out.variances.extend(record.variances);
        }
        Ok(out)
    }

    fn workspace(&self, n_outputs: usize) -> Workspace {
        match &self.projector {
            Some(projector) => {
                let design = projector.design();
                Workspace {
                    coefficients: Some(CoefficientMatrix::zeros(design.n_terms(), n_outputs)),
                    surrogate: Some(Surrogate::zeros(design)),
                    scanner: (self.method.scans_surrogate() || self.locate_extremes)
                        .then(|| {
                            Scanner::new(design.family(), self.dim, self.order, self.scan_options)
                                .ok()
                        })
                        .flatten(),
                    indices: SobolIndices::zeros(self.dim),
                    bernstein: None,
                }
            }
            None => Workspace {
                coefficients: None,
                surrogate: None,
                scanner: None,
                indices: SobolIndices::zeros(self.dim),
                bernstein: None,
            },
        }
    }

    fn bound_one(
        &self,
        values: &[f64],
        n_outputs: usize,
        excluded: &(dyn Fn(usize) -> bool + Sync),
        workspace: &mut Workspace,
    ) -> Result<RecordBounds, UqError> {
        let mut extremes = vec![None; n_outputs];
        let mut sobol = SobolRows::default();
        let mut points: Vec<EnvelopePoint> = match (&self.projector, &self.stencil) {
            (Some(projector), _) => {
                let (Some(coefficients), Some(surrogate)) =
                    (&mut workspace.coefficients, &mut workspace.surrogate)
                else {
                    return Err(UqError::Empty {
                        what: "analysis workspace",
                    });
                };
                let clock = &self.clock;
                let mut lap = Instant::now();
                projector.fit_into(values, n_outputs, coefficients)?;
                let design = projector.design();
                let mut points = Vec::with_capacity(n_outputs);
                for (o, extreme) in extremes.iter_mut().enumerate() {
                    surrogate.set_from_matrix(design, coefficients, o)?;
                    lap = clock.lap(BoundPhase::Fit, lap);
                    surrogate.sobol_indices_into(&mut workspace.indices)?;
                    sobol.push(&workspace.indices);
                    lap = clock.lap(BoundPhase::Sobol, lap);
                    let bound = match (self.method, &mut workspace.scanner) {
                        (Method::LegendreScan | Method::ChebyshevScan, Some(scanner)) => {
                            let outcome = scanner.scan(surrogate)?;
                            let bound = outcome.bound;
                            *extreme = Some(scanned_extremes(outcome));
                            lap = clock.lap(BoundPhase::Inner, lap);
                            bound
                        }
                        (method, scanner) => {
                            // An outer bound's check: the same surrogate scanned for where it
                            // takes its extremes.
                            if let Some(scanner) = scanner {
                                *extreme = Some(scanned_extremes(scanner.scan(surrogate)?));
                                lap = clock.lap(BoundPhase::Inner, lap);
                            }
                            let bound = outer_bound(method, surrogate, &mut workspace.bernstein)?;
                            lap = clock.lap(BoundPhase::Outer, lap);
                            bound
                        }
                    };
                    points.push(EnvelopePoint {
                        lower: bound.lower,
                        upper: bound.upper,
                        error: Some(bound.error.top_order),
                        outer: None,
                    });
                }
                points
            }
            (None, Some(stencil)) => {
                let bounds = stencil.bounds(values, n_outputs)?;
                if self.locate_extremes {
                    for (o, (extreme, b)) in extremes.iter_mut().zip(&bounds).enumerate() {
                        let (argmin, argmax) = stencil.linear_extremisers(values, n_outputs, o);
                        *extreme = Some(Extremes {
                            argmin,
                            argmax,
                            at_min: b.lower,
                            at_max: b.upper,
                        });
                    }
                }
                bounds
                    .into_iter()
                    .map(|b| EnvelopePoint {
                        lower: b.lower,
                        upper: b.upper,
                        error: Some(b.error.top_order),
                        outer: None,
                    })
                    .collect()
            }
            (None, None) => vec![EnvelopePoint::EMPTY; n_outputs],
        };
        include_runs(&mut points, values, n_outputs, excluded);
        Ok(RecordBounds {
            points,
            extremes,
            main_indices: sobol.main,
            total_indices: sobol.total,
            variances: sobol.variance,
        })
    }
}

/// Widens `points` (one record's outputs) to every run made at that record that is not
/// `excluded`: each is a true response inside the box. `values` is row-major `samples × outputs`.
pub(super) fn include_runs(
    points: &mut [EnvelopePoint],
    values: &[f64],
    n_outputs: usize,
    excluded: &(dyn Fn(usize) -> bool + Sync),
) {
    for (sample, run) in values.chunks_exact(n_outputs.max(1)).enumerate() {
        if excluded(sample) {
            continue;
        }
        for (point, &value) in points.iter_mut().zip(run) {
            point.lower = point.lower.min(value);
            point.upper = point.upper.max(value);
        }
    }
}

/// The extremes a scan of the surrogate found.
fn scanned_extremes(outcome: ScanOutcome) -> Extremes {
    Extremes {
        at_min: outcome.bound.lower,
        at_max: outcome.bound.upper,
        argmin: outcome.argmin,
        argmax: outcome.argmax,
    }
}

/// The outer bound of a tensor surrogate by `method`: its Chebyshev inclusion, its Bernstein form
/// (with the bounder in `bernstein`, made on first use), or interval arithmetic with exact `P_n`
/// ranges.
fn outer_bound(
    method: Method,
    surrogate: &Surrogate,
    bernstein: &mut Option<BernsteinBounder>,
) -> Result<Bound, UqError> {
    match method {
        Method::ChebyshevIa => chebyshev_inclusion(surrogate),
        Method::LegendreBernstein => {
            let b = bernstein
                .get_or_insert_with(BernsteinBounder::default)
                .bound(surrogate)?;
            Ok(Bound {
                lower: b.lower,
                upper: b.upper,
                kind: BoundKind::Outer,
                error: surrogate.error_estimate(),
            })
        }
        _ => interval_bound(surrogate, RangeMode::Exact),
    }
}

struct Workspace {
    coefficients: Option<CoefficientMatrix>,
    surrogate: Option<Surrogate>,
    scanner: Option<Scanner>,
    /// One surrogate's Sobol' indices.
    indices: SobolIndices,
    /// `legendre-bernstein`: the bounder (made on first use).
    bernstein: Option<BernsteinBounder>,
}

/// One record's Sobol' indices, output after output.
#[derive(Default)]
struct SobolRows {
    main: Vec<f64>,
    total: Vec<f64>,
    variance: Vec<f64>,
}

impl SobolRows {
    fn push(&mut self, indices: &SobolIndices) {
        self.main.extend_from_slice(&indices.main);
        self.total.extend_from_slice(&indices.total);
        self.variance.push(indices.variance);
    }
}
