"""What khepera_gym has, asked of the registries: tasks and their versions, default scenarios,
built-in scenes, sensors, Gymnasium ids and PettingZoo modules.

Everything here is read from the Rust core's registries (``_core.tasks()``,
``_core.default_config``, ``_core.builtin_configs()``) and from the packages themselves (the
registered env classes, the ``*_vN`` modules of :mod:`khepera_gym.pettingzoo`); nothing is listed
by hand, so a new task, version, scene or sensor shows up here, in ``khepera-gym list`` and in
the documentation without an edit. :func:`default_config` and :func:`scenes` are exported at the
package's top level.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from types import ModuleType

from khepera_gym import _core
from khepera_gym.config import builtin_config_names, tomllib
from khepera_gym.errors import ConfigError, KheperaError

#: The end of a sentence: a full stop before a capital, but not that of "Fig." or "eq.".
_SENTENCE_END = re.compile(r"(?<!Fig)(?<!eq)(?<!eqs)\.\s+(?=[A-Z])")
#: The sensor list in the core's message for an unknown sensor (``known: ["ir", ...]``).
_KNOWN_SENSORS = re.compile(r"known: \[([^\]]*)\]")


def task_names() -> list[str]:
    """The core's tasks, in registry order (``"nav"``, ``"avoid"``, ...)."""
    return [name for name, _, _ in _core.tasks()]


@functools.cache
def task_versions(task: str) -> tuple[int, ...]:
    """The behaviour versions a task exists in, as the core says (a task added with v1 has no
    v0).

    Raises:
        ConfigError: ``task`` is not a task of the core.
    """
    if task not in task_names():
        raise ConfigError(f"unknown task {task!r}; known: {', '.join(task_names())}")
    versions = []
    for version in range(_core.LATEST_VERSION + 1):
        try:
            _core.default_config(task, version)
        except ConfigError:
            continue
        versions.append(version)
    return tuple(versions)


def default_config(task: str, version: int | None = None) -> str:
    """A task's default scenario file: every key with its default and a comment giving its
    units and source, as TOML text. A scenario file or keyword override may change any of them
    and add none.

    Args:
        task: A task of the core (``"nav"``, ``"avoid"``, ..., see ``khepera-gym list``).
        version: The behaviour version whose defaults to give (None: the latest); the id
            ``KheperaIV-Nav-v0`` uses version 0's.

    Returns:
        The TOML text.

    Raises:
        ConfigError: An unknown task (scenes are :func:`scenes`), or a version the task does
            not exist in.
    """
    if task not in task_names():
        hint = " (a built-in scene: see khepera_gym.scenes())" if task in scenes() else ""
        raise ConfigError(f"unknown task {task!r}{hint}; known: {', '.join(task_names())}")
    return _core.default_config(task, version)


def _summary(text: str) -> str:
    """The first sentence of a scenario file's header comment."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    header = " ".join(lines)
    end = _SENTENCE_END.search(header)
    return header if end is None else header[: end.start() + 1]


def scenes() -> dict[str, str]:
    """The built-in scenes that ``config=`` takes besides a task's name, each with the first
    sentence of its description: ``{"paper_fig6": "The paper's Fig. 6 scene ...", ...}``.

    A scene is a scenario file overlaid on the task's defaults, e.g.
    ``gym.make("KheperaIV-Avoid", config="paper_fig6")``; :func:`scene_config` gives its text.
    """
    tasks = set(task_names())
    return {
        name: _summary(_core.default_config(name))
        for name in builtin_config_names()
        if name not in tasks
    }


def scene_config(name: str) -> str:
    """The TOML text of a built-in scene (see :func:`scenes`).

    Raises:
        ConfigError: ``name`` is not a built-in scene.
    """
    if name not in scenes():
        raise ConfigError(f"unknown scene {name!r}; known: {', '.join(scenes())}")
    return _core.default_config(name)


@dataclasses.dataclass(frozen=True)
class Sensor:
    """A sensor a robot can carry (``sensors.carry``) and observe (``sensors.observe``).

    Attributes:
        name: Its name in the scenario and in the observation layout.
        values: Values of its observation block (default scenario).
        carried: Carried by a Nav robot by default.
        observed: Observed by a Nav robot by default.
        keys: Its ``[sensors]`` keys (those named after it).
    """

    name: str
    values: int
    carried: bool
    observed: bool
    keys: tuple[str, ...]


def sensors() -> list[Sensor]:
    """The sensors of the core's sensor registry, in registry order (the order of their
    observation blocks)."""
    try:
        _core.Batch("nav", 1, overrides={"carry": ["?"]})
    except ConfigError as error:
        match = _KNOWN_SENSORS.search(str(error))
    else:  # pragma: no cover - the core always refuses an unknown sensor
        match = None
    if match is None:
        raise KheperaError("the core did not list its sensors")
    names = [name.strip().strip('"') for name in match.group(1).split(",") if name.strip()]
    batch = _core.Batch("nav", 1, overrides={"carry": names, "observe": names})
    sizes = {name: stop - start for name, start, stop in batch.obs_layout()}
    defaults = tomllib.loads(default_config("nav"))["sensors"]
    return [
        Sensor(
            name=name,
            values=sizes[name],
            carried=name in defaults["carry"],
            observed=name in defaults["observe"],
            keys=tuple(key for key in defaults if key.startswith(f"{name}_")),
        )
        for name in names
    ]


@dataclasses.dataclass(frozen=True)
class PettingZooModule:
    """A module ``khepera_gym.pettingzoo.<family>_v<version>``.

    Attributes:
        name: Its name (``"formation_v1"``).
        family: The name without the version (``"formation"``).
        version: Its behaviour version.
        task: The core's task it runs.
        module: The module itself (``parallel_env``, ``env``, maybe ``array_env``).
        env_class: Its ``ParallelEnv`` class.
    """

    name: str
    family: str
    version: int
    task: str
    module: ModuleType
    env_class: type


def pettingzoo_modules() -> list[PettingZooModule]:
    """Every ``*_vN`` module of :mod:`khepera_gym.pettingzoo` (one per family and behaviour
    version, :func:`khepera_gym.pettingzoo.modules`), sorted by family then version."""
    import khepera_gym.pettingzoo as package

    found = []
    for name, module in package.modules().items():
        family, _, version = name.rpartition("_v")
        env_class = getattr(module, package.FAMILIES[family].__name__)
        found.append(
            PettingZooModule(
                name=name,
                family=family,
                version=int(version),
                task=env_class.TASK,
                module=module,
                env_class=env_class,
            )
        )
    return found


__all__ = [
    "PettingZooModule",
    "Sensor",
    "default_config",
    "pettingzoo_modules",
    "scene_config",
    "scenes",
    "sensors",
    "task_names",
    "task_versions",
]
