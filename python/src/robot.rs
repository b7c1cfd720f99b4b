//! `ribbon.load(urdf, floating=False)` ⇒ a [`Robot`]: its parameters (`ribbon params`) and its
//! rigid-body dynamics at a state (`ribbon dynamics`), computed by the library's
//! [`StateDynamics`].

use crate::convert::{array1, array2, homogeneous, set_flags, vector_arg};
use crate::errors::{to_py, warn};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use ribbon::environment::Environment;
use ribbon::model::{LoadOptions, Model};
use ribbon::state_dynamics::{StateDynamics, StateRequest};
use std::path::PathBuf;

/// A robot loaded from its URDF.
#[pyclass(module = "ribbon", frozen)]
pub struct Robot {
    model: Model,
}

/// Loads a URDF (the root link on a floating joint with `floating=True`); the model's warnings
/// become `RibbonWarning`s.
#[pyfunction]
#[pyo3(signature = (urdf, floating = false))]
pub fn load(py: Python<'_>, urdf: PathBuf, floating: bool) -> PyResult<Robot> {
    let model = Model::from_urdf_file(
        &urdf,
        LoadOptions {
            floating_base: floating,
        },
    )
    .map_err(|e| to_py(e.into()))?;
    for warning in &model.warnings {
        warn(py, warning)?;
    }
    Ok(Robot { model })
}

#[pymethods]
impl Robot {
    /// The robot's name (`<robot name>`).
    #[getter]
    fn name(&self) -> &str {
        self.model.name()
    }

    /// Position coordinates.
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq
    }

    /// Velocity coordinates.
    #[getter]
    fn nv(&self) -> usize {
        self.model.nv
    }

    /// The joints with coordinates: `[{name, type, q_index, nq, v_index, nv}]`, in coordinate
    /// order (the `joints` of `ribbon dynamics --json`).
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.model
            .joints
            .iter()
            .map(|j| {
                let dict = PyDict::new(py);
                dict.set_item("name", &j.name)?;
                dict.set_item("type", j.type_name)?;
                dict.set_item("q_index", j.q_index)?;
                dict.set_item("nq", j.nq())?;
                dict.set_item("v_index", j.v_index)?;
                dict.set_item("nv", j.nv())?;
                Ok(dict)
            })
            .collect()
    }

    /// Every value that can be declared uncertain (`ribbon params`): `{"paths": [...],
    /// "values": ndarray, "units": [...]}`, one entry per parameter.
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        // A robot without a scene: the default environment, as `ribbon params` without a sidecar.
        let environment = Environment::default();
        let listed = ribbon::params::list(&self.model, &environment);
        let values: Vec<f64> = listed
            .iter()
            .map(|p| ribbon::params::get(&self.model, &environment, p.target))
            .collect();
        let dict = PyDict::new(py);
        dict.set_item(
            "paths",
            listed.iter().map(|p| p.path.as_str()).collect::<Vec<_>>(),
        )?;
        dict.set_item("values", array1(py, &values))?;
        dict.set_item("units", listed.iter().map(|p| p.unit).collect::<Vec<_>>())?;
        Ok(dict)
    }

    /// The dynamics at one state (`ribbon dynamics`): `q` (default: neutral) and `v` (default:
    /// zero), `tau` for forward dynamics, `qdd` for inverse dynamics, `set={path: value}` applied
    /// to a copy of the model first. Returns `{"q", "v", "mass_matrix", "bias", "qdd"?, "tau"?,
    /// "frames": {link: 4×4 world_from_link}}` as numpy arrays.
    #[pyo3(signature = (q = None, v = None, tau = None, qdd = None, set = None))]
    fn dynamics<'py>(
        &self,
        py: Python<'py>,
        q: Option<&Bound<'py, PyAny>>,
        v: Option<&Bound<'py, PyAny>>,
        tau: Option<&Bound<'py, PyAny>>,
        qdd: Option<&Bound<'py, PyAny>>,
        set: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let state = StateRequest {
            q: vector_arg(q, "--q")?,
            v: vector_arg(v, "--v")?,
            tau: vector_arg(tau, "--tau")?,
            qdd: vector_arg(qdd, "--qdd")?,
        };
        let flags = set_flags(set)?;
        let edited;
        let mut environment = Environment::default();
        let model = if flags.is_empty() {
            &self.model
        } else {
            let mut copy = self.model.clone();
            ribbon::cli::apply_set_flags(&mut copy, &mut environment, &flags).map_err(to_py)?;
            edited = copy;
            &edited
        };
        let result = StateDynamics::at(model, &environment.gravity, &state).map_err(to_py)?;
        let nv = model.nv;
        let dict = PyDict::new(py);
        dict.set_item("q", array1(py, &result.q))?;
        dict.set_item("v", array1(py, &result.v))?;
        // nalgebra is column-major; the symmetric M reads the same either way, but say it.
        let row_major: Vec<f64> = result.mass_matrix.transpose().as_slice().to_vec();
        dict.set_item("mass_matrix", array2(py, &row_major, nv, nv)?)?;
        dict.set_item("bias", array1(py, &result.bias))?;
        if let Some(qdd) = &result.qdd {
            dict.set_item("qdd", array1(py, qdd))?;
        }
        if let Some(tau) = &result.tau {
            dict.set_item("tau", array1(py, tau))?;
        }
        let frames = PyDict::new(py);
        for (name, placement) in &result.frames {
            frames.set_item(name, homogeneous(py, placement)?)?;
        }
        dict.set_item("frames", frames)?;
        Ok(dict)
    }

    fn __repr__(&self) -> String {
        format!(
            "<ribbon.Robot '{}': nq = {}, nv = {}>",
            self.model.name(),
            self.model.nq,
            self.model.nv
        )
    }
}
