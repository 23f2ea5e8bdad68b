"""The learning benchmark's results to the field's reporting standard (Agarwal et al., "Deep RL
at the edge of the statistical precipice", NeurIPS 2021; Gorsane et al., NeurIPS 2022): per task
and learner, the interquartile mean (IQM) and the mean of the runs' scores with 95 %
stratified-bootstrap intervals; scores normalised between a random policy (0) and the best
classical baseline (1), aggregated across tasks; the probability that one learner of a family
improves on another; performance profiles; and sample-efficiency curves from the runs' training
histories.

The estimators are rliable's (``rliable.metrics``: ``aggregate_iqm``, ``aggregate_mean``,
``probability_of_improvement``; ``pip install "khepera-gym[report]"``). Its stratified
bootstrap (``rliable.library``) is not used: it imports ``arch``, and every ``arch`` that
rliable 1.2 allows (< 8) fails to import beside pandas 3. :func:`stratified_bootstrap` does the
same resampling (each task's runs with replacement, tasks kept apart) with a seeded NumPy
generator, so the intervals reproduce.

A run's score is its held-out mean of the task's metric: the statistic of its criterion's error
condition if it has one (PathFollow is judged on laps and on its error to the path: the error tells
how far it is behind Samson's), else of its first condition (``configs/benchmark.toml``); higher
better for ``at_least``, lower better for ``at_most``. A lower-is-better metric is normalised on a
log scale (errors span decades: Track's learned 21 mm against Kanayama's 0.4 mm must not read as
0.97):

    linear: (x - random) / (best - random)
    log:    (log random - log x) / (log random - log best)

Units: those of each metric (m for errors, a share for success); normalised scores are
dimensionless.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.errors import KheperaError
from khepera_gym.learning.benchmark.suite import TaskEntry

#: The random policy's row among a task's baselines: the 0 of its normalised score.
RANDOM = "random"
#: Confidence of every interval.
CONFIDENCE = 0.95
#: Bootstrap resamples (rliable's examples use 2,000 to 50,000; 2,000 keeps a page build fast).
RESAMPLES = 2000
#: Seed of the bootstrap's generator: the intervals reproduce.
SEED = 0
#: Normalised-score thresholds of the performance profiles.
PROFILE_TAUS = np.linspace(0.0, 1.5, 31)

Scores = npt.NDArray[np.float64]


def _rliable_metrics() -> Any:
    try:
        from rliable import metrics
    except ImportError as error:
        raise KheperaError(
            'the benchmark\'s aggregate statistics need rliable: pip install "khepera-gym[report]"'
        ) from error
    return metrics


@dataclasses.dataclass(frozen=True)
class TaskMetric:
    """What a task is scored by.

    Attributes:
        task: The core's task.
        metric: The episode statistic (its criterion's first condition).
        higher_is_better: ``at_least`` conditions; errors and contacts are lower-is-better.
    """

    task: str
    metric: str
    higher_is_better: bool

    @property
    def log_scale(self) -> bool:
        """Lower-is-better metrics are normalised on a log scale."""
        return not self.higher_is_better

    def describe(self) -> str:
        """``success (higher is better)``."""
        scale = ", log scale" if self.log_scale else ""
        return f"{self.metric} ({'higher' if self.higher_is_better else 'lower'} is better{scale})"


def task_metric(entry: TaskEntry) -> TaskMetric:
    """The metric of a task's suite entry: its criterion's error condition, else its first."""
    errors = [c for c in entry.criterion if "error" in c.metric]
    chosen = (errors or list(entry.criterion))[0]
    return TaskMetric(entry.task, chosen.metric, chosen.bound == "at_least")


def normalise(value: float, random: float, best: float, metric: TaskMetric) -> float:
    """``value`` between the random policy (0) and the best baseline (1); NaN if undefined.

    Raises:
        KheperaError: The best baseline does no better than random (no scale).
    """
    if metric.log_scale:
        if min(value, random, best) <= 0:
            return math.nan
        low, high, x = math.log(random), math.log(best), math.log(value)
        span = low - high
        return math.nan if span == 0 else (low - x) / span
    span = best - random
    if span == 0:
        raise KheperaError(f"{metric.task}: the best baseline scores as random does")
    return (value - random) / span


def best_baseline(
    summaries: Mapping[str, Mapping[str, Any]], metric: TaskMetric
) -> tuple[str, float] | None:
    """The best classical baseline by ``metric`` (not the random row), and its mean."""
    values = {
        name: float(summary[metric.metric]["value"])
        for name, summary in summaries.items()
        if name != RANDOM and metric.metric in summary
    }
    values = {name: v for name, v in values.items() if math.isfinite(v)}
    if not values:
        return None
    pick = max if metric.higher_is_better else min
    name = pick(values, key=values.__getitem__)
    return name, values[name]


def stratified_bootstrap(
    strata: Sequence[Scores],
    statistic: Callable[[Sequence[Scores]], float],
    resamples: int = RESAMPLES,
    seed: int = SEED,
    confidence: float = CONFIDENCE,
) -> tuple[float, float, float]:
    """``statistic`` of ``strata`` (one array of run scores a task, or a learner) and its
    percentile interval: each stratum's runs resampled with replacement, strata kept apart.

    Returns:
        (value, low, high).
    """
    rng = np.random.default_rng(seed)
    value = statistic(strata)
    draws = np.empty(resamples)
    for i in range(resamples):
        draws[i] = statistic([s[rng.integers(0, len(s), len(s))] for s in strata])
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(draws, [tail, 100 - tail])
    return float(value), float(low), float(high)


def iqm(strata: Sequence[Scores]) -> float:
    """rliable's interquartile mean of every run of every stratum (pooled)."""
    pooled = np.concatenate(strata).reshape(-1, 1)
    return float(_rliable_metrics().aggregate_iqm(pooled))


def mean(strata: Sequence[Scores]) -> float:
    """rliable's mean of every run of every stratum (pooled)."""
    pooled = np.concatenate(strata).reshape(-1, 1)
    return float(_rliable_metrics().aggregate_mean(pooled))


def probability_of_improvement(x: Scores, y: Scores, higher_is_better: bool = True) -> float:
    """rliable's P(X > Y) of one task's runs (ties count half)."""
    sign = 1.0 if higher_is_better else -1.0
    metrics = _rliable_metrics()
    return float(
        metrics.probability_of_improvement(sign * x.reshape(-1, 1), sign * y.reshape(-1, 1))
    )


def improvement_interval(
    x: Scores, y: Scores, higher_is_better: bool = True
) -> tuple[float, float, float]:
    """:func:`probability_of_improvement` with its stratified-bootstrap interval (X's and Y's
    runs resampled apart)."""

    def statistic(strata: Sequence[Scores]) -> float:
        return probability_of_improvement(strata[0], strata[1], higher_is_better)

    return stratified_bootstrap([x, y], statistic)


def performance_profile(strata: Sequence[Scores], taus: Scores = PROFILE_TAUS) -> Scores:
    """The share of runs (pooled over tasks, each task weighing the same) whose normalised
    score exceeds each threshold: a score distribution (rliable's run-score profile)."""
    shares = [np.mean(s[:, None] > taus[None, :], axis=0) for s in strata if len(s)]
    return np.mean(shares, axis=0) if shares else np.full(len(taus), np.nan)


@dataclasses.dataclass(frozen=True)
class Curve:
    """A learner's sample-efficiency curve on a task: the metric of its training evaluations
    against steps and seconds, one row a seed (NaN past a seed's last evaluation)."""

    learner: str
    steps: Scores
    seconds: Scores
    values: Scores


def curves(runs: Sequence[Mapping[str, Any]], metric: TaskMetric) -> list[Curve]:
    """Each learner's curve on ``metric.task`` from the runs' ``history`` (their evaluations
    during training, on seeds apart from the held-out ones)."""
    by_learner: dict[str, list[Mapping[str, Any]]] = {}
    for run in runs:
        if run["key"]["task"] == metric.task and run.get("history"):
            by_learner.setdefault(run["key"]["learner"], []).append(run)
    found = []
    for learner, mine in sorted(by_learner.items()):
        length = max(len(r["history"]) for r in mine)
        shape = (len(mine), length)
        steps, seconds, values = (
            np.full(shape, np.nan),
            np.full(shape, np.nan),
            np.full(shape, np.nan),
        )
        for i, run in enumerate(mine):
            for j, point in enumerate(run["history"]):
                steps[i, j] = point["steps"]
                seconds[i, j] = point["train_seconds"]
                values[i, j] = point["means"].get(metric.metric, np.nan)
        found.append(Curve(learner, steps, seconds, values))
    return found


__all__ = [
    "CONFIDENCE",
    "PROFILE_TAUS",
    "RANDOM",
    "RESAMPLES",
    "SEED",
    "Curve",
    "TaskMetric",
    "best_baseline",
    "curves",
    "improvement_interval",
    "iqm",
    "mean",
    "normalise",
    "performance_profile",
    "probability_of_improvement",
    "stratified_bootstrap",
    "task_metric",
]
