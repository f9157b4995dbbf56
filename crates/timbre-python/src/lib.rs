//! The compiled half of the `timbre` Python package (`timbre._timbre`): `render`,
//! which renders a file or a text as `timbre render` does into numpy arrays (the mix,
//! or its stems); the embedding API's nouns as classes (`Engine`, `Library`,
//! `Scene`, `Instance`, `Variable`, `Keyframes`, `Fault`); and the exceptions
//! (`Error` for every diagnostic, `Cancelled`) and the warning category (`Warning`).
//! It goes through the `timbre` crate's embedding API only; it is not a second
//! command line (no files are written, no progress is drawn).

mod args;
mod errors;
mod live;
mod offline;

use pyo3::prelude::*;

/// The compiled module, `timbre._timbre`; `timbre` re-exports what it holds.
#[pymodule]
fn _timbre(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_function(wrap_pyfunction!(offline::render, m)?)?;
    m.add_class::<offline::Stems>()?;
    m.add_class::<live::Engine>()?;
    m.add_class::<live::Library>()?;
    m.add_class::<live::Scene>()?;
    m.add_class::<live::Instance>()?;
    m.add_class::<live::Variable>()?;
    m.add_class::<live::Keyframes>()?;
    m.add_class::<live::Fault>()?;
    m.add("Error", py.get_type::<errors::Error>())?;
    m.add("Cancelled", py.get_type::<errors::Cancelled>())?;
    m.add("Warning", py.get_type::<errors::Warning>())?;
    Ok(())
}
