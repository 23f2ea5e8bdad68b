"""PettingZoo environments: one agent per controlled Khepera IV robot, over the same Rust core.

One module per task and behaviour version, ``<task>_v<n>`` (:func:`modules` finds them by
listing this package; ``khepera-gym list pettingzoo`` prints them); the latest version of each:

* ``formation_vN``: followers holding a formation around a leader (agents ``follower_0``..,
  plus ``leader`` with ``leader="agent"``; the manual: :mod:`khepera_gym.pettingzoo.formation`);
* ``multinav_vN``: robots driving to their own goals (agents ``robot_0``..; the manual:
  :mod:`khepera_gym.pettingzoo.multinav`);
* ``consensus_vN``: robots reaching a rendezvous or a formation from their neighbours' messages
  (agents ``robot_0``..; the manual: its ``ConsensusParallelEnv``);
* ``drone_follow_vN``: a quadcopter following a Khepera IV (agent ``drone``, plus ``robot``
  with ``driver="agent"``; the manual: :class:`khepera_gym.envs.DroneFollowEnv`);
* ``platoon_vN``: robots tracking time-shifted copies of one reference trajectory (agents
  ``robot_0``..; the manual: its ``PlatoonParallelEnv``).

The ``_v0`` modules keep the v0 dynamics (kinematic drive, frictionless contacts, instant wheel
speeds) so that published v0 numbers reproduce; see the Version History of
:class:`khepera_gym.envs.NavEnv`. ``tests/test_lists_from_registries.py`` checks that this list
names every task of :func:`modules` and that ``__all__`` holds every module.

Each module has ``parallel_env(**kwargs)`` (a ``pettingzoo.ParallelEnv``) and ``env(**kwargs)``
(its AEC version). Requires ``pettingzoo`` (a dependency of khepera_gym).
"""

from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType

from khepera_gym.pettingzoo import (
    consensus_v1,
    consensus_v2,
    consensus_v3,
    drone_follow_v1,
    drone_follow_v2,
    drone_follow_v3,
    formation_v0,
    formation_v1,
    formation_v2,
    formation_v3,
    multinav_v0,
    multinav_v1,
    multinav_v2,
    multinav_v3,
    platoon_v1,
    platoon_v2,
    platoon_v3,
)


def modules() -> dict[str, ModuleType]:
    """Every versioned module of this package (``formation_v2`` → its module), found by listing
    the package: a new task's or version's module is included without a list to update."""
    found = {}
    for info in pkgutil.iter_modules(__path__):
        stem, _, version = info.name.rpartition("_v")
        if stem and version.isdigit():
            found[info.name] = importlib.import_module(f"{__name__}.{info.name}")
    return dict(sorted(found.items(), key=lambda item: (item[0].rpartition("_v")[0], _v(item[0]))))


def _v(name: str) -> int:
    return int(name.rpartition("_v")[2])


__all__ = [
    "consensus_v1",
    "consensus_v2",
    "consensus_v3",
    "drone_follow_v1",
    "drone_follow_v2",
    "drone_follow_v3",
    "formation_v0",
    "formation_v1",
    "formation_v2",
    "formation_v3",
    "modules",
    "multinav_v0",
    "multinav_v1",
    "multinav_v2",
    "multinav_v3",
    "platoon_v1",
    "platoon_v2",
    "platoon_v3",
]
