//! From the values of every sample at one record time to each output's envelope there.
//!
//! - surrogate methods: fit all outputs at once ([`Projector::fit_into`]), then bound each output's
//!   surrogate by scanning (inner) or interval arithmetic (outer); the error estimate is the
//!   magnitude of the top-order coefficients;
//! - `taylor`: first-order inclusion from the central differences;
//! - `scan`, `monte-carlo`: min and max over the runs.
//!
//! Every envelope also contains every model run made at that time (the design points and the
//! nominal run are true responses inside the box), so a surrogate's misfit never puts a real run
//! outside its own envelope.

use super::plan::Plan;
use super::Method;
use crate::uq::{
    chebyshev_inclusion, interval_bound, CoefficientMatrix, Projector, RangeMode, ScanOptions,
    Scanner, Surrogate, TaylorStencil, UqError,
};
use rayon::prelude::*;

/// One output's envelope at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvelopePoint {
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
    /// Error estimate, where the method has one.
    pub error: Option<f64>,
}

/// Where a surrogate predicts one output's extremes at one time (methods that locate them: the
/// surrogate scans). The a-posteriori check runs the true model there.
#[derive(Clone, Debug, PartialEq)]
pub struct Extremes {
    /// Where the surrogate takes its minimum (standard coordinates, length d).
    pub argmin: Vec<f64>,
    /// Where it takes its maximum.
    pub argmax: Vec<f64>,
    /// The surrogate's minimum (before the envelope takes in the model runs).
    pub at_min: f64,
    /// The surrogate's maximum.
    pub at_max: f64,
}

/// The envelopes of one block: `records × outputs` points, record-major, and beside each the
/// predicted extremes where the method locates them.
#[derive(Clone, Debug, Default)]
pub struct BoundedBlock {
    /// Envelope points, record-major.
    pub points: Vec<EnvelopePoint>,
    /// Predicted extremes, record-major (`None` where the method does not locate them).
    pub extremes: Vec<Option<Extremes>>,
}

/// Bounds record times for one method; cheap to share across threads.
pub struct Bounder {
    method: Method,
    projector: Option<Projector>,
    stencil: Option<TaylorStencil>,
    scan_options: ScanOptions,
    dim: usize,
    order: usize,
}

impl Bounder {
    /// A bounder for `method` with the study's `plan`; `scan_grid` overrides the surrogate scan's
    /// points per dimension.
    pub fn new(
        method: Method,
        plan: &Plan,
        dim: usize,
        order: usize,
        scan_grid: Option<usize>,
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
        if let (Some(projector), true) = (&projector, method.scans_surrogate()) {
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
        })
    }

    /// Envelopes of `n_outputs` outputs at each of `records` record times. `values(r)` gives record
    /// `r`'s values of the plan's samples (row-major `samples × outputs`), `excluded(i)` whether
    /// sample `i` is left out (only `scan` and `monte-carlo` can leave samples out). Returns
    /// `records × outputs` points, record-major, with the predicted extremes.
    pub fn bound_records(
        &self,
        records: usize,
        n_outputs: usize,
        values: &(dyn Fn(usize) -> Vec<f64> + Sync),
        excluded: &(dyn Fn(usize) -> bool + Sync),
        threads: &rayon::ThreadPool,
    ) -> Result<BoundedBlock, UqError> {
        type Record = (Vec<EnvelopePoint>, Vec<Option<Extremes>>);
        let per_record: Vec<Result<Record, UqError>> = threads.install(|| {
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
        };
        for record in per_record {
            let (points, extremes) = record?;
            out.points.extend(points);
            out.extremes.extend(extremes);
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
                    scanner: self
                        .method
                        .scans_surrogate()
                        .then(|| {
                            Scanner::new(design.family(), self.dim, self.order, self.scan_options)
                                .ok()
                        })
                        .flatten(),
                }
            }
            None => Workspace {
                coefficients: None,
                surrogate: None,
                scanner: None,
            },
        }
    }

    fn bound_one(
        &self,
        values: &[f64],
        n_outputs: usize,
        excluded: &(dyn Fn(usize) -> bool + Sync),
        workspace: &mut Workspace,
    ) -> Result<(Vec<EnvelopePoint>, Vec<Option<Extremes>>), UqError> {
        let n_samples = values.len() / n_outputs.max(1);
        let mut extremes = vec![None; n_outputs];
        let mut points: Vec<EnvelopePoint> = match (&self.projector, &self.stencil) {
            (Some(projector), _) => {
                let (Some(coefficients), Some(surrogate)) =
                    (&mut workspace.coefficients, &mut workspace.surrogate)
                else {
                    return Err(UqError::Empty {
                        what: "analysis workspace",
                    });
                };
                projector.fit_into(values, n_outputs, coefficients)?;
                let design = projector.design();
                let mut points = Vec::with_capacity(n_outputs);
                for (o, extreme) in extremes.iter_mut().enumerate() {
                    surrogate.set_from_matrix(design, coefficients, o)?;
                    let bound = match (self.method, &mut workspace.scanner) {
                        (Method::LegendreScan | Method::ChebyshevScan, Some(scanner)) => {
                            let outcome = scanner.scan(surrogate)?;
                            *extreme = Some(Extremes {
                                at_min: outcome.bound.lower,
                                at_max: outcome.bound.upper,
                                argmin: outcome.argmin,
                                argmax: outcome.argmax,
                            });
                            outcome.bound
                        }
                        (Method::ChebyshevIa, _) => chebyshev_inclusion(surrogate)?,
                        _ => interval_bound(surrogate, RangeMode::Exact)?,
                    };
                    points.push(EnvelopePoint {
                        lower: bound.lower,
                        upper: bound.upper,
                        error: Some(bound.error.top_order),
                    });
                }
                points
            }
            (None, Some(stencil)) => stencil
                .bounds(values, n_outputs)?
                .into_iter()
                .map(|b| EnvelopePoint {
                    lower: b.lower,
                    upper: b.upper,
                    error: Some(b.error.top_order),
                })
                .collect(),
            (None, None) => vec![
                EnvelopePoint {
                    lower: f64::INFINITY,
                    upper: f64::NEG_INFINITY,
                    error: None,
                };
                n_outputs
            ],
        };
        // Every run made is a true response inside the box: include it.
        for sample in 0..n_samples {
            if excluded(sample) {
                continue;
            }
            for (o, point) in points.iter_mut().enumerate() {
                let value = values[sample * n_outputs + o];
                point.lower = point.lower.min(value);
                point.upper = point.upper.max(value);
            }
        }
        Ok((points, extremes))
    }
}

struct Workspace {
    coefficients: Option<CoefficientMatrix>,
    surrogate: Option<Surrogate>,
    scanner: Option<Scanner>,
}
