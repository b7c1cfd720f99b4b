//! SIGINT and SIGTERM for long runs, shared by every command.
//!
//! [`install`] replaces the default "end the process" action of both signals by a watcher thread:
//! - the **first** signal sets the flag ([`flag`], [`requested`]); long loops check it and stop at
//!   their next check — a single run (`simulate`) once per integrator step, so the work between a
//!   signal and the stop is at most one HHT step (two Newton passes of at most
//!   `max_newton_iterations` iterations); the command then writes what was computed (marked
//!   partial) and exits 1;
//! - a **second** signal ends the process at once (exit 1) after removing every temporary output
//!   file still on disk ([`crate::atomic_file::remove_live_temporaries`]): outputs keep their previous
//!   contents, nothing half-written is left.
//!
//! Not done here: deciding what an interrupted command writes (the commands do).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

/// Set by the first SIGINT/SIGTERM after [`install`].
static REQUESTED: AtomicBool = AtomicBool::new(false);

/// The outcome of the one installation.
static INSTALLED: OnceLock<Result<(), String>> = OnceLock::new();

/// Installs the SIGINT/SIGTERM watcher (once per process; later calls return the first outcome).
/// An error says why the signals keep their default action (the caller prints it as a warning).
pub fn install() -> Result<(), String> {
    INSTALLED
        .get_or_init(|| {
            use signal_hook::consts::{SIGINT, SIGTERM};
            let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])
                .map_err(|e| format!("cannot install the SIGINT/SIGTERM handlers: {e}"))?;
            std::thread::Builder::new()
                .name("ribbon-signals".to_string())
                .spawn(move || {
                    for _ in signals.forever() {
                        if REQUESTED.swap(true, Ordering::SeqCst) {
                            let removed = crate::atomic_file::remove_live_temporaries();
                            eprintln!(
                                "\nerror: interrupted twice: stopped at once; {removed} temporary file(s) removed, no output was written or replaced"
                            );
                            std::process::exit(1);
                        }
                        eprintln!(
                            "\ninterrupt: stopping at the next step and writing what was computed; interrupt again to stop at once without writing"
                        );
                    }
                })
                .map(|_| ())
                .map_err(|e| format!("cannot start the signal thread: {e}"))
        })
        .clone()
}

/// The flag the first signal sets, for loops that take an `&AtomicBool` (the study engine).
pub fn flag() -> &'static AtomicBool {
    &REQUESTED
}

/// Whether an interruption was requested (one relaxed atomic load: cheap enough for every step).
#[inline]
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}
