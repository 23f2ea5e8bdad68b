"""Whether a calibration explains its logs: each channel's residuals against the noise the log
itself shows where nothing changes (:mod:`~khepera_gym.robot.calibrate.noise`), not against their
own spread, so that a fit can fail.

Per channel (:func:`channel_fit`):

* the **reduced chi-square** ``mean((residual / expected)²)``: 1 when the simulator explains the
  readings down to their noise. The fit is **poor** when it exceeds :data:`POOR_CHI2` (the
  part the simulator leaves unexplained is as large as the noise itself) by more than three
  standard errors of the mean of that many squares;
* **structure**: a Wald–Wolfowitz runs test on the residuals' signs, in the log's order, and
  their lag-1 autocorrelation: residuals that keep their sign or follow each other (a shape
  the simulator cannot take, a lag it cannot follow) are flagged, beyond three standard errors
  of either. Structure alone is a warning: the simulator's curve between its points and its
  lag are simpler than a robot's.

A channel with more than :data:`OUTLIER_SHARE` of its readings set aside as outliers is poor
too. ``khepera-gym calibrate`` says a poor fit failed, in the report and in its exit status, unless
``--accept-poor-fit`` is given. Units: each channel's own. Threading: none.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

#: The reduced chi-square above which a channel's fit is poor (before its allowance for the
#: number of readings): the unexplained part of the residuals as large as the noise.
POOR_CHI2 = 2.0
#: Standard errors a statistic may stray before it is flagged.
TOLERANCE = 3.0
#: The share of a channel's readings that may be set aside as outliers (five expected widths
#: away: one Gaussian reading in 1.7 million) before the channel is poor: more is a sensor
#: that is broken or stuck, or a model that is wrong [E].
OUTLIER_SHARE = 0.01


@dataclasses.dataclass(frozen=True)
class ChannelFit:
    """How one channel's residuals compare with its noise."""

    name: str
    unit: str
    count: int
    rms: float
    #: The expected noise's RMS over the same readings.
    expected: float
    chi2: float
    #: The largest reduced chi-square that is not poor, for this many readings.
    limit: float
    runs_z: float
    lag1: float
    outliers: int

    @property
    def poor(self) -> bool:
        """The simulator leaves more than the noise unexplained, or too many readings lie far
        outside it."""
        if self.outliers > OUTLIER_SHARE * (self.count + self.outliers):
            return True
        return self.count > 0 and self.chi2 > self.limit

    @property
    def structured(self) -> bool:
        """The residuals run in one direction or follow each other."""
        if self.count < 20:
            return False
        return abs(self.runs_z) > TOLERANCE or self.lag1 > TOLERANCE / math.sqrt(self.count)

    def why(self) -> str:
        """What makes the channel poor, in words."""
        if self.count > 0 and self.chi2 > self.limit:
            return f"{self.name} (reduced chi-square {self.chi2:.2f} > {self.limit:.2f})"
        share = self.outliers / max(self.count + self.outliers, 1)
        return f"{self.name} ({self.outliers} readings, {share:.1%}, far outside the noise)"

    def verdict(self) -> str:
        """ "poor", "structured" or "good"."""
        return "poor" if self.poor else ("structured" if self.structured else "good")


def channel_fit(
    name: str,
    residuals: npt.ArrayLike,
    expected: npt.ArrayLike,
    unit: str,
    outliers: int = 0,
) -> ChannelFit:
    """The fit of one channel: ``residuals`` in the log's order and their ``expected`` noise."""
    r = np.asarray(residuals, dtype=np.float64)
    s = np.asarray(expected, dtype=np.float64)
    keep = np.isfinite(r) & np.isfinite(s) & (s > 0)
    r, s = r[keep], s[keep]
    count = len(r)
    if count == 0:
        nan = math.nan
        return ChannelFit(name, unit, 0, nan, nan, nan, nan, nan, nan, outliers)
    z = r / s
    chi2 = float(np.mean(z * z))
    limit = POOR_CHI2 + TOLERANCE * POOR_CHI2 * math.sqrt(2.0 / count)
    return ChannelFit(
        name=name,
        unit=unit,
        count=count,
        rms=float(np.sqrt(np.mean(r * r))),
        expected=float(np.sqrt(np.mean(s * s))),
        chi2=chi2,
        limit=limit,
        runs_z=_runs_z(z),
        lag1=_lag1(z),
        outliers=outliers,
    )


def _runs_z(z: npt.NDArray[np.float64]) -> float:
    """The Wald–Wolfowitz z of the signs' runs (negative: too few runs, residuals that keep
    their sign)."""
    signs = z[z != 0] > 0
    n1, n2 = int(signs.sum()), int((~signs).sum())
    n = n1 + n2
    if n1 == 0 or n2 == 0 or n < 3:
        return 0.0
    runs = 1 + int(np.count_nonzero(signs[1:] != signs[:-1]))
    mean = 2.0 * n1 * n2 / n + 1.0
    variance = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1))
    return (runs - mean) / math.sqrt(variance) if variance > 0 else 0.0


def _lag1(z: npt.NDArray[np.float64]) -> float:
    """The lag-1 autocorrelation of the weighted residuals."""
    if len(z) < 3:
        return 0.0
    centred = z - z.mean()
    denominator = float(centred @ centred)
    return float(centred[1:] @ centred[:-1]) / denominator if denominator > 0 else 0.0


@dataclasses.dataclass(frozen=True)
class Goodness:
    """Every channel's fit."""

    channels: tuple[ChannelFit, ...]

    @property
    def poor(self) -> list[str]:
        """The channels the simulator does not explain."""
        return [c.name for c in self.channels if c.poor]

    @property
    def structured(self) -> list[str]:
        """The channels whose residuals have structure (a warning)."""
        return [c.name for c in self.channels if c.structured and not c.poor]

    def summary(self) -> str:
        """One line for the command's output."""
        if self.poor:
            worst = ", ".join(c.why() for c in self.channels if c.poor)
            return f"POOR FIT: the simulator does not explain {worst}"
        text = "good fit: every channel's residuals are within their noise"
        if self.structured:
            text += f" (structured: {', '.join(self.structured)})"
        return text


__all__ = ["OUTLIER_SHARE", "POOR_CHI2", "TOLERANCE", "ChannelFit", "Goodness", "channel_fit"]
