//! The package's exceptions and warnings: `timbre.Error` (every diagnostic, with the
//! first one's parts as attributes), `timbre.Cancelled` (a render its progress
//! callback stopped) and `timbre.Warning` (what a script warns of, issued through
//! Python's `warnings`); and [`Failure`], what goes wrong while the GIL is released,
//! made into one of them once it is held again.

use std::ffi::CString;

use pyo3::exceptions::{PyException, PyMemoryError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use timbre::{Diag, Diagnostics};

pyo3::create_exception!(
    timbre,
    Error,
    PyException,
    "A script or a render failed: the diagnostics timbre reports, as the command line\n\
     prints them (`str(error)`). The first one's parts are attributes: `code`,\n\
     `message`, `file`, `line` and `column` (1-based, where its primary label starts;\n\
     None when it points nowhere) and `help`."
);

pyo3::create_exception!(
    timbre,
    Cancelled,
    PyException,
    "A render stopped because its progress callback returned False."
);

pyo3::create_exception!(
    timbre,
    Warning,
    PyUserWarning,
    "What a script warns of (an unused binding, an instance after the render's end,\n\
     ...), issued with `warnings.warn`: its text is the report as the command line\n\
     prints it."
);

/// What went wrong, made into a Python exception once the GIL is held.
pub(crate) enum Failure {
    /// A script's diagnostics: `timbre.Error`.
    Diagnostics(Vec<Diag>),
    /// A failure that is not a diagnostic (a file that cannot be read): `timbre.Error`.
    Message(String),
    /// An argument that does not fit what was read: `ValueError`.
    Value(String),
    /// Memory the system would not give: `MemoryError`.
    Memory(String),
    /// The progress callback returned False: `timbre.Cancelled`.
    Cancelled,
    /// Python's own (Ctrl-C, or what the progress callback raised).
    Python(PyErr),
}

impl From<Diagnostics> for Failure {
    fn from(diagnostics: Diagnostics) -> Self {
        Failure::Diagnostics(diagnostics.0)
    }
}

impl From<timbre::Error> for Failure {
    fn from(error: timbre::Error) -> Self {
        match error {
            timbre::Error::Script(diagnostics) => Failure::Diagnostics(diagnostics.0),
            timbre::Error::Compile(e) => Failure::Message(format!("{e}; use engine=\"interp\"")),
            other => Failure::Message(other.to_string()),
        }
    }
}

impl From<PyErr> for Failure {
    fn from(error: PyErr) -> Self {
        Failure::Python(error)
    }
}

impl Failure {
    pub(crate) fn into_py(self, py: Python<'_>) -> PyErr {
        match self {
            Failure::Diagnostics(diagnostics) => diagnostics_error(py, &diagnostics),
            Failure::Message(message) => message_error(py, &message),
            Failure::Value(message) => PyValueError::new_err(message),
            Failure::Memory(message) => PyMemoryError::new_err(message),
            Failure::Cancelled => {
                Cancelled::new_err("the render was cancelled: its progress callback returned False")
            }
            Failure::Python(error) => error,
        }
    }
}

/// A `timbre::Error` as the Python exception it is (`timbre.Error`).
pub(crate) fn to_py(py: Python<'_>, error: timbre::Error) -> PyErr {
    Failure::from(error).into_py(py)
}

/// Diagnostics as `timbre.Error`.
pub(crate) fn diagnostics_to_py(py: Python<'_>, diagnostics: Diagnostics) -> PyErr {
    diagnostics_error(py, &diagnostics.0)
}

/// Issues `text` as a `timbre.Warning` pointing at the caller's line. Raises when the
/// warnings filter makes it an error.
pub(crate) fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    // A report holds no NUL; were one there, it is replaced rather than lost.
    let message =
        CString::new(text.replace('\0', "?")).map_err(|e| PyValueError::new_err(e.to_string()))?;
    PyErr::warn(py, py.get_type::<Warning>().as_any(), &message, 1)
}

/// Each diagnostic issued as a warning, its text as the command line prints it.
pub(crate) fn warn_diagnostics(py: Python<'_>, diagnostics: &[Diag]) -> PyResult<()> {
    for diag in diagnostics {
        let text = timbre::report_plain(std::slice::from_ref(diag));
        warn(py, text.trim_end())?;
    }
    Ok(())
}

/// The warnings of a script read: what lowering warned of, and each binding (`set`)
/// no tree uses, with the name it likely misspells.
pub(crate) fn warn_file(py: Python<'_>, file: &timbre::SceneFile) -> PyResult<()> {
    warn_diagnostics(py, file.warnings())?;
    for name in file.unused_bindings() {
        let close = file
            .closest_definition(name)
            .map(|n| format!("; did you mean '{n}'?"))
            .unwrap_or_default();
        warn(
            py,
            &format!("set={{'{name}': ...}} is not used by any expression{close}"),
        )?;
    }
    Ok(())
}

/// What `timbre.Error` carries besides its text.
#[derive(Default)]
struct Parts {
    code: Option<String>,
    message: String,
    file: Option<String>,
    line: Option<usize>,
    column: Option<usize>,
    help: Option<String>,
}

/// `timbre.Error` with `text` as its `str()` and `parts` as its attributes.
fn error_with(py: Python<'_>, text: String, parts: Parts) -> PyErr {
    let error = Error::new_err(text);
    let value = error.value(py);
    let set = || -> PyResult<()> {
        value.setattr("code", parts.code)?;
        value.setattr("message", parts.message)?;
        value.setattr("file", parts.file)?;
        value.setattr("line", parts.line)?;
        value.setattr("column", parts.column)?;
        value.setattr("help", parts.help)
    };
    match set() {
        Ok(()) => error,
        Err(e) => e,
    }
}

/// `timbre.Error` for `diagnostics`: the text the command line prints, and the first
/// one's parts as attributes.
fn diagnostics_error(py: Python<'_>, diagnostics: &[Diag]) -> PyErr {
    let text = timbre::report_plain(diagnostics).trim_end().to_owned();
    let parts = diagnostics.first().map_or_else(Parts::default, |first| {
        let (line, column) = position(first).unzip();
        Parts {
            code: Some(first.code.to_string()),
            message: first.message.clone(),
            file: first.source.as_ref().map(|s| s.name.clone()),
            line,
            column,
            help: first.help.clone(),
        }
    });
    error_with(py, text, parts)
}

/// `timbre.Error` for a failure that is not a diagnostic (a file that cannot be
/// read): the message as the command line prints it, no code and no position.
fn message_error(py: Python<'_>, message: &str) -> PyErr {
    let parts = Parts {
        message: message.to_owned(),
        ..Parts::default()
    };
    error_with(py, format!("error: {message}"), parts)
}

/// Line and column (1-based, in characters) where `diag`'s primary label starts.
fn position(diag: &Diag) -> Option<(usize, usize)> {
    let text = &diag.source.as_ref()?.text;
    let start = diag.span()?.start.min(text.len());
    let before = text.get(..start)?;
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |k| k + 1);
    Some((line, before[line_start..].chars().count() + 1))
}
