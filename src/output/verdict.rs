//! The a-posteriori check's verdict on a study it did not trust, as the MCAP log carries it (the
//! `check` entry of the `ribbon` metadata record) and the viewers show it (the titles of the
//! untrusted outputs' plots), docs/mcap.md §1, §4–§5.
//!
//! Only for studies that show the hull of their true runs ([`StudyReport::shows_runs_hull`]: the
//! check left some output untrusted): a trusted study's log keeps every byte it had. Does not:
//! judge anything (`analysis/check.rs`), or word the exit-4 message (`study_front/warnings.rs`).

use crate::analysis::{StudyReport, TRUST_RELATIVE_MISFIT};
use std::collections::BTreeMap;

/// Key of the verdict in the `ribbon` metadata record.
pub const CHECK_METADATA_KEY: &str = "check";

/// What the check said of a study it did not trust.
#[derive(Clone, Debug, PartialEq)]
pub struct UntrustedVerdict {
    /// The outputs' names, in the study's order.
    pub names: Vec<String>,
    /// Per output (the study's order): its misfit over its largest envelope width when the check
    /// did not trust it, `None` when it did.
    pub untrusted_misfit: Vec<Option<f64>>,
    /// The last record time up to which the check, judging only those times, trusts every
    /// output (the summary's `stats.check.passes_until_time_s`), s.
    pub passes_until_time_s: Option<f64>,
    /// The time up to which the horizon check's own runs confirmed the surrogate (the summary's
    /// `stats.check.horizon.verified_until_time_s`), s; `None` when no horizon check ran or it
    /// confirmed nothing.
    pub verified_until_time_s: Option<f64>,
}

impl UntrustedVerdict {
    /// The verdict of `report`, when its results show the hull of true runs (its check left some
    /// output untrusted); `None` otherwise.
    pub fn of_report(report: &StudyReport) -> Option<UntrustedVerdict> {
        if !report.shows_runs_hull() {
            return None;
        }
        let check = report.check.as_ref()?;
        let outputs = &report.envelope.outputs;
        let time_of = |record: Option<usize>| record.and_then(|r| report.envelope.times.get(r));
        let mut untrusted_misfit = vec![None; outputs.len()];
        for &o in &check.untrusted_outputs {
            untrusted_misfit[o] = check.relative_misfit.get(o).copied();
        }
        Some(UntrustedVerdict {
            names: outputs.iter().map(|o| o.name.clone()).collect(),
            untrusted_misfit,
            passes_until_time_s: time_of(check.passes_until_record).copied(),
            verified_until_time_s: check
                .horizon
                .as_ref()
                .and_then(|h| time_of(h.verified_until_record))
                .copied(),
        })
    }

    /// The `check` entry of the `ribbon` metadata record, JSON: `trusted` (false),
    /// `trust_relative_misfit` (the threshold), `untrusted_outputs` (`[{"name",
    /// "relative_misfit"}]`, in output order), `passes_until_time_s`, `verified_until_time_s`
    /// (`null` where there is none).
    pub fn metadata(&self) -> BTreeMap<String, String> {
        let untrusted: Vec<serde_json::Value> = self
            .names
            .iter()
            .zip(&self.untrusted_misfit)
            .filter_map(|(name, misfit)| {
                misfit.map(|m| serde_json::json!({"name": name, "relative_misfit": m}))
            })
            .collect();
        let json = serde_json::json!({
            "trusted": false,
            "trust_relative_misfit": TRUST_RELATIVE_MISFIT,
            "untrusted_outputs": untrusted,
            "passes_until_time_s": self.passes_until_time_s,
            "verified_until_time_s": self.verified_until_time_s,
        });
        BTreeMap::from([(CHECK_METADATA_KEY.to_string(), json.to_string())])
    }
}
