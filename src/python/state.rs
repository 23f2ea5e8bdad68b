//! Saved states and pickling of the `Batch` class: the state of every world as bytes
//! (`get_state`, `set_state`), and `__reduce__`, whose `_batch_from_state` builds the same batch
//! again from its resolved scenario and construction arguments and restores the state.
//!
//! Threading and copies: the state is written and read with the GIL released (`py.detach`),
//! from and into a Rust-owned byte buffer, copied into or out of a Python `bytes` object while
//! the GIL is held. No Python object crosses into the released section.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};

use super::batch::Batch;
use super::errors::{guard, raise, to_py};

impl Batch {
    /// `get_state`: the state of every world and of the last outputs, as bytes.
    pub(super) fn state_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        guard(py, || {
            let inner = &self.inner;
            let bytes = py.detach(|| inner.save_state()).map_err(|e| to_py(py, e))?;
            Ok(PyBytes::new(py, &bytes))
        })
    }

    /// `__reduce__`: `_batch_from_state` and its arguments.
    pub(super) fn reduce<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let this = slf.borrow();
        let state = this.state_bytes(py)?;
        let rebuild = py
            .import("khepera_gym._core")?
            .getattr("_batch_from_state")?;
        let args = (
            this.inner.envs()[0].kind().name(),
            this.inner.len(),
            this.inner.scenario().to_toml(),
            this.action_type.clone(),
            this.requested_threads,
            this.autoreset,
            this.trail_length,
            state,
            this.version,
        )
            .into_pyobject(py)?;
        Ok((rebuild, args))
    }

    /// `set_state`: restores `state`, the bytes of `get_state`.
    pub(super) fn restore_state(
        &mut self,
        py: Python<'_>,
        state: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        guard(py, || {
            let bytes: Vec<u8> = match state.cast::<PyBytes>() {
                Ok(b) => b.as_bytes().to_vec(),
                Err(_) => {
                    let kind = state.get_type().name()?;
                    return Err(raise(
                        py,
                        "StateError",
                        format!("a state is the bytes get_state() returned, got {kind}"),
                    ));
                }
            };
            let inner = &mut self.inner;
            py.detach(|| inner.load_state(&bytes))
                .map_err(|e| to_py(py, e))
        })
    }
}

/// Unpickles a `Batch` (see `Batch.__reduce__`).
#[pyfunction]
#[pyo3(signature = (task, num_worlds, config_text, action_type, num_threads, autoreset, trail_length, state, version=None))]
#[allow(clippy::too_many_arguments)]
pub fn _batch_from_state(
    py: Python<'_>,
    task: &str,
    num_worlds: i64,
    config_text: String,
    action_type: &str,
    num_threads: Option<i64>,
    autoreset: bool,
    trail_length: usize,
    state: &Bound<'_, PyAny>,
    version: Option<u32>,
) -> PyResult<Batch> {
    let mut batch = Batch::new(
        py,
        task,
        num_worlds,
        Some(config_text),
        "<pickled>",
        None,
        action_type,
        num_threads,
        autoreset,
        version,
    )?;
    batch.set_trail_length(trail_length);
    batch.restore_state(py, state)?;
    Ok(batch)
}
