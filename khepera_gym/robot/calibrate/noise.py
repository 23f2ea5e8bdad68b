"""Each channel's expected noise, taken from the log itself where nothing changes, never from
the fit's residuals: the gyroscope where the robot stands still, the infrared ring where a
sensor sees nothing (the floor's reflection), the ultrasonic sensor at rest in front of the
wall, the wheel speeds on the plateaus of the steps (:func:`robust_noise`).

Every estimate is robust: each group's median and the pooled median absolute deviation give a
first width; readings beyond :data:`OUTLIER_SIGMA` of it are set aside (and counted, so that the
report can flag them), and the standard deviation of the rest is the noise; its uncertainty is
half the larger side of its exact (chi-square) interval, a standard deviation from few readings
being found too low more often than too high. One reading of 1023
among thousands then changes nothing.

A reading also depends on when its sensor sampled, which the log does not say to better than
the sensor's own period (:data:`TIMING_S`): where the reading changes fast, its expected residual
grows by that rate times that time (:func:`expected_sigma`).

Units: each channel's own (counts, raw, cm, speed units). Threading: none.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

#: Readings farther than this many robust standard deviations from their group's median are
#: outliers (a Gaussian reading lies beyond it once in 1.7 million).
OUTLIER_SIGMA = 5.0
#: The median absolute deviation of a Gaussian is 0.6745 of its standard deviation.
MAD_TO_SIGMA = 1.0 / 0.6745
#: How well the log places each channel's reading in time (s, one standard deviation): a
#: sensor sampling on its own clock, of period P, read at a time that falls anywhere in its
#: period, P/√12. The firmware counts a wheel's pulses over its 10 ms period (manual §4.14) and
#: takes a set point at its next period, so that a wheel's speed against the command's time is
#: placed to √2 times that; the infrared ring refreshes every 5 ms (§4.1); the ultrasonic
#: sensors sweep in 100 ms (§4.2). The gyroscope samples at 95 Hz (§4.10), and a row averages
#: its newest five samples: 52.6 ms ending anywhere in the sample period before the read, so
#: that their middle falls some 5 ms before the middle of the encoders' interval, give or take
#: 3: one sample period, 10.5 ms, covers both.
TIMING_S = {
    "gyro": 1.0 / 95.0,
    **{
        channel: period / math.sqrt(12.0)
        for channel, period in {"speed": math.sqrt(2.0) * 0.01, "ir": 0.005, "us": 0.1}.items()
    },
}
#: The least noise a channel's residuals can have: the readings' rounding to whole units
#: (counts, raw, cm, speed units), one over √12 of a unit.
RESOLUTION = 1.0 / math.sqrt(12.0)
#: How well the log places a read of the encoders (s): an I²C transaction lands some 0.5 to 3 ms
#: after the row's time stamp, not always as long, its time varying by about this [E]; a rate
#: over a row from two reads of the encoders is then known to this times √2 over the row's
#: interval.
READ_TIMING_S = 0.0005


@dataclasses.dataclass(frozen=True)
class Noise:
    """A channel's noise as the log shows it.

    Attributes:
        sigma: The readings' standard deviation about their true value, as logged (with their
            rounding to whole units).
        error: Its standard error.
        count: The readings it comes from.
        outliers: The readings set aside.
        source: Where in the log it comes from.
    """

    sigma: float
    error: float
    count: int
    outliers: int
    source: str

    def less_rounding(self, step: float = 1.0) -> tuple[float, float]:
        """(noise, its error) before the rounding to ``step`` (variance step²/12 taken off),
        as the simulator's noise keys mean it (the simulator rounds its readings too)."""
        variance = self.sigma**2 - step * step / 12.0
        value = math.sqrt(max(variance, 0.0))
        return value, self.error * self.sigma / max(value, 1e-12)


def robust_noise(
    values: npt.ArrayLike, groups: npt.ArrayLike | None = None, source: str = ""
) -> tuple[Noise, npt.NDArray[np.bool_]]:
    """The noise of ``values`` about their groups' levels, with outliers set aside.

    Args:
        values: The readings.
        groups: A label per reading: readings of a group share a true value (None: one group).
        source: Where they come from (for the report).

    Returns:
        The noise and a mask of the outliers.
    """
    values = np.asarray(values, dtype=np.float64)
    labels = np.zeros(len(values), np.int64) if groups is None else np.asarray(groups)
    if len(values) < 3:
        return Noise(math.nan, math.nan, len(values), 0, source), np.zeros(len(values), bool)
    unique, index = np.unique(labels, return_inverse=True)
    medians = np.array([np.median(values[index == g]) for g in range(len(unique))])
    deviation = values - medians[index]
    width = MAD_TO_SIGMA * float(np.median(np.abs(deviation)))
    if width <= 0:
        # Readings mostly equal (whole counts of a quiet sensor): the spread of the rest.
        width = float(np.std(deviation)) or 1e-12
    outliers = np.abs(deviation) > OUTLIER_SIGMA * width
    kept = ~outliers
    means = np.array(
        [
            values[kept & (index == g)].mean() if (kept & (index == g)).any() else 0
            for g in range(len(unique))
        ]
    )
    residual = values[kept] - means[index[kept]]
    dof = max(int(kept.sum()) - len(unique), 1)
    variance = float(residual @ residual) / dof
    sigma = math.sqrt(variance)
    return Noise(
        sigma, _sigma_error(residual, variance, dof), int(kept.sum()), int(outliers.sum()), source
    ), outliers


def _sigma_error(residual: npt.NDArray[np.float64], variance: float, dof: int) -> float:
    """The uncertainty of a standard deviation from ``dof`` degrees of freedom. Its spread is
    skewed (found too low more often and by more than too high), so it is half the larger side
    of its interval of ±2 standard deviations' probability: the chi-square interval with the
    degrees of freedom that give the readings' own fourth moment (whole-unit readings of a
    quiet sensor are far from Gaussian; a Gaussian's at most)."""
    from scipy.stats import chi2, norm

    if variance <= 0 or not len(residual):
        return math.nan
    kurtosis = float(np.mean(residual**4)) / (variance * variance)
    effective = 2.0 * dof / max(kurtosis - 1.0, 2.0)
    low = float(chi2.ppf(norm.cdf(-2.0), effective))
    sigma = math.sqrt(variance)
    return 0.5 * sigma * (math.sqrt(effective / low) - 1.0)


def expected_sigma(
    noise: float,
    rate: npt.ArrayLike,
    channel: str,
    level: npt.ArrayLike | None = None,
    interval: npt.ArrayLike | None = None,
    step: float = 0.0,
) -> npt.NDArray[np.float64]:
    """The expected residual of each reading: the noise and the reading's change over the
    time the log cannot place it to (:data:`TIMING_S`), ``rate`` being its rate of change (units
    a second); for a model value ``level`` that is a rate over a row's ``interval`` from two
    reads of the encoders, also their timing (:data:`READ_TIMING_S`); for a model value the
    simulator integrates in steps of ``step`` s, also that step's resolution, step/√12."""
    timing = math.hypot(TIMING_S[channel], step / math.sqrt(12.0))
    rate = np.nan_to_num(np.asarray(rate, dtype=np.float64))
    variance = noise**2 + (rate * timing) ** 2
    if level is not None and interval is not None:
        reads = math.sqrt(2.0) * READ_TIMING_S / np.asarray(interval, dtype=np.float64)
        variance = variance + (np.nan_to_num(np.asarray(level, dtype=np.float64)) * reads) ** 2
    return np.sqrt(variance)


def still_rows(
    commands: npt.ArrayLike, encoders: npt.ArrayLike, rows: int
) -> npt.NDArray[np.bool_]:
    """Rows after ``rows`` rows in which no wheel was commanded and no encoder moved."""
    commands = np.asarray(commands)
    encoders = np.asarray(encoders)
    moving = np.any(commands != 0, axis=1) | np.any(
        np.diff(encoders, axis=0, prepend=encoders[:1]) != 0, axis=1
    )
    recent = np.convolve(moving.astype(float), np.ones(rows), mode="full")[: len(moving)]
    return (recent == 0) & (np.arange(len(moving)) >= rows)


def plateau_rows(
    commands: npt.ArrayLike, phases: npt.ArrayLike, settle: int
) -> npt.NDArray[np.bool_]:
    """Rows of a moving phase whose command has not changed for ``settle`` rows: the wheels
    have reached their speed."""
    commands = np.asarray(commands)
    phases = np.asarray(phases)
    same = np.ones(len(commands), dtype=np.int64)
    for row in range(1, len(commands)):
        unchanged = phases[row] == phases[row - 1] and np.all(commands[row] == commands[row - 1])
        same[row] = same[row - 1] + 1 if unchanged else 1
    return (same > settle) & np.any(commands != 0, axis=1)


__all__ = [
    "MAD_TO_SIGMA",
    "OUTLIER_SIGMA",
    "READ_TIMING_S",
    "RESOLUTION",
    "TIMING_S",
    "Noise",
    "expected_sigma",
    "plateau_rows",
    "robust_noise",
    "still_rows",
]
