"""Type stub of the Rust extension module ``khepera_gym._core`` (built by maturin from src/python/).

Threading and copy semantics: every method validates its inputs while holding the GIL, copies them
into Rust-owned buffers, releases the GIL for the simulation work, and returns freshly allocated
NumPy arrays (never views of internal buffers), so callers may keep or mutate what they get.
Errors are raised as the classes of ``khepera_gym.errors`` (ConfigError, ActionError, KheperaError).
"""

from typing import Any

import numpy as np
import numpy.typing as npt

__version__: str

class Batch:
    """N independent seeded Khepera IV worlds of one task, stepped in parallel by a rayon pool.

    Args:
        task: a task of the core's registry: a name of ``tasks()`` ("nav", ...).
        num_worlds: number of worlds N (>= 1).
        config_text: TOML text of a scenario file overlaid on the task's built-in defaults, or None.
        config_name: where config_text came from (a file path or built-in name), used in messages.
        overrides: keyword overrides, either leaf names (``goal_radius=0.1``), dotted names
            (``{"task.goal_radius": 0.1}``) or section dicts (``task={"goal_radius": 0.1}``).
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, w).
        num_threads: size of the batch's own rayon pool; None = all cores.
        autoreset: True for NEXT_STEP autoreset (vector env); False for a single env, where
            stepping a finished episode raises KheperaError until reset() is called.
        version: the behaviour version whose defaults apply (``task_versions(task)``); None:
            ``LATEST_VERSION``.
    """

    num_worlds: int
    #: The behaviour version whose defaults the scenario started from (``version``, or the
    #: latest).
    version: int
    obs_dim: int
    act_dim: int
    #: Action values per agent: 2 (its wheels), 5 with ``task.led_action`` (then its LEDs' RGB).
    agent_act_dim: int
    n_robots: int
    num_threads: int
    max_episode_steps: int
    autoreset: bool
    task: str
    def __init__(
        self,
        task: str,
        num_worlds: int,
        config_text: str | None = None,
        config_name: str = "<built-in>",
        overrides: dict[str, Any] | None = None,
        action_type: str = "wheels",
        num_threads: int | None = None,
        autoreset: bool = True,
        version: int | None = None,
    ) -> None: ...
    def obs_layout(self) -> list[tuple[str, int, int]]:
        """Joint observation layout of this batch's scenario: (name, start, stop) in order; with
        several agents the names are prefixed by the agent ("follower_0/ir")."""
    def agents(self) -> list[tuple[str, int, int, int, list[tuple[str, int, int]]]]:
        """The agents in joint order: (name, robot index, obs start, obs stop, own layout as
        (name, start, stop) within its block). Agent i's action is joint columns w·i .. w·(i + 1),
        w = ``agent_act_dim`` (2; 5 with ``task.led_action``). A robot index from
        ``n_robots`` on is a vehicle of the task (a drone), not a Khepera. Single-robot tasks:
        ["robot"]; formation: ["leader" if leader = "agent"] + "follower_0".."_K-1"; the others
        name theirs in their manuals."""
    def agent_rewards(self) -> npt.NDArray[np.float32]:
        """Each agent's reward on the last step, shape (N, n_agents); the joint reward returned
        by step() is their mean."""
    def agent_terminated(self) -> npt.NDArray[np.bool_]:
        """Each agent's termination on the last step, shape (N, n_agents) (multinav: its robot
        reached its goal and parks; platoon: its robot is lost and parks; all True when the
        episode terminated)."""
    def targets(self) -> npt.NDArray[np.float64]:
        """The task's target points other than goals (formation: the followers' eq. 12 targets),
        shape (N, K, 2); K = 0 for tasks without any."""
    def formation_targets(self) -> npt.NDArray[np.float64]:
        """``targets()`` under the formation task's name."""
    def extra_stats(self) -> list[str]:
        """Names of the task's own episode statistics (formation: "formation_error_mean",
        "formation_error_max")."""
    def obs_bounds(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """(low, high), each of shape (obs_dim,)."""
    def reset(self, seed: int | None = None) -> npt.NDArray[np.float32]:
        """Reset every world; world i is seeded with seed + i; None continues each world's stream.

        Returns observations of shape (N, obs_dim)."""
    def reset_world(self, index: int, seed: int | None = None) -> npt.NDArray[np.float32]:
        """Reset one world (seeded with ``seed`` itself when given); returns its (obs_dim,) obs."""
    def step(
        self, actions: npt.NDArray[np.float32]
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
    ]:
        """Step all worlds with actions of shape (N, act_dim), float32, C-contiguous.

        NaN/inf or a wrong shape raise ActionError; finite values outside [-1, 1] are clipped.
        With autoreset, a world that ended on the previous call is reset instead of stepped and
        returns its first observation with reward 0 and both flags False (Gymnasium NEXT_STEP).
        Returns (obs (N, obs_dim), reward (N,), terminated (N,), truncated (N,))."""
    def last_outputs(
        self,
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
    ]:
        """What the last step() returned, as each world now shows it: a world reset since shows
        its first observation, reward 0 and both flags False. Same shapes as step(); restored by
        set_state() with the rest of the state."""
    def episode_stats(self) -> dict[str, npt.NDArray[Any]]:
        """The world's statistics of its last episode that ended (valid where one ended; all
        agents together): "return" f32 (each step's mean reward, summed), "length" i64, "success"
        bool, "path_length" f32 (m, every robot's), "collisions" i64 (steps some robot was in
        contact), each of shape (N,); then the task's own (``extra_stats()``; formation:
        "formation_error_mean", "formation_error_max" f32, m)."""
    def agent_episode_stats(self, running: bool = False) -> dict[str, npt.NDArray[Any]]:
        """Each agent's own statistics, shape (N, n_agents) each: "return" f32 (its rewards while
        it took part), "length" i64 (its steps), "success" bool (as the task defines it for one
        agent), "path_length" f32 (m, its robot's, or its vehicle's flight), "collisions" i64
        (steps its robot was in contact). Of the last episode that ended (valid where one
        ended), or with ``running`` of the running one (an agent that has left holds its final
        figures until the world is reset)."""
    def poses(self) -> npt.NDArray[np.float64]:
        """Ground-truth robot poses, shape (N, n_robots, 3): x, y (m), theta (rad, (-pi, pi])."""
    def goals(self) -> npt.NDArray[np.float64]:
        """Goal positions, shape (N, n_goals, 2) in metres."""
    def sensor_readings(self) -> dict[str, npt.NDArray[Any]]:
        """Raw sensor values of the last observation, in the real robot's units: each carried
        sensor's channels, e.g. "ir_raw" (N, n_robots, 8) int32 0..1023 in K-Team order;
        "us_cm" (N, n_robots, 5) int32 with codes 0 (closer than 25 cm), 1000 (nothing in
        range), 2000 (disabled); then the body's
        "wheel_speeds" (N, n_robots, 2) float32 m/s; "encoders" (N, n_robots, 2) int64 pulses;
        "gyro_z" (N, n_robots) float32 rad/s."""
    def scene(self, index: int = 0) -> dict[str, Any]:
        """Geometry of world ``index`` for plots: {"arena": (w, h), "walls": bool,
        "wall_thickness": t, "robot_radius": r, "goal_radius": r, "obstacles": [...],
        "paths": [...]} with obstacles {"kind": "circle", "center", "radius"}, {"kind": "box",
        "center", "half_extents", "angle"} or {"kind": "segment", "a", "b"} (m, rad), and the
        reference paths the task draws (Track's, PathFollow's), each a list of (x, y)."""
    def render(
        self,
        index: int = 0,
        width: int = 480,
        height: int = 480,
        zoom: float = 1.0,
        center: tuple[float, float] | None = None,
    ) -> npt.NDArray[np.uint8]:
        """RGB frame (height, width, 3) of world ``index``, drawn in software (no display, no
        OpenGL): arena, obstacles, goals, formation targets, trails, IR rays and ultrasonic
        beams (dashed when they report nothing), robots with heading; a robot drawn under 12
        pixels across loses its rays. Sizes 16..4096 pixels a side; ``zoom`` in [1, 1000]
        magnifies about ``center`` (m; None: the arena's centre)."""
    def set_trail_length(self, length: int) -> None:
        """Keeps the last ``length`` robot positions of every world for the trails drawn by
        ``render`` (0, the default, keeps none and costs nothing)."""
    def config_toml(self) -> str:
        """The fully resolved scenario (defaults + file + overrides) as TOML text."""
    def get_state(self) -> bytes:
        """The state of every world and of the last outputs, for ``set_state``."""
    def set_state(self, state: bytes) -> None:
        """Restores a ``get_state`` state of a batch of the same task, scenario and size; raises
        StateError otherwise (and changes nothing)."""
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]: ...

def obs_layout(task: str) -> list[tuple[str, int, int]]:
    """Observation layout of a task: (name, start, stop) slices, in order."""

class Policy:
    """A baseline controller of ``src/controllers/`` acting on observations, batched.

    Args:
        name: The controller: a name of ``controllers()`` ("position_control", ...).
        params: Its parameters by name (``controller_params(name)`` lists them with defaults);
            missing ones take their defaults; unknown or impossible ones raise ConfigError.
        layout: (name, start, stop) blocks of the observations it reads (for leader_follower:
            of one follower's block); None: the first agent's of its task's default scenario.
        leader: leader_follower only: the policy of a leader block.

    ``act`` maps observations (N, obs_dim) float32 to normalised wheel actions (N, act_dim)
    float32 (ActionError on NaN or a wrong length)."""

    name: str
    obs_dim: int
    def __init__(
        self,
        name: str,
        params: dict[str, Any] | None = None,
        layout: list[tuple[str, int, int]] | None = None,
        leader: Policy | None = None,
    ) -> None: ...
    def act(self, obs: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]: ...

def tasks() -> list[tuple[str, str | None, list[str]]]:
    """The tasks, in registry order: (name, Gymnasium id without version or None, names of its
    extra episode statistics)."""

def task_versions(name: str) -> list[int]:
    """The behaviour versions of a task, oldest first (from the version that added it)."""

def task_agents(name: str) -> tuple[bool, bool, bool]:
    """What a task's agents are: (several agents in its default scenario, alike agents (robots
    with one observation layout), agents that end separately)."""

def task_scoring(name: str) -> dict[str, Any]:
    """How a task is scored: ``success``, ``time``, ``error_prefix``, ``error``, ``termination``
    (str or None), ``speed``, ``moving_reference``, ``path_trace`` (bool) and ``columns``, a list
    of (statistic, header, scale, digits)."""

def versions() -> list[tuple[int, str, str, str]]:
    """The behaviour versions, oldest first: (number, title, summary of what changed and why,
    the previous version's values of the keys it changed as TOML)."""

def motor_presets() -> list[tuple[str, str, str]]:
    """The named drives of ``motors.preset``: (name, the ``[drive]`` keys it sets as TOML, who
    sets it on the real robot)."""

def controllers() -> list[tuple[str, str]]:
    """The controllers: (name, the task whose default observation it reads)."""

def controller_params(name: str) -> list[tuple[str, Any, str]]:
    """A controller's parameters in order: (name, default, comment with units and source)."""

def formation_offsets(shape: str, spacing: float, n_followers: int) -> list[tuple[float, float]]:
    """(r, beta) offsets of a formation shape, as the scenarios' ``formation.shape`` computes."""

def braitenberg_weights(name: str) -> list[list[float]]:
    """Weight matrices of the Braitenberg block: "default" or "kteam" (m/s per unit proximity)."""

def default_config(name: str, version: int | None = None) -> str:
    """A built-in scenario file (TOML text): a task's defaults for behaviour ``version`` (None:
    the latest; every key with its comment) or a scene (``builtin_configs()`` lists both;
    ConfigError for a version the task does not exist in). The public form is
    ``khepera_gym.default_config`` (tasks) and ``khepera_gym.scenes`` (scenes)."""

def _batch_from_state(
    task: str,
    num_worlds: int,
    config_text: str,
    action_type: str,
    num_threads: int | None,
    autoreset: bool,
    trail_length: int,
    state: bytes,
    version: int | None = None,
) -> Batch:
    """Unpickles a Batch."""

def builtin_configs() -> list[str]:
    """Names of the built-in scenario files."""

def _panic_for_test() -> None:
    """Panics inside the binding guard (tests: a panic must surface as KheperaError)."""

MAX_WHEEL_SPEED: float  # m/s
MIN_WHEEL_SPEED: float  # m/s
AXLE_LENGTH: float  # m
BODY_RADIUS: float  # m
WHEEL_RADIUS: float  # m
#: The latest behaviour version (the default of ``Batch(version=None)`` and ``default_config``).
LATEST_VERSION: int

def speed_to_units(speed: float) -> int:
    """A wheel speed (m/s) in the real robot's ``kh4_set_speed`` units (0.678181 mm/s each)."""

def units_to_speed(units: int) -> float:
    """``kh4_set_speed`` units as a wheel speed in m/s."""

def simd_paths() -> list[tuple[str, bool]]:
    """The vector paths of the hot kernels, narrowest first: (name, whether this CPU has it)."""

def simd_path() -> str:
    """The vector path the kernels run now: ``portable``, ``avx2`` or ``avx512``."""

def force_simd(name: str) -> None:
    """Runs the kernels on the path ``name`` from now on (the same results on every path);
    ConfigError for an unknown path or one this CPU lacks."""
