"""Native vector environments: N worlds of one task stepped by the Rust core in one call.

``gym.make_vec("KheperaIV-Nav", num_envs=N)`` returns a :class:`NavVectorEnv` (every task's env
class ``<Name>Env`` has its ``<Name>VectorEnv``, :data:`VECTOR_ENV_CLASSES`) over a
``_core.Batch`` of N worlds: no
Python loop over worlds and no subprocesses. Worlds are stepped in parallel by the batch's own
rayon pool of ``num_threads`` threads (None = all cores) while the GIL is released; results do not
depend on the thread count.

Semantics follow Gymnasium's ``VectorEnv``:

* autoreset mode NEXT_STEP (the default): the step after a world terminated or was truncated
  resets it and returns its first observation with reward 0 and both flags False (its action is
  ignored);
* autoreset mode DISABLED (``gym.make_vec(id, num_envs=N,
  autoreset_mode=gym.vector.AutoresetMode.DISABLED)``; a keyword, as Gymnasium's ``make_vec``
  refuses ``vector_kwargs`` for a ``vector_entry_point``), for loops that reset worlds themselves
  (partial resets in the manner of TorchRL's ``"_reset"`` mask): nothing is reset by ``step``;
  stepping while a world that ended has not been reset raises
  :class:`~khepera_gym.errors.KheperaError` naming it (and steps no world), and the caller resets
  the worlds that ended with ``reset(options={"reset_mask": terminations | truncations})``;
* ``reset(seed=s)`` seeds world i with ``s + i``, so world i behaves bit for bit like a single env
  reset with seed ``s + i`` given the same actions;
* ``reset(seed=..., options={"reset_mask": mask})`` (either mode, as in Gymnasium's own vector
  envs) resets only the worlds where ``mask`` is True, each with the seed a full reset would give
  it (``s + i``, its entry of a seed sequence, or its own stream for None); the other worlds keep
  their state and return their current observation. ``mask`` is a NumPy bool array of shape (N,)
  with at least one True, anything else raises :class:`~khepera_gym.errors.ConfigError`; the first
  reset must start every world, so a mask leaving one out then raises
  :class:`~khepera_gym.errors.KheperaError`;
* ``info`` is ``{}`` except at steps where some world ended: ``info["episode_stats"]`` then holds
  arrays "return", "length", "success", "path_length", "collisions" (Formation adds
  "formation_error_mean", "formation_error_max") of shape (N,) with boolean masks ``"_return"``,
  ... (and ``info["_episode_stats"]``) true for the worlds that ended;
* ``step`` before the first ``reset()`` raises :class:`~khepera_gym.errors.KheperaError` (in
  either mode), as the single env does;
* every returned array is freshly allocated (copy semantics).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from khepera_gym._inputs import (
    SEED_LIMIT,
    as_action_array,
    check_int,
    check_options,
    check_reset_mask,
    check_seed,
    check_world_seeds,
)
from khepera_gym.batch_face import BatchFace, check_render_mode, first_seed
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.envs import KheperaEnv
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.render import Renderer

#: The autoreset modes of the native vector envs (the Rust batch resets a finished world on the
#: next step, or not at all; SAME_STEP would need the final observation kept in ``info``).
AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.DISABLED)


def resolve_autoreset_mode(autoreset_mode: AutoresetMode | str) -> AutoresetMode:
    """``autoreset_mode`` as an :class:`AutoresetMode` of :data:`AUTORESET_MODES`; like
    Gymnasium's own vector envs, it takes the enum or its value ("NextStep", "Disabled").

    Raises:
        ConfigError: Anything else, SAME_STEP included.
    """
    mode: AutoresetMode | None = None
    if isinstance(autoreset_mode, AutoresetMode):
        mode = autoreset_mode
    elif isinstance(autoreset_mode, str):
        mode = next((m for m in AutoresetMode if m.value == autoreset_mode), None)
    if mode is None or mode not in AUTORESET_MODES:
        supported = ", ".join(f"AutoresetMode.{m.name} ({m.value!r})" for m in AUTORESET_MODES)
        hint = (
            "; for SAME_STEP use Gymnasium's SyncVectorEnv over the single env: gym.make_vec(id, "
            "vectorization_mode='sync', vector_kwargs={'autoreset_mode': ...})"
            if mode is AutoresetMode.SAME_STEP
            else ""
        )
        raise ConfigError(
            f"autoreset_mode must be one of {supported}, got {autoreset_mode!r}{hint}"
        )
    return mode


class KheperaVectorEnv(BatchFace, VectorEnv):
    """N seeded Khepera IV worlds of one task, stepped in parallel by the Rust core.

    Args:
        num_envs: Number of worlds N (>= 1).
        task: A task of the Rust core's registry (a name of ``registry.task_names()``: "nav", ...).
        render_mode: None, "rgb_array" (``render()`` returns a mosaic of the first
            ``render_worlds`` worlds) or "human" (that mosaic in a pygame window).
        config: None (built-in defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        num_threads: Threads of the batch's rayon pool; None uses all cores.
        frame_size: (width, height) in pixels of one world's frame;
            None: 480 x 480, more for an arena over 4 m
            (:func:`khepera_gym.render.default_frame_size`).
        render_worlds: How many worlds ``render()`` tiles (default 4).
        max_episode_steps: If given, overrides the scenario's ``max_steps`` (truncation length).
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default: the step after a world ended
            resets it) or ``AutoresetMode.DISABLED`` (worlds that ended are reset by
            ``reset(options={"reset_mask": ...})``; stepping one before raises); the enum or its
            value string. ``metadata["autoreset_mode"]`` and :attr:`autoreset_mode` show it.
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
        frame_size: tuple[int, int] | None = None,
        render_worlds: int = 4,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **overrides: Any,
    ) -> None:
        if not isinstance(task, str):
            raise ConfigError(
                f"task names the task here (a name of the core's registry), got {task!r}; give "
                "[task] keys by their names (goal_radius=0.1), or use gym.make_vec with the id"
            )
        check_render_mode(render_mode, self.metadata["render_modes"])
        #: How a world that ended is reset (see the class docstring).
        self.autoreset_mode = resolve_autoreset_mode(autoreset_mode)
        # An instance's own metadata, as Gymnasium's vector envs do: the class keeps NEXT_STEP.
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self._batch = make_batch(
            task,
            num_envs,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=self.autoreset_mode == AutoresetMode.NEXT_STEP,
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
        self._render_worlds = check_int(render_worlds, "render_worlds", 1)
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
        """Reset every world, or the worlds of ``options["reset_mask"]``.

        Args:
            seed: An int s seeds world i with ``s + i``; a sequence of N seeds (int or None) seeds
                each world with its own; None continues each world's stream (the very first reset
                without a seed draws s from ``self.np_random``). With a reset mask, the worlds
                reset take the same seeds (``s + i``, or their entry of the sequence); the other
                worlds' entries are checked, and unused.
            options: ``{"reset_mask": mask}``, a NumPy bool array of shape (N,) with at least one
                True, resets only the worlds where it is True (in either autoreset mode, as
                Gymnasium's own vector envs do); the other worlds keep their state, and their row
                of the returned observations is their current one. Other keys are ignored, and
                ``options`` itself is not modified.

        Returns:
            Observations of shape (N, obs_dim) and an empty info dict.

        Raises:
            ConfigError: A bad seed, ``options`` not a dict, or a bad reset mask (not a NumPy
                array, another dtype or shape, no True value).
            KheperaError: A reset mask leaving a world out on the first reset (every world must
                start an episode first).
        """
        mask = self._reset_mask(options)
        if mask is not None and not mask.all():
            return self._reset_masked(seed, mask), {}
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

    def _reset_mask(self, options: Mapping[str, Any] | None) -> npt.NDArray[np.bool_] | None:
        """The checked ``options["reset_mask"]``, or None (reset every world)."""
        options = check_options(options)
        if options is None or "reset_mask" not in options:
            return None
        return check_reset_mask(options["reset_mask"], self.num_envs)

    def _reset_masked(
        self, seed: int | Sequence[int | None] | None, mask: npt.NDArray[np.bool_]
    ) -> npt.NDArray[np.float32]:
        """Resets the worlds of ``mask`` (some, not all) with the seeds a full reset would give
        them; returns every world's current observation."""
        if not self._has_reset:
            raise KheperaError(
                'reset(options={"reset_mask": mask}) before the first reset: the first reset '
                "starts every world, so drop the mask (or make it all True)"
            )
        worlds = np.flatnonzero(mask).tolist()
        if seed is None or isinstance(seed, (int, np.integer)):
            base = check_seed(seed)
            super().reset(seed=base)
            # As the core's full reset does: world i gets s + i, wrapping at 2**64.
            world_seeds = [None if base is None else (base + w) % SEED_LIMIT for w in worlds]
        else:
            seeds = check_world_seeds(seed, self.num_envs)
            world_seeds = [seeds[world] for world in worlds]
        for world, world_seed in zip(worlds, world_seeds, strict=True):
            self._batch.reset_world(world, world_seed)
        observations, _, _, _ = self._batch.last_outputs()
        return observations

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
        """Step every world once. NEXT_STEP: a world that ended on the previous step is reset
        instead (its action is ignored). DISABLED: every world must be in an episode.

        Args:
            actions: Shape (N, act_dim), normalised to [-1, 1]; finite values outside are clipped.

        Returns:
            ``(observations, rewards, terminations, truncations, infos)`` as arrays of N rows.

        Raises:
            ActionError: Actions are not numeric, have the wrong shape, or contain NaN/inf.
            KheperaError: ``step`` before the first ``reset()`` (either mode); DISABLED: a world
                ended and was not reset since (the message names the first such world). No world
                is stepped.
        """
        if not self._has_reset:
            raise KheperaError(
                "step() before reset(): the worlds were never started; call reset() first"
            )
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
            section = kwargs.pop("task")
            if not isinstance(section, Mapping):
                raise ConfigError(
                    f"{type(self).__name__} runs the task {self.TASK!r}; "
                    "use KheperaVectorEnv(task=...) for another (a table is the [task] section)"
                )
            # The scenario's [task] section, as everywhere else: its keys, dotted.
            kwargs.update({f"task.{key}": value for key, value in section.items()})
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


# --- generated by `python -m khepera_gym._generate` (make generated): do not edit ---
from khepera_gym.envs import FormationEnv  # noqa: E402


class DroneFollowVectorEnv(_TaskVectorEnv):
    """``DroneFollowEnv``'s task ('dronefollow') as a native vector env (the ``vector_entry_point``
    of its registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "dronefollow"


class NavVectorEnv(_TaskVectorEnv):
    """``NavEnv``'s task ('nav') as a native vector env (the ``vector_entry_point`` of its
    registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "nav"


class AvoidVectorEnv(_TaskVectorEnv):
    """``AvoidEnv``'s task ('avoid') as a native vector env (the ``vector_entry_point`` of its
    registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "avoid"


class FormationVectorEnv(_TaskVectorEnv):
    """``FormationEnv``'s task ('formation') as a native vector env (the ``vector_entry_point`` of
    its registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "formation"
    formation_targets = FormationEnv.formation_targets


class LineFollowVectorEnv(_TaskVectorEnv):
    """``LineFollowEnv``'s task ('linefollow') as a native vector env (the ``vector_entry_point``
    of its registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "linefollow"


class PathFollowVectorEnv(_TaskVectorEnv):
    """``PathFollowEnv``'s task ('pathfollow') as a native vector env (the ``vector_entry_point``
    of its registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "pathfollow"


class SeekVectorEnv(_TaskVectorEnv):
    """``SeekEnv``'s task ('seek') as a native vector env (the ``vector_entry_point`` of its
    registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "seek"


class TrackVectorEnv(_TaskVectorEnv):
    """``TrackEnv``'s task ('track') as a native vector env (the ``vector_entry_point`` of its
    registration).

    Takes the arguments of :class:`KheperaVectorEnv` except ``task``; accessors keep the world axis
    first."""

    TASK: ClassVar[str] = "track"


#: The vector env class of each task, by the Rust core's task name.
VECTOR_ENV_CLASSES: dict[str, type[KheperaVectorEnv]] = {
    "dronefollow": DroneFollowVectorEnv,
    "nav": NavVectorEnv,
    "avoid": AvoidVectorEnv,
    "formation": FormationVectorEnv,
    "linefollow": LineFollowVectorEnv,
    "pathfollow": PathFollowVectorEnv,
    "seek": SeekVectorEnv,
    "track": TrackVectorEnv,
}

__all__ = [
    "AUTORESET_MODES",
    "VECTOR_ENV_CLASSES",
    "AvoidVectorEnv",
    "DroneFollowVectorEnv",
    "FormationVectorEnv",
    "KheperaVectorEnv",
    "LineFollowVectorEnv",
    "NavVectorEnv",
    "PathFollowVectorEnv",
    "SeekVectorEnv",
    "TrackVectorEnv",
    "resolve_autoreset_mode",
    "vector_env_class",
]
# --- end of generated block ---
