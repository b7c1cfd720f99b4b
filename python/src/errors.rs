//! The library's errors as the package's exceptions (python/ribbon/_errors.py), by the CLI's exit
//! code: 2 (the input is at fault, nothing ran) ⇒ `InputError`, a `ValueError`; anything else ⇒
//! `RunError`, a `RuntimeError`. The message is the CLI's, without its `error: ` prefix.

use pyo3::prelude::*;

/// The exception class `name` of `ribbon._errors`.
pub fn exception_class<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("ribbon._errors")?.getattr(name)
}

/// `error` as the exception of its exit code.
pub fn to_py(error: ribbon::Error) -> PyErr {
    Python::attach(|py| {
        let class = match error.exit_code() {
            2 => "InputError",
            _ => "RunError",
        };
        // The CLI's text: a long message laid out as a headline and indented clauses.
        let message = ribbon::text::laid_out(&error.to_string());
        match exception_class(py, class).and_then(|c| c.call1((message,))) {
            Ok(exception) => PyErr::from_value(exception),
            Err(import_failed) => import_failed,
        }
    })
}

/// An `InputError` for a value given from Python that the library never sees (a keyword
/// argument's name or type), blamed on `option` as the CLI blames a flag.
pub fn input_error(option: &str, message: String) -> PyErr {
    to_py(ribbon::Error::BadArgument {
        flag: option.to_string(),
        message,
    })
}

/// Library warnings as Python warnings (`ribbon.RibbonWarning`), so that notebooks show them.
pub fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    let category = exception_class(py, "RibbonWarning")?;
    py.import("warnings")?
        .getattr("warn")?
        .call1((text, category, 2))?;
    Ok(())
}

/// The library's setup messages of a run, kept while it runs on the worker thread and given to
/// Python afterwards as warnings ([`SetupMessages::warn`]), before any error of the run.
#[derive(Default)]
pub struct SetupMessages(Vec<String>);

impl SetupMessages {
    /// Keeps one message (a note keeps its `note: ` prefix).
    pub fn keep(&mut self, kind: ribbon::setup::SetupMessage, text: &str) {
        self.0.push(match kind {
            ribbon::setup::SetupMessage::Warning => text.to_string(),
            ribbon::setup::SetupMessage::Note => format!("note: {text}"),
        });
    }

    /// Every message kept, as a `RibbonWarning`.
    pub fn warn(&self, py: Python<'_>) -> PyResult<()> {
        self.0.iter().try_for_each(|text| warn(py, text))
    }
}
