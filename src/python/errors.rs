//! Errors across the boundary: core errors become `khepera_gym.errors` classes (ConfigError,
//! ActionError, StateError, KheperaError) or Python's own `MemoryError` (memory the system
//! refused), and a Rust panic is caught here and raised as
//! KheperaError, never as pyo3's PanicException (which escapes `except Exception`).
//!
//! Threading: called with the GIL held. [`guard`] wraps a whole method body, including the parts
//! that release the GIL (`py.detach`), so a panic in the simulation is caught once it is back on
//! the calling thread (rayon re-raises its workers' panics there). Errors carry messages only,
//! no Python objects and no copies of data.

use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::types::PyType;

use crate::error::Error;

/// Raises `err` as the matching class of `khepera_gym.errors` (`MemoryError` for memory the
/// system refused).
pub fn to_py(py: Python<'_>, err: Error) -> PyErr {
    let class = match err {
        Error::Memory(message) => return PyMemoryError::new_err(message),
        Error::Config { .. } | Error::Param(_) => "ConfigError",
        Error::Action(_) => "ActionError",
        Error::State(_) => "KheperaError",
        Error::SavedState(_) => "StateError",
    };
    raise(py, class, err.to_string())
}

/// Raises `class` of `khepera_gym.errors` with `message`.
pub fn raise(py: Python<'_>, class: &str, message: String) -> PyErr {
    let found = py
        .import("khepera_gym.errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
    match found {
        Ok(cls) => PyErr::from_type(cls, message),
        Err(e) => e,
    }
}

/// Runs `f`, turning a panic into KheperaError.
pub fn guard<T>(py: Python<'_>, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(raise(
                py,
                "KheperaError",
                format!("internal error in the simulator core (please report): {what}"),
            ))
        }
    }
}
