//! `ribbon._ribbon`, the extension module of the Python package `ribbon` (python/ribbon/): the
//! library's own entry points — the study front end, the nominal run, the dynamics at a state —
//! called with Python values, results as numpy arrays.
//!
//! ```text
//! load(urdf) ─▶ Robot: params(), dynamics(q, v, …)         (robot.rs)
//! simulate(urdf, …) ─▶ Simulation: times, outputs          (simulation.rs)
//! analyze(urdf, …) ─▶ StudyResult: envelopes, check, Sobol' (study.rs; options.rs reads the keywords)
//! ```
//!
//! Runs go on a worker thread without the GIL while this thread waits, delivers progress and
//! checks for signals (background.rs); errors become the package's exceptions (errors.rs).

mod background;
mod convert;
mod errors;
mod options;
mod robot;
mod simulation;
mod study;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _ribbon(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(robot::load, module)?)?;
    module.add_function(wrap_pyfunction!(simulation::simulate, module)?)?;
    module.add_function(wrap_pyfunction!(study::analyze, module)?)?;
    module.add_class::<robot::Robot>()?;
    module.add_class::<simulation::Simulation>()?;
    module.add_class::<study::StudyResult>()?;
    module.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
