//! Module-level functions of `_core`: what the core knows (tasks, controllers, scenarios,
//! layouts) for the Python package to build on, and unit conversions.
//!
//! Units: wheel speeds in m/s or the robot's `kh4_set_speed` units; formation offsets in metres
//! and radians. Threading and copies: every function runs with the GIL held (none simulates, so
//! none releases it) and returns fresh Python values (lists, tuples, strings, numbers) built from
//! the core's declarations; nothing keeps a Python object.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::convert::{layout_slices, task_kind, toml_to_py};
use super::errors::{guard, to_py};
use crate::controllers::Policy;
use crate::error::Error;
use crate::scenario::{self, Source};
use crate::simd;
use crate::tasks::formation::FormationShape;
use crate::tasks::TaskKind;

/// The tasks, in registry order: (name, Gymnasium id without version or None, names of the
/// extra episode statistics).
#[pyfunction]
pub fn tasks() -> Vec<(&'static str, Option<&'static str>, Vec<&'static str>)> {
    TaskKind::ALL
        .iter()
        .map(|k| (k.name(), k.info().env_id, k.extra_stats().to_vec()))
        .collect()
}

/// The behaviour versions of task `name`, oldest first: from the version that added it to the
/// latest.
#[pyfunction]
pub fn task_versions(py: Python<'_>, name: &str) -> PyResult<Vec<u32>> {
    let kind = task_kind(py, name)?;
    Ok((kind.info().schema.since..=scenario::LATEST_VERSION).collect())
}

/// What task `name`'s agents are (its `AgentFacts`): (several agents in its default scenario,
/// alike agents, agents that end separately).
#[pyfunction]
pub fn task_agents(py: Python<'_>, name: &str) -> PyResult<(bool, bool, bool)> {
    let facts = task_kind(py, name)?.info().agents;
    Ok((facts.several, facts.alike, facts.end_separately))
}

/// How task `name` is scored (its `Scoring`), as a dict: success, time, error_prefix, error,
/// termination (str or None), speed, moving_reference, path_trace (bool), and columns, a list
/// of (statistic, header, scale, digits).
#[pyfunction]
pub fn task_scoring<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
    let scoring = task_kind(py, name)?.info().scoring;
    let dict = PyDict::new(py);
    dict.set_item("success", scoring.success)?;
    dict.set_item("time", scoring.time)?;
    dict.set_item("error_prefix", scoring.error_prefix)?;
    dict.set_item("error", scoring.error)?;
    dict.set_item("termination", scoring.termination)?;
    dict.set_item("speed", scoring.speed)?;
    dict.set_item("moving_reference", scoring.moving_reference)?;
    dict.set_item("path_trace", scoring.path_trace)?;
    let columns: Vec<(&str, &str, f64, u32)> = scoring
        .columns
        .iter()
        .map(|c| (c.stat, c.header, c.scale, c.digits))
        .collect();
    dict.set_item("columns", columns)?;
    Ok(dict)
}

/// The behaviour versions, oldest first: (number, title, summary of what changed and why, the
/// previous version's values of the keys it changed as TOML).
#[pyfunction]
pub fn versions() -> Vec<(u32, &'static str, &'static str, &'static str)> {
    scenario::VERSIONS
        .iter()
        .map(|v| (v.number, v.title, v.summary, v.before.trim()))
        .collect()
}

/// The named drives (`motors.preset`): (name, the `[drive]` keys it sets as TOML, who sets it on
/// the real robot).
#[pyfunction]
pub fn motor_presets() -> Vec<(&'static str, &'static str, &'static str)> {
    crate::motors::PRESETS
        .iter()
        .map(|p| (p.name, p.settings, p.source))
        .collect()
}

/// The controllers, in registry order: (name, the task whose observation it reads by default).
#[pyfunction]
pub fn controllers() -> Vec<(&'static str, &'static str)> {
    crate::controllers::NAMES
        .iter()
        .map(|n| (*n, Policy::reads(n).unwrap_or("")))
        .collect()
}

/// The parameters of controller `name`: (name, default value, comment), in order.
#[pyfunction]
pub fn controller_params<'py>(
    py: Python<'py>,
    name: &str,
) -> PyResult<Vec<(&'static str, Bound<'py, PyAny>, &'static str)>> {
    let keys = Policy::params(name).ok_or_else(|| {
        to_py(
            py,
            Error::config(
                "<policy>",
                "controller",
                format!(
                    "unknown controller {name:?}; known: {:?}",
                    crate::controllers::NAMES
                ),
            ),
        )
    })?;
    let defaults = crate::config::keys_table(keys);
    keys.iter()
        .map(|k| {
            let value = defaults
                .get(k.name)
                .map(|v| toml_to_py(py, v))
                .transpose()?
                .unwrap_or_else(|| py.None().into_bound(py));
            Ok((k.name, value, k.comment.trim()))
        })
        .collect()
}

/// The followers' (r, β) offsets of a formation shape ("cross", "line", "wedge", "circle") of
/// `n_followers` at `spacing` metres, as the scenarios' `formation.shape` computes them.
#[pyfunction]
pub fn formation_offsets(
    shape: &str,
    spacing: f32,
    n_followers: usize,
) -> PyResult<Vec<(f32, f32)>> {
    let shape: FormationShape = toml::Value::String(shape.to_string())
        .try_into()
        .map_err(|_| PyValueError::new_err(format!("unknown formation shape {shape:?}")))?;
    Ok(shape
        .offsets(n_followers, spacing)
        .into_iter()
        .map(|[r, b]| (r, b))
        .collect())
}

/// Observation layout of a task with its default scenario: (name, start, stop) in order.
#[pyfunction]
pub fn obs_layout(py: Python<'_>, task: &str) -> PyResult<Vec<(String, usize, usize)>> {
    let kind = task_kind(py, task)?;
    let cfg = kind
        .scenario(&Source::default())
        .map_err(|e| to_py(py, e))?;
    let layout = kind.obs_layout(&cfg).map_err(|e| to_py(py, e))?;
    Ok(layout_slices(&layout))
}

/// A built-in scenario file: a task's defaults for behaviour `version` (None: the latest;
/// every key with its comment) or a scene.
#[pyfunction]
#[pyo3(signature = (name, version=None))]
pub fn default_config(py: Python<'_>, name: &str, version: Option<u32>) -> PyResult<String> {
    if let Some(kind) = TaskKind::parse(name) {
        return kind.default_config(version).map_err(|e| to_py(py, e));
    }
    scenario::scene(name).map(str::to_string).ok_or_else(|| {
        to_py(
            py,
            Error::config(
                "<built-in>",
                "config",
                format!(
                    "no built-in scenario {name:?}; known: {:?}",
                    builtin_configs()
                ),
            ),
        )
    })
}

/// Names of the built-in scenarios: the tasks' defaults, then the scenes.
#[pyfunction]
pub fn builtin_configs() -> Vec<&'static str> {
    TaskKind::ALL
        .iter()
        .map(|k| k.name())
        .chain(scenario::SCENES.iter().map(|(n, _)| *n))
        .collect()
}

/// Default weights of the Braitenberg block (m/s per unit proximity; rows left, right).
#[pyfunction]
pub fn braitenberg_weights(py: Python<'_>, name: &str) -> PyResult<Vec<Vec<f32>>> {
    let w = crate::controllers::braitenberg::Weights::Named(name.to_string())
        .matrix()
        .map_err(|e| to_py(py, e))?;
    Ok(w.iter().map(|r| r.to_vec()).collect())
}

/// Panics inside the binding's guard, for the test that a Rust panic surfaces as KheperaError
/// (never as pyo3's PanicException, which escapes `except Exception`).
#[pyfunction]
pub fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    guard(py, || {
        let rows: Vec<u32> = Vec::new();
        // An out-of-bounds index: the kind of bug the guard exists for.
        let _ = rows[std::hint::black_box(3)];
        Ok(())
    })
}

/// A wheel speed in m/s as the real robot's `kh4_set_speed` units (0.678181 mm/s each).
#[pyfunction]
pub fn speed_to_units(speed: f32) -> PyResult<i32> {
    if !speed.is_finite() || speed.abs() > 10.0 {
        return Err(PyValueError::new_err(format!(
            "speed must be finite, |v| <= 10 m/s, got {speed}"
        )));
    }
    Ok(crate::robot::speed_to_units(speed))
}

/// The real robot's `kh4_set_speed` units as a wheel speed in m/s.
#[pyfunction]
pub fn units_to_speed(units: i32) -> f32 {
    crate::robot::units_to_speed(units)
}

/// The vector paths of the hot kernels, narrowest first: (name, whether this CPU has it).
#[pyfunction]
pub fn simd_paths() -> Vec<(&'static str, bool)> {
    simd::PATHS
        .iter()
        .map(|p| (p.name(), p.available()))
        .collect()
}

/// The vector path the kernels run now.
#[pyfunction]
pub fn simd_path() -> &'static str {
    simd::path().name()
}

/// Runs the kernels on the path `name` from now on, in every thread (the results are the same
/// on every path); a ConfigError for an unknown path or one this CPU lacks.
#[pyfunction]
pub fn force_simd(py: Python<'_>, name: &str) -> PyResult<()> {
    simd::Path::parse(name)
        .and_then(simd::force)
        .map_err(|e| to_py(py, e))
}
