//! Conversions of Python values into the core's: keyword overrides and controller parameters
//! into TOML tables, task names into [`TaskKind`], layouts into (name, start, stop) triples.
//!
//! Threading and copies: called with the GIL held, before any simulation; every value is copied
//! into Rust-owned TOML (or the other way, into fresh Python objects), and nothing here keeps a
//! Python object.

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use super::errors::to_py;
use crate::error::Error;
use crate::obs::{Block, ObsLayout};
use crate::tasks::TaskKind;

/// The task named `name`, or a ConfigError listing the known ones.
pub fn task_kind(py: Python<'_>, name: &str) -> PyResult<TaskKind> {
    TaskKind::parse(name).ok_or_else(|| {
        let known: Vec<&str> = TaskKind::ALL.iter().map(|k| k.name()).collect();
        to_py(
            py,
            Error::config(
                "<batch>",
                "task",
                format!("unknown task {name:?}; known: {known:?}"),
            ),
        )
    })
}

/// Converts a Python override value into TOML.
pub fn to_toml(
    py: Python<'_>,
    origin: &str,
    key: &str,
    value: &Bound<'_, PyAny>,
) -> PyResult<toml::Value> {
    let bad = |what: String| to_py(py, Error::config(origin, key, what));
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(value.extract()?));
    }
    // NumPy arrays and scalars: their Python equivalents (lists, int, float, bool).
    if value.get_type().module()?.to_str()?.starts_with("numpy") && value.hasattr("tolist")? {
        return to_toml(py, origin, key, &value.call_method0("tolist")?);
    }
    // Python ints and NumPy integers (which have __index__ but are not floats).
    let integral = value.is_instance_of::<PyInt>()
        || (value.hasattr("__index__")? && !value.is_instance_of::<PyFloat>());
    if integral {
        return value
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| bad("integer out of range".into()));
    }
    if let Ok(f) = value.extract::<f64>() {
        return Ok(toml::Value::Float(f));
    }
    if let Ok(d) = value.cast::<PyDict>() {
        return Ok(toml::Value::Table(dict_to_table(py, origin, d, Some(key))?));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, item) in value.try_iter()?.enumerate() {
            items.push(to_toml(py, origin, &format!("{key}[{i}]"), &item?)?);
        }
        return Ok(toml::Value::Array(items));
    }
    Err(bad(format!(
        "unsupported value type {} (use bool, int, float, str, list or dict)",
        value.get_type().name()?
    )))
}

/// The overrides (`prefix` None) or the table under the dotted key `prefix`, as TOML.
pub fn dict_to_table(
    py: Python<'_>,
    origin: &str,
    dict: &Bound<'_, PyDict>,
    prefix: Option<&str>,
) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (k, v) in dict.iter() {
        let key: String = k.extract().map_err(|_| {
            to_py(
                py,
                Error::config(
                    origin,
                    prefix.unwrap_or("the overrides"),
                    format!(
                        "keys must be str, got {}",
                        k.repr().map_or("?".into(), |r| r.to_string())
                    ),
                ),
            )
        })?;
        let path = match prefix {
            None => key.clone(),
            Some(prefix) => format!("{prefix}.{key}"),
        };
        table.insert(key, to_toml(py, origin, &path, &v)?);
    }
    Ok(table)
}

/// A short description of a Python value for messages: its type, shape and dtype.
pub fn describe(value: &Bound<'_, PyAny>) -> String {
    let shape = value
        .getattr("shape")
        .map(|s| s.to_string())
        .unwrap_or_default();
    let dtype = value
        .getattr("dtype")
        .map(|s| s.to_string())
        .unwrap_or_default();
    let ty = value
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default();
    if shape.is_empty() {
        ty
    } else {
        format!("{ty} of shape {shape} and dtype {dtype}")
    }
}

/// A layout as (name, start, stop) triples.
pub fn layout_slices(layout: &ObsLayout) -> Vec<(String, usize, usize)> {
    layout
        .slices()
        .into_iter()
        .map(|(name, range)| (name, range.start, range.end))
        .collect()
}

/// A layout from (name, start, stop) triples (contiguous from 0; bounds are not known here).
pub fn layout_from_slices(slices: &[(String, usize, usize)]) -> Result<ObsLayout, Error> {
    let mut at = 0;
    let mut blocks = Vec::new();
    for (name, start, stop) in slices {
        if *start != at || stop < start {
            return Err(Error::Param(format!(
                "layout: block {name:?} spans {start}..{stop}, expected it to start at {at} \
                 (blocks are contiguous from 0)"
            )));
        }
        blocks.push(Block::new(
            name,
            stop - start,
            f32::NEG_INFINITY,
            f32::INFINITY,
        ));
        at = *stop;
    }
    Ok(ObsLayout::new(blocks))
}

/// A TOML value as the Python value it stands for (bool, int, float, str, list, dict).
pub fn toml_to_py<'py>(py: Python<'py>, value: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        toml::Value::Boolean(b) => PyBool::new(py, *b).to_owned().into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(toml_to_py(py, item)?)?;
            }
            list.into_any()
        }
        toml::Value::Table(table) => {
            let dict = PyDict::new(py);
            for (k, v) in table {
                dict.set_item(k, toml_to_py(py, v)?)?;
            }
            dict.into_any()
        }
    })
}
