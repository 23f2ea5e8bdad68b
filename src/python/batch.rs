//! The `Batch` class: N seeded worlds of one task in the Rust core, as Python sees them: its
//! construction, the simulation (reset, step, render, saved states and pickling) and small
//! accessors; the dicts of sensor readings, scene geometry and episode statistics are built in
//! `views.rs`, saved states and pickling in `state.rs`.
//!
//! Units: actions normalised to [-1, 1] (two per agent), observations as the layout says,
//! poses and goals in metres and radians in the world frame (arena centred at the origin).
//!
//! Threading and copies: every method checks its inputs while holding the GIL, copies them into
//! Rust-owned buffers, releases the GIL (`py.detach`) for the simulation, then copies results
//! into freshly allocated NumPy arrays (never views of internal buffers). No Python object
//! crosses into the released section.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};

use super::convert::{describe, dict_to_table, layout_slices, task_kind};
use super::errors::{guard, to_py};
use super::views;
use crate::batch::Batch as CoreBatch;
use crate::config::OVERRIDE_ORIGIN;
use crate::error::Error;
use crate::robot::ActionType;
use crate::scenario::Source;

/// N independent seeded Khepera IV worlds of one task, stepped in parallel.
#[pyclass(module = "khepera_gym._core")]
pub struct Batch {
    pub(super) inner: CoreBatch,
    actions: Vec<f32>,
    /// Construction arguments not held by the core, for pickling (`state.rs`).
    pub(super) action_type: String,
    pub(super) requested_threads: Option<usize>,
    pub(super) autoreset: bool,
    pub(super) trail_length: usize,
    /// The behaviour version whose defaults the scenario started from.
    pub(super) version: u32,
}

#[pymethods]
impl Batch {
    #[new]
    #[pyo3(signature = (task, num_worlds, config_text=None, config_name="<built-in>", overrides=None, action_type="wheels", num_threads=None, autoreset=true, version=None))]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        py: Python<'_>,
        task: &str,
        num_worlds: i64,
        config_text: Option<String>,
        config_name: &str,
        overrides: Option<&Bound<'_, PyDict>>,
        action_type: &str,
        num_threads: Option<i64>,
        autoreset: bool,
        version: Option<u32>,
    ) -> PyResult<Self> {
        guard(py, || {
            let kind = task_kind(py, task)?;
            let overrides = match overrides {
                Some(d) => dict_to_table(py, OVERRIDE_ORIGIN, d, None)?,
                None => toml::Table::new(),
            };
            let source = Source {
                file: config_text.as_deref().map(|t| (t, config_name)),
                overrides,
                version,
            };
            let cfg = kind.scenario(&source).map_err(|e| to_py(py, e))?;
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
                version: version.unwrap_or(crate::scenario::LATEST_VERSION),
            })
        })
    }

    /// The behaviour version whose defaults the scenario started from (`version`, or the
    /// latest).
    #[getter]
    fn version(&self) -> u32 {
        self.version
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

    /// Action values per agent: 2 (its wheels), 5 with `task.led_action` (then its LEDs' red,
    /// green, blue).
    #[getter]
    fn agent_act_dim(&self) -> usize {
        crate::tasks::action_width(self.inner.scenario())
    }

    /// Robots per world.
    #[getter]
    fn n_robots(&self) -> usize {
        self.inner.envs()[0].world.robots.len()
    }

    /// Whether a world whose episode ended is reset by the next step (Gymnasium NEXT_STEP);
    /// without it, stepping a finished world raises until it is reset.
    #[getter]
    fn autoreset(&self) -> bool {
        self.autoreset
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
    fn obs_layout(&self, py: Python<'_>) -> PyResult<Vec<(String, usize, usize)>> {
        let env = &self.inner.envs()[0];
        let layout = env.kind().obs_layout(&env.cfg).map_err(|e| to_py(py, e))?;
        Ok(layout_slices(&layout))
    }

    /// The agents: (name, robot index, obs start, obs stop, [(name, start, stop) of its own
    /// block]) in joint order; agent i's action is columns w·i .. w·(i + 1), w = `agent_act_dim`.
    #[allow(clippy::type_complexity)]
    fn agents(
        &self,
        py: Python<'_>,
    ) -> PyResult<Vec<(String, usize, usize, usize, Vec<(String, usize, usize)>)>> {
        let env = &self.inner.envs()[0];
        let agents = env.kind().agents(&env.cfg).map_err(|e| to_py(py, e))?;
        let n_robots = env.world.robots.len();
        let mut start = 0;
        Ok(agents
            .into_iter()
            .map(|a| {
                let n = a.layout.len();
                let item = (
                    a.name,
                    a.body.index(n_robots),
                    start,
                    start + n,
                    layout_slices(&a.layout),
                );
                start += n;
                item
            })
            .collect())
    }

    /// Each agent's reward on the last step, shape (N, n_agents).
    fn agent_rewards<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.per_agent(py, |e| &e.agent_rewards)
    }

    /// Each agent's termination on the last step, shape (N, n_agents).
    fn agent_terminated<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.per_agent(py, |e| &e.agent_terminated)
    }

    /// Target points of the task other than goals (the followers' formation targets), shape
    /// (N, K, 2) (K = 0 for tasks without any).
    fn targets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let targets: Vec<Vec<_>> = self.inner.envs().iter().map(|e| e.targets()).collect();
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

    /// The followers' formation targets (the task's targets), shape (N, K, 2).
    fn formation_targets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.targets(py)
    }

    /// Name of the task.
    #[getter]
    fn task(&self) -> &'static str {
        self.inner.envs()[0].kind().name()
    }

    /// (low, high) observation bounds.
    #[allow(clippy::type_complexity)]
    fn obs_bounds<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, Bound<'py, PyArray1<f32>>)> {
        let env = &self.inner.envs()[0];
        let layout = env.kind().obs_layout(&env.cfg).map_err(|e| to_py(py, e))?;
        let (low, high) = layout.bounds();
        Ok((PyArray1::from_vec(py, low), PyArray1::from_vec(py, high)))
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
            self.outputs(py)
        })
    }

    /// What the last `step` returned, as each world now shows it: a world reset since shows its
    /// first observation, reward 0 and both flags false. Observations (N, obs_dim), rewards,
    /// terminated and truncated (N,); `set_state` restores them with the rest of the state.
    #[allow(clippy::type_complexity)]
    fn last_outputs<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
    )> {
        self.outputs(py)
    }

    /// The world's statistics of the last episode that ended (valid where one ended): all its
    /// agents together (the return sums each step's mean reward).
    fn episode_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        views::episode_stats(py, &self.inner)
    }

    /// Each agent's own statistics, arrays of shape (N, n_agents): of the last episode that
    /// ended, or with `running` of the running one (an agent that has left holds its final
    /// figures until the world is reset).
    #[pyo3(signature = (running=false))]
    fn agent_episode_stats<'py>(
        &self,
        py: Python<'py>,
        running: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        views::agent_episode_stats(py, &self.inner, running)
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
        let g = self.inner.envs()[0].goals().len();
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

    /// Raw sensor readings of the last observation, in the real robot's units: each carried
    /// sensor's channels (shape (N, n_robots, values) or (N, n_robots)), then the body's
    /// "wheel_speeds" (m/s), "encoders" (pulses) and "gyro_z" (rad/s).
    fn sensor_readings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        views::sensor_readings(py, &self.inner)
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
        views::scene(py, env)
    }

    /// An RGB frame (height, width, 3) uint8 of world `index`, drawn without a display: the
    /// whole arena, or with `zoom` > 1 a part of it about `center` (x, y in m; the arena's
    /// centre by default).
    #[pyo3(signature = (index=0, width=480, height=480, zoom=1.0, center=None))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        index: usize,
        width: u32,
        height: u32,
        zoom: f32,
        center: Option<(f32, f32)>,
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
            views::frame(py, env, (width, height), zoom, center)
        })
    }

    /// Keeps the last `length` positions of every robot for the trails of `render` (0: off).
    pub(super) fn set_trail_length(&mut self, length: usize) {
        self.trail_length = length.min(100_000);
        self.inner.set_trail_length(self.trail_length);
    }

    /// Names of the task's extra episode statistics.
    fn extra_stats(&self) -> Vec<&'static str> {
        self.inner.envs()[0].kind().extra_stats().to_vec()
    }

    /// The resolved scenario as TOML text.
    fn config_toml(&self) -> String {
        self.inner.scenario().to_toml()
    }

    /// The state of every world (poses, velocities, contacts, random streams, step counters,
    /// task state) and of the last outputs, as bytes for `set_state`.
    fn get_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        self.state_bytes(py)
    }

    /// Pickling: the resolved scenario, the construction arguments and the state; unpickling
    /// builds the same batch and restores the state (`_batch_from_state`).
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        Self::reduce(slf)
    }

    /// Restores a state from `get_state` of a batch of the same task, scenario and size.
    fn set_state(&mut self, py: Python<'_>, state: &Bound<'_, PyAny>) -> PyResult<()> {
        self.restore_state(py, state)
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

    /// Fresh arrays of the batch's output buffers: observations, rewards, terminated, truncated.
    #[allow(clippy::type_complexity)]
    fn outputs<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
    )> {
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
    }
}
