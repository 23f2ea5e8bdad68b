"""Registration of the environments with Gymnasium, from the task list the Rust core exports.

For every task that the core exports with a Gymnasium id (``registry.tasks()``: the ``env_id``
of its ``TaskInfo``) and that has an env class (:data:`khepera_gym.envs.ENV_CLASSES`, filled by the
classes themselves), each version the class declares in ``VERSIONS`` is registered as
``<id>-v<version>`` with its single-env entry point, its native vector entry point and the
version's scenario keyword defaults; ``gym.make("<id>")`` resolves to the latest. Nothing here
lists tasks by hand.
"""

from __future__ import annotations

import difflib
import functools
from collections.abc import Callable
from typing import Any

import gymnasium
import gymnasium.envs.registration

from khepera_gym import registry
from khepera_gym.envs import ENV_CLASSES
from khepera_gym.errors import ConfigError
from khepera_gym.vector import VECTOR_ENV_CLASSES, vector_env_class


def registered_ids() -> dict[str, list[str]]:
    """Every registered id of each task with a Gymnasium env, oldest version first."""
    ids: dict[str, list[str]] = {}
    for task, info in registry.tasks().items():
        env_id = info.env_id
        env_class = ENV_CLASSES.get(task)
        if env_id is None or env_class is None:
            continue
        ids[task] = [f"{env_id}-v{version}" for version in sorted(env_class.VERSIONS)]
    return ids


def latest_ids() -> dict[str, str]:
    """The latest id of each task with a Gymnasium env: ``{"nav": "KheperaIV-Nav-v3", ...}``."""
    return {task: ids[-1] for task, ids in registered_ids().items()}


def _entry_point(cls: type, package: str) -> str:
    """``package:Name`` when the package exports the class (its public path), else its module."""
    module = package if cls.__module__.startswith(package) else cls.__module__
    return f"{module}:{cls.__name__}"


def _first_versions() -> dict[str, tuple[int, int]]:
    """Each of our unversioned ids → (its task's first version, the latest)."""
    firsts = {}
    for task, ids in registered_ids().items():
        versions = registry.task_versions(task)
        firsts[ids[0].rsplit("-v", 1)[0]] = (versions[0], versions[-1])
    return firsts


def _check_our_version_exists(check: Callable[..., Any]) -> Callable[..., Any]:
    """Gymnasium's check that an id's version exists, which would call a version our task never
    had (Track's v0) "deprecated", made to say what is true of our ids first."""

    @functools.wraps(check)
    def wrapper(ns: str | None, name: str, version: int | None) -> Any:
        first, latest = _first_versions().get(name, (0, 0)) if ns is None else (0, 0)
        if version is not None and version < first:
            raise ConfigError(
                f"{name}-v{version} does not exist: the task was added with behaviour version "
                f"{first}, so its ids are {name}-v{first} to {name}-v{latest} (the latest, "
                f"also `{name}`); see `khepera-gym list envs`"
            )
        return check(ns, name, version)

    wrapper.__khepera_gym__ = True  # type: ignore[attr-defined]
    return wrapper


def register_envs() -> None:
    """Registers every version of every task's env; a second call registers nothing twice."""
    check = getattr(gymnasium.envs.registration, "_check_version_exists", None)
    if check is not None and not getattr(check, "__khepera_gym__", False):
        # Gymnasium (1.1 to 1.2 at least) calls this module-level function by name.
        gymnasium.envs.registration._check_version_exists = _check_our_version_exists(check)
    for task, ids in registered_ids().items():
        env_class = ENV_CLASSES[task]
        # A task whose vector class `make generated` has not written yet gets one made here,
        # so that the package (and the generator, which imports it) still loads;
        # tests/test_generated.py fails until the static class is written.
        vector_class = VECTOR_ENV_CLASSES.get(task) or vector_env_class(env_class)
        for env_id, version in zip(ids, sorted(env_class.VERSIONS), strict=True):
            if env_id in gymnasium.registry:
                continue
            gymnasium.register(
                id=env_id,
                entry_point=_entry_point(env_class, "khepera_gym.envs"),
                vector_entry_point=_entry_point(vector_class, "khepera_gym.vector"),
                kwargs=dict(env_class.VERSIONS[version]),
            )


def nearest_id(env_id: str) -> str | None:
    """The khepera_gym id (versioned, or a task's unversioned name) spelled most like
    ``env_id``, or None when none is close: for a did-you-mean that names our envs, not
    Gymnasium's whole registry."""
    ours = [i for ids in registered_ids().values() for i in ids]
    names = {i.rsplit("-v", 1)[0] for i in ours}
    candidates = {name.lower(): name for name in [*sorted(names), *ours]}
    match = difflib.get_close_matches(env_id.lower(), list(candidates), n=1, cutoff=0.5)
    return candidates[match[0]] if match else None


def resolve_env_id(env_id: str) -> str:
    """The registered id of a khepera_gym env: ``"KheperaIV-Nav"`` → its latest version.

    Raises:
        ConfigError: ``env_id`` is not a registered khepera_gym environment (the message names
            the nearest id, if one is close, and where the list is).
    """
    ours = [i for ids in registered_ids().values() for i in ids]
    if env_id in ours:
        return env_id
    versions = [i for i in ours if i.rsplit("-v", 1)[0] == env_id.rstrip("-")]
    if not versions:
        nearest = nearest_id(env_id)
        hint = f"did you mean {nearest!r}? " if nearest is not None else ""
        raise ConfigError(
            f"unknown environment {env_id!r}; {hint}khepera_gym registers "
            f"{', '.join(sorted(ours))} (`khepera-gym list envs`)"
        )
    return max(versions, key=lambda i: int(i.rsplit("-v", 1)[1]))


def version_of(env_id: str) -> int:
    """The behaviour version of a khepera_gym env id: ``"KheperaIV-Nav-v0"`` → 0, an id without
    its version → the latest.

    Raises:
        ConfigError: ``env_id`` is not a registered khepera_gym environment.
    """
    return int(resolve_env_id(env_id).rsplit("-v", 1)[1])


def task_of(env_id: str) -> str:
    """The Rust core's task name (a name of ``registry.task_names()``: "nav", ...) of a
    khepera_gym env id."""
    resolved = resolve_env_id(env_id)
    return next(task for task, ids in registered_ids().items() if resolved in ids)


def task_and_version(name: str) -> tuple[str, int]:
    """The core's task and the behaviour version that ``name`` stands for: a Gymnasium id
    (``"KheperaIV-Nav-v0"`` → ``("nav", 0)``; without its version, the latest), a PettingZoo
    module's name (``"multinav_v1"`` → ``("multinav", 1)``) or a task of the core (``"nav"``:
    its latest version).

    Raises:
        ConfigError: ``name`` is none of these (the message lists them and the nearest id).
    """
    from khepera_gym.pettingzoo import FAMILIES, modules

    tasks = registry.task_names()
    if name in tasks:
        return name, registry.latest_version(name)
    if name in modules():
        family, _, version = name.rpartition("_v")
        return FAMILIES[family].TASK, int(version)
    try:
        return task_of(name), version_of(name)
    except ConfigError as error:
        raise ConfigError(
            f"{error}; a PettingZoo module ({', '.join(modules())}) or a task "
            f"({', '.join(tasks)}) is also accepted here"
        ) from None


__all__ = [
    "latest_ids",
    "nearest_id",
    "register_envs",
    "registered_ids",
    "resolve_env_id",
    "task_and_version",
    "task_of",
    "version_of",
]
