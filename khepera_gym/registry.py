"""What khepera_gym has, asked of the Rust core's registries: the tasks (their ids, versions,
agents, statistics and scoring), the behaviour versions and their history, the controllers,
default scenarios, built-in scenes and sensors (the PettingZoo modules are
:func:`khepera_gym.pettingzoo.module_infos`).

This is the one module that asks ``_core`` which tasks, versions, agents, baselines, metrics and
criteria exist (``_core.tasks()``, ``_core.task_versions``, ``_core.task_agents``,
``_core.task_scoring``, ``_core.versions()``, ``_core.controllers()``); every other module asks
this one, and ``tests/test_layers.py`` holds that. Nothing is listed by hand, so a new task,
version, scene or sensor shows up here, in ``khepera-gym list`` and in the documentation without
an edit. :func:`default_config` and :func:`scenes` are exported at the package's top level.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import sys
import textwrap
from typing import Any

from khepera_gym import _core
from khepera_gym.errors import ConfigError, KheperaError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: The end of a sentence: a full stop before a capital, but not that of "Fig." or "eq.".
_SENTENCE_END = re.compile(r"(?<!Fig)(?<!eq)(?<!eqs)\.\s+(?=[A-Z])")
#: The sensor list in the core's message for an unknown sensor (``known: ["ir", ...]``).
_KNOWN_SENSORS = re.compile(r"known: \[([^\]]*)\]")

#: The behaviour version of the current defaults (what an id without ``-vN`` takes).
LATEST_VERSION: int = _core.LATEST_VERSION


@dataclasses.dataclass(frozen=True)
class TaskInfo:
    """A task of the core, as its registry declares it (``src/tasks/``).

    Attributes:
        name: Its name (``"nav"``).
        env_id: Its Gymnasium id without version (``"KheperaIV-Nav"``), or None for a
            PettingZoo-only task.
        extra_stats: Its own episode statistics, besides those every task has.
        versions: The behaviour versions it exists in, oldest first (a task added with v1 has
            no v0).
        several_agents: Its default scenario has more than one agent.
        alike_agents: All its agents have the same kind of observation and action (a team of
            robots), so one policy or one RLlib multi-agent config fits them all; DroneFollow's
            quadcopter and Khepera do not.
        agents_end_separately: An agent may end while the episode goes on (a multinav robot
            parks at its goal, a lost platoon robot parks where it is).
    """

    name: str
    env_id: str | None
    extra_stats: tuple[str, ...]
    versions: tuple[int, ...]
    several_agents: bool
    alike_agents: bool
    agents_end_separately: bool

    @property
    def latest(self) -> int:
        """Its newest behaviour version."""
        return self.versions[-1]

    def env_id_of(self, version: int | None = None) -> str | None:
        """Its versioned Gymnasium id (the latest version's for None), or None without one."""
        if self.env_id is None:
            return None
        return f"{self.env_id}-v{self.latest if version is None else version}"

    @property
    def scoring(self) -> dict[str, Any]:
        """How its episodes are scored (:func:`task_scoring`)."""
        return task_scoring(self.name)


@functools.cache
def tasks() -> dict[str, TaskInfo]:
    """Every task of the core, by name, in registry order."""
    found = {}
    for name, env_id, extra in _core.tasks():
        several, alike, end_separately = _core.task_agents(name)
        found[name] = TaskInfo(
            name=name,
            env_id=env_id,
            extra_stats=tuple(extra),
            versions=tuple(_core.task_versions(name)),
            several_agents=several,
            alike_agents=alike,
            agents_end_separately=end_separately,
        )
    return found


def task(name: str) -> TaskInfo:
    """The task ``name`` of the core.

    Raises:
        ConfigError: ``name`` is not a task of the core.
    """
    known = tasks()
    if name not in known:
        raise ConfigError(f"unknown task {name!r}; known: {', '.join(known)}")
    return known[name]


def task_names() -> list[str]:
    """The core's tasks, in registry order (``"nav"``, ``"avoid"``, ...)."""
    return list(tasks())


def task_versions(task_name: str) -> tuple[int, ...]:
    """The behaviour versions a task exists in, as the core says (a task added with v1 has no
    v0).

    Raises:
        ConfigError: ``task_name`` is not a task of the core.
    """
    return task(task_name).versions


def latest_version(task_name: str) -> int:
    """A task's newest behaviour version.

    Raises:
        ConfigError: ``task_name`` is not a task of the core.
    """
    return task(task_name).latest


@functools.cache
def _scoring(task_name: str) -> dict[str, Any]:
    return dict(_core.task_scoring(task_name))


def task_scoring(task_name: str) -> dict[str, Any]:
    """How a task's episodes are scored, as the core says (its ``Scoring``): success, time,
    error_prefix, error, termination (str or None), speed, moving_reference, path_trace (bool),
    and columns, a list of (statistic, header, scale, digits). A fresh dict each call.

    Raises:
        ConfigError: ``task_name`` is not a task of the core.
    """
    task(task_name)
    return dict(_scoring(task_name))


def controllers() -> dict[str, str]:
    """The core's controllers (the baselines' laws), name → one line of what it is, in
    registry order."""
    return dict(_core.controllers())


def builtin_config_names() -> list[str]:
    """The names ``config=`` takes besides a path: every task's defaults and every built-in
    scene."""
    return list(_core.builtin_configs())


def default_config(task: str, version: int | None = None) -> str:
    """A task's default scenario file: every key with its default and a comment giving its
    units and source, as TOML text. A scenario file or keyword override may change any of them
    and add none.

    Args:
        task: A task of the core (``"nav"``, ``"avoid"``, ..., see ``khepera-gym list``).
        version: The behaviour version whose defaults to give (None: the latest); an id
            gives its own (``KheperaIV-Nav-v0`` → version 0's).

    Returns:
        The TOML text.

    Raises:
        ConfigError: An unknown task (scenes are :func:`scenes`), or a version the task does
            not exist in.
    """
    if task not in tasks():
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


# The behaviour versions. Each is an entry of the core (``src/scenario/versions.rs``): its number,
# a title, one line of what changed and why, and the previous version's values of the keys it
# changed. The registered ids, the PettingZoo modules, every manual's Version History
# (:func:`with_history`), the documentation's tables and the tests' version lists derive from it.


@dataclasses.dataclass(frozen=True)
class Version:
    """A behaviour version (the ``-vN`` of an id).

    Attributes:
        number: N.
        title: A few words on what it is.
        summary: What changed from the version before, and why.
        before: The previous version's values of the keys it changed (TOML; empty for v0).
    """

    number: int
    title: str
    summary: str
    before: str


@functools.cache
def versions() -> tuple[Version, ...]:
    """Every behaviour version, oldest first."""
    return tuple(Version(*entry) for entry in _core.versions())


def history_lines(task: str) -> list[str]:
    """A task's Version History, one Markdown bullet a version it exists in."""
    numbers = task_versions(task)
    lines = []
    for version in versions():
        if version.number not in numbers:
            continue
        if version.number != numbers[0]:
            text = f"{version.title}. {version.summary}"
        elif version.number == 0:
            text = f"Initial version: {version.summary}"
        else:
            older = ", ".join(f"v{n}" for n in range(version.number))
            text = (
                f"Initial version, on behaviour version {version.number}'s dynamics "
                f"({_lower_first(version.title)}). There is no {older}: the task is newer."
            )
        lines.append(f"* v{version.number}: {text}")
    return lines


def _lower_first(text: str) -> str:
    return text[:1].lower() + text[1:]


def with_history(doc: str | None, task: str, indent: str = "    ") -> str:
    """A manual (a class docstring, its lines after the first indented by ``indent``; a module
    docstring: ``indent=""``) with its ``## Version History`` section appended: one line a
    version of ``task``, from the core, and where the full story is."""
    body = (doc or "").rstrip()
    bullets = "\n".join(
        textwrap.fill(line, 96, initial_indent=indent, subsequent_indent=indent + "  ")
        for line in history_lines(task)
    )
    note = textwrap.fill(
        "Older versions stay registered with their behaviour, so published numbers reproduce; "
        "the documentation's dynamics page tells each version's story, with the keys it "
        "changed.",
        96,
        initial_indent=indent,
        subsequent_indent=indent,
    )
    return f"{body}\n\n{indent}## Version History\n\n{bullets}\n\n{note}\n"


__all__ = [
    "LATEST_VERSION",
    "Sensor",
    "TaskInfo",
    "Version",
    "builtin_config_names",
    "controllers",
    "default_config",
    "history_lines",
    "latest_version",
    "scene_config",
    "scenes",
    "sensors",
    "task",
    "task_names",
    "task_scoring",
    "task_versions",
    "tasks",
    "versions",
    "with_history",
]
