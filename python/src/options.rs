//! The keyword arguments of `simulate` and `analyze` as the library's plain requests — the same
//! [`SceneInputs`] and [`StudyFlags`] the CLI fills from its flags, so every value is checked
//! where the CLI's is, with its message. A keyword is the flag's name with `_` for `-`
//! (`scan_grid=` is `--scan-grid`); `None` is "not given". Here only names and Python types are
//! checked: an unknown keyword is an `InputError` with the closest name.

use crate::errors::input_error;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use ribbon::scene::SceneOverrides;
use ribbon::study_front::{SceneInputs, StudyFlags};
use std::path::PathBuf;

/// The scene keywords every run takes.
pub const SCENE_KEYWORDS: [&str; 4] = ["duration", "step", "alpha", "floating"];

/// The study keywords of `analyze` (besides `method`, `progress` and the scene's).
pub const STUDY_KEYWORDS: [&str; 12] = [
    "order",
    "design",
    "grid",
    "scan_grid",
    "samples",
    "seed",
    "threads",
    "keep_going",
    "max_runs",
    "check_runs",
    "elements",
    "max_elements",
];

/// Keyword arguments being read; [`Keywords::finish`] refuses those nobody took.
pub struct Keywords<'py> {
    entries: Vec<(String, Bound<'py, PyAny>)>,
    accepted: Vec<&'static str>,
}

fn flag_of(keyword: &str) -> String {
    format!("--{}", keyword.replace('_', "-"))
}

impl<'py> Keywords<'py> {
    /// The keywords given (none: `None`), of which `accepted` are known.
    pub fn new(
        kwargs: Option<&Bound<'py, PyDict>>,
        accepted: Vec<&'static str>,
    ) -> PyResult<Keywords<'py>> {
        let mut entries = Vec::new();
        if let Some(kwargs) = kwargs {
            for (key, value) in kwargs.iter() {
                entries.push((key.extract::<String>()?, value));
            }
        }
        Ok(Keywords { entries, accepted })
    }

    fn take(&mut self, name: &str) -> Option<Bound<'py, PyAny>> {
        let at = self.entries.iter().position(|(k, _)| k == name)?;
        let (_, value) = self.entries.remove(at);
        (!value.is_none()).then_some(value)
    }

    fn typed<T: pyo3::conversion::FromPyObjectOwned<'py>>(
        &mut self,
        name: &str,
        expected: &str,
    ) -> PyResult<Option<T>> {
        match self.take(name) {
            None => Ok(None),
            Some(value) => value.extract::<T>().map(Some).map_err(|_| {
                input_error(&flag_of(name), format!("{name}={value} is not {expected}"))
            }),
        }
    }

    /// A number.
    pub fn float(&mut self, name: &str) -> PyResult<Option<f64>> {
        self.typed(name, "a number")
    }

    /// A count (a non-negative integer).
    pub fn count(&mut self, name: &str) -> PyResult<Option<usize>> {
        self.typed(name, "a non-negative integer")
    }

    /// A seed (a non-negative integer below 2^64).
    pub fn seed(&mut self, name: &str) -> PyResult<Option<u64>> {
        self.typed(name, "a non-negative integer below 2^64")
    }

    /// A switch.
    pub fn switch(&mut self, name: &str) -> PyResult<bool> {
        Ok(self.typed::<bool>(name, "True or False")?.unwrap_or(false))
    }

    /// A name (`elements=` also takes True for `on` and False for `off`).
    pub fn text(&mut self, name: &str) -> PyResult<Option<String>> {
        match self.take(name) {
            None => Ok(None),
            Some(value) if name == "elements" && value.is_instance_of::<pyo3::types::PyBool>() => {
                Ok(Some(
                    if value.is_truthy()? { "on" } else { "off" }.to_string(),
                ))
            }
            Some(value) => value.extract::<String>().map(Some).map_err(|_| {
                input_error(&flag_of(name), format!("{name}={value} is not a string"))
            }),
        }
    }

    /// Refuses the keywords nobody took, naming the closest accepted one.
    pub fn finish(self) -> PyResult<()> {
        match self.entries.first() {
            None => Ok(()),
            Some((name, _)) => Err(input_error(
                name,
                format!(
                    "unknown keyword argument{}; accepted: {}",
                    ribbon::text::closest_suggestion(name, self.accepted.iter().copied()),
                    self.accepted.join(", ")
                ),
            )),
        }
    }

    /// The robot, its sidecar and the scene keywords.
    pub fn scene_inputs(
        &mut self,
        urdf: PathBuf,
        sidecar: Option<PathBuf>,
    ) -> PyResult<SceneInputs> {
        Ok(SceneInputs {
            urdf,
            uncertainty: sidecar,
            overrides: SceneOverrides {
                duration_s: self.float("duration")?,
                step_s: self.float("step")?,
                alpha: self.float("alpha")?,
            },
            floating: self.switch("floating")?,
        })
    }

    /// The study keywords, with `method` (`None`: the sidecar's `[analysis] method`, else auto).
    pub fn study_flags(&mut self, method: Option<String>) -> PyResult<StudyFlags> {
        Ok(StudyFlags {
            method,
            order: self.count("order")?,
            design: self.text("design")?,
            grid: self.count("grid")?,
            scan_grid: self.count("scan_grid")?,
            samples: self.count("samples")?,
            seed: self.seed("seed")?,
            threads: self.count("threads")?,
            keep_going: self.switch("keep_going")?,
            max_runs: self.count("max_runs")?,
            check_runs: self.count("check_runs")?,
            elements: self.text("elements")?,
            max_elements: self.count("max_elements")?,
        })
    }
}
