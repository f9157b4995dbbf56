//! Python's arguments, checked before they are used: each one that makes no sense is
//! a `ValueError` (or a `TypeError`) naming the argument and what it must be. And the
//! script a `str` or a path names, read as the command line reads it.

use std::path::{Path, PathBuf};

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};
use timbre::{SceneFile, SourceFile};

use crate::errors::Failure;

/// The script to read: a file's path, or text.
pub(crate) enum Script {
    File(PathBuf),
    Text(String),
}

/// A `str` naming an existing file (with no parenthesis or newline, which a file's
/// name never has and source text always does) or an `os.PathLike` is a path;
/// another `str` is a script's text.
pub(crate) fn script(value: &Bound<'_, PyAny>) -> PyResult<Script> {
    if let Ok(text) = value.cast::<PyString>() {
        let text = text.to_str()?;
        let path = Path::new(text);
        return Ok(if !text.contains(['(', '\n']) && path.is_file() {
            Script::File(path.to_path_buf())
        } else {
            Script::Text(text.to_owned())
        });
    }
    value.extract::<PathBuf>().map(Script::File).map_err(|_| {
        PyTypeError::new_err(format!(
            "expected a path (str or os.PathLike) or a script's text, not {}",
            type_name(value)
        ))
    })
}

/// A file's text and the directory what it names is found in, or a text named
/// `text_name` in diagnostics (its files found relative to the working directory).
pub(crate) fn source(
    script: Script,
    text_name: &str,
) -> Result<(std::sync::Arc<SourceFile>, Option<PathBuf>), Failure> {
    Ok(match script {
        Script::Text(text) => (SourceFile::new(text_name, text), None),
        Script::File(path) => {
            let cannot = |why: &dyn std::fmt::Display| {
                Failure::Message(format!("cannot read `{}`: {why}", path.display()))
            };
            let bytes = std::fs::read(&path).map_err(|e| cannot(&e))?;
            let text = String::from_utf8(bytes).map_err(|_| cannot(&"it is not UTF-8 text"))?;
            let dir = path.parent().map(Path::to_path_buf);
            (SourceFile::new(path.display().to_string(), text), dir)
        }
    })
}

/// Reads and lowers a scene file as the command line does: a file is named in
/// diagnostics by the path given, and what it includes is found beside it.
pub(crate) fn read_scene(engine: &timbre::Engine, script: Script) -> Result<SceneFile, Failure> {
    let (source, dir) = source(script, "<source>")?;
    Ok(engine.read_scene_source(source, dir.as_deref())?)
}

fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map_or_else(|_| "that".to_owned(), |n| n.to_string())
}

pub(crate) fn positive(name: &str, value: f64) -> PyResult<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name}={value}: must be a finite number greater than 0"
        )))
    }
}

pub(crate) fn finite(name: &str, value: f64) -> PyResult<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name}={value}: must be a finite number"
        )))
    }
}

/// A time on a scene's timeline: finite seconds, ≥ 0.
pub(crate) fn time(name: &str, value: f64) -> PyResult<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name}={value}: must be finite seconds from the start of the scene, >= 0"
        )))
    }
}

pub(crate) fn sample_rate(rate: f64) -> PyResult<f64> {
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

pub(crate) fn thread_count(threads: i64) -> PyResult<usize> {
    match usize::try_from(threads) {
        Ok(n) if (1..=timbre::MAX_THREADS).contains(&n) => Ok(n),
        _ => Err(PyValueError::new_err(format!(
            "threads={threads}: must be from 1 to {}",
            timbre::MAX_THREADS
        ))),
    }
}

pub(crate) fn channel_count(channels: i64) -> PyResult<usize> {
    match usize::try_from(channels) {
        Ok(n) if (1..=timbre::MAX_CHANNELS).contains(&n) => Ok(n),
        _ => Err(PyValueError::new_err(format!(
            "channels={channels}: must be from 1 to {}",
            timbre::MAX_CHANNELS
        ))),
    }
}

pub(crate) fn block_size(samples: i64) -> PyResult<usize> {
    match usize::try_from(samples) {
        Ok(n) if (1..=timbre::MAX_BLOCK_SIZE).contains(&n) => Ok(n),
        _ => Err(PyValueError::new_err(format!(
            "block_size={samples}: must be from 1 to {} samples",
            timbre::MAX_BLOCK_SIZE
        ))),
    }
}

pub(crate) fn backend(engine: Option<&str>) -> PyResult<timbre::Backend> {
    match engine {
        None | Some("jit") => Ok(timbre::Backend::Jit),
        Some("interp") => Ok(timbre::Backend::Interpreter),
        Some(other) => Err(PyValueError::new_err(format!(
            "engine={other:?}: must be \"jit\" (compiled, the default) or \"interp\" (the reference interpreter)"
        ))),
    }
}

/// `set`: free parameters' values, each name a parameter's and each value finite.
pub(crate) fn bindings(set: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, f64)>> {
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

/// `normalize`: a peak in dBFS, or True for the command line's default of −1 dBFS
/// (and False or None for none).
pub(crate) fn normalize(value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<f64>> {
    let Some(value) = value else { return Ok(None) };
    if value.is_none() {
        return Ok(None);
    }
    if let Ok(flag) = value.cast::<PyBool>() {
        return Ok(flag.is_true().then_some(-1.0));
    }
    let db: f64 = value.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "normalize: expected a peak in dBFS (a number, e.g. -1.0) or True, not {}",
            type_name(value)
        ))
    })?;
    finite("normalize", db).map(Some)
}

/// Numbers from any iterable of them (a list, a tuple, a numpy array).
pub(crate) fn floats(name: &str, value: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let not_numbers = || {
        PyTypeError::new_err(format!(
            "{name}: expected a sequence of numbers, not {}",
            type_name(value)
        ))
    };
    if value.is_instance_of::<PyString>() {
        return Err(not_numbers());
    }
    let mut numbers = vec![];
    for item in value.try_iter().map_err(|_| not_numbers())? {
        numbers.push(item?.extract::<f64>().map_err(|_| not_numbers())?);
    }
    Ok(numbers)
}

/// A point or a direction: three finite numbers (metres).
pub(crate) fn vector(name: &str, value: &Bound<'_, PyAny>) -> PyResult<[f64; 3]> {
    let numbers = floats(name, value)?;
    match numbers[..] {
        [x, y, z] if numbers.iter().all(|v| v.is_finite()) => Ok([x, y, z]),
        [_, _, _] => Err(PyValueError::new_err(format!(
            "{name}={numbers:?}: each coordinate must be a finite number"
        ))),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected three numbers (x, y, z), got {}",
            numbers.len()
        ))),
    }
}
