"""Native vector environments: N worlds of one task stepped by the Rust core in one call.

``gym.make_vec("KheperaIV-Nav-v1", num_envs=N)`` returns a :class:`NavVectorEnv` (likewise
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

import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from khepera_gym._inputs import as_action_array, check_seed, check_world_seeds
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.envs import ENV_CLASSES, KheperaEnv
from khepera_gym.errors import ConfigError
from khepera_gym.face import BatchFace, check_render_mode, first_seed
from khepera_gym.render import DEFAULT_FRAME_SIZE, Renderer


class KheperaVectorEnv(BatchFace, VectorEnv):
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
    _WORLD: ClassVar[int | None] = None

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
        check_render_mode(render_mode, self.metadata["render_modes"])
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

        self.single_observation_space = self._row_observation_space()
        self.single_action_space = self._row_action_space()
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
                seed = first_seed(self.np_random)
            observations = self._batch.reset(seed)
        else:
            observations = self._reset_each(seed)
        self._has_reset = True
        return observations, {}

    def _reset_each(self, seeds: Sequence[int | None]) -> npt.NDArray[np.float32]:
        seeds = check_world_seeds(seeds, self.num_envs)
        if not self._has_reset:
            # Worlds given None still need a first seed: draw it as an int seed would be.
            base = first_seed(self.np_random)
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
            infos = self._vector_episode_info(terminations | truncations)
        else:
            infos = {}
        return observations, rewards, terminations, truncations, infos

    def close_extras(self, **kwargs: Any) -> None:
        """Closes the render window, if any (the Rust batch is freed with the env). Safe on an
        env whose construction failed (Gymnasium may close it when it is collected)."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()


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


def vector_env_class(env_class: type[KheperaEnv]) -> type[KheperaVectorEnv]:
    """The native vector env of a single-world env class: ``NavEnv`` → ``NavVectorEnv``, with
    the task's extra methods (such as ``formation_targets``) carried over."""
    name = env_class.__name__.removesuffix("Env") + "VectorEnv"
    extras = {
        attr: value
        for attr, value in vars(env_class).items()
        if callable(value) and not attr.startswith("_") and not hasattr(KheperaVectorEnv, attr)
    }
    doc = (
        f"``{env_class.__name__}``'s task ({env_class.TASK!r}) as a native vector env (the "
        "``vector_entry_point`` of its registration).\n\n    Takes the arguments of "
        ":class:`KheperaVectorEnv` except ``task``; accessors keep the world axis first."
    )
    return type(
        name,
        (_TaskVectorEnv,),
        {"TASK": env_class.TASK, "__doc__": doc, "__module__": __name__, **extras},
    )


#: The vector env class of each task, by the Rust core's task name.
VECTOR_ENV_CLASSES: dict[str, type[KheperaVectorEnv]] = {
    task: vector_env_class(env_class) for task, env_class in ENV_CLASSES.items()
}
globals().update({cls.__name__: cls for cls in VECTOR_ENV_CLASSES.values()})
NavVectorEnv = VECTOR_ENV_CLASSES["nav"]
AvoidVectorEnv = VECTOR_ENV_CLASSES["avoid"]
FormationVectorEnv = VECTOR_ENV_CLASSES["formation"]

__all__ = [
    "VECTOR_ENV_CLASSES",
    "AvoidVectorEnv",
    "FormationVectorEnv",
    "KheperaVectorEnv",
    "NavVectorEnv",
    "vector_env_class",
]
