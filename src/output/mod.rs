//! Sinks for results: CSV series, the summary JSON of the design contract, MCAP logs for Foxglove and
//! rerun ([`mcap`]) with what the viewers need to show them ([`viewer`]), band and scatter plots
//! ([`plot`]), the check's verdict on an untrusted study as the log carries it
//! ([`UntrustedVerdict`]) and the report directory of `analyze --report` ([`report`], its browser page
//! [`report_html`]).
//!
//! Every output goes through [`paths`]: checked before any simulation ([`check_outputs`]: never an
//! input, a directory, a special file or a symlink; never two outputs on one file), written to a
//! unique temporary file beside its target and renamed when complete, so a failure or an
//! interruption never leaves a corrupt or half-written output and never touches an input. No
//! non-finite number is ever written ([`first_non_finite`], [`check_finite`]); standard output is
//! one more output ([`write_stdout`]: a closed pipe is an error, not a panic). Every failure is an
//! [`OutputError`].

mod csv;
mod envelope_log;
mod error;
pub mod mcap;
pub mod paths;
pub mod plot;
pub mod report;
pub mod report_html;
mod study_summary;
mod summary;
mod verdict;
pub mod viewer;

pub use csv::{csv_field, write_csv};
pub use envelope_log::EnvelopeLog;
pub use error::OutputError;
pub use paths::{
    check_command_outputs, check_outputs, prepare_output_directory, write_atomically, AtomicFile,
};
pub use study_summary::{elements_json, peak_memory};
pub use summary::{
    EnvelopeSeries, OutputSobol, ParameterSummary, SensitivitySummary, SobolDimension,
    SobolSummary, Summary,
};
pub use verdict::{UntrustedVerdict, CHECK_METADATA_KEY};

/// The first NaN or infinity of a set of series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NonFinite<'a> {
    /// The series' name (an output name, or `NAME.lower` …).
    pub series: &'a str,
    /// The record time, s (NaN when the time itself is the bad value's index beyond `times`).
    pub time_s: f64,
    /// The value found.
    pub value: f64,
}

/// The first non-finite value of `columns[i][k]` (series `names[i]` at `times[k]`), scanning time by
/// time; a non-finite time counts too (reported under the name `t`).
pub fn first_non_finite<'a>(
    names: &[&'a str],
    times: &[f64],
    columns: &[&[f64]],
) -> Option<NonFinite<'a>> {
    if let Some(t) = times.iter().find(|t| !t.is_finite()) {
        return Some(NonFinite {
            series: "t",
            time_s: *t,
            value: *t,
        });
    }
    for (k, t) in times.iter().enumerate() {
        for (name, column) in names.iter().zip(columns) {
            let value = column.get(k).copied().unwrap_or(f64::NAN);
            if !value.is_finite() {
                return Some(NonFinite {
                    series: name,
                    time_s: *t,
                    value,
                });
            }
        }
    }
    None
}

/// Refuses to report a NaN or infinity: the first non-finite value of `columns[i][k]` (series
/// `names[i]` at `times[k]`) is an [`OutputError::NonFinite`] naming `what` (where it would have
/// gone), the series and the time (exit 1).
pub fn check_finite(
    what: &str,
    names: &[&str],
    times: &[f64],
    columns: &[&[f64]],
) -> Result<(), OutputError> {
    match first_non_finite(names, times, columns) {
        Some(bad) => Err(OutputError::NonFinite {
            what: what.to_string(),
            output: bad.series.to_string(),
            time_s: bad.time_s,
            value: bad.value,
        }),
        None => Ok(()),
    }
}

/// Writes `text` to stdout, turning a closed pipe into an error instead of a panic.
pub fn write_stdout(text: &str) -> Result<(), OutputError> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|source| OutputError::Write {
            what: "to standard output".to_string(),
            source,
        })
}
