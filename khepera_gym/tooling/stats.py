"""Interval estimates for the comparison tool: Wilson score intervals for rates, seeded
percentile bootstraps for means and percentiles (deterministic: the same results give the same
intervals), and the median of times to an event that may never happen (inf-aware).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from typing import Any

import numpy as np
import numpy.typing as npt

#: Confidence level of every interval.
CONFIDENCE = 0.95
#: Bootstrap resamples of an interval of a mean or percentile.
BOOTSTRAP_RESAMPLES = 2000
#: Seed of the bootstrap generator (fixed: the same results give the same intervals).
BOOTSTRAP_SEED = 0


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A statistic with its confidence interval; NaN everywhere when there is no data.

    A median of times to an event (:func:`event_time_median`) may be +inf: fewer than half the
    episodes saw the event; its upper bound is inf when the data cannot exclude that.

    Attributes:
        value: The estimate.
        low: Lower bound of the interval.
        high: Upper bound of the interval.
        n: Number of samples it is computed from.
    """

    value: float
    low: float
    high: float
    n: int

    def format(self, scale: float = 1.0, digits: int = 2) -> str:
        """``"value [low, high]"`` with every number multiplied by ``scale``; "–" without data,
        "inf" for an infinite bound or value (a median time of an event that did not happen)."""
        if self.n == 0 or math.isnan(self.value):
            return "–"
        value, low, high = (
            "inf" if math.isinf(x) else f"{x * scale:.{digits}f}"
            for x in (self.value, self.low, self.high)
        )
        return f"{value} [{low}, {high}]"

    def to_json(self) -> dict[str, float | int | str | None]:
        """A JSON-ready dict (strict JSON, no NaN or Infinity): NaN becomes None, ±inf the
        strings "inf" and "-inf"."""
        return {name: json_number(x) for name, x in dataclasses.asdict(self).items()}

    @classmethod
    def from_json(cls, record: dict[str, Any]) -> Estimate:
        """The estimate :meth:`to_json` wrote (None back to NaN, "inf" back to inf)."""

        def number(x: Any) -> float:
            return math.nan if x is None else float(x)

        return cls(
            number(record["value"]), number(record["low"]), number(record["high"]), int(record["n"])
        )


def json_number(x: Any) -> Any:
    """``x`` for strict JSON: a NaN float becomes None, ±inf "inf"/"-inf"; anything else as is."""
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


def _z(confidence: float) -> float:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    return statistics.NormalDist().inv_cdf(0.5 + confidence / 2)


def wilson_interval(successes: int, n: int, confidence: float = CONFIDENCE) -> Estimate:
    """A rate with its Wilson score interval.

    With p = successes / n and z the normal quantile of the confidence level, the interval is
    ``(p + z²/2n ± z·sqrt(p(1 - p)/n + z²/4n²)) / (1 + z²/n)``; unlike the normal approximation
    it stays inside [0, 1] and is not empty at p = 0 or 1.

    Args:
        successes: Number of successes, 0 <= successes <= n.
        n: Number of trials (0 gives NaN).
        confidence: Confidence level.

    Returns:
        The rate and its interval.
    """
    if not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got {successes} of {n}")
    if n == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    z = _z(confidence)
    p = successes / n
    denominator = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    # Exactly 0 (1) for no (all) successes, where rounding would leave a residue.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return Estimate(p, low, high, n)


def bootstrap_interval(
    values: npt.ArrayLike,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Estimate:
    """A mean or percentile with its percentile-bootstrap interval.

    The sample is resampled with replacement ``resamples`` times by a generator seeded with
    ``seed``; the interval holds the central ``confidence`` share of the resampled statistics.

    Args:
        values: The sample (NaN values are dropped).
        statistic: "mean", "median" or "pNN" (a percentile, e.g. "p95").
        confidence: Confidence level.
        resamples: Number of bootstrap resamples.
        seed: Seed of the resampling generator.

    Returns:
        The statistic of the sample and its interval (NaN for an empty sample; a point
        interval for one value).
    """
    sample = np.asarray(values, dtype=float).ravel()
    sample = sample[~np.isnan(sample)]
    if statistic == "mean":

        def compute(x: np.ndarray, axis: int | None = None) -> Any:
            return np.mean(x, axis=axis)
    elif statistic == "median" or statistic.startswith("p"):
        q = 50.0 if statistic == "median" else float(statistic[1:])

        def compute(x: np.ndarray, axis: int | None = None) -> Any:
            return np.percentile(x, q, axis=axis)
    else:
        raise ValueError(f"statistic must be 'mean', 'median' or 'pNN', got {statistic!r}")
    _z(confidence)
    if sample.size == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    value = float(compute(sample))
    rng = np.random.default_rng(seed)
    draws = compute(sample[rng.integers(0, sample.size, (resamples, sample.size))], axis=1)
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(draws, [tail, 100 - tail])
    return Estimate(value, float(min(low, value)), float(max(high, value)), int(sample.size))


def event_time_median(
    times: npt.ArrayLike,
    confidence: float = CONFIDENCE,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> Estimate:
    """The median time to an event that may never happen, with a percentile-bootstrap interval.

    ``times`` holds one time per episode, +inf for an episode where the event never happened
    (e.g. ``track_converge_time``: the error never stayed below 2 cm). No inf is ever averaged
    or interpolated: the median is the empirical one without interpolation (numpy's
    ``inverted_cdf``: the smallest time by which at least half of the episodes saw the event),
    so it is finite exactly when at least half of the episodes saw the event, and inf
    otherwise; each bootstrap resample's median is taken the same way, so the interval's upper
    bound is inf when the share of events could be below one half.

    Args:
        times: Times (s), +inf for never; NaN values are dropped.
        confidence: Confidence level.
        resamples: Number of bootstrap resamples.
        seed: Seed of the resampling generator.

    Returns:
        The median and its interval, any of them possibly inf (NaN for an empty sample).

    Raises:
        ValueError: A negative infinite time, or a confidence outside (0, 1).
    """
    _z(confidence)
    sample = np.asarray(times, dtype=float).ravel()
    sample = sample[~np.isnan(sample)]
    if np.any(sample == -np.inf):
        raise ValueError("times to an event must not be -inf")
    if sample.size == 0:
        return Estimate(math.nan, math.nan, math.nan, 0)
    value = float(np.quantile(sample, 0.5, method="inverted_cdf"))
    rng = np.random.default_rng(seed)
    draws = np.quantile(
        sample[rng.integers(0, sample.size, (resamples, sample.size))],
        0.5,
        axis=1,
        method="inverted_cdf",
    )
    tail = (1 - confidence) / 2
    low, high = np.quantile(draws, [tail, 1 - tail], method="inverted_cdf")
    return Estimate(value, float(min(low, value)), float(max(high, value)), int(sample.size))


__all__ = [
    "CONFIDENCE",
    "Estimate",
    "bootstrap_interval",
    "event_time_median",
    "json_number",
    "wilson_interval",
]
