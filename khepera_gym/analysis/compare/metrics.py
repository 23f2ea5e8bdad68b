"""What the comparison measures on each task: one small table, one entry a task.

Every task is scored by the common episode statistics (``success``, ``length``,
``path_length``, ``collisions``), and adds what its own statistics and its meaning of success
ask for: each task declares that in the core, beside its code (the ``scoring`` of its
``TaskInfo`` in ``src/tasks/``), and :data:`TASK_METRICS` reads it for every task of the core.
A task scored by an error to a reference (trajectory tracking, path following) names the
prefix of its four extra statistics, and the comparison summarises them without further code:

* ``<prefix>_error_rms`` (m): mean over the episodes of each episode's RMS error (after the
  task's transient; over the whole episode if it ended sooner);
* ``<prefix>_error_max`` (m): mean over the episodes of each episode's largest error (same span);
* ``<prefix>_iae`` (m·s): mean integral of the absolute error;
* ``<prefix>_converge_time`` (s; inf when the error is above the task's convergence radius at
  the end): never averaged; summarised as the share of episodes that converged (Wilson) and
  the median converge time over all episodes, those that never converged counting as inf
  (:func:`khepera_gym.tooling.stats.event_time_median`: finite only when at least half
  converged).

Besides, the share of episodes ended by termination is reported under the task's name for it
("lost %" for tracking), and the mean speed (m/s: ``path_length / (length · dt)`` per episode,
over the successful episodes for a task with success, over all episodes otherwise) for
single-robot tasks. ``length · dt`` of successful episodes is the task's time column: "time to
goal" for Nav, "lap time" for path following.

Adding a task: its ``TaskInfo`` says how it is scored (``Scoring::GOAL`` for a task of goals
reached); nothing here changes.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

from khepera_gym import registry
from khepera_gym.tooling.stats import (
    Estimate,
    bootstrap_interval,
    event_time_median,
    wilson_interval,
)

#: Suffixes of the four error statistics ``<prefix>_<suffix>`` of a task scored by an error.
ERROR_STATS = ("error_rms", "error_max", "iae", "converge_time")


@dataclasses.dataclass(frozen=True)
class TaskMetrics:
    """What the comparison reports for one task.

    Attributes:
        success: What a success is, as the table's rate header says it ("success", "lap");
            None for a task without success (its success, time and path columns are left out).
        time: Header of ``length · dt`` over the successful episodes ("time to goal", "lap time").
        error_prefix: Prefix of the task's error statistics (``"track"`` for
            ``track_error_rms``, ...), or None.
        error: What the error is, for headers and plots ("tracking error").
        termination: Header word of the share of episodes ended by termination when that is a
            failure ("lost"), or None not to report it.
        speed: Report the mean speed (single-robot tasks: a formation's path is summed over
            its robots).
        moving_reference: ``goals()`` moves along a reference during an episode: the plots
            draw it, and the error ``‖robot − goals()[0]‖`` over time.
        path_trace: ``targets()[0]`` is the path's point closest to the robot (path
            following): the trajectory plots draw its trace, the stretch of path the robot
            followed, as a dashed line.
        columns: Further statistics of the task reported as their mean over the episodes
            (bootstrap interval): ``(statistic, header, scale, digits)``, e.g.
            ``("on_line_share", "on line %", 100, 1)``.
    """

    success: str | None = "success"
    time: str = "time to goal"
    error_prefix: str | None = None
    error: str = "error"
    termination: str | None = None
    speed: bool = True
    moving_reference: bool = False
    path_trace: bool = False
    columns: tuple[tuple[str, str, float, int], ...] = ()

    def stat_name(self, suffix: str) -> str:
        """The episode statistic ``<error_prefix>_<suffix>`` (e.g. ``track_error_rms``)."""
        if self.error_prefix is None:
            raise ValueError("this task has no error statistics")
        return f"{self.error_prefix}_{suffix}"

    @classmethod
    def of_task(cls, task: str) -> TaskMetrics:
        """A task's entry, as the task declares its scoring in the core
        (``_core.task_scoring``)."""
        scoring = registry.task_scoring(task)
        columns = tuple(
            (stat, header, float(scale), int(digits))
            for stat, header, scale, digits in scoring.pop("columns")
        )
        return cls(**scoring, columns=columns)


#: Every task's entry, from the core's task registry (each task declares its scoring beside its
#: code: the ``scoring`` of its ``TaskInfo``).
TASK_METRICS: dict[str, TaskMetrics] = {
    name: TaskMetrics.of_task(name) for name in registry.task_names()
}


def task_metrics(task: str | None) -> TaskMetrics:
    """The entry of a task (core task name, e.g. "track"), or the default one (success, time to
    goal, speed) for None or a name that is not a task."""
    return TASK_METRICS.get(task or "", TaskMetrics())


def summarize_errors(
    metrics: TaskMetrics, stats: Sequence[Mapping[str, float]]
) -> dict[str, Estimate]:
    """The error columns of one policy from its episodes' task statistics.

    Args:
        metrics: The task's entry (with an ``error_prefix``).
        stats: One mapping per episode holding the task's ``<prefix>_*`` statistics.

    Returns:
        ``{"error_rms", "error_max", "iae"}`` (bootstrap means), ``"converged"`` (Wilson share
        of finite converge times) and ``"converge_time"`` (inf-aware median) for a task with
        error statistics; and the bootstrap mean of each statistic of ``metrics.columns``,
        under its name.

    Raises:
        KeyError: An episode lacks one of the statistics (the entry names a wrong prefix).
    """
    extra = {
        name: bootstrap_interval([float(s[name]) for s in stats], "mean")
        for name, *_ in metrics.columns
    }
    if metrics.error_prefix is None:
        return extra
    column = {
        suffix: [float(s[metrics.stat_name(suffix)]) for s in stats] for suffix in ERROR_STATS
    }
    converge = column["converge_time"]
    return {
        "error_rms": bootstrap_interval(column["error_rms"], "mean"),
        "error_max": bootstrap_interval(column["error_max"], "mean"),
        "iae": bootstrap_interval(column["iae"], "mean"),
        "converged": wilson_interval(sum(math.isfinite(t) for t in converge), len(converge)),
        "converge_time": event_time_median(converge),
        **extra,
    }


__all__ = ["ERROR_STATS", "TASK_METRICS", "TaskMetrics", "summarize_errors", "task_metrics"]
