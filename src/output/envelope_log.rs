//! An MCAP log of envelopes, one record time at a time: a channel per output (lower, nominal,
//! upper), optionally an error-estimate channel per output and two Sobol' index channels per output
//! (main, total; docs/sobol-indices.md §5), the hull of true runs per output when the block
//! carries it (an untrusted study's, docs/mcap.md §1), and the nominal robot's frames on `/tf`.
//! Used by `simulate` (lower = nominal = upper) and `analyze`. On [`finish`](EnvelopeLog::finish)
//! it adds what the viewers need (docs/mcap.md §4–§5): the Foxglove layout as an attachment (an
//! untrusted output's plot titled as such, its true runs beside the envelope) and the box the
//! robot moved in as entries of the `ribbon` metadata record.

use super::error::OutputError;
use super::mcap::{
    EnvelopeChannel, ErrorChannel, McapMetadata, McapSink, OutputName, ParentFromLink, RunsChannel,
    SobolChannel, SobolIndexKind, ENVELOPE_PREFIX, RUNS_PREFIX, SOBOL_PREFIX, WORLD_FRAME,
};
use super::verdict::UntrustedVerdict;
use super::viewer::{
    foxglove_layout, LayoutOutput, LayoutSensitivity, LayoutUntrusted, SceneExtent,
    FOXGLOVE_LAYOUT_NAME, SENSITIVITY_COLOURS,
};
use crate::analysis::BlockView;
use crate::dynamics::{forward_kinematics, world_from_link, Data};
use crate::model::Model;
use crate::scene::Output;
use std::path::Path;

/// The smallest peak total Sobol' index (over the record times) of a parameter that an output's
/// sensitivity plot shows: a parameter that never explains 1 % of the output's variance only
/// crowds the plot.
pub const SENSITIVITY_PLOT_FLOOR: f64 = 0.01;

/// The dimensions an output's sensitivity plot shows, from each dimension's peak total Sobol'
/// index over the record times: those reaching [`SENSITIVITY_PLOT_FLOOR`], largest peak first
/// (ties by dimension order), at most as many as there are sensitivity colours. The log's layout
/// and the report page plot the same ones.
pub fn plotted_dimensions(peaks: &[f64]) -> Vec<usize> {
    let mut ranked: Vec<usize> = (0..peaks.len())
        .filter(|&j| peaks[j] >= SENSITIVITY_PLOT_FLOOR)
        .collect();
    ranked.sort_by(|&a, &b| peaks[b].total_cmp(&peaks[a]).then(a.cmp(&b)));
    ranked.truncate(SENSITIVITY_COLOURS.len());
    ranked
}

/// An open envelope log.
pub struct EnvelopeLog {
    sink: McapSink,
    /// Output names, in channel order (for messages).
    names: Vec<String>,
    channels: Vec<EnvelopeChannel>,
    error_channels: Vec<ErrorChannel>,
    /// Per output, its main and total Sobol' index channels (empty unless
    /// [`add_sobol_channels`](EnvelopeLog::add_sobol_channels) was called).
    sobol_channels: Vec<(SobolChannel, SobolChannel)>,
    /// The box's dimension names (the Sobol' channels' series), empty without Sobol' channels.
    sobol_dimensions: Vec<String>,
    /// Per output, per dimension, the largest total Sobol' index written so far: which
    /// parameters the layout's sensitivity plots show.
    sobol_peaks: Vec<Vec<f64>>,
    /// Per output, the channel of its hull of true runs (empty until a block carries the hull).
    runs_channels: Vec<RunsChannel>,
    /// The check's verdict, when it did not trust the study ([`set_verdict`](Self::set_verdict)).
    verdict: Option<UntrustedVerdict>,
    /// What the Foxglove layout plots, in channel order.
    layout_outputs: Vec<LayoutOutput>,
    /// The box of every link origin written to `/tf`.
    extent: SceneExtent,
    /// Per URDF link, its parent link (the parent of the joint whose child it is); `None` for a
    /// root. Filled by the first [`write_frames`](EnvelopeLog::write_frames).
    parent_links: Option<Vec<Option<usize>>>,
}

fn mcap_error(error: super::mcap::McapError) -> OutputError {
    OutputError::Mcap(error)
}

/// Reads a file named in the log's attachments.
fn read_text(path: &Path, what: &str) -> Result<String, OutputError> {
    std::fs::read_to_string(path).map_err(|source| OutputError::Write {
        what: format!("{what} '{}' for the MCAP attachment", path.display()),
        source,
    })
}

impl EnvelopeLog {
    /// Creates the log at `path` (written to a temporary file beside it until
    /// [`finish`](Self::finish)), with the
    /// URDF and the sidecar attached, one channel per output and, when `with_errors`, one
    /// error-estimate channel per output.
    pub fn create(
        path: &Path,
        urdf: &Path,
        sidecar: Option<&Path>,
        metadata: McapMetadata,
        outputs: &[Output],
        with_errors: bool,
    ) -> Result<EnvelopeLog, OutputError> {
        let urdf_text = read_text(urdf, "URDF")?;
        let sidecar_text = sidecar.map(|p| read_text(p, "sidecar")).transpose()?;
        let name_of = |p: &Path| {
            p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            )
        };
        let sidecar_pair = sidecar
            .zip(sidecar_text.as_deref())
            .map(|(p, text)| (name_of(p), text));
        let mut sink = McapSink::create(
            path,
            &name_of(urdf),
            &urdf_text,
            sidecar_pair
                .as_ref()
                .map(|(name, text)| (name.as_str(), *text)),
            metadata,
        )
        .map_err(mcap_error)?;
        let mut channels = Vec::with_capacity(outputs.len());
        let mut error_channels = Vec::new();
        for output in outputs {
            channels.push(
                sink.add_output(OutputName::from_parts(&output.parts), output.unit)
                    .map_err(mcap_error)?,
            );
            if with_errors {
                error_channels.push(
                    sink.add_error_channel(OutputName::from_parts(&output.parts), output.unit)
                        .map_err(mcap_error)?,
                );
            }
        }
        let layout_outputs = outputs
            .iter()
            .map(|output| LayoutOutput {
                name: output.name.clone(),
                parts: output.parts.clone(),
                unit: output.unit.to_string(),
                topic: format!(
                    "{ENVELOPE_PREFIX}{}",
                    OutputName::from_parts(&output.parts).topic_suffix()
                ),
                sensitivity: None,
                untrusted: None,
            })
            .collect();
        Ok(EnvelopeLog {
            sink,
            names: outputs.iter().map(|o| o.name.clone()).collect(),
            channels,
            error_channels,
            sobol_channels: Vec::new(),
            sobol_dimensions: Vec::new(),
            sobol_peaks: Vec::new(),
            runs_channels: Vec::new(),
            verdict: None,
            layout_outputs,
            extent: SceneExtent::default(),
            parent_links: None,
        })
    }

    /// Adds the main and total Sobol' index channels of every output (docs/mcap.md §1), one series
    /// per dimension of the box named by `dimensions`; [`write_block`](Self::write_block) then
    /// writes the indices a block carries. Call before the first block.
    pub fn add_sobol_channels(&mut self, dimensions: &[String]) -> Result<(), OutputError> {
        for output in &self.layout_outputs {
            let name = OutputName::from_parts(&output.parts);
            let main = self
                .sink
                .add_sobol_channel(SobolIndexKind::Main, name.clone(), dimensions)
                .map_err(mcap_error)?;
            let total = self
                .sink
                .add_sobol_channel(SobolIndexKind::Total, name, dimensions)
                .map_err(mcap_error)?;
            self.sobol_channels.push((main, total));
            self.sobol_peaks.push(vec![0.0; dimensions.len()]);
        }
        self.sobol_dimensions = dimensions.to_vec();
        Ok(())
    }

    /// Writes one record time's Sobol' indices: `main(o)` and `total(o)` give output o's indices.
    /// A NaN or infinity is refused as in [`write_time`](Self::write_time).
    fn write_sobol(
        &mut self,
        t: f64,
        main: &dyn Fn(usize) -> Vec<f64>,
        total: &dyn Fn(usize) -> Vec<f64>,
    ) -> Result<(), OutputError> {
        for o in 0..self.sobol_channels.len() {
            let (main_channel, total_channel) = self.sobol_channels[o];
            for (label, channel, values) in [
                ("main Sobol' index", main_channel, main(o)),
                ("total Sobol' index", total_channel, total(o)),
            ] {
                if let Some(value) = values.iter().find(|v| !v.is_finite()) {
                    return Err(OutputError::NonFinite {
                        what: format!("MCAP '{}'", self.sink.path().display()),
                        output: format!(
                            "{} ({label})",
                            self.names.get(o).map_or("?", String::as_str)
                        ),
                        time_s: t,
                        value: *value,
                    });
                }
                self.sink
                    .write_sobol(channel, t, &values)
                    .map_err(mcap_error)?;
                if channel == total_channel {
                    for (peak, value) in self.sobol_peaks[o].iter_mut().zip(&values) {
                        *peak = peak.max(*value);
                    }
                }
            }
        }
        Ok(())
    }

    /// Writes every output's envelope at time `t` (s); `error` per output when the log has error
    /// channels. A NaN or infinity is refused ([`OutputError::NonFinite`], naming the output and
    /// time): the log is then never finished, and its temporary file is removed when dropped.
    pub fn write_time(
        &mut self,
        t: f64,
        lower: &[f64],
        nominal: &[f64],
        upper: &[f64],
        error: Option<&[f64]>,
    ) -> Result<(), OutputError> {
        let series: [(&str, &[f64]); 4] = [
            ("lower", lower),
            ("nominal", nominal),
            ("upper", upper),
            ("error estimate", error.unwrap_or(&[])),
        ];
        for (label, values) in series {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(OutputError::NonFinite {
                    what: format!("MCAP '{}'", self.sink.path().display()),
                    output: format!(
                        "{} ({label})",
                        self.names.get(i).map_or("?", String::as_str)
                    ),
                    time_s: t,
                    value: values[i],
                });
            }
        }
        for (i, channel) in self.channels.iter().enumerate() {
            self.sink
                .write_envelope(*channel, t, lower[i], nominal[i], upper[i])
                .map_err(mcap_error)?;
        }
        if let Some(error) = error {
            for (channel, value) in self.error_channels.iter().zip(error) {
                self.sink
                    .write_error(*channel, t, *value)
                    .map_err(mcap_error)?;
            }
        }
        Ok(())
    }

    /// Writes every URDF link's placement on `/tf` at time `t`, from the body placements of the
    /// last forward kinematics in `data`: each link relative to its parent link in the URDF tree
    /// (the root relative to `world`), so that the viewers' frame trees follow the kinematic chain.
    pub fn write_frames(&mut self, t: f64, model: &Model, data: &Data) -> Result<(), OutputError> {
        let links = &model.description.links;
        let parents = self.parent_links.get_or_insert_with(|| {
            let mut parents = vec![None; links.len()];
            for joint in &model.description.joints {
                if let Some(slot) = parents.get_mut(joint.child) {
                    slot.get_or_insert(joint.parent);
                }
            }
            parents
        });
        let world_from_links: Vec<crate::spatial::Transform> = (0..links.len())
            .map(|l| world_from_link(model, data, l))
            .collect();
        let mut frames = Vec::with_capacity(links.len());
        for (l, world_from_link) in world_from_links.iter().enumerate() {
            let translation = world_from_link.translation;
            self.extent
                .include([translation.x, translation.y, translation.z]);
            let (parent, parent_from_link) = match parents[l] {
                Some(p) => (
                    links[p].name.as_str(),
                    world_from_links[p].inverse().compose(world_from_link),
                ),
                None => (WORLD_FRAME, *world_from_link),
            };
            let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(
                &nalgebra::Rotation3::from_matrix_unchecked(parent_from_link.rotation),
            );
            frames.push(ParentFromLink {
                parent,
                link: &links[l].name,
                translation_m: [
                    parent_from_link.translation.x,
                    parent_from_link.translation.y,
                    parent_from_link.translation.z,
                ],
                rotation_xyzw: [rotation.i, rotation.j, rotation.k, rotation.w],
            });
        }
        self.sink.write_transforms(t, &frames).map_err(mcap_error)
    }

    /// Adds the channel of every output's hull of true runs (docs/mcap.md §1), once.
    fn add_runs_channels(&mut self) -> Result<(), OutputError> {
        if !self.runs_channels.is_empty() {
            return Ok(());
        }
        for output in &self.layout_outputs {
            let channel = self
                .sink
                .add_runs_channel(OutputName::from_parts(&output.parts), &output.unit)
                .map_err(mcap_error)?;
            self.runs_channels.push(channel);
        }
        Ok(())
    }

    /// Writes every output's hull of true runs at time `t` (s): `hull[o]` = (lowest, highest). A
    /// NaN or infinity is refused as in [`write_time`](Self::write_time).
    fn write_runs(&mut self, t: f64, hull: &[(f64, f64)]) -> Result<(), OutputError> {
        if let Some(o) = hull
            .iter()
            .position(|(lowest, highest)| !(lowest.is_finite() && highest.is_finite()))
        {
            let (lowest, highest) = hull[o];
            return Err(OutputError::NonFinite {
                what: format!("MCAP '{}'", self.sink.path().display()),
                output: format!(
                    "{} (hull of true runs)",
                    self.names.get(o).map_or("?", String::as_str)
                ),
                time_s: t,
                value: if lowest.is_finite() { highest } else { lowest },
            });
        }
        for (channel, &(lowest, highest)) in self.runs_channels.iter().zip(hull) {
            self.sink
                .write_runs(*channel, t, lowest, highest)
                .map_err(mcap_error)?;
        }
        Ok(())
    }

    /// Writes one block of a study: every record time's envelopes (and error estimates, where the
    /// method has them; the hull of true runs, where the block carries it; Sobol' indices, where
    /// the block has them and the log has their channels) and the nominal robot's frames, placed
    /// by forward kinematics of the nominal run's configuration into `data`. Every message of a
    /// record time is written before the next time's, so a reader gets them in time order.
    pub fn write_block(
        &mut self,
        block: &BlockView,
        model: &Model,
        data: &mut Data,
    ) -> Result<(), OutputError> {
        let n = self.channels.len();
        let nq = model.nq;
        if block.runs_hull.is_some() {
            self.add_runs_channels()?;
        }
        for (r, t) in block.times.iter().enumerate() {
            let points = &block.points[r * n..(r + 1) * n];
            let lower: Vec<f64> = points.iter().map(|p| p.lower).collect();
            let upper: Vec<f64> = points.iter().map(|p| p.upper).collect();
            let errors: Option<Vec<f64>> = points.iter().map(|p| p.error).collect();
            self.write_time(
                *t,
                &lower,
                &block.nominal[r * n..(r + 1) * n],
                &upper,
                errors.as_deref(),
            )?;
            if let Some(hull) = block.runs_hull {
                self.write_runs(*t, &hull[r * n..(r + 1) * n])?;
            }
            if let (Some(sobol), false) = (&block.sobol, self.sobol_channels.is_empty()) {
                self.write_sobol(*t, &|o| sobol.main(r, n, o).to_vec(), &|o| {
                    sobol.total(r, n, o).to_vec()
                })?;
            }
            forward_kinematics(model, data, &block.nominal_positions[r * nq..(r + 1) * nq]);
            self.write_frames(*t, model, data)?;
        }
        Ok(())
    }

    /// Adds entries to the `ribbon` metadata record written at the end (e.g. `elements`: the
    /// elements a split study made, as the summary's JSON).
    pub fn add_metadata(
        &mut self,
        entries: std::collections::BTreeMap<String, String>,
    ) -> Result<(), OutputError> {
        self.sink.add_metadata_entries(entries).map_err(mcap_error)
    }

    /// Records the check's verdict on a study it did not trust: the `check` entry of the `ribbon`
    /// metadata record, and the titles of the untrusted outputs' plots in the Foxglove layout
    /// (with their true runs beside the envelope when the log has the hull's channels).
    pub fn set_verdict(&mut self, verdict: UntrustedVerdict) -> Result<(), OutputError> {
        self.sink
            .add_metadata_entries(verdict.metadata())
            .map_err(mcap_error)?;
        self.verdict = Some(verdict);
        Ok(())
    }

    /// The metadata to be written at the end (e.g. to correct `runs` after an interruption).
    pub fn metadata_mut(&mut self) -> &mut McapMetadata {
        self.sink.metadata_mut()
    }

    /// The Foxglove layout of this log (docs/mcap.md §4): one plot per output, grouped in tabs,
    /// and the robot with a camera framing every link origin written so far.
    pub fn foxglove_layout(&self) -> serde_json::Value {
        let mut outputs = self.layout_outputs.clone();
        for (o, output) in outputs.iter_mut().enumerate() {
            output.sensitivity = self.sensitivity(o, output);
            output.untrusted = self.untrusted(o, output);
        }
        foxglove_layout(&outputs, &self.extent)
    }

    /// How output `o`'s plot says that the check did not trust it: its relative misfit, and the
    /// topic of its hull of true runs when the log has it; `None` for a trusted output.
    fn untrusted(&self, o: usize, output: &LayoutOutput) -> Option<LayoutUntrusted> {
        let relative_misfit = (*self.verdict.as_ref()?.untrusted_misfit.get(o)?)?;
        Some(LayoutUntrusted {
            relative_misfit,
            runs_topic: (!self.runs_channels.is_empty()).then(|| {
                format!(
                    "{RUNS_PREFIX}{}",
                    OutputName::from_parts(&output.parts).topic_suffix()
                )
            }),
        })
    }

    /// What output `o`'s sensitivity plot shows: the parameters whose total Sobol' index reached
    /// [`SENSITIVITY_PLOT_FLOOR`] at some record time, largest peak first (ties by dimension
    /// order), at most as many as there are sensitivity colours; `None` without Sobol' channels.
    fn sensitivity(&self, o: usize, output: &LayoutOutput) -> Option<LayoutSensitivity> {
        let peaks = self.sobol_peaks.get(o)?;
        let ranked = plotted_dimensions(peaks);
        Some(LayoutSensitivity {
            topic: format!(
                "{SOBOL_PREFIX}{}/{}",
                SobolIndexKind::Total.name(),
                OutputName::from_parts(&output.parts).topic_suffix()
            ),
            parameters: ranked
                .into_iter()
                .map(|j| (j, self.sobol_dimensions[j].clone()))
                .collect(),
        })
    }

    /// Writes the viewer facts (the Foxglove layout as the attachment `foxglove-layout.json`, the
    /// scene extent as `scene_centre_m` / `scene_radius_m` in the `ribbon` metadata record), the
    /// metadata record, summary and index, and renames the file into place.
    pub fn finish(mut self, partial: bool) -> Result<(), OutputError> {
        // `{:#}` pretty-prints a JSON value (infallible, unlike `to_vec_pretty`'s signature).
        let layout = format!("{:#}", self.foxglove_layout());
        self.sink
            .attach(FOXGLOVE_LAYOUT_NAME, "application/json", layout.as_bytes())
            .map_err(mcap_error)?;
        self.sink
            .add_metadata_entries(self.extent.metadata())
            .map_err(mcap_error)?;
        self.sink.finish(partial).map_err(mcap_error)
    }
}
