//! `ribbon.analyze(urdf, sidecar=None, method=None, progress=None, **options)` ⇒ a
//! [`StudyResult`]: the study `ribbon analyze` runs, through the same front end
//! (`study_front`: options, memory check, plan, `Study::run_stages`, warnings, summary), on a
//! worker thread; the finished blocks are kept so that the MCAP log, the CSV, the summary and the
//! report are written on request with the CLI's writers.
//!
//! An untrusted result raises `UntrustedResult` (the CLI's exit 4) carrying the result; an
//! interrupted one re-raises the `KeyboardInterrupt` with the partial result as `.result`.

use crate::background::run_in_background;
use crate::convert::{array1, array2, json_to_py};
use crate::errors::{exception_class, to_py, SetupMessages};
use crate::options::{Keywords, SCENE_KEYWORDS, STUDY_KEYWORDS};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use ribbon::analysis::{SimulateHere, Study, StudyOptions, StudyReport};
use ribbon::model::Model;
use ribbon::output::Summary;
use ribbon::scene::{LimitExcursion, Scene};
use ribbon::setup::{Setup, SetupMessage};
use ribbon::study_front::options::{order_of, study_options};
use ribbon::study_front::report_page::{prepare_report, write_report, ReportText};
use ribbon::study_front::run_study::{
    check_envelope_finite, check_study_memory, write_envelope_csv,
};
use ribbon::study_front::study_log::{close_log, LogHeader, RecordedBlocks};
use ribbon::study_front::warnings::{untrusted, warn as study_warnings, StudyWarnings};
use ribbon::study_front::{table::table, StudyOutputs, StudyRequest};
use ribbon::uncertainty::ParameterSpace;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A finished study and what it ran on.
#[pyclass(module = "ribbon", frozen)]
pub struct StudyResult {
    urdf: PathBuf,
    sidecar_path: PathBuf,
    model: Model,
    scene: Scene,
    space: ParameterSpace,
    options: StudyOptions,
    header: LogHeader,
    blocks: RecordedBlocks,
    report: StudyReport,
    warnings: Vec<String>,
    excursions: Vec<LimitExcursion>,
    advice: Option<String>,
    wall_seconds: f64,
}

/// What the worker thread hands back.
struct Finished {
    setup: Setup,
    options: StudyOptions,
    header: LogHeader,
    blocks: RecordedBlocks,
    report: StudyReport,
}

/// Runs the study of `request` as `run_study` does, up to its report (no file is written).
fn run_study_here(
    request: &StudyRequest,
    stop: &std::sync::atomic::AtomicBool,
    progress: &mut dyn FnMut(ribbon::analysis::Progress),
    message: &mut dyn FnMut(SetupMessage, &str),
) -> Result<Finished, ribbon::Error> {
    let setup = Setup::load(&request.scene.request(), message)?;
    let options = study_options(&request.flags, &setup.sidecar.analysis)?;
    check_study_memory(&setup.scene, &options, &setup.space, false)?;
    let study = Study::new(
        &setup.model,
        &setup.environment,
        &setup.scene,
        &setup.space,
        options.clone(),
    );
    let plan = study.plan()?;
    let header = LogHeader::of_plan(setup.model.name(), &plan, &options, &setup.space);
    let mut blocks = RecordedBlocks::default();
    let report = study.run_stages(plan, &mut SimulateHere, stop, progress, &mut |block| {
        blocks.record(block);
        Ok(())
    })?;
    Ok(Finished {
        setup,
        options,
        header,
        blocks,
        report,
    })
}

/// Runs a study (module documentation). `method=None` takes the sidecar's `[analysis] method`,
/// else `auto`, as `ribbon analyze` without `--method`; `progress`, when given, is called after
/// every block with `{phase, records_done, records_total, runs, elapsed_s}` (an exception it
/// raises stops the study and is re-raised).
#[pyfunction]
#[pyo3(signature = (urdf, sidecar = None, method = None, progress = None, **options))]
pub fn analyze(
    py: Python<'_>,
    urdf: PathBuf,
    sidecar: Option<PathBuf>,
    method: Option<String>,
    progress: Option<&Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<StudyResult>> {
    let started = Instant::now();
    let accepted: Vec<&'static str> = ["method", "progress"]
        .into_iter()
        .chain(SCENE_KEYWORDS)
        .chain(STUDY_KEYWORDS)
        .collect();
    let mut keywords = Keywords::new(options, accepted)?;
    let request = StudyRequest {
        scene: keywords.scene_inputs(urdf.clone(), sidecar)?,
        flags: keywords.study_flags(method)?,
        outputs: StudyOutputs::default(),
    };
    keywords.finish()?;
    let mut messages = SetupMessages::default();
    let (outcome, stopped) = run_in_background(py, progress, |stop, progress| {
        run_study_here(&request, stop, progress, &mut |kind, text| {
            messages.keep(kind, text)
        })
    });
    messages.warn(py)?;
    let finished = outcome.map_err(to_py)?;
    let wall_seconds = started.elapsed().as_secs_f64();
    check_envelope_finite(&finished.report.envelope).map_err(to_py)?;
    let Setup {
        sidecar_path,
        model,
        scene,
        space,
        ..
    } = finished.setup;
    let StudyWarnings {
        warnings,
        excursions,
        advice,
    } = study_warnings(&finished.report, &model, &scene, &space);
    let result = StudyResult {
        urdf,
        sidecar_path,
        model,
        scene,
        space,
        options: finished.options,
        header: finished.header,
        blocks: finished.blocks,
        report: finished.report,
        warnings,
        excursions,
        advice,
        wall_seconds,
    };
    let untrusted_error = match (&result.report.check, &result.advice) {
        (Some(check), Some(advice)) if !result.report.partial => Some(ribbon::text::laid_out(
            &untrusted(&result.report, check, advice.clone()).to_string(),
        )),
        _ => None,
    };
    let result = Py::new(py, result)?;
    if let Some(stopped) = stopped {
        return Err(with_result(py, stopped.exception, result.into_any()));
    }
    if let Some(message) = untrusted_error {
        let exception = exception_class(py, "UntrustedResult")?.call1((message, result))?;
        return Err(PyErr::from_value(exception));
    }
    Ok(result)
}

/// `exception` with `result` as its `.result` attribute (a partial result of an interrupted run).
pub fn with_result(py: Python<'_>, exception: PyErr, result: Py<PyAny>) -> PyErr {
    let value = exception.value(py);
    match value.setattr("result", result) {
        Ok(()) => exception,
        Err(e) => e,
    }
}

impl StudyResult {
    /// Refuses an output path that is an input, a directory, a special file, … (the CLI's checks;
    /// `what` names the method in the message).
    fn check_output(&self, what: &str, path: &Path) -> Result<(), ribbon::Error> {
        Ok(ribbon::output::check_command_outputs(
            &self.urdf,
            Some(&self.sidecar_path),
            &[(what, Some(path))],
        )?)
    }

    /// The summary JSON of `ribbon analyze --summary`.
    fn summary_of_study(&self) -> Summary {
        Summary::of_study(
            self.model.name(),
            order_of(self.report.method, &self.options),
            &self.space,
            &self.report,
            self.excursions.clone(),
            self.wall_seconds,
        )
    }

    /// `{output: values}` of one series of the envelope.
    fn series<'py>(&self, py: Python<'py>, series: &[Vec<f64>]) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (output, values) in self.report.envelope.outputs.iter().zip(series) {
            dict.set_item(&output.name, array1(py, values))?;
        }
        Ok(dict)
    }
}

#[pymethods]
impl StudyResult {
    /// Record times, s.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        array1(py, &self.report.envelope.times)
    }

    /// The outputs' names, in the sidecar's order.
    #[getter]
    fn outputs(&self) -> Vec<String> {
        self.report
            .envelope
            .outputs
            .iter()
            .map(|o| o.name.clone())
            .collect()
    }

    /// `{output: unit}`.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for output in &self.report.envelope.outputs {
            dict.set_item(&output.name, output.unit)?;
        }
        Ok(dict)
    }

    /// `{output: lower bound at the record times}`.
    #[getter]
    fn lower<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.series(py, &self.report.envelope.lower)
    }

    /// `{output: the nominal run at the record times}`.
    #[getter]
    fn nominal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.series(py, &self.report.envelope.nominal)
    }

    /// `{output: upper bound at the record times}`.
    #[getter]
    fn upper<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.series(py, &self.report.envelope.upper)
    }

    /// `{output: the surrogate's error estimate}`, or `None` for methods without one (scan,
    /// monte-carlo).
    #[getter]
    fn error_estimate<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.report
            .envelope
            .error
            .as_ref()
            .map(|errors| self.series(py, errors))
            .transpose()
    }

    /// The summary JSON of `ribbon analyze --summary` as Python objects, without its `outputs`
    /// series (those are the arrays `lower`, `nominal`, `upper`, `error_estimate`).
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut json = serde_json::to_value(self.summary_of_study())
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        if let Some(object) = json.as_object_mut() {
            object.remove("outputs");
        }
        json_to_py(py, &json)
    }

    /// The a-posteriori check as the summary JSON has it (its `stats.check`: the runs, misfits,
    /// trusted and untrusted outputs; `None` when there was none).
    #[getter]
    fn check<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let json = serde_json::to_value(self.summary_of_study())
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        match json.pointer("/stats/check") {
            Some(check) if !check.is_null() => Ok(Some(json_to_py(py, check)?)),
            _ => Ok(None),
        }
    }

    /// Whether every output is trusted: `False` when the check did not trust one (the CLI's exit
    /// 4) or the study was interrupted; `True` also for methods without a check (scan,
    /// monte-carlo), whose envelopes are hulls of true runs.
    #[getter]
    fn trusted(&self) -> bool {
        self.advice.is_none() && !self.report.partial
    }

    /// Whether the study was interrupted: the envelopes cover the record times done.
    #[getter]
    fn partial(&self) -> bool {
        self.report.partial
    }

    /// The method that ran (`auto` resolved).
    #[getter]
    fn method(&self) -> &'static str {
        self.report.method.name()
    }

    /// Model runs made, the nominal and the check runs included.
    #[getter]
    fn runs(&self) -> usize {
        self.report.runs
    }

    /// The warnings the study printed (without `warning: `).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// What to do about the untrusted outputs (`None` when all are trusted).
    #[getter]
    fn advice(&self) -> Option<String> {
        self.advice.clone()
    }

    /// Surrogate methods: `{"parameters": [names], "main": {output: records × d},
    /// "total": {output: records × d}}`, the main and total Sobol' indices of every output at
    /// every record time; `None` for other methods.
    #[getter]
    fn sobol<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(series) = &self.report.sobol else {
            return Ok(None);
        };
        let outputs = &self.report.envelope.outputs;
        let (records, d) = (series.records(), series.dim());
        let (main, total) = (PyDict::new(py), PyDict::new(py));
        for (o, output) in outputs.iter().enumerate() {
            let mut main_values = Vec::with_capacity(records * d);
            let mut total_values = Vec::with_capacity(records * d);
            for record in 0..records {
                main_values.extend_from_slice(series.main(record, o));
                total_values.extend_from_slice(series.total(record, o));
            }
            main.set_item(&output.name, array2(py, &main_values, records, d)?)?;
            total.set_item(&output.name, array2(py, &total_values, records, d)?)?;
        }
        let dict = PyDict::new(py);
        let names: Vec<&str> = self
            .space
            .dimensions()
            .iter()
            .map(|d| d.name.as_str())
            .collect();
        dict.set_item("parameters", names)?;
        dict.set_item("main", main)?;
        dict.set_item("total", total)?;
        Ok(Some(dict))
    }

    /// One output's series: `{"lower", "nominal", "upper", "error_estimate"}`.
    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let e = &self.report.envelope;
        let Some(o) = e.outputs.iter().position(|output| output.name == name) else {
            let names = e.outputs.iter().map(|output| output.name.as_str());
            return Err(pyo3::exceptions::PyKeyError::new_err(format!(
                "no output '{name}'{}",
                ribbon::text::closest_suggestion(name, names)
            )));
        };
        let dict = PyDict::new(py);
        dict.set_item("lower", array1(py, &e.lower[o]))?;
        dict.set_item("nominal", array1(py, &e.nominal[o]))?;
        dict.set_item("upper", array1(py, &e.upper[o]))?;
        dict.set_item(
            "error_estimate",
            e.error.as_ref().map(|errors| array1(py, &errors[o])),
        )?;
        Ok(dict)
    }

    /// Writes the envelopes as `ribbon analyze --csv` does.
    fn write_csv(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| {
            self.check_output("write_csv", &path)?;
            write_envelope_csv(&path, &self.report)
        })
        .map_err(to_py)
    }

    /// Writes the summary JSON as `ribbon analyze --summary` does.
    fn write_summary(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| {
            self.check_output("write_summary", &path)?;
            Ok(self.summary_of_study().write(&path)?)
        })
        .map_err(to_py)
    }

    /// Writes the MCAP log as `ribbon analyze --out` does (the same blocks, in the same order).
    fn write_mcap(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| -> Result<(), ribbon::Error> {
            self.check_output("write_mcap", &path)?;
            let mut log =
                self.header
                    .open(&path, &self.urdf, &self.sidecar_path, &self.scene.outputs)?;
            let mut data = ribbon::dynamics::Data::new(&self.model);
            self.blocks.replay(
                self.scene.outputs.len(),
                self.report.sobol.as_ref(),
                &mut |block| log.write_block(block, &self.model, &mut data),
            )?;
            close_log(log, &self.report, &self.space)?;
            Ok(())
        })
        .map_err(to_py)
    }

    /// Writes the report of `ribbon analyze --report DIR` into `dir` (created if missing): the
    /// table, a band plot per output, the warnings, the page for the browser (`index.html`).
    fn report(&self, py: Python<'_>, dir: PathBuf) -> PyResult<()> {
        py.detach(|| -> Result<(), ribbon::Error> {
            let outputs = StudyOutputs {
                report: Some(dir.clone()),
                ..StudyOutputs::default()
            };
            let stems = prepare_report(&self.urdf, &outputs, &self.sidecar_path, &self.scene)?
                .unwrap_or_default();
            let table_text = table(&self.options, &self.space, &self.report, self.wall_seconds);
            let summary = self.summary_of_study();
            write_report(
                &dir,
                self.model.name(),
                &self.report,
                &ReportText {
                    table: &table_text,
                    warnings: &self.warnings,
                    summary: &summary,
                    log: None,
                },
                &stems,
                None,
            )
        })
        .map_err(to_py)
    }

    /// The table `ribbon analyze` prints.
    fn table(&self) -> String {
        table(&self.options, &self.space, &self.report, self.wall_seconds)
    }

    fn __repr__(&self) -> String {
        format!(
            "<ribbon.StudyResult: {} ({}), {} outputs at {} record times, {} runs, {}>",
            self.report.method.name(),
            self.report.design,
            self.report.envelope.outputs.len(),
            self.report.envelope.times.len(),
            self.report.runs,
            if self.report.partial {
                "partial"
            } else if self.advice.is_some() {
                "untrusted"
            } else {
                "trusted"
            }
        )
    }
}
