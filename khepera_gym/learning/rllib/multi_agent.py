"""A khepera_gym PettingZoo world as a native RLlib ``MultiAgentEnv``, and the policy mappings.

:class:`KheperaMultiAgentEnv` is a face over the ``_core.Batch`` of one PettingZoo parallel env
(:mod:`khepera_gym.pettingzoo`: ``formation_v3``, ``multinav_v3``): the PettingZoo env steps the
world and keeps the agents' bookkeeping, :class:`khepera_gym.batch_face.BatchFace` shows the world
(ground truth, layouts, saved state, episode statistics), and this module adds RLlib's
conventions (``"__all__"`` flags, the seed of each runner's copy). :class:`SharedPolicy` and
:func:`policy_per_agent` are the two ``policy_mapping_fn`` of
:func:`khepera_gym.learning.rllib.policy_mapping`.

Units are SI (m, s, rad). Threading and copies: ``step`` and ``reset`` release the GIL inside
the Rust core; every returned observation is a fresh array.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import numpy.typing as npt
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from khepera_gym.batch_face import BatchFace
from khepera_gym.learning.rllib.seeding import multi_agent_world_seed

if TYPE_CHECKING:
    from khepera_gym.pettingzoo._parallel import KheperaParallelEnv


class KheperaMultiAgentEnv(BatchFace, MultiAgentEnv):
    """A khepera_gym PettingZoo parallel env (one world) as a native RLlib ``MultiAgentEnv``.

    Semantics are those of :mod:`khepera_gym.pettingzoo` (``formation_v3``, ``multinav_v3``):
    each agent observes its own block and acts with ``Box(-1, 1, (2,))`` (``(5,)`` with
    ``task.led_action``: its LEDs' colour too); an agent that
    terminates (a multinav robot on its goal) gets its last observation with
    ``terminateds[agent] = True`` and then leaves ``agents``; ``"__all__"`` is set in
    ``terminateds`` (every robot arrived, or the formation's leader did) or in ``truncateds``
    (time limit) when no agent is left. ``agents`` and ``possible_agents`` keep the env's fixed
    order (unlike RLlib's ``ParallelPettingZooEnv``, which builds them from a set), and
    ``render()`` takes no argument. The world's accessors are those of every khepera_gym env of
    one world (``poses()``, ``goals()``, ``targets()``, ``obs_layout()``, ``agent_layouts()``,
    ``get_state()``, ...).

    Args:
        parallel_env: The PettingZoo env, e.g. ``formation_v3.parallel_env(n_followers=3)``.
        worker_index: The EnvRunner's index when RLlib builds the env: an int reset seed s is
            then mapped to :func:`~khepera_gym.learning.rllib.multi_agent_world_seed` so that no two
            runners share worlds; None (direct use) seeds the world with s itself.
    """

    _WORLD: ClassVar[int | None] = 0

    def __init__(self, parallel_env: KheperaParallelEnv, worker_index: int | None = None) -> None:
        super().__init__()
        self.parallel_env = parallel_env
        # The PettingZoo env's own batch: both faces show the same world.
        self._batch = parallel_env._batch
        self._has_reset = False
        self.worker_index = worker_index
        self.possible_agents = list(parallel_env.possible_agents)
        self.agents = []
        self.observation_spaces = {
            agent: parallel_env.observation_space(agent) for agent in self.possible_agents
        }
        self.action_spaces = {
            agent: parallel_env.action_space(agent) for agent in self.possible_agents
        }
        self.render_mode = parallel_env.render_mode
        self.metadata = dict(parallel_env.metadata)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Resets the world; returns observations and infos of every agent."""
        if seed is not None and self.worker_index is not None:
            seed = multi_agent_world_seed(seed, self.worker_index)
        observations, infos = self.parallel_env.reset(seed=seed, options=options)
        self.agents = list(self.parallel_env.agents)
        self._has_reset = True
        return observations, infos

    def step(
        self, action_dict: dict[str, Any]
    ) -> tuple[dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, Any]]:
        """Steps the world with one action per live agent (see the class docstring).

        Raises:
            ActionError: A live agent has no action, or an action is malformed (PettingZoo
                env's checks).
        """
        observations, rewards, terminated, truncated, infos = self.parallel_env.step(action_dict)
        self.agents = list(self.parallel_env.agents)
        over = not self.agents
        time_limit = any(truncated.values())
        terminateds = {**terminated, "__all__": over and not time_limit}
        truncateds = {**truncated, "__all__": over and time_limit}
        return observations, rewards, terminateds, truncateds, infos

    def set_state(self, state: bytes) -> None:
        """Restores a state from :meth:`get_state` (of this env or another of the same scenario)
        through the PettingZoo env, so that a later ``reset()`` without a seed continues the
        restored random stream. The live agents are not part of the state: restore one saved
        while the same agents were live (as for the PettingZoo env).

        Raises:
            StateError: ``state`` is not a state of this world (the env is then unchanged).
        """
        self.parallel_env.set_state(state)
        self._has_reset = True

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The world's frame (rgb_array), or shown in a window (human); None without a mode."""
        return self.parallel_env.render()

    def close(self) -> None:
        """Closes the render window, if any."""
        self.parallel_env.close()

    def state(self) -> npt.NDArray[np.float32]:
        """The joint observation of every possible agent (for centralised critics)."""
        return self.parallel_env.state()


class SharedPolicy:
    """A ``policy_mapping_fn`` mapping every agent to one module (parameter sharing)."""

    def __init__(self, module_id: str) -> None:
        self.module_id = module_id

    def __call__(self, agent_id: str, episode: Any = None, **kwargs: Any) -> str:
        """The shared module's id, whatever the agent."""
        return self.module_id


def policy_per_agent(agent_id: str, episode: Any = None, **kwargs: Any) -> str:
    """A ``policy_mapping_fn`` giving each agent a module of its own, named after it."""
    return agent_id


__all__ = ["KheperaMultiAgentEnv", "SharedPolicy", "policy_per_agent"]
