//! `ribbon.simulate(urdf, sidecar=None, set={}, **scene)` ⇒ a [`Simulation`]: the nominal
//! trajectory of `ribbon simulate`, run by the library's [`NominalRun`] on a worker thread.

use crate::background::run_in_background;
use crate::convert::{array1, array2, set_flags};
use crate::errors::{to_py, warn, SetupMessages};
use crate::options::{Keywords, SCENE_KEYWORDS};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use ribbon::nominal_run::{NominalCopies, NominalRun};
use std::path::PathBuf;

/// A nominal trajectory.
#[pyclass(module = "ribbon", frozen)]
pub struct Simulation {
    run: NominalRun,
    urdf: PathBuf,
}

/// Simulates the sidecar's scene once with the nominal parameters (`set={path or symbol: value}`
/// as `--set`; keywords `duration`, `step`, `alpha`, `floating` as the flags). Ctrl-C stops after
/// the current step and raises `KeyboardInterrupt` with the partial result as `.result`.
#[pyfunction]
#[pyo3(signature = (urdf, sidecar = None, set = None, **scene))]
pub fn simulate(
    py: Python<'_>,
    urdf: PathBuf,
    sidecar: Option<PathBuf>,
    set: Option<&Bound<'_, PyAny>>,
    scene: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<Simulation>> {
    let mut keywords = Keywords::new(scene, SCENE_KEYWORDS.to_vec())?;
    let inputs = keywords.scene_inputs(urdf.clone(), sidecar)?;
    keywords.finish()?;
    let flags = set_flags(set)?;
    let mut messages = SetupMessages::default();
    let (outcome, stopped) = run_in_background(py, None, |stop, _progress| {
        NominalRun::run(
            &inputs.request(),
            &flags,
            NominalCopies::TrajectoryOnly,
            stop,
            &mut |kind, text| messages.keep(kind, text),
        )
    });
    messages.warn(py)?;
    let run = outcome.map_err(to_py)?;
    run.check_finite().map_err(to_py)?;
    let excursions = run.limit_excursions();
    if !excursions.is_empty() {
        warn(
            py,
            &ribbon::scene::describe_limit_excursions(&excursions, false),
        )?;
    }
    let simulation = Py::new(py, Simulation { run, urdf })?;
    match stopped {
        Some(stopped) => Err(crate::study::with_result(
            py,
            stopped.exception,
            simulation.into_any(),
        )),
        None => Ok(simulation),
    }
}

#[pymethods]
impl Simulation {
    /// Record times, s.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        array1(py, &self.run.trajectory.times)
    }

    /// `{output name: values at the record times}`.
    #[getter]
    fn outputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        let t = &self.run.trajectory;
        for (output, values) in t.outputs.iter().zip(&t.values) {
            dict.set_item(&output.name, array1(py, values))?;
        }
        Ok(dict)
    }

    /// `{output name: unit}`.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for output in &self.run.trajectory.outputs {
            dict.set_item(&output.name, output.unit)?;
        }
        Ok(dict)
    }

    /// The configuration at every record time, `records × nq`.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let t = &self.run.trajectory;
        let flat: Vec<f64> = t.positions.iter().flatten().copied().collect();
        array2(py, &flat, t.positions.len(), self.run.model.nq)
    }

    /// Whether the run was interrupted before the scene's duration.
    #[getter]
    fn partial(&self) -> bool {
        self.run.trajectory.partial
    }

    /// Writes the series as `ribbon simulate --csv` does (`t`, then one column per output).
    fn write_csv(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let run = &self.run;
        py.detach(|| -> Result<(), ribbon::Error> {
            ribbon::output::check_command_outputs(
                &self.urdf,
                run.sidecar_path.as_deref(),
                &[("write_csv", Some(&path))],
            )?;
            let columns: Vec<&[f64]> = run.trajectory.values.iter().map(Vec::as_slice).collect();
            Ok(ribbon::output::write_csv(
                &path,
                &run.trajectory.times,
                &run.output_names(),
                &columns,
            )?)
        })
        .map_err(to_py)
    }

    fn __repr__(&self) -> String {
        let t = &self.run.trajectory;
        format!(
            "<ribbon.Simulation: {} outputs at {} record times{}>",
            t.outputs.len(),
            t.times.len(),
            if t.partial { " (partial)" } else { "" }
        )
    }
}
