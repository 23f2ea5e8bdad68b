"""The learning benchmark's suite: for each task, the learners it is trained with, the baselines
it is compared with, and the criterion that says it is solved (``configs/benchmark.toml``).

A task's entry is data about that task, read and checked here::

    [seek]
    learners = ["ppo"]
    baselines = ["blob_vfh", "blob_servo"]
    criterion = [{ metric = "success", at_least = "blob_vfh" }]
    why = "BlobVFH, the stronger baseline, reaches 80 % of Seek's targets"

A condition bounds the mean of one episode statistic over the held-out episodes: ``success``,
``return``, ``length``, ``path_length``, ``collisions`` or one of the task's own statistics
(``track_error_rms``, ...), ``at_least`` or ``at_most`` a number or a baseline's mean on the
same episodes. A task is solved when every condition holds. Every mistake (an unknown task,
learner, statistic or baseline, a condition without a bound) is a :class:`ConfigError` naming
the valid choices. A task of the core without an entry is reported as having none, never
skipped silently.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from khepera_gym import registry
from khepera_gym.config import tomllib
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import VARIANTS
from khepera_gym.learning.recipes import HYPERPARAMS_DIR
from khepera_gym.tooling.arguments import did_you_mean

#: The suite file of a source checkout.
SUITE_PATH = HYPERPARAMS_DIR.parent / "benchmark.toml"
#: The episode statistics every task has (besides its own, ``registry.task_names()``).
COMMON_STATS = ("success", "return", "length", "path_length", "collisions")
#: The two bounds a condition may set.
BOUNDS = ("at_least", "at_most")
#: Keys of a task's entry.
ENTRY_KEYS = ("learners", "baselines", "criterion", "why", "tried", "searched")
#: What a learner's recipe says of its search when the suite names none.
NOT_SEARCHED = "not searched"


def all_baselines() -> dict[str, type]:
    """Every baseline class by its controller's name, those of PettingZoo-only tasks too."""
    from khepera_gym.baselines.base import BaselinePolicy

    found: dict[str, type] = {}
    pending = list(BaselinePolicy.__subclasses__())
    while pending:
        cls = pending.pop(0)
        pending += cls.__subclasses__()
        if cls.CONTROLLER:
            found.setdefault(cls.CONTROLLER, cls)
    return found


def task_stats(task: str) -> tuple[str, ...]:
    """The episode statistics of a task: the common ones, then its own."""
    own = registry.task(task).extra_stats
    return (*COMMON_STATS, *own)


@dataclasses.dataclass(frozen=True)
class Condition:
    """One condition of a criterion: the held-out mean of ``metric`` at least (or at most) a
    number, or a baseline's held-out mean (``reference`` names it)."""

    metric: str
    bound: str
    value: float | None = None
    reference: str | None = None

    def threshold(self, baselines: Mapping[str, Mapping[str, float]]) -> float:
        """The number the mean is held to: ``value``, or the baseline's mean."""
        if self.reference is None:
            assert self.value is not None
            return self.value
        return float(baselines[self.reference][self.metric])

    def holds(self, mean: float, threshold: float) -> bool:
        """Whether ``mean`` meets ``threshold`` (a NaN mean never does)."""
        if math.isnan(mean):
            return False
        return mean >= threshold if self.bound == "at_least" else mean <= threshold

    def describe(self) -> str:
        """``success ≥ blob_vfh``, ``success ≥ 0.95``."""
        sign = "≥" if self.bound == "at_least" else "≤"
        return f"{self.metric} {sign} {self.reference or f'{self.value:g}'}"

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class TaskEntry:
    """A task's entry of the suite.

    Attributes:
        task: The core's task.
        learners: The learners it is trained with (names of :data:`LEARNER_NAMES`).
        baselines: The baselines it is compared with (``khepera-gym compare``'s names).
        criterion: The conditions that say it is solved (all must hold).
        why: How the criterion was chosen from the baselines.
        tried: What was tried where a learner does not meet the criterion (the results page
            prints it under the task's table), or "".
    """

    task: str
    learners: tuple[str, ...]
    baselines: tuple[str, ...]
    criterion: tuple[Condition, ...]
    why: str
    tried: str = ""
    searched: Mapping[str, str] = dataclasses.field(default_factory=dict)

    def search_of(self, learner: str) -> str:
        """How ``learner``'s recipe for this task was chosen: the ``khepera-gym tune`` results
        file whose search chose it, or why it was not searched."""
        return self.searched.get(learner, NOT_SEARCHED)

    def describe_criterion(self) -> str:
        return " and ".join(c.describe() for c in self.criterion)


def _condition(task: str, where: str, table: Any, baselines: Sequence[str]) -> Condition:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: a condition is a table {{metric = ..., at_least = ...}}")
    unknown = sorted(set(table) - {"metric", *BOUNDS})
    if unknown:
        raise ConfigError(
            f"{where}: unknown key {unknown[0]!r}; a condition has metric, at_least or at_most"
        )
    metric = table.get("metric")
    stats = task_stats(task)
    if metric not in stats:
        raise ConfigError(
            f"{where}: {task} has no statistic {metric!r}; {did_you_mean(str(metric), stats)}"
        )
    bounds = [b for b in BOUNDS if b in table]
    if len(bounds) != 1:
        raise ConfigError(f"{where}: give exactly one of at_least and at_most")
    bound = bounds[0]
    value = table[bound]
    if isinstance(value, str):
        if value not in baselines:
            raise ConfigError(
                f"{where}: {bound} = {value!r} is not a baseline of the entry; "
                f"{did_you_mean(value, baselines)}"
            )
        return Condition(metric, bound, reference=value)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(
            f"{where}: {bound} must be a finite number or a baseline's name, got {value!r}"
        )
    return Condition(metric, bound, value=float(value))


def _entry(task: str, table: Any, where: str, learners: Sequence[str]) -> TaskEntry:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: [{task}] must be a table")
    unknown = sorted(set(table) - set(ENTRY_KEYS))
    if unknown:
        raise ConfigError(
            f"{where}: [{task}] has an unknown key {unknown[0]!r}; "
            f"{did_you_mean(unknown[0], ENTRY_KEYS)}"
        )
    names = table.get("learners", [])
    if not isinstance(names, list) or not names:
        raise ConfigError(f"{where}: [{task}] learners must be a non-empty list")
    for name in names:
        if name not in learners:
            raise ConfigError(
                f"{where}: [{task}] unknown learner {name!r}; {did_you_mean(str(name), learners)}"
            )
    known_baselines = [*all_baselines(), *VARIANTS]
    baselines = table.get("baselines", [])
    for name in baselines:
        if name not in known_baselines:
            raise ConfigError(
                f"{where}: [{task}] unknown baseline {name!r}; "
                f"{did_you_mean(str(name), known_baselines)}"
            )
    conditions = table.get("criterion")
    if not isinstance(conditions, list) or not conditions:
        raise ConfigError(f"{where}: [{task}] criterion must be a non-empty list of conditions")
    criterion = tuple(
        _condition(task, f"{where}: [{task}] criterion[{i}]", c, baselines)
        for i, c in enumerate(conditions)
    )
    tried = table.get("tried", "")
    if not isinstance(tried, str):
        raise ConfigError(f"{where}: [{task}] tried must be a string, got {tried!r}")
    searched = table.get("searched", {})
    if not isinstance(searched, dict) or not all(isinstance(v, str) for v in searched.values()):
        raise ConfigError(f'{where}: [{task}] searched must be a table of learner = "..."')
    for name in searched:
        if name not in names:
            raise ConfigError(
                f"{where}: [{task}] searched names {name!r}, not a learner of the task; "
                f"{did_you_mean(str(name), names)}"
            )
    return TaskEntry(
        task,
        tuple(names),
        tuple(baselines),
        criterion,
        str(table.get("why", "")),
        tried,
        dict(searched),
    )


def load_suite(path: str | Path | None = None) -> dict[str, TaskEntry]:
    """Every entry of the suite file, by task, in the core's task order.

    Raises:
        ConfigError: A missing or unreadable file, or an entry that is wrong (see the module
            docstring).
    """
    from khepera_gym.learning.benchmark.learners import LEARNERS

    file = Path(path) if path is not None else SUITE_PATH
    try:
        tables = tomllib.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(
            f"{file}: the benchmark's suite file is not there (installed from a "
            "wheel? pass --suite FILE; the repository's configs/ has it)"
        ) from None
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ConfigError(f"{file}: cannot read the suite: {error}") from None
    tasks = registry.task_names()
    for name in tables:
        if name not in tasks:
            raise ConfigError(
                f"{file}: [{name}] is not a task of the core; {did_you_mean(name, tasks)}"
            )
    return {t: _entry(t, tables[t], str(file), list(LEARNERS)) for t in tasks if t in tables}


__all__ = [
    "BOUNDS",
    "COMMON_STATS",
    "SUITE_PATH",
    "Condition",
    "TaskEntry",
    "all_baselines",
    "load_suite",
    "task_stats",
]
