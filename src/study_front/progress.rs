//! A study's progress on stderr: after every block of every phase, how many record times of how
//! many runs are done, the elapsed time and an estimate of the rest — a line rewritten in place
//! on a terminal, otherwise at most one line per [`PROGRESS_INTERVAL_S`] (logs stay short).
//!
//! Does not: measure anything (the study hands it [`Progress`]).

use crate::analysis::Progress;
use std::io::IsTerminal;

/// Without a terminal, at most one progress line per this many seconds (after the first).
pub const PROGRESS_INTERVAL_S: f64 = 1.0;

/// Progress on stderr: a rewritten line on a terminal, otherwise a line at most every
/// [`PROGRESS_INTERVAL_S`] (and always the first).
pub struct ProgressReporter {
    terminal: bool,
    last_line_s: Option<f64>,
}

impl Default for ProgressReporter {
    fn default() -> Self {
        Self::new()
    }
}

impl ProgressReporter {
    /// A reporter for stderr.
    pub fn new() -> Self {
        Self {
            terminal: std::io::stderr().is_terminal(),
            last_line_s: None,
        }
    }

    /// Reports one block's progress.
    pub fn report(&mut self, p: Progress) {
        let fraction = p.records_done as f64 / p.records_total.max(1) as f64;
        let eta = if fraction > 0.0 {
            p.elapsed_s * (1.0 - fraction) / fraction
        } else {
            f64::NAN
        };
        let line = format!(
            "progress: {} {}/{} record times ({:.0} %) of {} runs, {:.1} s elapsed, ETA {:.1} s",
            p.phase,
            p.records_done,
            p.records_total,
            100.0 * fraction,
            p.runs,
            p.elapsed_s,
            eta
        );
        if self.terminal {
            eprint!("\r{line}   ");
        } else if self
            .last_line_s
            .is_none_or(|last| p.elapsed_s - last >= PROGRESS_INTERVAL_S)
        {
            eprintln!("{line}");
            self.last_line_s = Some(p.elapsed_s);
        }
    }

    /// Ends the line on a terminal.
    pub fn finish(&self) {
        if self.terminal {
            eprintln!();
        }
    }
}
