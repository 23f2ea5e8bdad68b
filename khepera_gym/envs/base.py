"""The base of the single-world Gymnasium environments: one world of a task in the Rust core.

Each env owns a ``_core.Batch`` of one world without autoreset: the Rust core simulates,
observes, rewards and ends episodes; this layer only validates actions, converts outputs to
Python scalars and builds ``info``. Ground truth and the rest come from
:class:`khepera_gym.batch_face.BatchFace`. A task's env class (its manual in the docstring)
subclasses
:class:`KheperaEnv` with ``TASK``; :data:`ENV_CLASSES` collects them, and registration
(``khepera_gym/__init__.py``) pairs them with the tasks the core exports.

Units are SI (m, s, rad); the world frame has x right, y up, angles counter-clockwise; the robot
frame has x forward, y left. Threading and copies: ``step`` and ``reset`` release the GIL inside
the Rust core while simulating; every returned array is freshly allocated, so callers may keep or
mutate observations.
"""

from __future__ import annotations

from typing import Any, ClassVar, SupportsFloat

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym import registry
from khepera_gym._inputs import as_action_array, check_options, check_seed
from khepera_gym.batch_face import BatchFace, check_render_mode, first_seed
from khepera_gym.config import VERSION_KEY, ConfigArg, make_batch
from khepera_gym.errors import ConfigError
from khepera_gym.registry import with_history
from khepera_gym.render import Renderer

#: The single-world env class of each task, by the Rust core's task name (filled by subclasses).
ENV_CLASSES: dict[str, type[KheperaEnv]] = {}


class KheperaEnv(BatchFace, gym.Env[npt.NDArray[np.float32], npt.NDArray[np.float32]]):
    """Base of the single-world Khepera IV environments; subclasses set :attr:`TASK`.

    Args:
        render_mode: None, "rgb_array" (``render()`` returns the frame) or "human" (a pygame
            window refreshed after every step; ``pip install khepera-gym[render]``).
        config: None (built-in defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        frame_size: (width, height) of rendered frames in pixels;
            None: 480 x 480, more for an arena over 4 m
            (:func:`khepera_gym.render.default_frame_size`).
        **overrides: Scenario keys overriding the file, e.g. ``goal_radius=0.1`` or
            ``task={"max_steps": 100}`` (see the task's docstring, section Scenario file), and
            ``version``: the behaviour version whose defaults apply (registered ids pass it;
            None: the latest; see the manual's Version History).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "human"], "render_fps": 20}
    #: Task name in the Rust core.
    TASK: ClassVar[str] = ""
    #: Registered versions (``KheperaIV-<Task>-v<n>``) and the scenario keywords each one
    #: passes, so that an older version keeps its behaviour (see the manual's Version History):
    #: every version of the task the core knows, from the one that added it (set per subclass).
    VERSIONS: ClassVar[dict[int, dict[str, Any]]] = {}
    _WORLD: ClassVar[int | None] = 0

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.TASK:
            if "VERSIONS" not in cls.__dict__:
                cls.VERSIONS = {v: {VERSION_KEY: v} for v in registry.task_versions(cls.TASK)}
            if "TASK" in cls.__dict__ and ENV_CLASSES.setdefault(cls.TASK, cls) is cls:
                # The task's manual: its Version History comes from the core's versions.
                cls.__doc__ = with_history(cls.__doc__, cls.TASK)

    def __init__(
        self,
        render_mode: str | None = None,
        config: ConfigArg = None,
        action_type: str = "wheels",
        frame_size: tuple[int, int] | None = None,
        **overrides: Any,
    ) -> None:
        if "num_envs" in overrides:
            raise ConfigError(
                f"num_envs={overrides['num_envs']!r}: gym.make builds one world; for N worlds "
                "stepped together in Rust use gym.make_vec(env_id, num_envs=N) (or "
                "khepera_gym.learning.sb3.make_vec_env(env_id, N) for stable-baselines3)"
            )
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.action_type = action_type
        self._batch = make_batch(
            self.TASK,
            1,
            config,
            overrides,
            action_type=action_type,
            num_threads=1,
            autoreset=False,
        )
        self.observation_space = self._row_observation_space()
        self.action_space = self._row_action_space()
        self._action_shape = (self._batch.act_dim,)
        # Reused input buffer of shape (1, act_dim): the Rust core copies actions on entry.
        self._action_buffer = np.zeros((1, self._batch.act_dim), dtype=np.float32)
        self._has_reset = False
        self._renderer = Renderer(
            self._batch,
            render_mode,
            frame_size,
            fps=self.metadata["render_fps"],
            title=f"khepera_gym {self.TASK}",
        )

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The current frame, drawn in software without a display: (height, width, 3) uint8 for
        ``render_mode="rgb_array"``; for ``"human"`` it is shown in a pygame window (also after
        every step) and None is returned; None without a render mode.

        The frame shows the arena, obstacles, goal(s), formation targets, the robots' fading
        trails, IR rays (green, turning red as an obstacle nears) and ultrasonic rays (blue, to
        the echo), and each robot with its heading (red rim while in contact).
        """
        return self._renderer.render()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Start a new episode.

        Args:
            seed: Seeds the world's random stream (a Python int in [0, 2**64)); None continues
                it (the very first reset without a seed draws one
                from ``self.np_random``).
            options: None or a dict; unused, accepted for API compatibility.

        Returns:
            The first observation and an empty info dict.

        Raises:
            ConfigError: A seed that is not a Python int in [0, 2**64) or None, or options that
                are not a dict (before Gymnasium sees them).
        """
        if seed is not None and not isinstance(seed, int):
            # Gymnasium seeds with Python ints only (not NumPy's): say so with our error.
            raise ConfigError(
                f"seed must be a Python int in [0, 2**64) or None, got {type(seed).__name__}: "
                f"{seed!r}"
            )
        check_seed(seed)
        check_options(options)
        super().reset(seed=seed)
        if seed is None and not self._has_reset:
            seed = first_seed(self.np_random)
        observations = self._batch.reset(seed)
        self._has_reset = True
        if self.render_mode == "human":
            self.render()
        return observations[0], {}

    def step(
        self, action: npt.ArrayLike
    ) -> tuple[npt.NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply one control step (0.05 s by default) of wheel commands.

        Args:
            action: Shape ``(act_dim,)``, normalised to [-1, 1]; finite values outside are
                clipped.

        Returns:
            ``(observation, reward, terminated, truncated, info)``; ``info`` is empty during an
            episode and holds ``"episode_stats"`` statistics and ``"is_success"`` at its last step.

        Raises:
            ActionError: The action is not numeric, has the wrong shape, or is NaN/inf.
            KheperaError: ``step`` after the episode ended without ``reset``.
        """
        buffer = self._action_buffer
        buffer[0] = as_action_array(action, self._action_shape, "action")
        observations, rewards, terminations, truncations = self._batch.step(buffer)
        terminated = bool(terminations[0])
        truncated = bool(truncations[0])
        info = self._episode_info() if terminated or truncated else {}
        if self.render_mode == "human":
            self.render()
        return observations[0], float(rewards[0]), terminated, truncated, info

    def close(self) -> None:
        """Closes the render window, if any (the Rust world is freed with the env); safe to call
        twice."""
        renderer = getattr(self, "_renderer", None)  # absent when construction failed
        if renderer is not None:
            renderer.close()
        super().close()


__all__ = ["ENV_CLASSES", "KheperaEnv"]
