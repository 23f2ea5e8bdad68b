"""The versioned PettingZoo modules (``formation_v3``, ...), made from the families and the core's
versions rather than written one file a version.

A family is a :class:`~khepera_gym.pettingzoo._parallel.KheperaParallelEnv` subclass that names
itself in ``FAMILY`` (``formation``), defined in the family's own module with its manual
(``khepera_gym/pettingzoo/formation.py``). For each behaviour version its task exists in
(``_core.task_versions``), :func:`versioned_module` makes the module ``<family>_v<n>``: a
subclass of the family's class of the same name with ``VERSION = n`` and PettingZoo's
``metadata["name"]``, and the module functions ``parallel_env``, ``env`` (its AEC version) and,
for a family of swarms (``ARRAY_ENV``), ``array_env``. The package registers each one in
``sys.modules``, so ``import khepera_gym.pettingzoo.formation_v3``, ``from khepera_gym.pettingzoo
import formation_v3`` and pickling all work as for a module written in a file.
"""

from __future__ import annotations

import functools
from types import ModuleType
from typing import Any

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym import registry
from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs, KheperaParallelEnv
from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv

#: The package the modules belong to.
PACKAGE = "khepera_gym.pettingzoo"


@functools.cache
def version_notes() -> dict[int, tuple[str, str]]:
    """Each behaviour version's title and summary, from the core (``_core.versions()``)."""
    return {v.number: (v.title, v.summary) for v in registry.versions()}


def module_name(family: str, version: int) -> str:
    """``formation``, 3 → ``formation_v3``."""
    return f"{family}_v{version}"


def _module_doc(base: type[KheperaParallelEnv], name: str, version: int) -> str:
    family = base.FAMILY
    title, summary = version_notes()[version]
    first = min(registry.task_versions(base.TASK))
    history = f"{title}: {summary}" + (" The task's first version." if version == first else "")
    return (
        f"``{name}``: :mod:`{PACKAGE}.{family}` (the manual) with behaviour version {version}.\n\n"
        f"Version {version}: {history}\n\nThe Version History of the manual and the dynamics "
        "page of the documentation say what each version changed::\n\n"
        f"    from {PACKAGE} import {name}\n\n"
        f"    env = {name}.parallel_env()\n"
    )


def versioned_module(base: type[KheperaParallelEnv], version: int) -> ModuleType:
    """The module ``<family>_v<version>`` of a family's class ``base``."""
    name = module_name(base.FAMILY, version)
    qualified = f"{PACKAGE}.{name}"
    module = ModuleType(qualified, _module_doc(base, name, version))
    cls = type(
        base.__name__,
        (base,),
        {
            "__module__": qualified,
            "__qualname__": base.__name__,
            "__doc__": f":class:`{base.__module__}.{base.__name__}` with behaviour version "
            f"{version}.",
            "metadata": {**base.metadata, "name": name},
            "VERSION": version,
        },
    )

    def parallel_env(**kwargs: Any) -> KheperaParallelEnv:
        return cls(**kwargs)

    def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
        return parallel_to_aec(parallel_env(**kwargs))

    parallel_env.__doc__ = (
        f"The task as a PettingZoo ``ParallelEnv`` with behaviour version {version}; takes the "
        f"arguments of :class:`{base.__module__}.{base.__name__}`."
    )
    env.__doc__ = (
        "The task as a PettingZoo AEC env (agents act in turn, the world steps once all have "
        "acted); takes the arguments of :func:`parallel_env`."
    )
    functions: dict[str, Any] = {"parallel_env": parallel_env, "env": env}
    if base.ARRAY_ENV:

        def array_env(num_envs: int = 1, **kwargs: Any) -> MultiAgentArrayEnv:
            return MultiAgentArrayEnv(base.TASK, num_envs, version=version, **kwargs)

        array_env.__doc__ = (
            f"Every agent's data in one array, for swarms: ``num_envs`` worlds of behaviour "
            f"version {version} stepped with actions ``(num_envs, n_agents, 2)``; takes "
            "``config``, ``action_type``, ``num_threads`` and scenario keys (see "
            ":class:`khepera_gym.pettingzoo.arrays.MultiAgentArrayEnv`)."
        )
        functions["array_env"] = array_env
    for function_name, function in functions.items():
        function.__module__ = qualified
        function.__qualname__ = function_name
        function.__name__ = function_name
    vars(module).update({cls.__name__: cls, **functions})
    module.__all__ = sorted([cls.__name__, *functions])  # type: ignore[attr-defined]
    return module


__all__ = ["PACKAGE", "module_name", "version_notes", "versioned_module"]
