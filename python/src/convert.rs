//! Values between the library and Python: numpy arrays out (copies: a result owns its data),
//! numpy arrays or sequences in, JSON values as the objects `json.loads` makes.

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use ribbon::spatial::Transform;

/// A copy of `values` as a 1-D float64 array.
pub fn array1<'py>(py: Python<'py>, values: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, values)
}

/// `rows × columns` values, row-major, as a 2-D float64 array.
pub fn array2<'py>(
    py: Python<'py>,
    values: &[f64],
    rows: usize,
    columns: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    PyArray1::from_slice(py, values).reshape([rows, columns])
}

/// A rigid transform as the 4 × 4 homogeneous matrix `[R p; 0 1]`.
pub fn homogeneous<'py>(
    py: Python<'py>,
    transform: &Transform,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let mut values = [0.0; 16];
    for row in 0..3 {
        for column in 0..3 {
            values[4 * row + column] = transform.rotation[(row, column)];
        }
        values[4 * row + 3] = transform.translation[row];
    }
    values[15] = 1.0;
    array2(py, &values, 4, 4)
}

/// A JSON value as Python objects (dicts, lists, floats, …), as `json.loads` makes them.
pub fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?
        .getattr("loads")?
        .call1((value.to_string(),))
}

/// A float vector from Python (a 1-D numpy array or any sequence of numbers), or `None`;
/// `name` is the argument, for the message when it is neither.
pub fn vector_arg(value: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Option<Vec<f64>>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let bad = |detail: String| {
        crate::errors::input_error(
            name,
            format!("expected a 1-D sequence of numbers: {detail}"),
        )
    };
    let array = value
        .py()
        .import("numpy")?
        .getattr("asarray")?
        .call1((value, "float64"))
        .map_err(|e| bad(e.to_string()))?;
    let ndim: usize = array.getattr("ndim")?.extract()?;
    if ndim != 1 {
        return Err(bad(format!("got an array of {ndim} dimensions")));
    }
    Ok(Some(array.call_method0("tolist")?.extract::<Vec<f64>>()?))
}

/// `set={path_or_symbol: value, …}` as the CLI's `--set PATH=VALUE` flags (a value's shortest
/// decimal form reads back as the same bits), checked by the library as the CLI's are.
pub fn set_flags(set: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<String>> {
    let Some(set) = set.filter(|s| !s.is_none()) else {
        return Ok(Vec::new());
    };
    let dict = set.cast::<pyo3::types::PyDict>().map_err(|_| {
        crate::errors::input_error(
            "--set",
            "set= takes a dict {parameter path or sidecar symbol: value}".to_string(),
        )
    })?;
    let mut flags = Vec::with_capacity(dict.len());
    for (key, value) in dict.iter() {
        let name: String = key.extract().map_err(|_| {
            crate::errors::input_error("--set", format!("the key {key} is not a string"))
        })?;
        let value: f64 = value.extract().map_err(|_| {
            crate::errors::input_error(
                "--set",
                format!("the value of '{name}' ({value}) is not a number"),
            )
        })?;
        flags.push(format!("{name}={value}"));
    }
    Ok(flags)
}
