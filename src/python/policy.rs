//! The `Policy` class: a baseline controller of `src/controllers/` acting on observations, built
//! from its name and keyword parameters (the controller's own table says which exist, their
//! defaults and their checks; nothing is restated here).
//!
//! Threading and copies: `act` copies the observations into Rust, releases the GIL while
//! acting, and returns a fresh float32 array. A policy is immutable.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::convert::{dict_to_table, layout_from_slices};
use super::errors::{guard, to_py};
use crate::controllers::Policy;
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::scenario::Source;
use crate::tasks::TaskKind;

/// A baseline controller of the paper acting on observations (src/controllers/).
#[pyclass(module = "khepera_gym._core", name = "Policy", frozen)]
pub struct PyPolicy {
    inner: Policy,
}

/// The layout of the observations controller `name` reads by default: the first agent's of
/// its task's default scenario.
fn default_layout(name: &str) -> Result<ObsLayout> {
    let task = Policy::reads(name).ok_or_else(|| {
        Error::config(
            "<policy>",
            "controller",
            format!(
                "unknown controller {name:?}; known: {:?}",
                crate::controllers::NAMES
            ),
        )
    })?;
    let kind = TaskKind::parse(task)
        .ok_or_else(|| Error::config("<policy>", "task", format!("unknown task {task:?}")))?;
    let cfg = kind.scenario(&Source::default())?;
    let agents = kind.agents(&cfg)?;
    Ok(agents
        .into_iter()
        .next()
        .map(|a| a.layout)
        .unwrap_or_default())
}

#[pymethods]
impl PyPolicy {
    /// Controller `name` with keyword `params` (missing ones take their defaults), reading
    /// observations of `layout` ((name, start, stop) triples; None: the default observation of
    /// the task it is for); a leader_follower policy drives a leader block with `leader`.
    #[new]
    #[pyo3(signature = (name, params=None, layout=None, leader=None))]
    fn new(
        py: Python<'_>,
        name: &str,
        params: Option<&Bound<'_, PyDict>>,
        layout: Option<Vec<(String, usize, usize)>>,
        leader: Option<&PyPolicy>,
    ) -> PyResult<Self> {
        guard(py, || {
            let table = match params {
                Some(d) => dict_to_table(py, name, d, None)?,
                None => toml::Table::new(),
            };
            let layout = match layout {
                Some(slices) => layout_from_slices(&slices),
                None => default_layout(name),
            }
            .map_err(|e| to_py(py, e))?;
            let mut policy = Policy::new(name, &table, &layout).map_err(|e| to_py(py, e))?;
            if let Some(leader) = leader {
                policy = policy
                    .with_leader(leader.inner.clone())
                    .map_err(|e| to_py(py, e))?;
            }
            Ok(Self { inner: policy })
        })
    }

    /// The controller's name.
    #[getter]
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    /// Length of the observation rows (for leader_follower: of one follower block) it reads.
    #[getter]
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim()
    }

    /// Actions (N, act_dim) float32 for observations (N, obs_dim).
    fn act<'py>(
        &self,
        py: Python<'py>,
        obs: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<Bound<'py, PyAny>> {
        guard(py, || {
            let shape = obs.shape().to_vec();
            let data: Vec<f32> = match obs.as_slice().ok().filter(|_| obs.is_c_contiguous()) {
                Some(s) => s.to_vec(),
                None => obs.as_array().iter().copied().collect(),
            };
            let act_dim = self.inner.act_dim(shape[1]).map_err(|e| to_py(py, e))?;
            let policy = &self.inner;
            let actions = py
                .detach(|| policy.act_batch(&data, shape[1]))
                .map_err(|e| to_py(py, e))?;
            Ok(PyArray1::from_vec(py, actions)
                .reshape([shape[0], act_dim])?
                .into_any())
        })
    }
}
