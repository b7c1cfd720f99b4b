//! The summary JSON (design contract): robot, method, parameters, runs, and per output the time
//! series of lower, upper and nominal bounds with an error estimate.

use super::write_atomically;
use crate::Error;
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
    /// Model runs made.
    pub samples: usize,
    /// Samples excluded with `--keep-going`.
    pub excluded_samples: Vec<serde_json::Value>,
    /// Wall time, s.
    pub wall_seconds: f64,
    /// Envelopes.
    pub outputs: Vec<EnvelopeSeries>,
    /// Integrator and method statistics.
    pub stats: serde_json::Value,
}

impl Summary {
    /// Writes the summary as pretty JSON to `path`.
    pub fn write(&self, path: &Path) -> Result<(), Error> {
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::Output {
            what: format!("summary '{}'", path.display()),
            source: std::io::Error::other(e),
        })?;
        write_atomically(path, "summary", text.as_bytes())
    }
}
