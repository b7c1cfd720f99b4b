//! The summary JSON (design contract): robot, method, parameters, runs, and per output the time
//! series of lower, upper and nominal bounds with an error estimate; for surrogate studies also the
//! Sobol' indices of every output at every record time (`sobol_indices`, docs/sobol-indices.md §5).

use super::error::OutputError;
use super::first_non_finite;
use super::paths::AtomicFile;
use crate::analysis::{widest_record, Envelope, SobolSeries};
use crate::uncertainty::ParameterSpace;
use serde::Serialize;
use std::path::Path;

/// One interval parameter (one dimension of the box) as the summary lists it.
#[derive(Clone, Debug, Serialize)]
pub struct ParameterSummary {
    /// Path, free symbol, or the pattern key of a shared group.
    pub name: String,
    /// Lower bound (in `unit`).
    pub lower: f64,
    /// Upper bound (in `unit`).
    pub upper: f64,
    /// Nominal value (URDF value, the symbol's midpoint, 1 for a shared factor, 0 for a shared
    /// offset).
    pub nominal: f64,
    /// The sidecar key it came from: the name itself, or the pattern key (added to the contract's
    /// `{name, lower, upper, nominal}`).
    pub source: String,
    /// The unit of the bounds (`kg`, `m`, …; `""` for unitless values, symbols and factors).
    pub unit: String,
}

/// How much one parameter moves the outputs (the summary's `sensitivities`, ranked).
#[derive(Clone, Debug, Serialize)]
pub struct SensitivitySummary {
    /// The dimension's name.
    pub name: String,
    /// 1 for the most influential.
    pub rank: usize,
    /// Screening: the largest secant slope `|y(e_j) − y(−e_j)|/2` over outputs and times, relative
    /// to the output's largest envelope width.
    pub relative_slope: Option<f64>,
    /// The output where `relative_slope` is attained.
    pub slope_output: Option<String>,
    /// Screening: the largest share of an output's one-at-a-time spread.
    pub importance: Option<f64>,
    /// Sparse surrogates: the largest total Sobol' index over outputs and times.
    pub total_index: Option<f64>,
    /// The output where `total_index` is attained.
    pub total_index_output: Option<String>,
    /// The time where `total_index` is attained, s.
    pub total_index_time: Option<f64>,
}

/// One output's envelope over time.
#[derive(Clone, Debug, Serialize)]
pub struct EnvelopeSeries {
    /// Output name (`q.elbow_joint`).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Record times, s.
    pub time: Vec<f64>,
    /// Lower bound per time.
    pub lower: Vec<f64>,
    /// Upper bound per time.
    pub upper: Vec<f64>,
    /// The run at the nominal parameters.
    pub nominal: Vec<f64>,
    /// Error estimate per time; `null` where the method has none (a nominal run).
    pub error_estimate: Option<Vec<f64>>,
    /// An outer bound of the surrogate beside the inner one (sparse designs), per time; absent
    /// otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub outer_lower: Option<Vec<f64>>,
    /// Upper counterpart of `outer_lower`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub outer_upper: Option<Vec<f64>>,
    /// A study's: the smallest value any of its true-model runs took, per time (design, nominal,
    /// screening and check runs; `lower` ≤ it always). Absent for one run (`simulate`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub runs_lower: Option<Vec<f64>>,
    /// Upper counterpart of `runs_lower` (≤ `upper`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub runs_upper: Option<Vec<f64>>,
}

/// One dimension of the box as the Sobol' indices name it.
#[derive(Clone, Debug, Serialize)]
pub struct SobolDimension {
    /// The dimension's name (a path, a symbol, or a shared group's pattern key), as in
    /// `parameters`.
    pub name: String,
    /// The `[parameters]` key it came from.
    pub source: String,
}

/// One output's Sobol' indices over time (index `[k][j]`: record time k, dimension j).
#[derive(Clone, Debug, Serialize)]
pub struct OutputSobol {
    /// Output name, as in `outputs`.
    pub name: String,
    /// The surrogate's variance under uniform ξ per record time, in the output's unit squared.
    pub variance: Vec<f64>,
    /// Main indices, `[record][dimension]`.
    pub main: Vec<Vec<f64>>,
    /// Total indices, `[record][dimension]`.
    pub total: Vec<Vec<f64>>,
    /// The record time of the output's widest envelope, s (`null` without records).
    pub widest_time: Option<f64>,
    /// Main indices there.
    pub widest_main: Option<Vec<f64>>,
    /// Total indices there.
    pub widest_total: Option<Vec<f64>>,
}

/// The summary's `sobol_indices`: variance-based sensitivity of every output's surrogate at every
/// record time, per dimension of the box (docs/sobol-indices.md §5).
#[derive(Clone, Debug, Serialize)]
pub struct SobolSummary {
    /// The dimensions, in index order (shared groups are one dimension; `[bind]`-bound parameters
    /// have none).
    pub dimensions: Vec<SobolDimension>,
    /// Per output, in `outputs` order.
    pub outputs: Vec<OutputSobol>,
}

impl SobolSummary {
    /// From a study's series, its envelope (names, times, widths) and its box.
    pub fn from_study(series: &SobolSeries, envelope: &Envelope, space: &ParameterSpace) -> Self {
        let records = series.records().min(envelope.times.len());
        let dimensions = space
            .dimensions()
            .iter()
            .map(|d| SobolDimension {
                name: d.name.clone(),
                source: d.source.clone(),
            })
            .collect();
        let outputs = envelope
            .outputs
            .iter()
            .enumerate()
            .take(series.n_outputs())
            .map(|(o, output)| {
                let widest = widest_record(envelope, o).filter(|&k| k < records);
                OutputSobol {
                    name: output.name.clone(),
                    variance: (0..records).map(|k| series.variance(k, o)).collect(),
                    main: (0..records).map(|k| series.main(k, o).to_vec()).collect(),
                    total: (0..records).map(|k| series.total(k, o).to_vec()).collect(),
                    widest_time: widest.map(|k| envelope.times[k]),
                    widest_main: widest.map(|k| series.main(k, o).to_vec()),
                    widest_total: widest.map(|k| series.total(k, o).to_vec()),
                }
            })
            .collect();
        SobolSummary {
            dimensions,
            outputs,
        }
    }

    /// The first non-finite number: `(output, what, record)`.
    fn first_non_finite(&self) -> Option<(&str, &'static str, usize, f64)> {
        for output in &self.outputs {
            for (k, v) in output.variance.iter().enumerate() {
                if !v.is_finite() {
                    return Some((&output.name, "Sobol' variance", k, *v));
                }
            }
            for (what, rows) in [
                ("main Sobol' index", &output.main),
                ("total Sobol' index", &output.total),
            ] {
                for (k, row) in rows.iter().enumerate() {
                    if let Some(v) = row.iter().find(|v| !v.is_finite()) {
                        return Some((&output.name, what, k, *v));
                    }
                }
            }
        }
        None
    }
}

/// The whole summary.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Robot name.
    pub robot: String,
    /// Method (`nominal` for `simulate`).
    pub method: String,
    /// Polynomial order, `null` where meaningless.
    pub order: Option<usize>,
    /// Design (`tensor`, `total`), `null` where meaningless.
    pub design: Option<String>,
    /// `inner`, `outer`, `reference` or `nominal`.
    pub bound_kind: String,
    /// The interval parameters.
    pub parameters: Vec<ParameterSummary>,
    /// How much each parameter moves the outputs, ranked; `null` where the study measured nothing
    /// of the kind (tensor designs, `simulate`).
    pub sensitivities: Option<Vec<SensitivitySummary>>,
    /// Model runs made.
    pub samples: usize,
    /// Samples excluded with `--keep-going`.
    pub excluded_samples: Vec<serde_json::Value>,
    /// Runs that failed at the fixed step and were re-run from t = 0 with the adaptive step
    /// (docs/step-control.md §3): phase, run, index, ξ, parameter values, where (`time`) and why
    /// (`error`) the fixed step failed, and the first record time that is the adaptive run's;
    /// absent when there are none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub retried_samples: Vec<serde_json::Value>,
    /// Wall time, s.
    pub wall_seconds: f64,
    /// Envelopes.
    pub outputs: Vec<EnvelopeSeries>,
    /// Integrator and method statistics.
    pub stats: serde_json::Value,
    /// Surrogate studies: the Sobol' indices of every output at every record time; absent
    /// otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sobol_indices: Option<SobolSummary>,
    /// Joints whose positions went past their URDF limits in a scene that does not enforce them
    /// ([`crate::scene::limit_excursions`]), deepest first; absent when there are none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub limit_excursions: Vec<crate::scene::LimitExcursion>,
}

impl Summary {
    /// Writes the summary as pretty JSON to `path`, streaming through a temporary file (see
    /// [`super::paths`]). JSON has no NaN or infinity (serde would write `null`): a non-finite
    /// value in any series is refused, naming the output and time, and nothing is written.
    pub fn write(&self, path: &Path) -> Result<(), OutputError> {
        for output in &self.outputs {
            let mut names: Vec<String> = vec![
                format!("{}.lower", output.name),
                format!("{}.upper", output.name),
                format!("{}.nominal", output.name),
            ];
            let mut columns: Vec<&[f64]> = vec![&output.lower, &output.upper, &output.nominal];
            for (series, values) in [
                ("error_estimate", &output.error_estimate),
                ("outer_lower", &output.outer_lower),
                ("outer_upper", &output.outer_upper),
                ("runs_lower", &output.runs_lower),
                ("runs_upper", &output.runs_upper),
            ] {
                if let Some(values) = values {
                    names.push(format!("{}.{series}", output.name));
                    columns.push(values);
                }
            }
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            if let Some(bad) = first_non_finite(&names, &output.time, &columns) {
                return Err(OutputError::NonFinite {
                    what: format!("summary '{}'", path.display()),
                    output: bad.series.to_string(),
                    time_s: bad.time_s,
                    value: bad.value,
                });
            }
        }
        if let Some((output, what, record, value)) = self
            .sobol_indices
            .as_ref()
            .and_then(SobolSummary::first_non_finite)
        {
            let time_s = self
                .outputs
                .iter()
                .find(|o| o.name == output)
                .and_then(|o| o.time.get(record).copied())
                .unwrap_or(f64::NAN);
            return Err(OutputError::NonFinite {
                what: format!("summary '{}'", path.display()),
                output: format!("{output} ({what})"),
                time_s,
                value,
            });
        }
        let mut file = AtomicFile::create(path, "summary")?;
        serde_json::to_writer_pretty(&mut file, self)
            .map_err(|e| file.error(std::io::Error::other(e)))?;
        std::io::Write::write_all(&mut file, b"\n").map_err(|e| file.error(e))?;
        file.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_non_finite_value_is_refused_not_written_as_null() {
        let dir = std::env::temp_dir().join(format!("ribbon-summary-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("summary.json");
        let series = |upper: f64| EnvelopeSeries {
            name: "frame.tip.x".to_string(),
            unit: "m".to_string(),
            time: vec![0.0, 0.25],
            lower: vec![1.0, 1.0],
            upper: vec![1.0, upper],
            nominal: vec![1.0, 1.0],
            error_estimate: None,
            outer_lower: None,
            outer_upper: None,
            runs_lower: None,
            runs_upper: None,
        };
        let mut summary = Summary {
            robot: "r".to_string(),
            method: "nominal".to_string(),
            order: None,
            design: None,
            bound_kind: "nominal".to_string(),
            parameters: Vec::new(),
            sensitivities: None,
            samples: 1,
            excluded_samples: Vec::new(),
            retried_samples: Vec::new(),
            wall_seconds: 0.0,
            outputs: vec![series(f64::INFINITY)],
            stats: serde_json::Value::Null,
            sobol_indices: None,
            limit_excursions: Vec::new(),
        };
        let m = summary.write(&path).unwrap_err().to_string();
        assert!(
            m.contains("output 'frame.tip.x.upper' is inf at t = 0.25 s"),
            "{m}"
        );
        assert!(!path.exists());
        summary.outputs = vec![series(2.0)];
        summary.write(&path).unwrap();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(json["outputs"][0]["upper"][1], serde_json::json!(2.0));
        assert!(json.get("sobol_indices").is_none());
        // A non-finite Sobol' index is refused too.
        summary.sobol_indices = Some(SobolSummary {
            dimensions: vec![SobolDimension {
                name: "l1".to_string(),
                source: "l1".to_string(),
            }],
            outputs: vec![OutputSobol {
                name: "frame.tip.x".to_string(),
                variance: vec![0.0, 1.0],
                main: vec![vec![0.0], vec![f64::NAN]],
                total: vec![vec![0.0], vec![1.0]],
                widest_time: Some(0.25),
                widest_main: Some(vec![1.0]),
                widest_total: Some(vec![1.0]),
            }],
        });
        let m = summary.write(&path).unwrap_err().to_string();
        assert!(
            m.contains("frame.tip.x (main Sobol' index)") && m.contains("t = 0.25 s"),
            "{m}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
