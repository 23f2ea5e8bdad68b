//! The `khepera_gym._core` Python module: the `Batch` class and layout/config helpers.
//!
//! Threading and copies: every method checks its inputs while holding the GIL, copies them into
//! Rust-owned buffers, releases the GIL (`py.detach`) for the simulation, then copies results
//! into freshly allocated NumPy arrays (never views of internal buffers). No Python object
//! crosses into the released section.
//!
//! Errors: core errors become `khepera_gym.errors` classes (ConfigError, ActionError,
//! KheperaError); a Rust panic is caught at this boundary and raised as KheperaError, never as
//! pyo3's PanicException.

use std::panic::{catch_unwind, AssertUnwindSafe};

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple, PyType};

use crate::batch::Batch as CoreBatch;
use crate::controllers::{Braitenberg, LeaderFollower, Policy, PositionControl, Vfh, WheelMap};
use crate::error::Error;
use crate::robot::{ActionType, PULSES_PER_WHEEL_TURN};
use crate::scenario::{self, Scenario, Source};
use crate::tasks::{EpisodeStats, TaskKind};
use crate::world::scene::Geometry;

/// Raises `err` as the matching class of `khepera_gym.errors`.
fn to_py(py: Python<'_>, err: Error) -> PyErr {
    let class = match err {
        Error::Config { .. } => "ConfigError",
        Error::Action(_) => "ActionError",
        Error::State(_) => "KheperaError",
        Error::SavedState(_) => "StateError",
    };
    raise(py, class, err.to_string())
}

fn raise(py: Python<'_>, class: &str, message: String) -> PyErr {
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
fn guard<T>(py: Python<'_>, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
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

fn task_kind(py: Python<'_>, name: &str) -> PyResult<TaskKind> {
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
fn to_toml(py: Python<'_>, key: &str, value: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    let bad = |what: String| to_py(py, Error::config(scenario::OVERRIDE_ORIGIN, key, what));
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(value.extract()?));
    }
    // NumPy arrays and scalars: their Python equivalents (lists, int, float, bool).
    if value.get_type().module()?.to_str()?.starts_with("numpy") && value.hasattr("tolist")? {
        return to_toml(py, key, &value.call_method0("tolist")?);
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
        return Ok(toml::Value::Table(dict_to_table(py, d, Some(key))?));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, item) in value.try_iter()?.enumerate() {
            items.push(to_toml(py, &format!("{key}[{i}]"), &item?)?);
        }
        return Ok(toml::Value::Array(items));
    }
    Err(bad(format!(
        "unsupported value type {} (use bool, int, float, str, list or dict)",
        value.get_type().name()?
    )))
}

/// The overrides (`prefix` None) or the table under the dotted key `prefix`, as TOML.
fn dict_to_table(
    py: Python<'_>,
    dict: &Bound<'_, PyDict>,
    prefix: Option<&str>,
) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (k, v) in dict.iter() {
        let key: String = k.extract().map_err(|_| {
            to_py(
                py,
                Error::config(
                    scenario::OVERRIDE_ORIGIN,
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
        table.insert(key, to_toml(py, &path, &v)?);
    }
    Ok(table)
}

/// N independent seeded Khepera IV worlds of one task, stepped in parallel.
#[pyclass(module = "khepera_gym._core")]
pub struct Batch {
    inner: CoreBatch,
    actions: Vec<f32>,
    /// Construction arguments not held by the core, for pickling.
    action_type: String,
    requested_threads: Option<usize>,
    autoreset: bool,
    trail_length: usize,
}

#[pymethods]
impl Batch {
    #[new]
    #[pyo3(signature = (task, num_worlds, config_text=None, config_name="<built-in>", overrides=None, action_type="wheels", num_threads=None, autoreset=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        task: &str,
        num_worlds: i64,
        config_text: Option<String>,
        config_name: &str,
        overrides: Option<&Bound<'_, PyDict>>,
        action_type: &str,
        num_threads: Option<i64>,
        autoreset: bool,
    ) -> PyResult<Self> {
        guard(py, || {
            let kind = task_kind(py, task)?;
            let overrides = match overrides {
                Some(d) => dict_to_table(py, d, None)?,
                None => toml::Table::new(),
            };
            let source = Source {
                file: config_text.as_deref().map(|t| (t, config_name)),
                overrides,
            };
            let cfg = Scenario::load(kind.name(), &source).map_err(|e| to_py(py, e))?;
            let action_type = ActionType::parse(action_type).ok_or_else(|| {
                to_py(
                    py,
                    Error::config(
                        "<batch>",
                        "action_type",
                        format!("must be \"wheels\" or \"unicycle\", got {action_type:?}"),
                    ),
                )
            })?;
            if num_worlds < 1 {
                return Err(to_py(
                    py,
                    Error::config(
                        "<batch>",
                        "num_envs",
                        format!("must be >= 1, got {num_worlds}"),
                    ),
                ));
            }
            let num_threads = match num_threads {
                None => None,
                Some(n) if n < 1 => {
                    return Err(to_py(
                        py,
                        Error::config("<batch>", "num_threads", format!("must be >= 1, got {n}")),
                    ))
                }
                Some(n) => Some(n as usize),
            };
            let inner = py
                .detach(|| {
                    CoreBatch::new(
                        kind,
                        cfg,
                        num_worlds as usize,
                        action_type,
                        num_threads,
                        autoreset,
                    )
                })
                .map_err(|e| to_py(py, e))?;
            let actions = vec![0.0; inner.len() * inner.act_dim()];
            Ok(Self {
                inner,
                actions,
                action_type: action_type.name().to_string(),
                requested_threads: num_threads,
                autoreset,
                trail_length: 0,
            })
        })
    }

    /// Number of worlds.
    #[getter]
    fn num_worlds(&self) -> usize {
        self.inner.len()
    }

    /// Observation length per world.
    #[getter]
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim()
    }

    /// Action length per world.
    #[getter]
    fn act_dim(&self) -> usize {
        self.inner.act_dim()
    }

    /// Robots per world.
    #[getter]
    fn n_robots(&self) -> usize {
        self.inner.envs()[0].world.robots.len()
    }

    /// Threads stepping the batch.
    #[getter]
    fn num_threads(&self) -> usize {
        self.inner.num_threads()
    }

    /// Steps before truncation.
    #[getter]
    fn max_episode_steps(&self) -> u32 {
        self.inner.scenario().task.max_steps
    }

    /// Joint observation layout of this batch's scenario: (name, start, stop) in order.
    fn obs_layout(&self) -> Vec<(String, usize, usize)> {
        let env = &self.inner.envs()[0];
        layout_slices(env.kind().obs_layout(&env.cfg))
    }

    /// The agents: (name, robot index, obs start, obs stop, [(name, start, stop) of its own
    /// block]) in joint order; agent i's action is columns 2i, 2i+1.
    #[allow(clippy::type_complexity)]
    fn agents(&self) -> Vec<(String, usize, usize, usize, Vec<(String, usize, usize)>)> {
        let env = &self.inner.envs()[0];
        let mut start = 0;
        env.kind()
            .agents(&env.cfg)
            .into_iter()
            .map(|a| {
                let n = a.obs_dim();
                let own =
                    layout_slices(a.layout.iter().map(|(k, n)| (k.to_string(), *n)).collect());
                let item = (a.name, a.robot, start, start + n, own);
                start += n;
                item
            })
            .collect()
    }

    /// Each agent's reward on the last step, shape (N, n_agents).
    fn agent_rewards<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.per_agent(py, |e| &e.agent_rewards)
    }

    /// Each agent's termination on the last step, shape (N, n_agents).
    fn agent_terminated<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.per_agent(py, |e| &e.agent_terminated)
    }

    /// Formation targets of the followers, shape (N, K, 2) (K = 0 for other tasks).
    fn formation_targets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let targets: Vec<Vec<_>> = self
            .inner
            .envs()
            .iter()
            .map(|e| e.formation_targets())
            .collect();
        let k = targets.first().map_or(0, Vec::len);
        let data: Vec<f64> = targets
            .iter()
            .flatten()
            .flat_map(|p| [p.x as f64, p.y as f64])
            .collect();
        Ok(PyArray1::from_vec(py, data)
            .reshape([self.inner.len(), k, 2])?
            .into_any())
    }

    /// Name of the task.
    #[getter]
    fn task(&self) -> &'static str {
        self.inner.envs()[0].kind().name()
    }

    /// (low, high) observation bounds.
    fn obs_bounds<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f32>>, Bound<'py, PyArray1<f32>>) {
        let env = &self.inner.envs()[0];
        let (low, high) = env.kind().obs_bounds(&env.cfg);
        (PyArray1::from_vec(py, low), PyArray1::from_vec(py, high))
    }

    /// Resets every world (world i seeded with seed + i); returns observations (N, obs_dim).
    #[pyo3(signature = (seed=None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Bound<'py, PyAny>> {
        guard(py, || {
            let inner = &mut self.inner;
            py.detach(|| inner.reset(seed));
            self.obs_array(py)
        })
    }

    /// Resets world `index` (seeded with `seed` when given); returns its observation.
    #[pyo3(signature = (index, seed=None))]
    fn reset_world<'py>(
        &mut self,
        py: Python<'py>,
        index: usize,
        seed: Option<u64>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        guard(py, || {
            let obs = self
                .inner
                .reset_world(index, seed)
                .map_err(|e| to_py(py, e))?;
            Ok(PyArray1::from_slice(py, obs))
        })
    }

    /// Steps all worlds with actions (N, act_dim) float32.
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: &Bound<'py, PyAny>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
    )> {
        guard(py, || {
            let (n, d) = (self.inner.len(), self.inner.act_dim());
            let array: PyReadonlyArray2<f32> = actions.extract().map_err(|_| {
                to_py(
                    py,
                    Error::Action(format!(
                        "actions must be a float32 array of shape ({n}, {d}), got {}",
                        describe(actions)
                    )),
                )
            })?;
            if array.shape() != [n, d] {
                return Err(to_py(
                    py,
                    Error::Action(format!(
                        "actions must have shape ({n}, {d}), got {:?}",
                        array.shape()
                    )),
                ));
            }
            // as_slice() also accepts column-major data: only take it for C order.
            match array.as_slice().ok().filter(|_| array.is_c_contiguous()) {
                Some(s) => self.actions.copy_from_slice(s),
                None => {
                    for (dst, src) in self.actions.iter_mut().zip(array.as_array().iter()) {
                        *dst = *src;
                    }
                }
            }
            let (inner, acts) = (&mut self.inner, &self.actions);
            py.detach(|| inner.step(acts)).map_err(|e| to_py(py, e))?;
            let outcomes = self.inner.outcomes();
            let rewards: Vec<f32> = outcomes.iter().map(|o| o.reward).collect();
            let terminated: Vec<bool> = outcomes.iter().map(|o| o.terminated).collect();
            let truncated: Vec<bool> = outcomes.iter().map(|o| o.truncated).collect();
            Ok((
                self.obs_array(py)?,
                PyArray1::from_vec(py, rewards),
                PyArray1::from_vec(py, terminated),
                PyArray1::from_vec(py, truncated),
            ))
        })
    }

    /// Statistics of the episodes that ended on the last step (valid where they ended).
    fn episode_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let stats: Vec<_> = self.inner.episode_stats().copied().collect();
        let d = PyDict::new(py);
        let f32s = |f: fn(&EpisodeStats) -> f32| PyArray1::from_iter(py, stats.iter().map(f));
        let i64s = |f: fn(&EpisodeStats) -> i64| PyArray1::from_iter(py, stats.iter().map(f));
        d.set_item("return", f32s(|s| s.ret))?;
        d.set_item("length", i64s(|s| s.length as i64))?;
        d.set_item(
            "success",
            PyArray1::from_iter(py, stats.iter().map(|s| s.success)),
        )?;
        d.set_item("path_length", f32s(|s| s.path_length))?;
        d.set_item("collisions", i64s(|s| s.collisions as i64))?;
        if self.inner.envs()[0].kind() == TaskKind::Formation {
            d.set_item("formation_error_mean", f32s(|s| s.formation_error_mean))?;
            d.set_item("formation_error_max", f32s(|s| s.formation_error_max))?;
        }
        Ok(d)
    }

    /// Robot poses (N, n_robots, 3): x, y, theta.
    fn poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let r = self.n_robots();
        let data: Vec<f64> = self
            .inner
            .envs()
            .iter()
            .flat_map(|e| e.world.robots.iter())
            .flat_map(|r| [r.position.x as f64, r.position.y as f64, r.heading as f64])
            .collect();
        Ok(PyArray1::from_vec(py, data)
            .reshape([self.inner.len(), r, 3])?
            .into_any())
    }

    /// Goal positions (N, n_goals, 2).
    fn goals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let g = self.inner.envs()[0].n_goals();
        let data: Vec<f64> = self
            .inner
            .envs()
            .iter()
            .flat_map(|e| e.goals())
            .flat_map(|p| [p.x as f64, p.y as f64])
            .collect();
        Ok(PyArray1::from_vec(py, data)
            .reshape([self.inner.len(), g, 2])?
            .into_any())
    }

    /// Raw sensor readings of the last observation, in the real robot's units.
    fn sensor_readings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (n, r) = (self.inner.len(), self.n_robots());
        let robots = || self.inner.envs().iter().flat_map(|e| e.world.robots.iter());
        let wheel_circumference =
            2.0 * std::f64::consts::PI * self.inner.scenario().robot.wheel_radius as f64;
        let d = PyDict::new(py);
        let ir: Vec<i32> = robots().flat_map(|r| r.ir_raw.map(i32::from)).collect();
        d.set_item("ir_raw", PyArray1::from_vec(py, ir).reshape([n, r, 8])?)?;
        let us: Vec<i32> = robots().flat_map(|r| r.us_code).collect();
        d.set_item("us_cm", PyArray1::from_vec(py, us).reshape([n, r, 5])?)?;
        let wheels: Vec<f32> = robots().flat_map(|r| r.wheel_speeds).collect();
        d.set_item(
            "wheel_speeds",
            PyArray1::from_vec(py, wheels).reshape([n, r, 2])?,
        )?;
        let encoders: Vec<i64> = robots()
            .flat_map(|r| {
                r.wheel_travel
                    .map(|t| (t / wheel_circumference * PULSES_PER_WHEEL_TURN).round() as i64)
            })
            .collect();
        d.set_item(
            "encoders",
            PyArray1::from_vec(py, encoders).reshape([n, r, 2])?,
        )?;
        let gyro: Vec<f32> = robots().map(|r| r.yaw_rate).collect();
        d.set_item("gyro_z", PyArray1::from_vec(py, gyro).reshape([n, r])?)?;
        Ok(d)
    }

    /// Geometry of world `index` for plots.
    #[pyo3(signature = (index=0))]
    fn scene<'py>(&self, py: Python<'py>, index: usize) -> PyResult<Bound<'py, PyDict>> {
        let env = self.inner.envs().get(index).ok_or_else(|| {
            to_py(
                py,
                Error::State(format!(
                    "world index {index} out of range 0..{}",
                    self.inner.len()
                )),
            )
        })?;
        let scene = &env.world.scene;
        let d = PyDict::new(py);
        d.set_item("arena", scene.arena)?;
        d.set_item("walls", scene.walled)?;
        d.set_item("wall_thickness", scene.wall_thickness)?;
        d.set_item("robot_radius", env.cfg.robot.radius)?;
        d.set_item("goal_radius", env.cfg.task.goal_radius)?;
        let obstacles = PyList::empty(py);
        for shape in &scene.shapes {
            let o = PyDict::new(py);
            let c = (shape.center.x, shape.center.y);
            match shape.geometry {
                Geometry::Circle(b) => {
                    o.set_item("kind", "circle")?;
                    o.set_item("center", c)?;
                    o.set_item("radius", b.radius)?;
                }
                Geometry::Box(b) => {
                    o.set_item("kind", "box")?;
                    o.set_item("center", c)?;
                    o.set_item("half_extents", (b.half_extents.x, b.half_extents.y))?;
                    o.set_item("angle", shape.angle)?;
                }
                Geometry::Segment(s) => {
                    o.set_item("kind", "segment")?;
                    o.set_item("a", (s.a.x + c.0, s.a.y + c.1))?;
                    o.set_item("b", (s.b.x + c.0, s.b.y + c.1))?;
                }
            }
            obstacles.append(o)?;
        }
        d.set_item("obstacles", obstacles)?;
        Ok(d)
    }

    /// An RGB frame (height, width, 3) uint8 of world `index`, drawn without a display.
    #[pyo3(signature = (index=0, width=480, height=480))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        index: usize,
        width: u32,
        height: u32,
    ) -> PyResult<Bound<'py, PyAny>> {
        guard(py, || {
            let env = self.inner.envs().get(index).ok_or_else(|| {
                to_py(
                    py,
                    Error::State(format!(
                        "world index {index} out of range 0..{}",
                        self.inner.len()
                    )),
                )
            })?;
            if !(16..=4096).contains(&width) || !(16..=4096).contains(&height) {
                return Err(PyValueError::new_err(format!(
                    "frame size must be 16..=4096 pixels a side, got {width}x{height}"
                )));
            }
            let rgb = py.detach(|| crate::render::render(env, width, height));
            Ok(PyArray1::from_vec(py, rgb)
                .reshape([height as usize, width as usize, 3])?
                .into_any())
        })
    }

    /// Keeps the last `length` positions of every robot for the trails of `render` (0: off).
    fn set_trail_length(&mut self, length: usize) {
        self.trail_length = length.min(100_000);
        self.inner.set_trail_length(self.trail_length);
    }

    /// The resolved scenario as TOML text.
    fn config_toml(&self) -> String {
        self.inner.scenario().to_toml()
    }

    /// The state of every world (poses, velocities, contacts, random streams, step counters,
    /// task state) and of the last outputs, as bytes for `set_state`.
    fn get_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        guard(py, || {
            let inner = &self.inner;
            let bytes = py.detach(|| inner.save_state()).map_err(|e| to_py(py, e))?;
            Ok(PyBytes::new(py, &bytes))
        })
    }

    /// Pickling: the resolved scenario, the construction arguments and the state; unpickling
    /// builds the same batch and restores the state (`_batch_from_state`).
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let this = slf.borrow();
        let state = this.get_state(py)?;
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
        )
            .into_pyobject(py)?;
        Ok((rebuild, args))
    }

    /// Restores a state from `get_state` of a batch of the same task, scenario and size.
    fn set_state(&mut self, py: Python<'_>, state: &Bound<'_, PyAny>) -> PyResult<()> {
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

impl Batch {
    /// A per-agent field of every world as an (N, n_agents) array.
    fn per_agent<'py, T: numpy::Element + Copy>(
        &self,
        py: Python<'py>,
        field: impl Fn(&crate::tasks::Env) -> &Vec<T>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n_agents = field(&self.inner.envs()[0]).len();
        let data: Vec<T> = self
            .inner
            .envs()
            .iter()
            .flat_map(|e| field(e).iter().copied())
            .collect();
        Ok(PyArray1::from_vec(py, data)
            .reshape([self.inner.len(), n_agents])?
            .into_any())
    }

    fn obs_array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        Ok(PyArray1::from_slice(py, self.inner.obs())
            .reshape([self.inner.len(), self.inner.obs_dim()])?
            .into_any())
    }
}

fn describe(value: &Bound<'_, PyAny>) -> String {
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

/// A baseline controller of the paper acting on observations (src/controllers/).
#[pyclass(module = "khepera_gym._core", name = "Policy", frozen)]
pub struct PyPolicy {
    inner: Policy,
}

fn wheel_map(axle_length: f32, max_wheel_speed: f32) -> PyResult<WheelMap> {
    if !(axle_length > 0.0 && axle_length.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "axle_length must be > 0, got {axle_length}"
        )));
    }
    if !(max_wheel_speed > 0.0 && max_wheel_speed.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "max_wheel_speed must be > 0, got {max_wheel_speed}"
        )));
    }
    Ok(WheelMap {
        axle_length,
        max_wheel_speed,
    })
}

fn position_control(vmax: f32, wmax: f32, kr: f32, stop_radius: f32) -> PyResult<PositionControl> {
    for (name, v) in [("vmax", vmax), ("wmax", wmax), ("kr", kr)] {
        if !(v > 0.0 && v.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "{name} must be > 0, got {v}"
            )));
        }
    }
    if !(stop_radius >= 0.0 && stop_radius.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "stop_radius must be >= 0, got {stop_radius}"
        )));
    }
    Ok(PositionControl {
        vmax,
        wmax,
        kr,
        stop_radius,
    })
}

fn braitenberg(weights: Vec<Vec<f32>>, threshold: f32) -> PyResult<Braitenberg> {
    if weights.len() != 2 || weights.iter().any(|row| row.len() != 8) {
        return Err(PyValueError::new_err(
            "weights must be a 2 x 8 matrix (left wheel row, right wheel row; K-Team sensor order)",
        ));
    }
    if weights.iter().flatten().any(|w| !w.is_finite()) || threshold.is_nan() || threshold < 0.0 {
        return Err(PyValueError::new_err(
            "weights must be finite and threshold >= 0",
        ));
    }
    let mut w = [[0.0f32; 8]; 2];
    for (dst, src) in w.iter_mut().zip(&weights) {
        dst.copy_from_slice(src);
    }
    Ok(Braitenberg {
        weights: w,
        threshold,
    })
}

#[pymethods]
impl PyPolicy {
    /// Position control, eqs. 1–4.
    #[staticmethod]
    fn position_control(
        vmax: f32,
        wmax: f32,
        kr: f32,
        stop_radius: f32,
        axle_length: f32,
        max_wheel_speed: f32,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: Policy::PositionControl(
                position_control(vmax, wmax, kr, stop_radius)?,
                wheel_map(axle_length, max_wheel_speed)?,
            ),
        })
    }

    /// Position control followed by Braitenberg avoidance, eqs. 1–7.
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn braitenberg(
        weights: Vec<Vec<f32>>,
        threshold: f32,
        vmax: f32,
        wmax: f32,
        kr: f32,
        stop_radius: f32,
        axle_length: f32,
        max_wheel_speed: f32,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: Policy::Braitenberg(
                position_control(vmax, wmax, kr, stop_radius)?,
                braitenberg(weights, threshold)?,
                wheel_map(axle_length, max_wheel_speed)?,
            ),
        })
    }

    /// Vector Field Histogram, eqs. 8–11.
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn vfh(
        sectors: usize,
        threshold: f32,
        hm: f32,
        vmax: f32,
        wmax: f32,
        kr: f32,
        stop_radius: f32,
        us_range: f32,
        beam_width: f32,
        min_valley: f32,
        axle_length: f32,
        max_wheel_speed: f32,
    ) -> PyResult<Self> {
        if !(4..=360).contains(&sectors) {
            return Err(PyValueError::new_err(format!(
                "sectors must be in 4..=360, got {sectors}"
            )));
        }
        position_control(vmax, wmax, kr, stop_radius)?;
        for (name, v) in [
            ("threshold", threshold),
            ("hm", hm),
            ("us_range", us_range),
            ("beam_width", beam_width),
            ("min_valley", min_valley),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "{name} must be > 0, got {v}"
                )));
            }
        }
        Ok(Self {
            inner: Policy::Vfh(
                Vfh {
                    sectors,
                    threshold,
                    hm,
                    vmax,
                    wmax,
                    kr,
                    stop_radius,
                    us_range,
                    beam_width,
                    min_valley,
                    ..Vfh::default()
                },
                wheel_map(axle_length, max_wheel_speed)?,
            ),
        })
    }

    /// Leader–follower formation control, eq. 12; `offsets` None follows the observation's
    /// own targets; `weights` None turns avoidance off; `leader` drives a leader block.
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn leader_follower(
        offsets: Option<Vec<(f32, f32)>>,
        vmax: f32,
        wmax: f32,
        kr: f32,
        stop_radius: f32,
        feedforward: bool,
        weights: Option<Vec<Vec<f32>>>,
        threshold: f32,
        leader: &PyPolicy,
        axle_length: f32,
        max_wheel_speed: f32,
    ) -> PyResult<Self> {
        let control = position_control(vmax, wmax, kr, stop_radius)?;
        let avoidance = weights.map(|w| braitenberg(w, threshold)).transpose()?;
        let make = |offset| LeaderFollower {
            offset,
            control,
            feedforward,
            avoidance,
        };
        let followers = match offsets {
            None => vec![make(None)],
            Some(list) => {
                if list
                    .iter()
                    .any(|(r, b)| !r.is_finite() || !b.is_finite() || *r < 0.0)
                {
                    return Err(PyValueError::new_err(
                        "offsets must be finite (r >= 0, beta) pairs",
                    ));
                }
                list.into_iter().map(|(r, b)| make(Some([r, b]))).collect()
            }
        };
        Ok(Self {
            inner: Policy::LeaderFollower {
                followers,
                leader: Box::new(leader.inner.clone()),
                wheels: wheel_map(axle_length, max_wheel_speed)?,
            },
        })
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

/// Default weights of the Braitenberg block (m/s per unit proximity; rows left, right).
#[pyfunction]
fn braitenberg_weights(name: &str) -> PyResult<Vec<Vec<f32>>> {
    let w = match name {
        "default" => crate::controllers::braitenberg::DEFAULT_WEIGHTS,
        "kteam" => crate::controllers::braitenberg::KTEAM_WEIGHTS,
        _ => {
            return Err(PyValueError::new_err(format!(
                "unknown weight set {name:?}; known: \"default\", \"kteam\""
            )))
        }
    };
    Ok(w.iter().map(|r| r.to_vec()).collect())
}

/// Observation layout of a task with its default scenario: (name, start, stop) in order.
#[pyfunction]
fn obs_layout(py: Python<'_>, task: &str) -> PyResult<Vec<(String, usize, usize)>> {
    let kind = task_kind(py, task)?;
    let cfg = Scenario::load(kind.name(), &Source::default()).map_err(|e| to_py(py, e))?;
    Ok(layout_slices(kind.obs_layout(&cfg)))
}

fn layout_slices(layout: Vec<(String, usize)>) -> Vec<(String, usize, usize)> {
    let mut start = 0;
    layout
        .into_iter()
        .map(|(name, len)| {
            let item = (name, start, start + len);
            start += len;
            item
        })
        .collect()
}

/// The built-in scenario file of `name` (TOML text).
#[pyfunction]
fn default_config(py: Python<'_>, name: &str) -> PyResult<String> {
    scenario::builtin(name).map(str::to_string).ok_or_else(|| {
        let known: Vec<&str> = scenario::BUILTIN.iter().map(|(n, _)| *n).collect();
        to_py(
            py,
            Error::config(
                "<built-in>",
                "config",
                format!("no built-in scenario {name:?}; known: {known:?}"),
            ),
        )
    })
}

/// Panics inside the binding's guard, for the test that a Rust panic surfaces as KheperaError
/// (never as pyo3's PanicException, which escapes `except Exception`).
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    guard(py, || {
        let rows: Vec<u32> = Vec::new();
        // An out-of-bounds index: the kind of bug the guard exists for.
        let _ = rows[std::hint::black_box(3)];
        Ok(())
    })
}

/// A wheel speed in m/s as the real robot's `kh4_set_speed` units (0.678181 mm/s each).
#[pyfunction]
fn speed_to_units(speed: f32) -> PyResult<i32> {
    if !speed.is_finite() || speed.abs() > 10.0 {
        return Err(PyValueError::new_err(format!(
            "speed must be finite, |v| <= 10 m/s, got {speed}"
        )));
    }
    Ok(crate::robot::speed_to_units(speed))
}

/// The real robot's `kh4_set_speed` units as a wheel speed in m/s.
#[pyfunction]
fn units_to_speed(units: i32) -> f32 {
    crate::robot::units_to_speed(units)
}

/// Unpickles a `Batch` (see `Batch.__reduce__`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn _batch_from_state(
    py: Python<'_>,
    task: &str,
    num_worlds: i64,
    config_text: String,
    action_type: &str,
    num_threads: Option<i64>,
    autoreset: bool,
    trail_length: usize,
    state: &Bound<'_, PyAny>,
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
    )?;
    batch.set_trail_length(trail_length);
    batch.set_state(py, state)?;
    Ok(batch)
}

/// Names of the built-in scenarios.
#[pyfunction]
fn builtin_configs() -> Vec<&'static str> {
    scenario::BUILTIN.iter().map(|(n, _)| *n).collect()
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Batch>()?;
    m.add_class::<PyPolicy>()?;
    m.add_function(wrap_pyfunction!(braitenberg_weights, m)?)?;
    m.add_function(wrap_pyfunction!(obs_layout, m)?)?;
    m.add_function(wrap_pyfunction!(default_config, m)?)?;
    m.add_function(wrap_pyfunction!(_batch_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_configs, m)?)?;
    m.add_function(wrap_pyfunction!(speed_to_units, m)?)?;
    m.add_function(wrap_pyfunction!(units_to_speed, m)?)?;
    m.add("MAX_WHEEL_SPEED", crate::robot::MAX_WHEEL_SPEED)?;
    m.add("MIN_WHEEL_SPEED", crate::robot::MIN_WHEEL_SPEED)?;
    m.add("AXLE_LENGTH", crate::robot::AXLE_LENGTH)?;
    m.add("BODY_RADIUS", crate::robot::BODY_RADIUS)?;
    m.add("WHEEL_RADIUS", crate::robot::WHEEL_RADIUS)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    Ok(())
}
