"""``multinav_v3``: robots driving to their own goals, as PettingZoo agents.

Behaviour version 3: v2's drive (K-Team's speed profile at Acc_Inc 40, 2.71 m/s², which the
exported program sets on the robot), with a robot's contacts with walls and obstacles solved as a
rigid disc's instead of by rapier's step (see the Version History of
:class:`khepera_gym.envs.NavEnv`).
Everything else is that of :mod:`khepera_gym.pettingzoo.multinav`::

    from khepera_gym.pettingzoo import multinav_v3

    env = multinav_v3.parallel_env()
"""

from __future__ import annotations

from typing import Any, ClassVar

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym.pettingzoo import multinav as _source
from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs
from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv

_BASE = _source.MultiNavParallelEnv


class MultiNavParallelEnv(_BASE):
    """:class:`khepera_gym.pettingzoo.multinav.MultiNavParallelEnv` with behaviour version 3."""

    metadata: ClassVar[dict[str, Any]] = {**_BASE.metadata, "name": "multinav_v3"}
    VERSION: ClassVar[int | None] = 3


def parallel_env(**kwargs: Any) -> MultiNavParallelEnv:
    """The task as a PettingZoo ``ParallelEnv``; see :class:`MultiNavParallelEnv`."""
    return MultiNavParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
    """The task as a PettingZoo AEC env (agents act in turn, the world steps once all have
    acted); takes the arguments of :func:`parallel_env`."""
    return parallel_to_aec(parallel_env(**kwargs))


def array_env(num_envs: int = 1, **kwargs: Any) -> MultiAgentArrayEnv:
    """Multi-robot navigation with every agent's data in one array, for swarms: ``num_envs``
    worlds stepped with actions ``(num_envs, n_robots, 2)``; takes ``config``,
    ``action_type``, ``num_threads`` and scenario keys (see :class:`MultiAgentArrayEnv`)."""
    return MultiAgentArrayEnv("multinav", num_envs, version=2, **kwargs)


__all__ = ["MultiNavParallelEnv", "array_env", "env", "parallel_env"]
