"""``multinav_v1``: robots driving to their own goals, as PettingZoo agents,
with the latest dynamics (tyre grip, contact friction, the motor's speed profile).

The environment, its agents, spaces and rewards are documented in
:mod:`khepera_gym.pettingzoo.multinav`::

    from khepera_gym.pettingzoo import multinav_v1

    env = multinav_v1.parallel_env()

For swarms (hundreds of robots, e.g. ``config="swarm"``: 1,000 robots in a 20 m arena),
:func:`array_env` returns every agent's observation, reward and termination in one array
(:class:`khepera_gym.pettingzoo.arrays.MultiAgentArrayEnv`) instead of a dict per agent.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym.pettingzoo import multinav as _multinav
from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs
from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv

_BASE = _multinav.MultiNavParallelEnv


class MultiNavParallelEnv(_BASE):
    """:class:`khepera_gym.pettingzoo.multinav.MultiNavParallelEnv` with behaviour version 1."""

    metadata: ClassVar[dict[str, Any]] = {**_BASE.metadata, "name": "multinav_v1"}
    VERSION: ClassVar[int | None] = 1


def parallel_env(**kwargs: Any) -> MultiNavParallelEnv:
    """Multi-robot navigation as a PettingZoo ``ParallelEnv``; see :class:`MultiNavParallelEnv`."""
    return MultiNavParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
    """Multi-robot navigation as a PettingZoo AEC env (agents act in turn, the world steps
    once all have acted); takes the arguments of :func:`parallel_env`."""
    return parallel_to_aec(parallel_env(**kwargs))


def array_env(num_envs: int = 1, **kwargs: Any) -> MultiAgentArrayEnv:
    """Multi-robot navigation with every agent's data in one array, for swarms: ``num_envs``
    worlds stepped with actions ``(num_envs, n_robots, 2)``; takes ``config``,
    ``action_type``, ``num_threads`` and scenario keys (see :class:`MultiAgentArrayEnv`)."""
    return MultiAgentArrayEnv("multinav", num_envs, version=1, **kwargs)


__all__ = ["MultiNavParallelEnv", "array_env", "env", "parallel_env"]
