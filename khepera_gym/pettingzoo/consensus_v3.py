"""``consensus_v3``: robots reaching a rendezvous or a formation from their neighbours' messages, as
PettingZoo agents.

Behaviour version 3: v2's drive (K-Team's speed profile at Acc_Inc 40, 2.71 m/s², which the
exported program sets on the robot), with a robot's contacts with walls and obstacles solved as a
rigid disc's instead of by rapier's step (see the Version History of
:class:`khepera_gym.envs.NavEnv`).
Everything else is that of :mod:`khepera_gym.pettingzoo.consensus_v1`::

    from khepera_gym.pettingzoo import consensus_v3

    env = consensus_v3.parallel_env()
"""

from __future__ import annotations

from typing import Any, ClassVar

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym.pettingzoo import consensus_v1 as _source
from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs

_BASE = _source.ConsensusParallelEnv


class ConsensusParallelEnv(_BASE):
    """:class:`khepera_gym.pettingzoo.consensus_v1.ConsensusParallelEnv`, behaviour
    version 3."""

    metadata: ClassVar[dict[str, Any]] = {**_BASE.metadata, "name": "consensus_v3"}
    VERSION: ClassVar[int | None] = 3


def parallel_env(**kwargs: Any) -> ConsensusParallelEnv:
    """The task as a PettingZoo ``ParallelEnv``; see :class:`ConsensusParallelEnv`."""
    return ConsensusParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
    """The task as a PettingZoo AEC env (agents act in turn, the world steps once all have
    acted); takes the arguments of :func:`parallel_env`."""
    return parallel_to_aec(parallel_env(**kwargs))


__all__ = ["ConsensusParallelEnv", "env", "parallel_env"]
