"""What every env of khepera_gym shows of its Rust batch, written once.

Every env class (the single Gymnasium env, the native vector env, the SB3 VecEnv, the PettingZoo
env, and the RLlib/TorchRL adapters) owns one ``_core.Batch`` and mixes in :class:`BatchFace`,
which gives them the same ground truth (``poses``, ``goals``, ``targets``, ``scene``,
``sensor_readings``), the same scenario and layout accessors (``config_toml``,
``obs_layout``, ``agent_layouts``), the same saved state (``get_state``/``set_state``,
pickling through the batch) and the same episode statistics, in one of two shapes:

* a face of one world (``_WORLD = 0``: single env, PettingZoo) drops the world axis;
* a face of every world (``_WORLD = None``: vector env, SB3 VecEnv) keeps it first.

Episode statistics come in two kinds (:data:`WORLD_STATS_KEY`): each agent's own (its return,
length, success, path and contacts, under ``"episode_stats"`` in a multi-agent env's infos) and
the world's (all agents together, with the task's own statistics).

It also builds the spaces of an observation row and an action row from the batch's bounds, and
holds the seed rules shared by the faces (:data:`SEED_BOUND`, :func:`first_seed`).

Units are SI (m, s, rad); the world frame has x right, y up; robot frame x forward, y left.
Threading and copies: every accessor copies out of the Rust core (fresh arrays).
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym import _core
from khepera_gym._inputs import check_world_index
from khepera_gym.errors import ConfigError, KheperaError, StateError
from khepera_gym.observations import layout_dict

#: The info key of the world's episode statistics in a multi-agent env (every agent together:
#: the return sums each step's mean reward, success is the task's, path and contacts are every
#: robot's, then the task's own statistics), beside each agent's own under ``"episode_stats"``.
WORLD_STATS_KEY = "world_episode_stats"

#: Largest seed drawn from an env's ``np_random`` on a first ``reset()`` without a seed
#: (exclusive).
SEED_BOUND = 2**62


def first_seed(np_random: np.random.Generator | None = None) -> int:
    """The seed of a first ``reset()`` without one: drawn from ``np_random`` (Gymnasium's
    seeded generator) or, without it, from the operating system's entropy."""
    generator = np.random.default_rng() if np_random is None else np_random
    return int(generator.integers(SEED_BOUND))


def check_render_mode(render_mode: str | None, render_modes: list[str]) -> None:
    """Raises ConfigError unless ``render_mode`` is None or one of ``render_modes``."""
    if render_mode is not None and render_mode not in render_modes:
        raise ConfigError(
            f"render_mode={render_mode!r} is not supported (supported: {[None, *render_modes]})"
        )


class BatchFace:
    """The accessors of an env over a ``_core.Batch`` in ``self._batch``.

    Subclasses set :attr:`_WORLD`: 0 for a face of one world (arrays lose the world axis),
    None for a face of every world (arrays keep it first).
    """

    #: The world this face shows, or None for all of them.
    _WORLD: ClassVar[int | None] = None
    _batch: _core.Batch
    _has_reset: bool

    def _pick(self, array: Any) -> Any:
        return array if self._WORLD is None else array[self._WORLD]

    # --- spaces -------------------------------------------------------------------------------

    def _row_observation_space(self) -> gym.spaces.Box:
        """The Box of one world's joint observation, from the Rust core's bounds."""
        low, high = self._batch.obs_bounds()
        return gym.spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)

    def _row_action_space(self) -> gym.spaces.Box:
        """The Box of one world's joint action: normalised values in [-1, 1]."""
        return gym.spaces.Box(-1.0, 1.0, shape=(self._batch.act_dim,), dtype=np.float32)

    # --- the world(s) --------------------------------------------------------------------------

    @property
    def behaviour_version(self) -> int:
        """The behaviour version this env runs: the ``-vN`` of its id or ``_vN`` of its module
        (the Version History of its manual says what each changed)."""
        return self._batch.version

    @property
    def max_episode_steps(self) -> int:
        """Steps after which the Rust core truncates an episode (the scenario's ``max_steps``)."""
        return self._batch.max_episode_steps

    @property
    def n_robots(self) -> int:
        """Number of robots per world."""
        return self._batch.n_robots

    @property
    def num_threads(self) -> int:
        """Threads of the batch's rayon pool."""
        return self._batch.num_threads

    def poses(self) -> npt.NDArray[np.float64]:
        """Ground-truth robot poses: x, y (m), θ (rad, (-π, π]), shape (n_robots, 3) (one world)
        or (N, n_robots, 3)."""
        return self._pick(self._batch.poses())

    def goals(self) -> npt.NDArray[np.float64]:
        """Goal positions (m), shape (n_goals, 2) (one world) or (N, n_goals, 2)."""
        return self._pick(self._batch.goals())

    def targets(self) -> npt.NDArray[np.float64]:
        """The task's target points other than goals (the followers' formation targets, eq. 12),
        shape (K, 2) (one world) or (N, K, 2); K = 0 for tasks without any."""
        return self._pick(self._batch.targets())

    def sensor_readings(self) -> dict[str, npt.NDArray[Any]]:
        """Raw readings of the last observation in the real robot's units: each carried
        sensor's channels ("ir_raw" 0..1023, "us_cm" cm or codes 0/1000/2000, ...) and the
        body's "wheel_speeds" (m/s), "encoders" (pulses), "gyro_z" (rad/s), and the IMU's
        "accel_g" (g) and "imu_gyro" (rad/s) when carried, "leds" (the top LEDs' red, green,
        blue, 0..63) with ``task.led_action``; with a robot axis first (one world) or a world
        axis then a robot axis."""
        return {name: self._pick(values) for name, values in self._batch.sensor_readings().items()}

    def scene(self, index: int | None = None) -> dict[str, Any]:
        """Geometry of a world for plots: arena, walls, obstacles, robot and goal radius.

        Args:
            index: The world (a face of every world; default 0); a face of one world shows its
                own and takes no index.

        Raises:
            ConfigError: ``index`` is not an int naming one of the worlds.
        """
        if self._WORLD is not None:
            if index is not None and not (
                isinstance(index, (int, np.integer))
                and not isinstance(index, bool)
                and index == self._WORLD
            ):
                raise ConfigError(f"this env has one world; scene() takes no index, got {index!r}")
            return self._batch.scene(self._WORLD)
        world = 0 if index is None else check_world_index(index, self._batch.num_worlds, "scene()")
        return self._batch.scene(world)

    def config_toml(self) -> str:
        """The fully resolved scenario (defaults + file + overrides) as TOML text."""
        return self._batch.config_toml()

    def obs_layout(self) -> dict[str, slice]:
        """The layout of one world's joint observation, name → slice (with agent prefixes such
        as "follower_0/ir" when there are several agents)."""
        return layout_dict(self._batch.obs_layout())

    def agent_layouts(self) -> dict[str, dict[str, slice]]:
        """Each agent's own observation layout, name → slice within its block."""
        return {name: layout_dict(own) for name, _, _, _, own in self._batch.agents()}

    def agent_rewards(self) -> npt.NDArray[np.float32]:
        """Each agent's reward on the last step, shape (n_agents,) (one world) or (N, n_agents);
        the env's reward is their mean."""
        return self._pick(self._batch.agent_rewards())

    def set_render_view(self, zoom: float = 1.0, center: Any = None) -> None:
        """Which part of the world ``render()`` shows: ``zoom`` times magnified (1: the whole
        arena; 4: a quarter of its width and height) about ``center`` (x, y in m; None: the
        arena's centre), e.g. a few robots of a 1,000-robot swarm.

        Raises:
            ConfigError: A zoom below 1, or a center that is not two finite numbers.
            KheperaError: This env draws no frames of its own.
        """
        renderer = getattr(self, "_renderer", None)
        if renderer is None:
            raise KheperaError(f"{type(self).__name__} has no renderer to set a view of")
        renderer.set_view(zoom, center)

    # --- episode statistics --------------------------------------------------------------------

    def _world_episode_stats(self, world: int) -> dict[str, Any]:
        """World ``world``'s statistics of the episode that ended on the last step, as Python
        scalars: "return", "length", "success", "path_length" (m), "collisions" (steps in
        contact), and the task's own (Formation: "formation_error_mean", "formation_error_max")."""
        return {name: values[world].item() for name, values in self._batch.episode_stats().items()}

    def _episode_info(self, world: int = 0) -> dict[str, Any]:
        """The info of a step that ended world ``world``'s episode: ``episode_stats`` and, as
        stable-baselines3 expects, ``is_success``."""
        stats = self._world_episode_stats(world)
        return {"episode_stats": stats, "is_success": stats["success"]}

    def _agent_episode_stats(self, world: int, running: bool = True) -> list[dict[str, Any]]:
        """Each agent's own statistics in world ``world``, in agent order, as Python scalars:
        "return", "length" (steps it took part in), "success" (as its task defines it for one
        agent), "path_length" (m), "collisions" (steps its robot was in contact). ``running``:
        of the running episode (an agent that left holds its final figures until the world is
        reset); else of the last episode that ended."""
        stats = self._batch.agent_episode_stats(running)
        n_agents = next(iter(stats.values())).shape[1]
        return [
            {name: values[world, agent].item() for name, values in stats.items()}
            for agent in range(n_agents)
        ]

    def _vector_agent_episode_info(
        self, ended: npt.NDArray[np.bool_], rows: bool = False
    ) -> dict[str, Any]:
        """Vector-env infos of each agent's own statistics for a step where the worlds of
        ``ended`` finished, beside the world's (under :data:`WORLD_STATS_KEY`).

        Args:
            ended: Which worlds' episodes ended at this step, shape (N,).
            rows: One row per (world, agent) pair: arrays (N · n_agents,) with masks of that
                shape; else arrays (N, n_agents) with (N,) masks of the worlds.
        """
        world_info = self._vector_episode_info(ended)
        stats = self._batch.agent_episode_stats(True)
        n_agents = next(iter(stats.values())).shape[1]
        mask = np.repeat(ended, n_agents) if rows else ended
        agents: dict[str, Any] = {}
        for name, values in stats.items():
            values[~ended] = 0
            agents[name] = values.reshape(-1) if rows else values
            agents[f"_{name}"] = mask.copy()
        return {
            "episode_stats": agents,
            "_episode_stats": mask,
            WORLD_STATS_KEY: world_info["episode_stats"],
            f"_{WORLD_STATS_KEY}": ended,
        }

    def _vector_episode_info(self, ended: npt.NDArray[np.bool_]) -> dict[str, Any]:
        """Gymnasium vector-env infos for a step where the worlds of ``ended`` finished: arrays of
        one value per world with ``_name`` masks, zero where no episode ended."""
        not_ended = ~ended
        episode: dict[str, Any] = {}
        for name, values in self._batch.episode_stats().items():
            values[not_ended] = 0
            episode[name] = values
            episode[f"_{name}"] = ended.copy()
        return {"episode_stats": episode, "_episode_stats": ended}

    # --- saved state ---------------------------------------------------------------------------

    def get_state(self) -> bytes:
        """The simulation state of every world, as bytes (picklable, writable to a file).

        It holds the robots' poses, velocities and encoders, the physics' contact state, each
        world's random stream, step counters, goals and task state, and the last observations.
        Restoring it with :meth:`set_state` and replaying the same actions reproduces the
        trajectory bit for bit.
        """
        return self._batch.get_state()

    def set_state(self, state: bytes) -> None:
        """Restores a state from :meth:`get_state` of an env of the same task, scenario and
        number of worlds (in this process or another).

        Raises:
            StateError: ``state`` is not bytes, not a state, is corrupt, is of an older format,
                or was saved from another env (the message says which); the env is then
                unchanged.
        """
        if not isinstance(state, (bytes, bytearray, memoryview)):
            raise StateError(
                f"set_state() takes the bytes get_state() returned, got {type(state).__name__}"
            )
        self._batch.set_state(bytes(state))
        self._has_reset = True


__all__ = ["SEED_BOUND", "WORLD_STATS_KEY", "BatchFace", "check_render_mode", "first_seed"]
