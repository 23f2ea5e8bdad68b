"""stable-baselines3 vector environments over the Rust batch: no DummyVecEnv, no subprocesses.

:func:`make_vec_env` gives an SB3 ``VecEnv`` whose rows are the N worlds of one ``_core.Batch``
(of any registered id); :func:`make_formation_vec_env` one whose rows
are the (world, follower) pairs of a Formation batch, so one policy drives every follower
(parameter sharing). Ground truth and saved state come from
:class:`khepera_gym.batch_face.BatchFace`; the SB3 semantics are in the package docstring
(:mod:`khepera_gym.learning.sb3`).

Threading and copies: ``step_wait`` and ``reset`` release the GIL inside the Rust core, which
steps the worlds on its own pool of ``num_threads`` threads; every returned array is fresh.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices

from khepera_gym._inputs import SEED_LIMIT, as_action_array, check_seed, check_world_index
from khepera_gym.batch_face import WORLD_STATS_KEY, BatchFace, first_seed
from khepera_gym.config import VERSION_KEY, ConfigArg, make_batch
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.observations import layout_dict
from khepera_gym.registration import resolve_env_id, task_and_version, task_of
from khepera_gym.render import TRAIL_LENGTH, check_frame_size, default_frame_size, mosaic


class KheperaSB3VecEnv(BatchFace, VecEnv):
    """An SB3 ``VecEnv`` over N worlds of one task in a ``_core.Batch``; row i is world i.

    Args:
        task: A task of the Rust core's registry (a name of ``registry.task_names()``: "nav", ...).
        num_worlds: Number of worlds N (>= 1).
        seed: If given, world i is seeded with ``seed + i`` at the first ``reset()``.
        num_threads: Threads of the batch's rayon pool; None uses all cores.
        config: None (built-in defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        max_episode_steps: If given, overrides the scenario's ``max_steps`` (truncation length).
        render_mode: None, or "rgb_array": ``get_images()`` then gives one frame per world
            (drawn in software by the Rust core, no display needed) and ``render()`` tiles
            them, so SB3's ``VecVideoRecorder`` works.
        frame_size: (width, height) in pixels of one world's frame;
            None: 480 x 480, more for an arena over 4 m
            (:func:`khepera_gym.render.default_frame_size`).
        **overrides: Scenario keys overriding the file, e.g. ``goal_radius=0.1``.

    Attributes that SB3 reads: ``num_envs`` (rows), ``observation_space`` and ``action_space``
    (one row's), ``render_mode``. ``get_attr`` knows the attributes every world shares
    (:attr:`SHARED_ATTRIBUTES`); ``env_method`` calls the single env's ground-truth methods on
    each world (:attr:`WORLD_METHODS`); ``set_attr`` raises (a scenario is fixed at
    construction: build a new env with other overrides instead).
    """

    _WORLD: ClassVar[int | None] = None
    #: Whether a row is one agent of a world (its infos then hold the agent's own statistics),
    #: rather than the world.
    _AGENT_ROWS: ClassVar[bool] = False
    #: Attributes of a single env that are the same for every world, for ``get_attr``.
    SHARED_ATTRIBUTES: ClassVar[tuple[str, ...]] = (
        "render_mode",
        "observation_space",
        "action_space",
        "metadata",
        "action_type",
        "task",
        "max_episode_steps",
        "n_robots",
    )
    #: Methods of a single env (``env.unwrapped.NAME()``) that ``env_method`` runs per world.
    WORLD_METHODS: ClassVar[tuple[str, ...]] = (
        "poses",
        "goals",
        "scene",
        "sensor_readings",
        "formation_targets",
        "targets",
        "obs_layout",
        "config_toml",
    )

    def __init__(
        self,
        task: str,
        /,
        num_worlds: int,
        *,
        seed: int | None = None,
        num_threads: int | None = None,
        config: ConfigArg = None,
        action_type: str = "wheels",
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        frame_size: tuple[int, int] | None = None,
        **overrides: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(
                f"render_mode must be None or 'rgb_array' for an SB3 VecEnv, got {render_mode!r} "
                "(for a window use gym.make(env_id, render_mode='human'))"
            )
        if frame_size is not None:
            check_frame_size(frame_size)
        self._batch = make_batch(
            task,
            num_worlds,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=False,
            episode_steps=("max_episode_steps", max_episode_steps),
        )
        if frame_size is None:
            frame_size = default_frame_size(self._batch.scene(0)["arena"])
        self._frame_size = check_frame_size(frame_size)
        self.task = task
        self.action_type = action_type
        self.render_mode: str | None = render_mode
        if render_mode is not None:
            self._batch.set_trail_length(TRAIL_LENGTH)
        self.num_worlds: int = self._batch.num_worlds
        self._configure_rows()
        super().__init__(
            self.num_worlds * self.rows_per_world,
            self._row_observation_space(),
            self._row_action_space(),
        )
        self._actions: npt.NDArray[np.float32] | None = None
        self._has_reset = False
        self._closed = False
        if seed is not None:
            self.seed(seed)

    # --- rows: one per world here; subclasses map several agents of a world to rows ----------

    def _configure_rows(self) -> None:
        #: Rows (SB3 envs) per world.
        self.rows_per_world = 1

    def row_observations(self, joint: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """Rows of observations from joint observations of shape (worlds, obs_dim)."""
        return joint

    def row_rewards(self, rewards: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """Rows of rewards of the last step (read before any world is reset)."""
        return rewards

    def joint_actions(self, actions: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """Joint actions (worlds, act_dim) from row actions (num_envs, row action)."""
        return actions

    # --- SB3 VecEnv API ------------------------------------------------------------------------

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seeds world w with ``seed + w`` at the next ``reset()`` (SB3: seeds act on reset only).

        Args:
            seed: A non-negative int; None draws one from the operating system's entropy.

        Returns:
            The seed of each row's world.
        """
        seed = check_seed(seed)
        if seed is None:
            seed = first_seed()
        # As the core's reset does: world w gets seed + w, wrapping at 2**64.
        self._seeds = [
            (seed + row // self.rows_per_world) % SEED_LIMIT for row in range(self.num_envs)
        ]
        return list(self._seeds)

    def reset(self) -> npt.NDArray[np.float32]:
        """Resets every world: seeded where ``seed()`` asked for it, else continuing its stream.

        Returns:
            Observations of shape (num_envs, obs_dim), float32.
        """
        self._check_open()
        world_seeds: list[int | None] = list(self._seeds[:: self.rows_per_world])
        if not self._has_reset and None in world_seeds:
            base = first_seed()
            world_seeds = [base + w if s is None else s for w, s in enumerate(world_seeds)]
        first = world_seeds[0]
        if all(s is None for s in world_seeds):
            joint = self._batch.reset(None)
        elif first is not None and world_seeds == [first + w for w in range(self.num_worlds)]:
            joint = self._batch.reset(int(first))
        else:
            joint = np.stack(
                [
                    self._batch.reset_world(w, None if s is None else int(s))
                    for w, s in enumerate(world_seeds)
                ]
            )
        self._reset_seeds()
        self._reset_options()
        self._has_reset = True
        self._actions = None
        return self.row_observations(joint)

    def step_async(self, actions: npt.ArrayLike) -> None:
        """Stores the actions of every row, shape (num_envs, 2 or act_dim), for ``step_wait``.

        Raises:
            ActionError: Actions are not numeric or have the wrong shape (NaN/inf are reported
                by ``step_wait``).
        """
        self._check_open()
        expected = (self.num_envs, *self.action_space.shape)
        action_array = as_action_array(actions, expected, "actions")
        self._actions = np.ascontiguousarray(self.joint_actions(action_array))

    def step_wait(
        self,
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        list[dict[str, Any]],
    ]:
        """Steps every world once; a world that ends is reset at once (SB3 semantics).

        Returns:
            ``(observations, rewards, dones, infos)``: observations (num_envs, obs_dim) float32,
            rewards (num_envs,) float32, dones (num_envs,) bool, and one info dict per row (see
            the module docstring for the keys at an episode's end).

        Raises:
            ActionError: An action is NaN/inf.
            KheperaError: ``step_wait`` without ``step_async``, or before ``reset()``.
        """
        self._check_open()
        if self._actions is None:
            raise KheperaError("step_wait() without step_async(actions)")
        if not self._has_reset:
            raise KheperaError("step() before reset(): call reset() first")
        actions, self._actions = self._actions, None
        joint, rewards, terminated, truncated = self._batch.step(actions)
        row_rewards = self.row_rewards(rewards)
        observations = self.row_observations(joint)
        ended = terminated | truncated
        rows = self.rows_per_world
        dones = np.repeat(ended, rows) if rows > 1 else ended
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if np.count_nonzero(ended):
            for world in np.flatnonzero(ended):
                world_stats = self._world_episode_stats(int(world))
                # Rows of agents: each its own statistics (read before the world's reset).
                agent_stats = self._agent_episode_stats(int(world)) if self._AGENT_ROWS else None
                time_limit = bool(truncated[world] and not terminated[world])
                first_rows = self.row_observations(self._batch.reset_world(int(world))[None])
                for offset in range(rows):
                    row = world * rows + offset
                    stats = world_stats if agent_stats is None else agent_stats[offset]
                    infos[row] = {
                        "terminal_observation": observations[row].copy(),
                        "TimeLimit.truncated": time_limit,
                        "is_success": stats["success"],
                        "episode_stats": dict(stats),
                    }
                    if agent_stats is not None:
                        infos[row][WORLD_STATS_KEY] = dict(world_stats)
                observations[world * rows : (world + 1) * rows] = first_rows
        return observations, row_rewards, dones, infos

    def close(self) -> None:
        """Marks the env closed (the Rust worlds are freed with it); safe to call twice."""
        self._closed = True

    def render(self, mode: str | None = None) -> npt.NDArray[np.uint8] | None:
        """The frames of every world tiled into one RGB image (``render_mode="rgb_array"``).

        Raises:
            NotImplementedError: The env was made without ``render_mode="rgb_array"``, or
                another mode is asked for (SB3's "human" needs OpenCV; for a window use
                ``gym.make(env_id, render_mode="human")``).
        """
        if self.render_mode != "rgb_array" or mode not in (None, "rgb_array"):
            raise NotImplementedError(
                f"render(mode={mode!r}) on an env made with render_mode={self.render_mode!r}: "
                "make it with render_mode='rgb_array' (frames of every world, tiled); for a "
                "window use gym.make(env_id, render_mode='human')"
            )
        return mosaic(list(self.get_images()))

    def get_images(self) -> Sequence[npt.NDArray[np.uint8] | None]:
        """One RGB frame (height, width, 3) per world (not per row), with ``render_mode=
        "rgb_array"``; without it, None for each world (as SB3's DummyVecEnv gives)."""
        if self.render_mode != "rgb_array":
            return [None] * self.num_worlds
        width, height = self._frame_size
        return [self._batch.render(world, width, height) for world in range(self.num_worlds)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The value of a single env's attribute for each row (the same for every world).

        Raises:
            AttributeError: ``attr_name`` is not one of :attr:`SHARED_ATTRIBUTES`.
        """
        if attr_name not in self.SHARED_ATTRIBUTES:
            raise AttributeError(
                f"{type(self).__name__}.get_attr knows {self.SHARED_ATTRIBUTES}, not {attr_name!r}"
            )
        value = getattr(self, attr_name)
        return [value for _ in self._row_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Not supported: every world's scenario is fixed when the batch is built.

        Raises:
            NotImplementedError: Always; build a new env with other scenario overrides instead.
        """
        raise NotImplementedError(
            f"set_attr({attr_name!r}): the worlds of a Rust batch share one scenario fixed at "
            "construction; make a new env with the overrides you need, e.g. "
            "make_vec_env(env_id, n_envs, max_steps=200)"
        )

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Runs a single env's ground-truth method on the world of each row.

        ``poses`` (n_robots, 3), ``goals`` (n_goals, 2), ``scene()``, ``sensor_readings()``,
        ``formation_targets`` (K, 2), ``obs_layout()``, ``config_toml()``: the results a single
        env's ``env.unwrapped.NAME()`` gives for that world.

        Raises:
            AttributeError: ``method_name`` is not one of :attr:`WORLD_METHODS`.
            TypeError: Arguments were given (these methods take none).
        """
        if method_name not in self.WORLD_METHODS:
            raise AttributeError(
                f"{type(self).__name__}.env_method knows {self.WORLD_METHODS}, not {method_name!r}"
            )
        if method_args or method_kwargs:
            raise TypeError(f"{method_name}() takes no arguments")
        worlds = [row // self.rows_per_world for row in self._row_indices(indices)]
        if method_name == "scene":
            return [self.scene(world) for world in worlds]
        if method_name in ("obs_layout", "config_toml"):
            return [getattr(self, method_name)() for _ in worlds]
        if method_name == "sensor_readings":
            readings = self.sensor_readings()
            return [{name: values[world] for name, values in readings.items()} for world in worlds]
        # formation_targets is the formation task's name for its targets.
        arrays = (
            self.targets() if method_name == "formation_targets" else getattr(self, method_name)()
        )
        return [arrays[world].copy() for world in worlds]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """False for every row: the worlds are not Gymnasium envs, so nothing wraps them (use
        SB3's ``VecMonitor`` rather than ``Monitor``)."""
        return [False for _ in self._row_indices(indices)]

    # --- helpers -------------------------------------------------------------------------------

    def _row_indices(self, indices: VecEnvIndices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, (int, np.integer)):
            return [check_world_index(indices, self.num_envs, "indices")]
        if isinstance(indices, (str, bytes)) or not hasattr(indices, "__iter__"):
            raise ConfigError(f"indices must be None, an int or ints, got {indices!r}")
        return [check_world_index(index, self.num_envs, "indices") for index in indices]

    def _check_open(self) -> None:
        if self._closed:
            raise KheperaError(f"{type(self).__name__} is closed")


class SharedAgentsVecEnv(KheperaSB3VecEnv):
    """An SB3 ``VecEnv`` whose rows are the (world, agent) pairs of a multi-agent task.

    Row ``w · K + k`` is agent k of world w: it observes its own block of the joint observation,
    acts with its own two numbers and earns its own reward (``batch.agent_rewards()``), so one
    policy trained on these rows drives every agent (parameter sharing, as in MAPPO/IPPO with a
    shared network). A world's episode ends for all its agents together: their rows are done at
    the same step; each row's info then holds its agent's own ``"episode_stats"`` (the sum of its
    rewards while it took part, its steps, its success as the task defines it for one agent, its
    path length and steps in contact; ``"is_success"`` is that success) and the world's under
    ``"world_episode_stats"`` (with the task's own statistics). ``seed(s)`` seeds world w with
    ``s + w``, so world w's rows are the agents of the PettingZoo env reset with seed ``s + w``.

    Args:
        task: A task whose agents' observation blocks have the same length ("consensus",
            "multinav", "platoon", "formation" with its scripted leader, ...).
        num_worlds: Number of worlds N; the env has N · K rows.
        **kwargs: As :class:`KheperaSB3VecEnv` (``config=``, scenario overrides such as
            ``n_robots=6`` or ``trigger="event"``).

    Raises:
        ConfigError: The task's agents observe blocks of different lengths (a drone and a
            robot), so no one policy reads them all.
    """

    _AGENT_ROWS: ClassVar[bool] = True

    def _configure_rows(self) -> None:
        agents = self._batch.agents()
        block = agents[0][3] - agents[0][2]
        same = all(
            start == k * block and stop == start + block
            for k, (_, _, start, stop, _) in enumerate(agents)
        )
        if not same or agents[-1][3] != self._batch.obs_dim:
            sizes = {name: stop - start for name, _, start, stop, _ in agents}
            raise ConfigError(
                f"a shared policy needs agents with observation blocks of one length; task "
                f"{self.task!r} has {sizes}"
            )
        self.rows_per_world = len(agents)
        #: Length of one agent's observation block.
        self.agent_obs_dim = block
        #: The layout of one agent's block, name → slice.
        self.agent_layout = layout_dict(agents[0][4])
        #: Agent names of the rows of one world, in order.
        self.agent_names = [name for name, *_ in agents]

    def _row_observation_space(self) -> gym.spaces.Box:
        # Each element's widest bounds over the agents' blocks (they are equal in every task).
        low, high = (
            bounds.reshape(self.rows_per_world, self.agent_obs_dim)
            for bounds in self._batch.obs_bounds()
        )
        return gym.spaces.Box(
            low.min(axis=0).astype(np.float32), high.max(axis=0).astype(np.float32)
        )

    def _row_action_space(self) -> gym.spaces.Box:
        # One agent's action: its wheels (and its LEDs with task.led_action).
        return gym.spaces.Box(-1.0, 1.0, shape=(self._batch.agent_act_dim,), dtype=np.float32)

    def row_observations(self, joint: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        return joint.reshape(-1, self.agent_obs_dim)

    def row_rewards(self, rewards: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        return self._batch.agent_rewards().reshape(-1)

    def joint_actions(self, actions: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        return actions.reshape(self.num_worlds, -1)


class FormationFollowersVecEnv(SharedAgentsVecEnv):
    """An SB3 ``VecEnv`` whose rows are the (world, follower) pairs of a Formation batch.

    Row ``w · K + k`` is follower k of world w: it observes its own 23-value block (IR,
    ultrasonic, ``target_offset``, ``leader_offset``, ``leader_heading``, ``leader_velocity``,
    ``wheel_speeds``; see :class:`khepera_gym.envs.FormationEnv`), acts with its (left, right)
    wheel pair and earns its own reward (``batch.agent_rewards()``), so one policy trained on
    these rows drives every follower (parameter sharing). The leader is scripted. A world's
    episode ends for all its followers together: their rows are done at the same step; each
    row's info holds its follower's own ``"episode_stats"`` (``"is_success"``: the leader
    arrived and the follower stands within ``task.goal_radius`` of its target) and the world's
    ``"world_episode_stats"`` (with ``"formation_error_mean"``, ``"formation_error_max"``).
    ``seed(s)`` seeds world w with ``s + w``.

    Args:
        num_worlds: Number of worlds N; the env has N · K rows.
        **kwargs: As :class:`KheperaSB3VecEnv` (scenario overrides such as ``n_followers=3`` or
            ``shape="wedge"``); ``leader="agent"`` is refused.
    """

    def __init__(self, num_worlds: int, **kwargs: Any) -> None:
        if "task" in kwargs:
            raise ConfigError("FormationFollowersVecEnv runs the task 'formation'")
        super().__init__("formation", num_worlds, **kwargs)

    def _configure_rows(self) -> None:
        agents = self._batch.agents()
        if any(not name.startswith("follower_") for name, *_ in agents):
            raise ConfigError(
                "FormationFollowersVecEnv needs the scripted leader (formation.leader = "
                f"'scripted'); the agents here are {[name for name, *_ in agents]}"
            )
        super()._configure_rows()
        #: Length of one follower's observation block.
        self.follower_obs_dim = self.agent_obs_dim
        #: The layout of one follower's block, name → slice.
        self.follower_layout = self.agent_layout
        #: Agent names of the rows of one world, in order ("follower_0", ...).
        self.follower_names = self.agent_names

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12) of every world, shape (num_worlds, K, 2)."""
        return self.targets()


def make_vec_env(
    env_id: str,
    n_envs: int = 1,
    seed: int | None = None,
    num_threads: int | None = None,
    **config: Any,
) -> KheperaSB3VecEnv:
    """An SB3 ``VecEnv`` of ``n_envs`` worlds of a khepera_gym env, stepped by the Rust batch.

    Args:
        env_id: A Gymnasium id (``"KheperaIV-Nav-v3"``; an unversioned id picks the latest
            version): one row per world. Or a PettingZoo module's name (``"multinav_v3"``): one
            row per agent of every world (:class:`SharedAgentsVecEnv`, parameter sharing), for
            a family whose agents observe blocks of one length.
        n_envs: Number of worlds.
        seed: World i is seeded with ``seed + i`` at the first ``reset()``; None draws a seed.
        num_threads: Threads of the batch's pool; None uses all cores.
        **config: ``config=`` (scenario name or TOML path), ``action_type=``,
            ``max_episode_steps=`` and scenario overrides, as for ``gym.make``.

    Returns:
        A :class:`KheperaSB3VecEnv` running the behaviour version of ``env_id``; wrap it in
        ``VecMonitor`` for SB3's episode logging.

    Raises:
        ConfigError: An unknown id or module (the message names the nearest), or a scenario
            error.

    Example:
        >>> from stable_baselines3 import PPO
        >>> envs = make_vec_env("KheperaIV-Nav", n_envs=16, seed=0)
        >>> model = PPO("MlpPolicy", envs)  # doctest: +SKIP
    """
    from khepera_gym.pettingzoo import modules

    task, version = task_and_version(env_id)
    config.setdefault(VERSION_KEY, version)
    cls = SharedAgentsVecEnv if env_id in modules() else KheperaSB3VecEnv
    return cls(task, n_envs, seed=seed, num_threads=num_threads, **config)


def make_formation_vec_env(
    n_worlds: int,
    seed: int | None = None,
    num_threads: int | None = None,
    **config: Any,
) -> FormationFollowersVecEnv:
    """An SB3 ``VecEnv`` whose rows are the followers of ``n_worlds`` Formation worlds.

    Args:
        n_worlds: Number of worlds; the env has ``n_worlds · K`` rows (K followers each).
        seed: World w is seeded with ``seed + w`` at the first ``reset()``.
        num_threads: Threads of the batch's pool; None uses all cores.
        **config: ``config=``, ``action_type=``, ``max_episode_steps=`` and scenario overrides
            (``n_followers=3``, ``shape="wedge"``, ...); the leader must stay scripted.

    Returns:
        A :class:`FormationFollowersVecEnv`.
    """
    return FormationFollowersVecEnv(n_worlds, seed=seed, num_threads=num_threads, **config)


# --- loading trained models ------------------------------------------------------------------


__all__ = [
    "FormationFollowersVecEnv",
    "KheperaSB3VecEnv",
    "SharedAgentsVecEnv",
    "make_formation_vec_env",
    "make_vec_env",
    "resolve_env_id",
    "task_of",
]
