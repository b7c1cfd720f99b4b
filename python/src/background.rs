//! A run on a worker thread while the calling thread, which holds the GIL only between waits,
//! hands progress to the Python callback and checks for signals: the GIL is released while
//! simulating, and Ctrl-C (`KeyboardInterrupt`) or an exception in the callback sets the run's
//! stop flag, so that it ends after the current step with what it computed.
//!
//! Python runs signal handlers only on the main thread and only when asked, so the waiting thread
//! asks ([`Python::check_signals`]) every [`SIGNAL_POLL`].

use pyo3::prelude::*;
use ribbon::analysis::Progress;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::Duration;

/// How often the waiting thread checks for signals: short beside a person's reaction, long
/// beside the cost of taking the GIL (microseconds).
pub const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// What stopped a run early from the Python side.
pub struct Stopped {
    /// The exception raised by a signal handler (`KeyboardInterrupt`) or by the callback.
    pub exception: PyErr,
}

/// Runs `work` on a worker thread with a stop flag and a progress function; returns its result
/// and, when the run was asked to stop, the exception that asked.
pub fn run_in_background<T, W>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: W,
) -> (T, Option<Stopped>)
where
    T: Send,
    W: FnOnce(&AtomicBool, &mut dyn FnMut(Progress)) -> T + Send,
{
    let stop = AtomicBool::new(false);
    let (sender, receiver) = channel::<Progress>();
    let mut stopped: Option<Stopped> = None;
    let result = std::thread::scope(|scope| {
        let stop = &stop;
        let worker = scope.spawn(move || {
            work(stop, &mut |p| {
                // The waiting thread outlives the run; a send fails only if it is gone.
                let _ = sender.send(p);
            })
        });
        let mut receiver: Receiver<Progress> = receiver;
        loop {
            let (received, back) = py.detach(move || {
                let received = receiver.recv_timeout(SIGNAL_POLL);
                (received, receiver)
            });
            receiver = back;
            match received {
                Ok(p) => {
                    if let (Some(callback), None) = (progress, &stopped) {
                        if let Err(exception) = callback.call1((progress_dict(py, &p),)) {
                            stop.store(true, Ordering::SeqCst);
                            stopped = Some(Stopped { exception });
                        }
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if stopped.is_none() {
                if let Err(exception) = py.check_signals() {
                    stop.store(true, Ordering::SeqCst);
                    stopped = Some(Stopped { exception });
                }
            }
        }
        match worker.join() {
            Ok(result) => result,
            Err(panic) => std::panic::resume_unwind(panic),
        }
    });
    (result, stopped)
}

/// One block's progress as the callback receives it.
fn progress_dict<'py>(py: Python<'py>, p: &Progress) -> Bound<'py, pyo3::types::PyDict> {
    let dict = pyo3::types::PyDict::new(py);
    // Setting items of a fresh dict to plain values cannot fail.
    let _ = dict.set_item("phase", p.phase);
    let _ = dict.set_item("records_done", p.records_done);
    let _ = dict.set_item("records_total", p.records_total);
    let _ = dict.set_item("runs", p.runs);
    let _ = dict.set_item("elapsed_s", p.elapsed_s);
    dict
}
