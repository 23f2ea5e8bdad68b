"""The followers of N Formation worlds as the rows of one Gymnasium ``VectorEnv``, for RLlib.

:class:`FormationFollowersVectorEnv` is a face over one ``_core.Batch`` of the task "formation"
with autoreset: what it shows of the batch (ground truth, layouts, saved state, episode
statistics) comes from :class:`khepera_gym.batch_face.BatchFace`; this module only maps the worlds'
follower blocks to rows and back. It is registered with Ray Tune as
``khepera_gym/formation_followers_v0`` (:mod:`khepera_gym.learning.rllib.creators`), for one policy
shared by every follower; the SB3 counterpart is
:class:`khepera_gym.learning.sb3.FormationFollowersVecEnv`.

Units are SI (m, s, rad); robot frame x forward, y left. Threading and copies: the Rust batch
steps the worlds on its pool of ``num_threads`` threads with the GIL released; returned arrays
are fresh.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym._inputs import as_action_array, check_seed
from khepera_gym.batch_face import WORLD_STATS_KEY, BatchFace, check_render_mode, first_seed
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.observations import layout_dict
from khepera_gym.render import Renderer

#: The Rust core's task whose followers are the rows.
TASK = "formation"


class FormationFollowersVectorEnv(BatchFace, gym.vector.VectorEnv):
    """The followers of N Formation worlds as the rows of one Gymnasium ``VectorEnv``.

    Row ``w · K + k`` is follower k of world w: it observes its own 23-value block (IR,
    ultrasonic, ``target_offset``, ``leader_offset``, ``leader_heading``, ``leader_velocity``,
    ``wheel_speeds``; see :class:`khepera_gym.envs.FormationEnv`), acts with its (left, right)
    wheel pair and earns its own reward, so one policy trained on these rows drives every
    follower (parameter sharing). The leader is scripted. All rows of a world end together.

    Semantics as :class:`khepera_gym.vector.KheperaVectorEnv`: NEXT_STEP autoreset (the step
    after a world ended resets it: first observations, reward 0, flags False, its actions
    ignored), ``reset(seed=s)`` seeds world w with ``s + w`` (``None`` continues the streams),
    and at a step where a world ended ``info["episode_stats"]`` holds each of its rows' own
    statistics (its follower's return, length, success, path length and contacts) and
    ``info["world_episode_stats"]`` the world's on each of its rows (with the formation
    errors), arrays of shape (N · K,) with boolean masks ``"_return"``, .... Ground
    truth keeps the world axis first (``poses()`` is (N, K + 1, 3), the leader first;
    ``targets()`` (N, K, 2)); ``get_state``/``set_state`` save and restore every world.

    Args:
        num_worlds: Number of worlds N; the env has ``num_envs = N · K`` rows.
        config: None, a built-in scenario name (e.g. "paper_fig7") or a TOML path.
        action_type: "wheels" or "unicycle".
        num_threads: Threads of the batch's pool; None uses every core.
        max_episode_steps: If given, overrides the scenario's ``max_steps``.
        render_mode: None, "rgb_array" or "human" (a mosaic of the first ``render_worlds``).
        frame_size: (width, height) in pixels of one world's frame;
            None: 480 x 480, more for an arena over 4 m
            (:func:`khepera_gym.render.default_frame_size`).
        render_worlds: Worlds tiled by ``render()``.
        **overrides: Scenario keys (``n_followers=3``, ``shape="wedge"``, ...).

    Raises:
        ConfigError: An agent leader (``leader="agent"``), or any scenario error.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array", "human"],
        "render_fps": 20,
        "autoreset_mode": gym.vector.AutoresetMode.NEXT_STEP,
    }
    _WORLD: ClassVar[int | None] = None

    def __init__(
        self,
        num_worlds: int = 1,
        *,
        config: ConfigArg = None,
        action_type: str = "wheels",
        num_threads: int | None = None,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        frame_size: tuple[int, int] | None = None,
        render_worlds: int = 4,
        **overrides: Any,
    ) -> None:
        if "task" in overrides:
            raise ConfigError(f"FormationFollowersVectorEnv runs the task {TASK!r}")
        check_render_mode(render_mode, self.metadata["render_modes"])
        self._batch = make_batch(
            TASK,
            num_worlds,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=True,
            episode_steps=("max_episode_steps", max_episode_steps),
        )
        agents = self._batch.agents()
        names = [name for name, *_ in agents]
        if any(not name.startswith("follower_") for name in names):
            raise ConfigError(
                "the formation-followers env needs the scripted leader (formation.leader = "
                f"'scripted'); the agents here are {names}: use khepera_gym/formation_v1 for "
                "an agent leader"
            )
        block = agents[0][3] - agents[0][2]
        if [(start, stop) for _, _, start, stop, _ in agents] != [
            (k * block, (k + 1) * block) for k in range(len(agents))
        ] or agents[-1][3] != self._batch.obs_dim:
            raise KheperaError(f"unexpected follower blocks in the joint observation: {agents}")
        #: Worlds in the batch.
        self.num_worlds: int = self._batch.num_worlds
        #: Followers per world (rows per world), K.
        self.followers_per_world: int = len(agents)
        #: Agent names of the rows of one world, in order.
        self.follower_names: list[str] = names
        #: Layout of one follower's block, name → slice.
        self.follower_layout: dict[str, slice] = layout_dict(agents[0][4])
        self.num_envs = self.num_worlds * self.followers_per_world
        self.render_mode = render_mode
        self.action_type = action_type
        self._block = block
        self.single_observation_space = self._row_observation_space()
        self.single_action_space = self._row_action_space()
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, self.num_envs
        )
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._action_shape = (self.num_envs, self._batch.agent_act_dim)
        self._has_reset = False
        self._render_worlds = max(1, int(render_worlds))
        self._renderer = Renderer(
            self._batch,
            render_mode,
            frame_size,
            fps=self.metadata["render_fps"],
            title="khepera_gym formation followers",
        )

    # --- rows: one per follower ----------------------------------------------------------------

    def _row_observation_space(self) -> gym.spaces.Box:
        """The Box of one follower's block (every follower's bounds are the same)."""
        low, high = self._batch.obs_bounds()
        block = slice(0, self._block)
        return gym.spaces.Box(
            low[block].astype(np.float32), high[block].astype(np.float32), dtype=np.float32
        )

    def _row_action_space(self) -> gym.spaces.Box:
        """The Box of one follower's (left, right) wheel pair, normalised to [-1, 1] (then its
        LEDs' red, green, blue with ``task.led_action``)."""
        return gym.spaces.Box(-1.0, 1.0, shape=(self._batch.agent_act_dim,), dtype=np.float32)

    def _rows(self, joint: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        return joint.reshape(self.num_envs, self._block)

    # --- Gymnasium VectorEnv API ----------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Resets every world (world w seeded ``seed + w``; None continues each stream, the
        very first reset drawing a base seed from ``self.np_random``).

        Returns:
            Observations (num_envs, 23) and an empty info dict.

        Raises:
            ConfigError: ``seed`` is not None or an int in [0, 2**64) (per-world sequences are
                not taken: a world's rows share one seed).
        """
        seed = check_seed(seed)
        super().reset(seed=seed)
        if seed is None and not self._has_reset:
            seed = first_seed(self.np_random)
        self._has_reset = True
        return self._rows(self._batch.reset(seed)), {}

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Steps every world once with the followers' actions, shape (num_envs, 2) ((num_envs, 5)
        with ``task.led_action``).

        Returns:
            ``(observations, rewards, terminations, truncations, infos)`` of num_envs rows; a
            row's reward is its follower's (``agent_rewards()``, 0 on the step that resets its
            world).

        Raises:
            ActionError: Wrong shape, non-numeric or NaN/inf actions.
            KheperaError: ``step`` before the first ``reset()``.
        """
        if not self._has_reset:
            raise KheperaError(
                "step() before reset(): the worlds were never started; call reset() first"
            )
        action_array = as_action_array(
            actions, self._action_shape, "actions (num_envs, agent_act_dim)"
        )
        joint, _, terminated, truncated = self._batch.step(
            action_array.reshape(self.num_worlds, -1)
        )
        rows = self.followers_per_world
        rewards = self.agent_rewards().reshape(-1)
        ended = terminated | truncated
        infos: dict[str, Any] = {}
        if np.count_nonzero(ended):
            infos = self._vector_agent_episode_info(ended, rows=True)
            # The world's statistics on each of its rows.
            for key in (WORLD_STATS_KEY, f"_{WORLD_STATS_KEY}"):
                value = infos[key]
                infos[key] = (
                    np.repeat(value, rows)
                    if isinstance(value, np.ndarray)
                    else {name: np.repeat(v, rows) for name, v in value.items()}
                )
        return (
            self._rows(joint),
            rewards,
            np.repeat(terminated, rows),
            np.repeat(truncated, rows),
            infos,
        )

    def render(self) -> npt.NDArray[np.uint8] | None:
        """A mosaic of the first ``render_worlds`` worlds (rgb_array), or shown in a window."""
        return self._renderer.render(self._render_worlds)

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12) of every world, shape (num_worlds, K, 2):
        :meth:`targets` under its task's name."""
        return self.targets()

    def close_extras(self, **kwargs: Any) -> None:
        """Closes the render window, if any (also after a constructor that raised)."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()


__all__ = ["FormationFollowersVectorEnv"]
