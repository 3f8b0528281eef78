//! `phalanx._phalanx`, the extension module under the Python package `phalanx`: the
//! simulation environment with its observation buffers as NumPy arrays (`world::World`),
//! many of them stepped in one call (`vector::VecWorld`),
//! instances, the planners and the validator (`toolkit`) and the shipped policies
//! (`policy`). The PettingZoo classes are the thin pure-Python layer in `python/phalanx`.
//!
//! Nothing panics across the boundary: bad input comes back as `phalanx.PhalanxError` (a
//! `ValueError`) carrying the Rust message with its causes (file, line, value).

use pyo3::prelude::*;

mod policy;
mod toolkit;
mod vector;
mod world;

pyo3::create_exception!(
    _phalanx,
    PhalanxError,
    pyo3::exceptions::PyValueError,
    "Bad input to phalanx: a file, a setting, an instance, a plan or an action."
);

/// The Python exception of `err`, its message the error and its causes joined by ": ".
pub(crate) fn error(err: &(dyn std::error::Error + 'static)) -> PyErr {
    PhalanxError::new_err(message(err))
}

/// The message of `err` with its causes, joined by ": ".
pub(crate) fn message(err: &(dyn std::error::Error + 'static)) -> String {
    let mut message = err.to_string();
    let mut source = err.source();
    while let Some(cause) = source {
        message.push_str(": ");
        message.push_str(&cause.to_string());
        source = cause.source();
    }
    message
}

/// A `PhalanxError` with `message`.
pub(crate) fn bad(message: impl Into<String>) -> PyErr {
    PhalanxError::new_err(message.into())
}

#[pymodule]
fn _phalanx(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("PhalanxError", m.py().get_type::<PhalanxError>())?;
    // The default map settings, phalanx-gen's (the Python layer's defaults read them).
    m.add("DEFAULT_SIZE", phalanx_gen::DEFAULT_SIZE)?;
    m.add("DEFAULT_DENSITY", phalanx_gen::DEFAULT_DENSITY)?;
    m.add("DEFAULT_AGENTS", phalanx_gen::DEFAULT_AGENTS)?;
    m.add("DEFAULT_FOV", phalanx_gen::DEFAULT_FOV)?;
    m.add("TEAM_DEADBAND", phalanx_env::obs::TEAM_DEADBAND)?;
    m.add_class::<world::World>()?;
    m.add_class::<vector::VecWorld>()?;
    m.add_class::<toolkit::PyInstance>()?;
    m.add_class::<policy::PyPolicy>()?;
    m.add_class::<policy::PyHierarchy>()?;
    m.add_function(wrap_pyfunction!(toolkit::generate, m)?)?;
    m.add_function(wrap_pyfunction!(toolkit::read_instance, m)?)?;
    m.add_function(wrap_pyfunction!(toolkit::solve, m)?)?;
    m.add_function(wrap_pyfunction!(toolkit::validate, m)?)?;
    m.add_function(wrap_pyfunction!(toolkit::default_formation_weight, m)?)?;
    Ok(())
}
