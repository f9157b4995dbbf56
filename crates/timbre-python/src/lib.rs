//! The compiled half of the `timbre` Python package (`timbre._timbre`): `render`, which
//! renders a file or a text as `timbre render` does into a numpy array, and
//! `timbre.Error`, raised for every diagnostic. It goes through the `timbre` crate's
//! embedding API only; it is not a second command line (no files are written, no
//! progress is drawn).

use std::path::{Path, PathBuf};

use numpy::ndarray::Array2;
use numpy::IntoPyArray;
use pyo3::exceptions::{PyException, PyNotImplementedError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use timbre::{Diag, Diagnostics, SceneFile, SourceFile};

pyo3::create_exception!(
    _timbre,
    Error,
    PyException,
    "A script or a render failed: the diagnostics timbre reports, as the command line\n\
     prints them (`str(error)`). The first one's parts are attributes: `code`,\n\
     `message`, `file`, `line` and `column` (1-based, where its primary label starts;\n\
     None when it points nowhere) and `help`."
);

/// The sample rate of a file that names none, as on the command line.
const DEFAULT_RATE: f64 = 48_000.0;

/// Frames rendered between two looks at Python's signals (Ctrl-C).
const CHUNK_FRAMES: usize = 8192;

/// What `render` was asked, checked.
struct Options {
    duration: Option<f64>,
    rate: Option<f64>,
    seed: Option<u64>,
    bindings: Vec<(String, f64)>,
    backend: timbre::Backend,
    threads: Option<usize>,
}

/// A render's failure, made into a Python exception once the GIL is held.
enum Failure {
    Diagnostics(Vec<Diag>),
    Message(String),
    Interrupted(PyErr),
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

impl Failure {
    fn into_py(self, py: Python<'_>) -> PyErr {
        match self {
            Failure::Diagnostics(diagnostics) => diagnostics_error(py, &diagnostics),
            Failure::Message(message) => message_error(py, &message),
            Failure::Interrupted(error) => error,
        }
    }
}

/// Render a timbre file, or timbre source text, to samples.
///
/// `path_or_source` is a path (a `str` naming an existing file, or an `os.PathLike`)
/// or the text of a script. The options mean what `timbre render`'s do: `duration`
/// in seconds (default: the file's `(scene :duration …)`; else a scene lasts until
/// its last instance has ended, at most 600 s, and a sound 1 s), `rate` in Hz (the
/// file's `:sample-rate`, else 48000), `seed` of the random nodes, `set` a dict of
/// free parameters' values (`--set NAME=VALUE`), `engine` "jit" (default) or
/// "interp", `threads` rendering a scene's instances (the samples do not depend on
/// it).
///
/// Returns a float32 array of frames × channels, equal bit for bit to the samples
/// of `timbre render --format f32`. Raises `timbre.Error` for a script's
/// diagnostics and `ValueError` for an option that makes no sense. The GIL is
/// released while rendering, and Ctrl-C stops it (KeyboardInterrupt).
#[pyfunction]
#[pyo3(signature = (path_or_source, *, duration=None, rate=None, seed=None, set=None, engine=None, threads=None, stems=false))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments, one per option.
fn render<'py>(
    py: Python<'py>,
    path_or_source: &Bound<'py, PyAny>,
    duration: Option<f64>,
    rate: Option<f64>,
    seed: Option<u64>,
    set: Option<&Bound<'py, PyDict>>,
    engine: Option<&str>,
    threads: Option<i64>,
    stems: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if stems {
        return Err(PyNotImplementedError::new_err(
            "stems are not rendered from Python yet: use `timbre render --stems DIR`",
        ));
    }
    let options = Options {
        duration: duration.map(|d| positive("duration", d)).transpose()?,
        rate: rate.map(sample_rate).transpose()?,
        seed,
        bindings: bindings(set)?,
        backend: backend(engine)?,
        threads: threads.map(thread_count).transpose()?,
    };
    let source = source_of(path_or_source)?;
    let (samples, channels) = py
        .detach(|| render_source(source, &options))
        .map_err(|failure| failure.into_py(py))?;
    let frames = samples.len() / channels;
    let array = Array2::from_shape_vec((frames, channels), samples)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py).into_any())
}

/// The script to read: a file's path and its directory, or text.
enum Script {
    File(PathBuf),
    Text(String),
}

fn source_of(value: &Bound<'_, PyAny>) -> PyResult<Script> {
    if let Ok(text) = value.cast::<PyString>() {
        let text = text.to_str()?;
        let path = Path::new(text);
        // Source text is never a file's name: it has a parenthesis or a newline.
        return Ok(if !text.contains(['(', '\n']) && path.is_file() {
            Script::File(path.to_path_buf())
        } else {
            Script::Text(text.to_owned())
        });
    }
    Ok(Script::File(value.extract::<PathBuf>()?))
}

/// Reads, plans and renders, without the GIL (it is taken briefly between chunks to
/// see whether Ctrl-C was pressed); returns interleaved samples and the channels.
fn render_source(script: Script, options: &Options) -> Result<(Vec<f32>, usize), Failure> {
    let mut engine = timbre::Engine::new(DEFAULT_RATE).with_file_access();
    if let Some(seed) = options.seed {
        engine = engine.with_seed(seed);
    }
    for (name, value) in &options.bindings {
        engine = engine.with_binding(name.clone(), *value);
    }
    let file = read(&engine, script)?;
    if !file.has_sound() {
        return Err(Failure::Message(
            "nothing to render: the file defines trees but has no sound expression or instance"
                .into(),
        ));
    }
    let rate = options.rate.or(file.sample_rate()).unwrap_or(DEFAULT_RATE);
    let (duration, open_ended) = file.render_length(options.duration);
    let engine = engine.with_sample_rate(rate).with_backend(options.backend);
    let mut scene = engine.scene_from(&file, duration)?;
    let threads = options
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    scene
        .set_threads(threads)
        .map_err(|e| Failure::Message(format!("cannot start {threads} threads: {e}")))?;
    let channels = file.channels();
    let frames = (duration * rate).round() as u64;
    let mut out = Vec::new();
    let mut chunk = vec![0.0f64; CHUNK_FRAMES * channels];
    let mut done = 0u64;
    while done < frames {
        Python::attach(|py| py.check_signals()).map_err(Failure::Interrupted)?;
        let n = (frames - done).min(CHUNK_FRAMES as u64) as usize;
        let first = scene.frame();
        let block = &mut chunk[..n * channels];
        scene.render(block)?;
        if let Some(fault) = scene.first_fault() {
            return Err(Failure::Diagnostics(vec![scene.explain(&fault)]));
        }
        let kept = if open_ended && scene.finished() {
            (scene.ended_at_frame().saturating_sub(first) as usize).min(n)
        } else {
            n
        };
        // Rounded to the nearest f32, as the command line writes f32.
        out.extend(block[..kept * channels].iter().map(|&x| x as f32));
        done += kept as u64;
        if kept < n || (open_ended && scene.finished()) {
            break;
        }
    }
    Ok((out, channels))
}

/// Reads and lowers the script as the command line does: a file is named in
/// diagnostics by the path given, and what it includes is found beside it.
fn read(engine: &timbre::Engine, script: Script) -> Result<SceneFile, Failure> {
    let (source, dir) = match script {
        Script::Text(text) => (SourceFile::new("<source>", text), None),
        Script::File(path) => {
            let cannot = |why: &dyn std::fmt::Display| {
                Failure::Message(format!("cannot read `{}`: {why}", path.display()))
            };
            let bytes = std::fs::read(&path).map_err(|e| cannot(&e))?;
            let text = String::from_utf8(bytes).map_err(|_| cannot(&"it is not UTF-8 text"))?;
            let dir = path.parent().map(Path::to_path_buf);
            (SourceFile::new(path.display().to_string(), text), dir)
        }
    };
    Ok(engine.read_scene_source(source, dir.as_deref())?)
}

fn positive(name: &str, value: f64) -> PyResult<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name}={value}: must be a finite number greater than 0"
        )))
    }
}

fn sample_rate(rate: f64) -> PyResult<f64> {
    use timbre::{MAX_SAMPLE_RATE, MIN_SAMPLE_RATE};
    if (MIN_SAMPLE_RATE..=MAX_SAMPLE_RATE).contains(&rate) && rate.fract() == 0.0 {
        Ok(rate)
    } else {
        Err(PyValueError::new_err(format!(
            "rate={rate}: not a sample rate (a whole number of Hz from {MIN_SAMPLE_RATE} to \
             {MAX_SAMPLE_RATE})"
        )))
    }
}

fn thread_count(threads: i64) -> PyResult<usize> {
    match usize::try_from(threads) {
        Ok(n) if (1..=timbre::MAX_THREADS).contains(&n) => Ok(n),
        _ => Err(PyValueError::new_err(format!(
            "threads={threads}: must be from 1 to {}",
            timbre::MAX_THREADS
        ))),
    }
}

fn backend(engine: Option<&str>) -> PyResult<timbre::Backend> {
    match engine {
        None | Some("jit") => Ok(timbre::Backend::Jit),
        Some("interp") => Ok(timbre::Backend::Interpreter),
        Some(other) => Err(PyValueError::new_err(format!(
            "engine={other:?}: must be \"jit\" (compiled, the default) or \"interp\" (the reference interpreter)"
        ))),
    }
}

fn bindings(set: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, f64)>> {
    let Some(set) = set else { return Ok(vec![]) };
    let mut bindings = Vec::with_capacity(set.len());
    for (name, value) in set.iter() {
        let name: String = name.extract()?;
        let value: f64 = value.extract()?;
        if name.trim().is_empty() || !value.is_finite() {
            return Err(PyValueError::new_err(format!(
                "set={{{name:?}: {value}}}: each name must be a parameter's and each value a finite number"
            )));
        }
        bindings.push((name.trim().to_owned(), value));
    }
    Ok(bindings)
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

/// The compiled module, `timbre._timbre`; `timbre` re-exports what it holds.
#[pymodule]
fn _timbre(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add("Error", m.py().get_type::<Error>())?;
    Ok(())
}
