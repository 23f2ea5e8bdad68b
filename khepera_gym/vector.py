"""Native vector environments: N worlds of one task stepped by the Rust core in one call.

``gym.make_vec("KheperaIV-Nav-v0", num_envs=N)`` returns a :class:`NavVectorEnv` (likewise
:class:`AvoidVectorEnv` and :class:`FormationVectorEnv`) over a ``_core.Batch`` of N worlds: no
Python loop over worlds and no subprocesses. Worlds are stepped in parallel by the batch's own
rayon pool of ``num_threads`` threads (None = all cores) while the GIL is released; results do not
depend on the thread count.

Semantics follow Gymnasium's ``VectorEnv``:

* autoreset mode NEXT_STEP: the step after a world terminated or was truncated resets it and
  returns its first observation with reward 0 and both flags False (its action is ignored);
* ``reset(seed=s)`` seeds world i with ``s + i``, so world i behaves bit for bit like a single env
  reset with seed ``s + i`` given the same actions;
* ``info`` is ``{}`` except at steps where some world ended: ``info["episode_stats"]`` then holds
  arrays "return", "length", "success", "path_length", "collisions" (Formation adds
  "formation_error_mean", "formation_error_max") of shape (N,) with boolean masks ``"_return"``,
  ... (and ``info["_episode_stats"]``) true for the worlds that ended;
* every returned array is freshly allocated (copy semantics).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from khepera_gym._inputs import as_action_array, check_seed, check_world_seeds
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.envs import _SEED_BOUND, _check_render_mode
from khepera_gym.errors import ConfigError
from khepera_gym.layout import layout_dict
from khepera_gym.render import DEFAULT_FRAME_SIZE, Renderer
from khepera_gym.state import StateMixin


class KheperaVectorEnv(StateMixin, VectorEnv):
    """N seeded Khepera IV worlds of one task, stepped in parallel by the Rust core.

    Args:
        num_envs: Number of worlds N (>= 1).
        task: Task name in the Rust core: "nav", "avoid", "formation" (or "multinav").
        render_mode: None, "rgb_array" (``render()`` returns a mosaic of the first
            ``render_worlds`` worlds) or "human" (that mosaic in a pygame window).
        config: None (built-in defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        num_threads: Threads of the batch's rayon pool; None uses all cores.
        frame_size: (width, height) in pixels of one world's frame.
        render_worlds: How many worlds ``render()`` tiles (default 4).
        max_episode_steps: If given, overrides the scenario's ``max_steps`` (truncation length).
        **overrides: Scenario keys overriding the file, e.g. ``goal_radius=0.1``.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array", "human"],
        "render_fps": 20,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        task: str = "nav",
        render_mode: str | None = None,
        config: ConfigArg = None,
        action_type: str = "wheels",
        num_threads: int | None = None,
        max_episode_steps: int | None = None,
        frame_size: tuple[int, int] = DEFAULT_FRAME_SIZE,
        render_worlds: int = 4,
        **overrides: Any,
    ) -> None:
        _check_render_mode(render_mode, self.metadata["render_modes"])
        self._batch = make_batch(
            task,
            num_envs,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=True,
            episode_steps=("max_episode_steps", max_episode_steps),
        )
        self.task = task
        self.num_envs = self._batch.num_worlds
        self.render_mode = render_mode
        self.action_type = action_type

        low, high = self._batch.obs_bounds()
        self.single_observation_space = gym.spaces.Box(
            low.astype(np.float32), high.astype(np.float32), dtype=np.float32
        )
        self.single_action_space = gym.spaces.Box(
            -1.0, 1.0, shape=(self._batch.act_dim,), dtype=np.float32
        )
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._action_shape = (self.num_envs, self._batch.act_dim)
        self._has_reset = False
        self._render_worlds = max(1, int(render_worlds))
        self._renderer = Renderer(
            self._batch,
            render_mode,
            frame_size,
            fps=self.metadata["render_fps"],
            title=f"khepera_gym {task} x{self.num_envs}",
        )

    def render(self) -> npt.NDArray[np.uint8] | None:
        """A mosaic of the first ``render_worlds`` worlds' frames (rgb_array), or shown in a
        window (human, returns None); None without a render mode."""
        return self._renderer.render(self._render_worlds)

    @property
    def num_threads(self) -> int:
        """Threads of the batch's rayon pool."""
        return self._batch.num_threads

    @property
    def max_episode_steps(self) -> int:
        """Steps after which the Rust core truncates an episode (the scenario's ``max_steps``)."""
        return self._batch.max_episode_steps

    @property
    def n_robots(self) -> int:
        """Number of robots per world."""
        return self._batch.n_robots

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Reset every world.

        Args:
            seed: An int s seeds world i with ``s + i``; a sequence of N seeds (int or None) seeds
                each world with its own; None continues each world's stream (the very first reset
                without a seed draws s from ``self.np_random``).
            options: Unused; accepted for API compatibility.

        Returns:
            Observations of shape (N, obs_dim) and an empty info dict.
        """
        if seed is None or isinstance(seed, (int, np.integer)):
            seed = check_seed(seed)
            super().reset(seed=seed)
            if seed is None and not self._has_reset:
                seed = int(self.np_random.integers(_SEED_BOUND))
            observations = self._batch.reset(seed)
        else:
            observations = self._reset_each(seed)
        self._has_reset = True
        return observations, {}

    def _reset_each(self, seeds: Sequence[int | None]) -> npt.NDArray[np.float32]:
        seeds = check_world_seeds(seeds, self.num_envs)
        if not self._has_reset:
            # Worlds given None still need a first seed: draw it as an int seed would be.
            base = int(self.np_random.integers(_SEED_BOUND))
            seeds = [base + index if s is None else s for index, s in enumerate(seeds)]
        observations = np.empty((self.num_envs, *self.single_observation_space.shape), np.float32)
        for index, world_seed in enumerate(seeds):
            observations[index] = self._batch.reset_world(index, world_seed)
        return observations

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Step every world once (a world that ended on the previous step is reset instead).

        Args:
            actions: Shape (N, act_dim), normalised to [-1, 1]; finite values outside are clipped.

        Returns:
            ``(observations, rewards, terminations, truncations, infos)`` as arrays of N rows.

        Raises:
            ActionError: Actions are not numeric, have the wrong shape, or contain NaN/inf.
        """
        action_array = as_action_array(actions, self._action_shape, "actions (num_envs, act_dim)")
        observations, rewards, terminations, truncations = self._batch.step(action_array)
        # count_nonzero is several times cheaper than ndarray.any() on small arrays (hot path).
        if np.count_nonzero(terminations) or np.count_nonzero(truncations):
            infos = self._episode_infos(terminations | truncations)
        else:
            infos = {}
        return observations, rewards, terminations, truncations, infos

    def _episode_infos(self, ended: npt.NDArray[np.bool_]) -> dict[str, Any]:
        not_ended = ~ended
        episode: dict[str, Any] = {}
        for name, values in self._batch.episode_stats().items():
            values[not_ended] = 0
            episode[name] = values
            episode[f"_{name}"] = ended.copy()
        return {"episode_stats": episode, "_episode_stats": ended}

    def obs_layout(self) -> dict[str, slice]:
        """Observation layout of this env's scenario, name → slice (with agent prefixes such as
        "follower_0/ir" when there are several robots)."""
        return layout_dict(self._batch.obs_layout())

    def poses(self) -> npt.NDArray[np.float64]:
        """Ground-truth robot poses, shape (N, n_robots, 3): x, y (m), θ (rad, (-π, π])."""
        return self._batch.poses()

    def goals(self) -> npt.NDArray[np.float64]:
        """Goal positions, shape (N, n_goals, 2), in metres."""
        return self._batch.goals()

    def sensor_readings(self) -> dict[str, npt.NDArray[Any]]:
        """Raw sensor values of the last observations (see ``_core.Batch.sensor_readings``)."""
        return self._batch.sensor_readings()

    def scene(self, index: int = 0) -> dict[str, Any]:
        """Geometry of world ``index`` for plots: arena size, robot radius, obstacles, goal."""
        return self._batch.scene(index)

    def config_toml(self) -> str:
        """The fully resolved scenario (defaults + file + overrides) as TOML text."""
        return self._batch.config_toml()

    def close_extras(self, **kwargs: Any) -> None:
        """Closes the render window, if any (the Rust batch is freed with the env)."""
        self._renderer.close()


class _TaskVectorEnv(KheperaVectorEnv):
    """A :class:`KheperaVectorEnv` whose task is fixed by the subclass (:attr:`TASK`)."""

    #: Task name in the Rust core.
    TASK: ClassVar[str] = ""

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        if "task" in kwargs:
            raise ConfigError(
                f"{type(self).__name__} runs the task {self.TASK!r}; "
                "use KheperaVectorEnv(task=...) for another"
            )
        super().__init__(num_envs, task=self.TASK, **kwargs)


class NavVectorEnv(_TaskVectorEnv):
    """``KheperaIV-Nav`` as a native vector env (the ``vector_entry_point`` of its registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``, fixed to "nav".
    """

    TASK: ClassVar[str] = "nav"


class AvoidVectorEnv(_TaskVectorEnv):
    """``KheperaIV-Avoid`` as a native vector env (the ``vector_entry_point`` of its registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``, fixed to "avoid".
    ``scene(i)`` lists world i's obstacles of the current episode.
    """

    TASK: ClassVar[str] = "avoid"


class FormationVectorEnv(_TaskVectorEnv):
    """``KheperaIV-Formation`` as a native vector env (its registration's ``vector_entry_point``).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``, fixed to "formation".
    ``poses()`` has the leader first, shape (N, K + 1, 3); episode statistics add
    "formation_error_mean" and "formation_error_max" (m).
    """

    TASK: ClassVar[str] = "formation"

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12), shape (N, K, 2), in metres."""
        return self._batch.formation_targets()


__all__ = [
    "AvoidVectorEnv",
    "FormationVectorEnv",
    "KheperaVectorEnv",
    "NavVectorEnv",
]
