"""``multinav_v0``: robots driving to their own goals, as PettingZoo agents,
with the v0 dynamics (kinematic drive, frictionless contacts, instant wheel speeds) of the
published v0 numbers.

The environment, its agents, spaces and rewards are documented in
:mod:`khepera_gym.pettingzoo.multinav`; the Version History of
:class:`khepera_gym.envs.NavEnv` says what changed in v1::

    from khepera_gym.pettingzoo import multinav_v0

    env = multinav_v0.parallel_env()
"""

from __future__ import annotations

from typing import Any, ClassVar

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym.pettingzoo import multinav as _multinav
from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs

_BASE = _multinav.MultiNavParallelEnv


class MultiNavParallelEnv(_BASE):
    """:class:`khepera_gym.pettingzoo.multinav.MultiNavParallelEnv` with behaviour version 0."""

    metadata: ClassVar[dict[str, Any]] = {**_BASE.metadata, "name": "multinav_v0"}
    VERSION: ClassVar[int | None] = 0


def parallel_env(**kwargs: Any) -> MultiNavParallelEnv:
    """Multi-robot navigation as a PettingZoo ``ParallelEnv``; see :class:`MultiNavParallelEnv`."""
    return MultiNavParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
    """Multi-robot navigation as a PettingZoo AEC env (agents act in turn, the world steps
    once all have acted); takes the arguments of :func:`parallel_env`."""
    return parallel_to_aec(parallel_env(**kwargs))


__all__ = ["MultiNavParallelEnv", "env", "parallel_env"]
