"""PettingZoo environments: one agent per controlled Khepera IV robot, over the same Rust core.

One module per task family and behaviour version, ``<family>_v<n>``, for every version the
family's task exists in (:func:`modules` returns them; ``khepera-gym list pettingzoo`` prints
them). The families, each with its manual:

* ``formation_vN``: followers holding a formation around a leader (agents ``follower_0``..,
  plus ``leader`` with ``leader="agent"``; the manual: :mod:`khepera_gym.pettingzoo.formation`);
* ``multinav_vN``: robots driving to their own goals (agents ``robot_0``..; the manual:
  :mod:`khepera_gym.pettingzoo.multinav`);
* ``consensus_vN``: robots reaching a rendezvous or a formation from their neighbours' messages
  (agents ``robot_0``..; the manual:
  :class:`khepera_gym.pettingzoo.consensus.ConsensusParallelEnv`);
* ``drone_follow_vN``: a quadcopter following a Khepera IV (agent ``drone``, plus ``robot``
  with ``driver="agent"``; the manual: :class:`khepera_gym.envs.DroneFollowEnv`);
* ``platoon_vN``: robots tracking time-shifted copies of one reference trajectory (agents
  ``robot_0``..; the manual: :class:`khepera_gym.pettingzoo.platoon.PlatoonParallelEnv`).

Each module has ``parallel_env(**kwargs)`` (a ``pettingzoo.ParallelEnv``) and ``env(**kwargs)``
(its AEC version), and a family of swarms ``array_env(num_envs, **kwargs)``. The modules are made
from the family's class and the core's behaviour versions (:mod:`khepera_gym.pettingzoo._versions`)
when this package is imported, so ``from khepera_gym.pettingzoo import formation_v0`` keeps the
paper's v0 dynamics and a new version adds its modules without a file. The Version History of
each manual says what each version changed. Requires ``pettingzoo`` (a dependency of
khepera_gym).

A new family is one module here with its manual and a :class:`KheperaParallelEnv` subclass that
sets ``TASK`` and ``FAMILY``; ``tests/test_lists_from_registries.py`` checks that the list above
names every family.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from types import ModuleType

from khepera_gym import registry
from khepera_gym.pettingzoo._parallel import FAMILIES, KheperaParallelEnv
from khepera_gym.pettingzoo._versions import module_name, versioned_module

# The families' own modules (their manuals and classes), found by listing the package.
for _info in pkgutil.iter_modules(__path__):
    if not _info.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_info.name}")

#: Every versioned module, ``formation_v2`` → its module, sorted by family then version.
_MODULES: dict[str, ModuleType] = {}
for _family, _base in sorted(FAMILIES.items()):
    for _version in registry.task_versions(_base.TASK):
        _module = versioned_module(_base, _version)
        _MODULES[module_name(_family, _version)] = _module
        sys.modules[_module.__name__] = _module
globals().update(_MODULES)


def modules() -> dict[str, ModuleType]:
    """Every versioned module of this package (``formation_v2`` → its module), sorted by family
    then version: one per family and behaviour version its task exists in."""
    return dict(_MODULES)


__all__ = ["FAMILIES", "KheperaParallelEnv", "modules", *_MODULES]
