"""Stage 2 of the calibration fit: the drive, from the wheel speeds the robot measured while
the simulator is driven by the logged commands (:class:`DriveFit`; see
:mod:`~khepera_gym.calibrate.fit` for the method).

Units: SI for the values; speed units for the residuals. Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym.calibrate.replay as rp
from khepera_gym.calibrate.logformat import RobotLog
from khepera_gym.calibrate.solver import (
    Estimate,
    Progress,
    fit_covariance,
    residual_noise,
    solve_scaled,
)

#: Where the speed mode's fit starts (m/s²): the simulator's estimate (motors.speed_accel).
SPEED_MODE_ACCEL = 2.74


# --------------------------------------------------------------------------------------------
# Stage 2: the drive.


@dataclasses.dataclass
class DriveResult:
    """Stage 2's values with their uncertainties and what the report draws."""

    mode: str
    #: The mode's acceleration as written: ``motors.acc_inc`` (the program's, which the firmware
    #: sets exactly; its fitted value is in ``fitted_acc_inc``) or ``motors.speed_accel``.
    accel: Estimate
    motor_time_constant: Estimate
    #: Per log: the command replay with the drive written.
    replays: list[rp.Replay]
    #: Wheel speed residuals (speed units) of that replay.
    residuals: npt.NDArray[np.float64]
    #: The measured speeds' noise (speed units), from the residuals less their rounding.
    speed_noise: float
    chi2: float
    #: Profile mode: the acc_inc the wheels follow best (a whole value's neighbourhood, the
    #: vertex of the chi-square's parabola) and its uncertainty; NaN in speed mode.
    fitted_acc_inc: tuple[float, float]
    #: Profile mode: the chi-square of each whole acc_inc tried (each with its best lag).
    profile: dict[int, float]


#: The lag's scale (s) for the optimiser, and its bounds.
_TAU_SCALE = 0.02
_TAU_BOUNDS = (0.0, 0.5)
#: Where the lag's fit starts (s).
_TAU_START = 0.03


class DriveFit:
    """Stage 2 on the calibration logs, with the fitted wheel radius.

    The simulator is replayed as it is used: a command of u speed units drives its wheel at
    u times the speed unit of the fitted wheel radius (the ground speed the robot's wheel has),
    and its wheel speeds are compared with the measured ones in the same unit. The simulator's
    speed profile, though, ramps in the units of 21 mm wheels while the firmware's ramps the
    wheels' turning: on wheels 1 % larger than 21 mm the real ground acceleration is 1 % higher
    than the simulated one, and the lag fitted here makes up for part of it (the sim-to-real page
    notes it). The replays run on an open floor: the drive is measured without contacts.
    """

    def __init__(
        self,
        logs: Sequence[RobotLog],
        wheel_radius: float,
        base: Mapping[str, Any],
        progress: Progress,
    ) -> None:
        self.logs = list(logs)
        self.wheel_radius = wheel_radius
        self.base = dict(base)
        self.progress = progress
        self.sigma = 3.0
        head = self.logs[0].metadata
        self.mode = head["motors"]
        self.profile = {
            key: int(head[key]) for key in ("acc_inc", "acc_div", "min_speed_acc", "min_speed_dec")
        }
        self.floor = {
            "arena.walls": False,
            "arena.width": 20.0,
            "arena.height": 20.0,
            "obstacles.count": 0,
            "obstacles.fixed": [],
            "spawn.start": [0.0, 0.0, 0.0],
            "spawn.goal": [-9.0, -9.0],
        }

    def _overrides(self, accel: float, tau: float) -> dict[str, Any]:
        drive: dict[str, Any] = {"motors.mode": self.mode, "robot.motor_time_constant": tau}
        if self.mode == "profile":
            drive.update({f"motors.{k}": v for k, v in self.profile.items()})
            drive["motors.acc_inc"] = round(float(accel))
        else:
            drive["motors.speed_accel"] = accel
        return {**self.base, **self.floor, **drive, "robot.wheel_radius": self.wheel_radius}

    def replays(self, accel: float, tau: float) -> list[rp.Replay]:
        """The logs' command replays with this drive (the gyroscope carried only)."""
        overrides = self._overrides(accel, tau)
        found = [
            rp.command_replay(log, overrides, self.wheel_radius, carry=("gyro",))
            for log in self.logs
        ]
        self.progress.replayed()
        return found

    def channel(self, accel: float, tau: float) -> npt.NDArray[np.float64]:
        """Unweighted residuals: measured minus simulated wheel speeds (speed units)."""
        unit = rp.speed_unit(self.wheel_radius)
        found = []
        for log, replay in zip(self.logs, self.replays(accel, tau), strict=True):
            found.append((log.speeds[1:] - replay.wheel_speeds[1:] / unit).ravel())
        return np.concatenate(found)

    def _fit_tau(self, accel: float) -> tuple[float, float, float]:
        """The best lag for an acceleration: (tau, its uncertainty, chi-square)."""
        low, high = _TAU_BOUNDS
        result = solve_scaled(
            lambda z: self.channel(accel, _TAU_START + z[0] * _TAU_SCALE) / self.sigma,
            np.zeros(1),
            np.array([(low - _TAU_START) / _TAU_SCALE]),
            np.array([(high - _TAU_START) / _TAU_SCALE]),
        )
        covariance, _ = fit_covariance(result.jac, result.fun)
        tau = _TAU_START + float(result.x[0]) * _TAU_SCALE
        return tau, math.sqrt(float(covariance[0, 0])) * _TAU_SCALE, float(2 * result.cost)

    def fit(self) -> DriveResult:
        profile_chi2: dict[int, float] = {}
        fitted_acc_inc = (math.nan, math.nan)
        for _ in range(2):
            if self.mode == "profile":
                fitted_acc_inc = self._scan_profile(profile_chi2)
                accel = float(self.profile["acc_inc"])
                accel_sigma = math.nan
                tau, tau_sigma, chi2 = self._fit_tau(accel)
            else:
                start = np.array([SPEED_MODE_ACCEL, _TAU_START])
                scale = np.array([0.5, _TAU_SCALE])
                result = solve_scaled(
                    lambda z, start=start, scale=scale: (
                        self.channel(*(start + z * scale)) / self.sigma
                    ),
                    np.zeros(2),
                    (np.array([0.05, _TAU_BOUNDS[0]]) - start) / scale,
                    (np.array([20.0, _TAU_BOUNDS[1]]) - start) / scale,
                )
                accel, tau = (float(v) for v in start + result.x * scale)
                chi2 = float(2 * result.cost)
                covariance, _ = fit_covariance(result.jac, result.fun)
                errors = np.sqrt(np.diag(covariance)) * scale
                accel_sigma, tau_sigma = float(errors[0]), float(errors[1])
            self.progress.replayed(chi2)
            residuals = self.channel(accel, tau)
            self.sigma = max(float(np.std(residuals)), 0.3)
        noise, _ = residual_noise(residuals, 1.0 / 12.0)
        dof = max(len(residuals) - 2, 1)
        if self.mode == "profile":
            value, sigma = fitted_acc_inc
            accel_estimate = Estimate(
                "motors.acc_inc",
                accel,
                math.nan,
                "speed units per 10 ms",
                f"the program's setting, which the firmware follows exactly; the measured wheel "
                f"speeds are followed best at {value:.2f} ± {sigma:.2g} (whole values tried)",
            )
        else:
            accel_estimate = Estimate(
                "motors.speed_accel",
                accel,
                accel_sigma,
                "m/s²",
                "the measured wheel speeds against the replay (speed mode)",
            )
        return DriveResult(
            mode=self.mode,
            accel=accel_estimate,
            motor_time_constant=Estimate(
                "robot.motor_time_constant",
                tau,
                tau_sigma,
                "s",
                "the measured wheel speeds against the replay (steps and turns)",
            ),
            replays=self.replays(accel, tau),
            residuals=residuals,
            speed_noise=noise,
            chi2=float(residuals @ residuals) / (self.sigma**2) / dof,
            fitted_acc_inc=fitted_acc_inc,
            profile=dict(sorted(profile_chi2.items())),
        )

    def _scan_profile(self, chi2s: dict[int, float]) -> tuple[float, float]:
        """The acc_inc the measured speeds follow best: whole values tried from the program's,
        each with its best lag, walking downhill; the vertex of the parabola through the best
        and its neighbours, and the uncertainty from its curvature (chi-square + 1)."""
        chi2s.clear()

        def at(units: int) -> float:
            if units not in chi2s:
                chi2s[units] = self._fit_tau(float(units))[2]
            return chi2s[units]

        best = min(255, max(1, self.profile["acc_inc"]))
        while True:
            neighbours = [u for u in (best - 1, best + 1) if 1 <= u <= 255]
            better = [u for u in neighbours if at(u) < at(best)]
            if not better:
                break
            best = min(better, key=at)
        if best - 1 not in chi2s or best + 1 not in chi2s:
            return float(best), math.nan
        low, mid, high = chi2s[best - 1], chi2s[best], chi2s[best + 1]
        curvature = low - 2.0 * mid + high
        if curvature <= 0:
            return float(best), math.inf
        return best - 0.5 * (high - low) / curvature, math.sqrt(2.0 / curvature)


__all__ = ["SPEED_MODE_ACCEL", "DriveFit", "DriveResult"]
