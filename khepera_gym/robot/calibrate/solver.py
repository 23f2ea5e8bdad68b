"""The least-squares machinery both stages of the calibration fit share: scipy's
:func:`~scipy.optimize.least_squares` on scaled parameters with fixed-step Jacobians
(:func:`solve_scaled`), the covariance of a fit (:func:`fit_covariance`), a channel's noise from its
residuals (:func:`residual_noise`), a fitted value with its uncertainty (:class:`Estimate`) and the
progress bar (:class:`Progress`).

Units: whatever the residuals carry. Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

#: The extra that brings the optimiser.
CALIBRATE_EXTRA = "pip install 'khepera-gym[calibrate]'"


def scipy_least_squares() -> Callable[..., Any]:
    """scipy's least_squares, or an ImportError naming the extra."""
    try:
        from scipy.optimize import least_squares
    except ImportError as error:  # pragma: no cover - scipy is in the test environment
        raise ImportError(f"khepera-gym calibrate needs scipy: {CALIBRATE_EXTRA}") from error
    return least_squares


@dataclasses.dataclass
class Estimate:
    """A fitted value with its standard uncertainty (one standard deviation).

    Attributes:
        key: The scenario key (``robot.wheel_radius``), or a name of the report's only.
        value: The value (a list for ``sensors.ir_curve``).
        sigma: Its uncertainty, statistical and systematic together (a list likewise); NaN
            when the logs cannot tell (then ``identified`` is False).
        unit: Its unit.
        how: What in the logs determined it.
        sigma_stat: The readings' noise carried through the fit.
        sigma_sys: What the model's error adds (:mod:`~khepera_gym.robot.calibrate.uncertainty`).
        identified: Whether the logs determine it (a list for the curve); if not, the value is
            the nominal one (or, for the curve, extended along K-Team's shape).
        flags: What the report must say about it (at a bound of the search, changed to be
            written...).
    """

    key: str
    value: float | list[float]
    sigma: float | list[float]
    unit: str
    how: str
    sigma_stat: float | list[float] = math.nan
    sigma_sys: float | list[float] = math.nan
    identified: bool | list[bool] = True
    flags: list[str] = dataclasses.field(default_factory=list)


class Progress:
    """A count of replays with the stage and its cost, on standard error (tqdm)."""

    def __init__(self, enabled: bool = True) -> None:
        from tqdm import tqdm

        self._bar = tqdm(desc="calibrate", unit=" replays", disable=not enabled, leave=True)

    def stage(self, name: str) -> None:
        self._bar.set_description(f"calibrate: {name}")

    def replayed(self, cost: float | None = None) -> None:
        self._bar.update(1)
        if cost is not None:
            self._bar.set_postfix_str(f"chi2 {cost:.4g}")

    def close(self) -> None:
        self._bar.close()


class _Objective:
    """Residuals of scaled parameters z (value = start + z · scale) with a forward-difference
    Jacobian of fixed steps: the replays compute in float32 and read whole counts, so the
    optimiser's default steps (relative, down to 1e-8) would see no change at all.

    Args:
        fun: z → residuals (a vector of fixed length).
        step: The difference step in z (a fraction of each parameter's spread).
        lower: z's lower bounds (a step that would leave them goes the other way).
        upper: z's upper bounds.
    """

    def __init__(
        self,
        fun: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]],
        step: float,
        lower: npt.NDArray[np.float64],
        upper: npt.NDArray[np.float64],
    ) -> None:
        self.fun = fun
        self.step = step
        self.lower = lower
        self.upper = upper
        self._last: tuple[bytes, npt.NDArray[np.float64]] | None = None

    def __call__(self, z: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        key = np.asarray(z, dtype=np.float64).tobytes()
        if self._last is None or self._last[0] != key:
            self._last = (key, np.asarray(self.fun(np.asarray(z, dtype=np.float64))))
        return self._last[1]

    def jac(self, z: npt.NDArray[np.float64], *_: Any) -> npt.NDArray[np.float64]:
        z = np.asarray(z, dtype=np.float64)
        base = self(z).copy()
        columns = []
        for i in range(len(z)):
            h = self.step if z[i] + self.step <= self.upper[i] else -self.step
            moved = z.copy()
            moved[i] += h
            columns.append((np.asarray(self.fun(moved)) - base) / h)
        self._last = (z.tobytes(), base)
        return np.stack(columns, axis=1)


#: The difference step of the Jacobians, in units of each parameter's spread.
JACOBIAN_STEP = 0.1


def solve_scaled(
    fun: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]],
    z0: npt.NDArray[np.float64],
    lower: npt.NDArray[np.float64],
    upper: npt.NDArray[np.float64],
) -> Any:
    """least_squares (trust region reflective) of scaled parameters within bounds."""
    least_squares = scipy_least_squares()
    objective = _Objective(fun, JACOBIAN_STEP, lower, upper)
    return least_squares(
        objective, z0, jac=objective.jac, bounds=(lower, upper), method="trf", x_scale=1.0
    )


def fit_covariance(jacobian: npt.NDArray[np.float64], residuals: npt.NDArray[np.float64]) -> Any:
    """s² (JᵀJ)⁻¹ of weighted residuals (pseudo-inverse if singular)."""
    m, n = jacobian.shape
    dof = max(m - n, 1)
    s2 = float(residuals @ residuals) / dof
    return np.linalg.pinv(jacobian.T @ jacobian) * s2, s2


def residual_noise(residuals: npt.NDArray[np.float64], rounding: float) -> tuple[float, float]:
    """The noise (std) behind residuals that also carry ``rounding`` (a variance in the same
    units², from whole-count readings), with its uncertainty."""
    residuals = residuals[np.isfinite(residuals)]
    if len(residuals) < 3:
        return math.nan, math.nan
    variance = float(np.var(residuals, ddof=1)) - rounding
    sigma = math.sqrt(max(variance, 0.0))
    return sigma, sigma / math.sqrt(2.0 * (len(residuals) - 1))


__all__ = [
    "CALIBRATE_EXTRA",
    "JACOBIAN_STEP",
    "Estimate",
    "Progress",
    "fit_covariance",
    "residual_noise",
    "scipy_least_squares",
    "solve_scaled",
]
