//! A study's MCAP log around its blocks: what the log says before the first block ([`LogHeader`],
//! from the plan), how it is closed ([`close_log`], from the report), and the finished blocks kept
//! in memory ([`RecordedBlocks`]) so that a log can be written after the study (the Python
//! package's `StudyResult.write_mcap`) with the bytes `analyze --out` writes while it runs.
//!
//! ```text
//! plan ⇒ LogHeader ⇒ open ⇒ blocks (streamed by the study, or replayed by RecordedBlocks;
//!   an untrusted study's carry the hull of its true runs) ⇒ close_log (runs, elements, the
//!   check's verdict on an untrusted study, partial)
//! ```
//!
//! Does not: format MCAP (`output::EnvelopeLog`), or run anything.

use super::options::order_of;
use crate::analysis::{
    has_sobol_indices, BlockView, EnvelopePoint, Method, SobolSeries, StudyOptions, StudyPlan,
    StudyReport,
};
use crate::output::mcap::McapMetadata;
use crate::output::{EnvelopeLog, ParameterSummary, UntrustedVerdict};
use crate::scene::Output;
use crate::uncertainty::ParameterSpace;
use crate::Error;
use std::path::Path;

/// What a study's MCAP log says before its first block: the metadata, whether the method has
/// error estimates, and the parameters' names when it has Sobol' indices.
#[derive(Clone, Debug)]
pub struct LogHeader {
    /// The `ribbon` metadata record (its `runs` corrected by [`close_log`]).
    pub metadata: McapMetadata,
    /// Whether the log has error-estimate channels (surrogate methods and taylor).
    pub with_errors: bool,
    /// The parameters' names, when the log has Sobol' channels.
    pub sobol_names: Option<Vec<String>>,
}

impl LogHeader {
    /// The header of the log of a study planned as `plan` with `options` over `space`.
    pub fn of_plan(
        robot: &str,
        plan: &StudyPlan,
        options: &StudyOptions,
        space: &ParameterSpace,
    ) -> LogHeader {
        LogHeader {
            metadata: McapMetadata {
                robot: robot.to_string(),
                method: plan.method.name().to_string(),
                order: order_of(plan.method, options),
                runs: plan.max_runs(),
                parameters_json: serde_json::to_string(&ParameterSummary::of_space(space))
                    .unwrap_or_else(|_| "[]".to_string()),
            },
            with_errors: plan.method.family().is_some() || plan.method == Method::Taylor,
            sobol_names: has_sobol_indices(plan.method)
                .then(|| space.dimensions().iter().map(|d| d.name.clone()).collect()),
        }
    }

    /// Creates the log at `path` (the URDF and sidecar embedded) with its channels.
    pub fn open(
        &self,
        path: &Path,
        urdf: &Path,
        sidecar: &Path,
        outputs: &[Output],
    ) -> Result<EnvelopeLog, Error> {
        let mut log = EnvelopeLog::create(
            path,
            urdf,
            Some(sidecar),
            self.metadata.clone(),
            outputs,
            self.with_errors,
        )?;
        if let Some(names) = &self.sobol_names {
            log.add_sobol_channels(names)?;
        }
        Ok(log)
    }
}

/// Closes a study's log: the runs made, the elements (when the box was split), the check's
/// verdict (when it did not trust the study: the `check` metadata entry, the untrusted outputs'
/// plot titles) and whether the study stopped early. Returns the Foxglove layout it attached
/// (docs/mcap.md §4), for the report directory.
pub fn close_log(
    mut log: EnvelopeLog,
    report: &StudyReport,
    space: &ParameterSpace,
) -> Result<serde_json::Value, Error> {
    log.metadata_mut().runs = report.runs;
    if let Some(elements) = &report.elements {
        let json = crate::output::elements_json(elements, space, &report.envelope);
        log.add_metadata([("elements".to_string(), json.to_string())].into())?;
    }
    if let Some(verdict) = UntrustedVerdict::of_report(report) {
        log.set_verdict(verdict)?;
    }
    let layout = log.foxglove_layout();
    log.finish(report.partial)?;
    Ok(layout)
}

/// The finished blocks a study handed its sink, kept (the Sobol' indices stay in the report).
#[derive(Clone, Debug, Default)]
pub struct RecordedBlocks {
    /// Each block's first record and record count.
    ranges: Vec<(usize, usize)>,
    times: Vec<f64>,
    points: Vec<EnvelopePoint>,
    nominal: Vec<f64>,
    nominal_positions: Vec<f64>,
    /// Each block's range of `nominal_positions`.
    position_ranges: Vec<std::ops::Range<usize>>,
    /// The blocks' hull of true runs, `records × outputs`, when they carry it (every block of a
    /// study does, or none).
    runs_hull: Option<Vec<(f64, f64)>>,
}

impl RecordedBlocks {
    /// Keeps a copy of `block`.
    pub fn record(&mut self, block: &BlockView) {
        self.ranges.push((block.first_record, block.times.len()));
        self.times.extend_from_slice(block.times);
        self.points.extend_from_slice(block.points);
        self.nominal.extend_from_slice(block.nominal);
        let start = self.nominal_positions.len();
        self.nominal_positions
            .extend_from_slice(block.nominal_positions);
        self.position_ranges
            .push(start..self.nominal_positions.len());
        if let Some(hull) = block.runs_hull {
            self.runs_hull
                .get_or_insert_with(Vec::new)
                .extend_from_slice(hull);
        }
    }

    /// Hands every kept block to `sink` again, in order, with its Sobol' indices from `sobol`
    /// (the report's).
    pub fn replay<E>(
        &self,
        n_outputs: usize,
        sobol: Option<&SobolSeries>,
        sink: &mut dyn FnMut(&BlockView) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut done = 0;
        for (&(first, count), positions) in self.ranges.iter().zip(&self.position_ranges) {
            sink(&BlockView {
                first_record: first,
                times: &self.times[done..done + count],
                points: &self.points[done * n_outputs..(done + count) * n_outputs],
                nominal: &self.nominal[done * n_outputs..(done + count) * n_outputs],
                nominal_positions: &self.nominal_positions[positions.clone()],
                sobol: sobol.and_then(|s| s.block(first, count)),
                runs_hull: self
                    .runs_hull
                    .as_ref()
                    .map(|hull| &hull[done * n_outputs..(done + count) * n_outputs]),
            })?;
            done += count;
        }
        Ok(())
    }
}
