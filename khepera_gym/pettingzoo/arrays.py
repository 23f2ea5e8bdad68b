"""All agents' arrays at once: a multi-agent env for swarms, where PettingZoo's dict per agent
costs far more than the Rust core (a 1,000-robot world steps in about 1.2 ms; building and
reading 1,000-entry dicts takes several times that).

A :class:`MultiAgentArrayEnv` owns a ``_core.Batch`` of ``num_envs`` worlds of one multi-robot
task and steps them all with one array of actions ``(num_envs, n_agents, 2)``; it returns
observations ``(num_envs, n_agents, obs_dim)``, rewards and terminations ``(num_envs, n_agents)``
and truncations ``(num_envs,)``, in the order of ``agents``. A world whose episode ended is reset
by the next ``step``, which returns its first observation with zero rewards and false flags
(Gymnasium's NEXT_STEP autoreset). At the step a world's episode ends, ``info["episode_stats"]``
holds each agent's own statistics, arrays ``(num_envs, n_agents)`` ("return": the sum of its
rewards while it took part, "length", "success" as the task defines it for one agent,
"path_length", "collisions"), and ``info["world_episode_stats"]`` the world's, arrays
``(num_envs,)`` (all agents together, with the task's own statistics); each has ``_name`` masks
``(num_envs,)`` of the worlds that ended, as a Gymnasium vector env's infos. The agents' rewards
and terminations are the PettingZoo env's (a multinav robot that arrived is terminated as an
agent and parks; its statistics stop there).

Units are SI (m, s, rad); robot frame x forward, y left. Threading: the worlds (and a swarm's
robots) are stepped on ``num_threads`` threads with the GIL released; results do not depend on
it. Copies: every returned array is fresh.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import numpy.typing as npt

from khepera_gym._inputs import check_seed
from khepera_gym.batch_face import BatchFace, first_seed
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.render import Renderer

#: Wheel actions per agent: normalised (left, right) wheel speeds, or (v, ω) with "unicycle";
#: with ``task.led_action`` each agent has 3 more, its LEDs' red, green, blue (5 in all).
ACTION_DIM = 2


class MultiAgentArrayEnv(BatchFace):
    """``num_envs`` worlds of a multi-robot task, every agent's data in one array.

    Args:
        task: The task's name in the Rust core ("multinav").
        num_envs: Worlds stepped together.
        version: Behaviour version whose defaults apply (None: the latest).
        config: None (the task's defaults), a built-in scenario name ("swarm") or a TOML path.
        action_type: "wheels" or "unicycle".
        num_threads: Threads stepping the worlds and a swarm's robots; None uses every core.
        render_mode: None or "rgb_array" (``render()`` returns world 0's frame).
        frame_size: (width, height) of the frame in pixels;
            None: 480 x 480, more for an arena over 4 m
            (:func:`khepera_gym.render.default_frame_size`).
        **overrides: Scenario keys overriding the file, as for the Gymnasium envs.

    Raises:
        ConfigError: Unknown or impossible scenario keys, or agents whose observations differ
            in size (the array needs one size).
    """

    def __init__(
        self,
        task: str,
        /,
        num_envs: int = 1,
        *,
        version: int | None = None,
        config: ConfigArg = None,
        action_type: str = "wheels",
        num_threads: int | None = None,
        render_mode: str | None = None,
        frame_size: tuple[int, int] | None = None,
        **overrides: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self._batch = make_batch(
            task,
            num_envs,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=True,
            version=version,
        )
        specs = self._batch.agents()
        sizes = {stop - start for _, _, start, stop, _ in specs}
        starts = [start for _, _, start, _, _ in specs]
        size = sizes.pop() if len(sizes) == 1 else None
        if size is None or starts != [k * size for k in range(len(specs))]:
            raise ConfigError(
                f"{task}: agents' observations differ in size ({sorted({*sizes})}); the array "
                "env needs one size (use the PettingZoo parallel_env)"
            )
        #: Number of worlds.
        self.num_envs: int = self._batch.num_worlds
        #: Agent names, in the order of the arrays' agent axis.
        self.agents: list[str] = [name for name, *_ in specs]
        #: Observation values per agent.
        self.agent_obs_dim: int = size
        low, high = self._batch.obs_bounds()
        #: One agent's observation space.
        self.single_observation_space = gymnasium.spaces.Box(
            low[:size], high[:size], dtype=np.float32
        )
        #: One agent's action space.
        self.single_action_space = gymnasium.spaces.Box(
            -1.0, 1.0, shape=(self._batch.agent_act_dim,), dtype=np.float32
        )
        self._shape = (self.num_envs, len(self.agents))
        self._has_reset = False
        self.render_mode = render_mode
        self._renderer = Renderer(self._batch, render_mode, frame_size)

    @property
    def n_agents(self) -> int:
        """Agents per world."""
        return len(self.agents)

    def _observations(self, joint: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        return joint.reshape(*self._shape, self.agent_obs_dim)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Resets every world (world i seeded with ``seed + i``; None continues the streams).

        Returns:
            Observations ``(num_envs, n_agents, obs_dim)`` and an empty info dict.
        """
        seed = check_seed(seed)
        if seed is None and not self._has_reset:
            seed = first_seed()
        self._has_reset = True
        return self._observations(self._batch.reset(seed)), {}

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Steps every world with ``actions`` of shape ``(num_envs, n_agents, A)``, A = 2 (5 with
        ``task.led_action``).

        Returns:
            ``(observations, rewards, terminated, truncated, info)``: observations
            ``(num_envs, n_agents, obs_dim)``, each agent's reward and termination
            ``(num_envs, n_agents)``, each world's truncation ``(num_envs,)``, and on an episode's
            end ``info["episode_stats"]`` (each agent's own, ``(num_envs, n_agents)``) and
            ``info["world_episode_stats"]`` (the world's, ``(num_envs,)``), with ``_name`` masks
            of the worlds that ended.

        Raises:
            ActionError: ``actions`` of another shape, not numbers, or not finite.
            KheperaError: ``step`` before the first ``reset()``.
        """
        if not self._has_reset:
            raise KheperaError("step() before reset(): the worlds were never started; call reset()")
        shape = (*self._shape, self._batch.agent_act_dim)
        try:
            array = np.asarray(actions, dtype=np.float32)
        except (TypeError, ValueError) as error:
            raise ActionError(f"actions must be numbers of shape {shape}: {error}") from None
        if array.shape != shape:
            raise ActionError(f"actions must have shape {shape}, got {array.shape}")
        if not np.all(np.isfinite(array)):
            raise ActionError("actions must be finite (no NaN or inf)")
        joint = np.ascontiguousarray(array.reshape(self.num_envs, -1))
        observations, _, terminations, truncations = self._batch.step(joint)
        rewards = self._batch.agent_rewards()
        terminated = self._batch.agent_terminated()
        ended = terminations | truncations
        info = self._vector_agent_episode_info(ended) if ended.any() else {}
        return self._observations(observations), rewards, terminated, truncations, info

    def render(self) -> npt.NDArray[np.uint8] | None:
        """World 0's frame (height, width, 3) uint8 with ``render_mode="rgb_array"``, else
        None."""
        return self._renderer.render()

    def close(self) -> None:
        """Closes the renderer, if any (the Rust worlds are freed with the env), as every env
        kind of the package can be closed; safe to call twice, and on an env whose
        construction failed."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()


__all__ = ["ACTION_DIM", "MultiAgentArrayEnv"]
