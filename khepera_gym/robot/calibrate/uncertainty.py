"""Uncertainties of a least-squares fit that hold when the simulator is not the robot.

Each fitted value gets two parts (:class:`Uncertainty`):

* **statistical**: the readings' noise carried through the fit, ``(JᵀJ)⁻¹`` of the Jacobian of
  residuals weighted by each channel's *expected* noise (measured at rest or stated by the
  sensor, :mod:`~khepera_gym.robot.calibrate.noise`), not by the residuals' own spread;
* **systematic**: what the model's error adds. The manoeuvre's parts (its phases, cut into
  blocks of :data:`BLOCK_S`, :func:`blocks`) each pull the fit toward their own best values; a
  delete-one-block jackknife, linearised (the cluster-robust "sandwich" covariance), measures
  how far they disagree. Where the model is right, it equals the statistical part within its
  own noise; where it is wrong, the disagreement is larger, and the excess is the systematic
  part. ``total² = max(stat², jackknife²)``, ``systematic² = total² - stat²``.

A value is *not identified* when the logs carry no information on it or less than the real
robots' spread already gives (:func:`identified`); the fit then keeps its nominal value.

Units: those of the scaled parameters the solver works on. Threading: none.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from khepera_gym.robot.calibrate.logformat import RobotLog

#: The longest block of the jackknife (s): a phase longer than this is cut into blocks, so that
#: the approach and the spin give several each while a step and its rest stay whole [E: a
#: design choice].
BLOCK_S = 2.0


@dataclasses.dataclass
class Uncertainty:
    """Per parameter: the statistical, systematic and total standard uncertainties."""

    stat: npt.NDArray[np.float64]
    sys: npt.NDArray[np.float64]
    total: npt.NDArray[np.float64]
    #: The statistical covariance (for values derived from several parameters).
    covariance: npt.NDArray[np.float64]
    #: The jackknife's covariance.
    jackknife: npt.NDArray[np.float64]


def blocks(log: RobotLog, offset: int = 0) -> npt.NDArray[np.int64]:
    """A block label per row: runs of rows of one phase, cut every :data:`BLOCK_S`; labels
    start at ``offset`` (so that several logs' labels do not meet)."""
    labels = np.zeros(len(log), dtype=np.int64)
    label = offset
    start = log.time[0]
    for row in range(1, len(log)):
        if log.phases[row] != log.phases[row - 1] or log.time[row] - start >= BLOCK_S:
            label += 1
            start = log.time[row]
        labels[row] = label
    labels[0] = offset
    return labels


def uncertainty(
    jacobian: npt.NDArray[np.float64],
    residuals: npt.NDArray[np.float64],
    labels: npt.NDArray[np.int64],
) -> Uncertainty:
    """Both parts of the uncertainty of a least-squares optimum.

    Args:
        jacobian: (m, n) of the weighted residuals (each divided by its expected noise).
        residuals: (m,) the weighted residuals at the optimum.
        labels: (m,) each residual's block (:func:`blocks`); residuals of no block (a prior,
            a measured gap) are their own.
    """
    information = jacobian.T @ jacobian
    covariance = np.linalg.pinv(information)
    scores = jacobian * residuals[:, None]
    unique, index = np.unique(labels, return_inverse=True)
    per_block = np.zeros((len(unique), jacobian.shape[1]))
    np.add.at(per_block, index, scores)
    count = len(unique)
    middle = per_block.T @ per_block * (count / max(count - 1, 1))
    jackknife = covariance @ middle @ covariance
    stat = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    total = np.sqrt(np.maximum(np.diag(covariance), np.diag(jackknife)).clip(0.0))
    sys = np.sqrt(np.clip(total**2 - stat**2, 0.0, None))
    return Uncertainty(stat, sys, total, covariance, jackknife)


def identified(
    jacobian: npt.NDArray[np.float64], prior: npt.NDArray[np.float64]
) -> npt.NDArray[np.bool_]:
    """Which parameters the data determine: each one's statistical uncertainty, with the others
    free, is below ``prior`` (the real robots' spread, in the scaled units; inf: any)."""
    information = jacobian.T @ jacobian
    diagonal = np.diag(information)
    ok = diagonal > 1e-12 * max(float(diagonal.max(initial=0.0)), 1e-300)
    if not ok.any():
        return ok
    sub = information[np.ix_(ok, ok)]
    sigma = np.full(len(diagonal), np.inf)
    try:
        sigma[ok] = np.sqrt(np.clip(np.diag(np.linalg.inv(sub)), 0.0, None))
    except np.linalg.LinAlgError:
        return np.zeros(len(diagonal), dtype=bool)
    return ok & (sigma < prior)


__all__ = ["BLOCK_S", "Uncertainty", "blocks", "identified", "uncertainty"]
