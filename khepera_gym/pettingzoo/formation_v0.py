"""``formation_v0``: leader-follower formation (paper §3.5, Fig. 7), as PettingZoo agents,
with the v0 dynamics (kinematic drive, frictionless contacts, instant wheel speeds) of the
published v0 numbers.

The environment, its agents, spaces and rewards are documented in
:mod:`khepera_gym.pettingzoo.formation`; the Version History of
:class:`khepera_gym.envs.FormationEnv` says what changed in v1::

    from khepera_gym.pettingzoo import formation_v0

    env = formation_v0.parallel_env()
"""

from __future__ import annotations

from typing import Any, ClassVar

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym.pettingzoo import formation as _formation
from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs

_BASE = _formation.FormationParallelEnv


class FormationParallelEnv(_BASE):
    """:class:`khepera_gym.pettingzoo.formation.FormationParallelEnv` with behaviour version 0."""

    metadata: ClassVar[dict[str, Any]] = {**_BASE.metadata, "name": "formation_v0"}
    VERSION: ClassVar[int | None] = 0


def parallel_env(**kwargs: Any) -> FormationParallelEnv:
    """The formation task as a PettingZoo ``ParallelEnv``; see :class:`FormationParallelEnv`."""
    return FormationParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
    """The formation task as a PettingZoo AEC env (agents act in turn, the world steps
    once all have acted); takes the arguments of :func:`parallel_env`."""
    return parallel_to_aec(parallel_env(**kwargs))


__all__ = ["FormationParallelEnv", "env", "parallel_env"]
