"""Leader-follower formation (paper §3.5, Fig. 7), one PettingZoo agent per robot: the manual of
the ``formation_vN`` modules (one a behaviour version, the same env on that version's dynamics).

The scenario of ``KheperaIV-Formation`` (:class:`khepera_gym.envs.FormationEnv`, whose manual
details the observation, reward and scenario keys) with one agent per follower::

    from khepera_gym.pettingzoo import formation_v3

    env = formation_v3.parallel_env(n_followers=4, shape="cross")
    observations, infos = env.reset(seed=0)
    while env.agents:
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        observations, rewards, terminations, truncations, infos = env.step(actions)

Agents: ``follower_0`` .. ``follower_{K-1}``, with ``leader`` first when ``leader="agent"``.

* Observation of a follower: its 23-value block of the Formation observation (IR, ultrasonic,
  ``target_offset`` in its robot frame, ``leader_offset``, ``leader_heading``,
  ``leader_velocity``, ``wheel_speeds``). All followers
  have equal spaces (same bounds), so one shared policy can drive them all (parameter sharing).
  An agent leader observes the 18-value Nav block. ``agent_obs_layout(agent)`` names the slices;
  ``state()`` is the joint observation (``state_space``).
* Action of every agent: ``Box(-1, 1, (2,), float32)``, normalised (left, right) wheel speeds.
* Reward of follower k per step: ``-error_weight · e_k - collision_penalty · [in contact]
  - team_weight · mean error`` (e_k its distance to its target, m); the agent leader's is Nav's.
* The episode ends for all agents together: terminated when the leader reaches its goal (or on
  contact with ``terminate_on_collision``), truncated after ``max_cycles`` steps (the scenario's
  ``task.max_steps``, 800). Each agent's last info holds its own ``"episode_stats"`` (a
  follower's success: the leader arrived and the follower stands within ``task.goal_radius`` of
  its target) and the world's ``"world_episode_stats"``, with ``"formation_error_mean"`` and
  ``"formation_error_max"``.

``env(**kwargs)`` is the AEC version (``parallel_to_aec``, which adds PettingZoo's order-enforcing
wrapper). No clipping wrapper is added: out-of-range actions are clipped by the core, as in the
Gymnasium envs.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.config import ConfigArg
from khepera_gym.pettingzoo._parallel import KheperaParallelEnv, merge_table_keywords


class FormationParallelEnv(KheperaParallelEnv):
    """K followers (and optionally the leader) of a formation as PettingZoo parallel agents.

    Args:
        n_followers: K, 1..16; None keeps the scenario's (4 by default).
        shape: "cross", "line", "wedge", "circle" or "custom"; None keeps the scenario's.
        leader: "scripted" (position control + Braitenberg in Rust) or "agent"; None keeps the
            scenario's ("scripted" by default).
        config: None, a built-in scenario name (e.g. "paper_fig7") or a path to a TOML file.
        max_cycles: Steps before truncation; None keeps the scenario's ``task.max_steps``.
        **kwargs: Further scenario overrides (e.g. ``spacing=0.4``, or ``formation={...}``, a
            dict of ``[formation]`` keys), ``action_type``.

    Raises:
        ConfigError: A keyword of the wrong type (``formation=5``) or value, as the scenario's
            keys say.
    """

    TASK: ClassVar[str] = "formation"
    FAMILY: ClassVar[str] = "formation"

    def __init__(
        self,
        n_followers: int | None = None,
        shape: str | None = None,
        leader: str | None = None,
        config: ConfigArg = None,
        max_cycles: int | None = None,
        **kwargs: Any,
    ) -> None:
        values = {"n_followers": n_followers, "shape": shape, "leader": leader}
        merge_table_keywords(kwargs, "formation", values)
        super().__init__(config=config, max_cycles=max_cycles, **kwargs)

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12), shape (K, 2), in metres."""
        return self.targets()


__all__ = ["FormationParallelEnv"]
