"""Stage 2 of the calibration fit: the drive, from the wheel speeds the robot measured while
the simulator is driven by the logged commands (:class:`DriveFit`; see
:mod:`~khepera_gym.robot.calibrate.fit` for the method).

The lag fitted is the **simulator's effective lag at its step**: the ``robot.motor_time_constant``
with which the simulator, stepping ``physics.dt / physics.substeps``, follows the logged wheel
speeds best. It holds the motors' own lag and what the simulator does not model: the firmware's
10 ms tick (a set point waits for it), the read latency, the speed measured over the last
10 ms, and the simulator's own step. It is therefore tied to that step: a scenario that
changes ``physics.dt`` or ``physics.substeps`` needs the fit made again (the scenario and the
report say so).

Units: SI for the values; speed units for the residuals. Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym.robot.calibrate.replay as rp
from khepera_gym.config import tomllib
from khepera_gym.robot.calibrate.goodness import OUTLIER_SHARE
from khepera_gym.robot.calibrate.logformat import RobotLog
from khepera_gym.robot.calibrate.noise import (
    OUTLIER_SIGMA,
    RESOLUTION,
    Noise,
    expected_sigma,
    plateau_rows,
    robust_noise,
)
from khepera_gym.robot.calibrate.solver import Estimate, Progress, solve_scaled
from khepera_gym.robot.calibrate.timing import row_intervals
from khepera_gym.robot.calibrate.uncertainty import blocks, uncertainty

#: Where the speed mode's fit starts (m/s²): the simulator's estimate (motors.speed_accel).
SPEED_MODE_ACCEL = 2.74
#: The lag's scale (s) for the optimiser, and its bounds.
_TAU_SCALE = 0.02
_TAU_BOUNDS = (0.0, 0.5)
#: Where the lag's fit starts (s).
_TAU_START = 0.03
#: A step's speed is taken as reached this long after the profile's ramp (s): five times the
#: real robots' largest lag (synthetic.SPREAD, 60 ms) and a period of margin.
_SETTLE_S = 0.35


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
    #: Wheel speed residuals (speed units) of that replay, and their expected noise.
    residuals: npt.NDArray[np.float64]
    expected: npt.NDArray[np.float64]
    #: The measured speeds' noise on the steps' plateaus.
    noise: Noise
    #: Readings set aside as outliers.
    outliers: int
    chi2: float
    #: Profile mode: the acc_inc the wheels follow best (a whole value's neighbourhood, the
    #: vertex of the chi-square's parabola) and its uncertainty; NaN in speed mode.
    fitted_acc_inc: tuple[float, float]
    #: Profile mode: the chi-square of each whole acc_inc tried (each with its best lag).
    profile: dict[int, float]
    #: The simulator's step (s) the lag was fitted at, and its dt and substeps.
    step: float
    dt: float
    substeps: int


class DriveFit:
    """Stage 2 on the calibration logs, with the fitted wheel radius (``speed_noise``: the
    measured speeds' noise to weight by, in place of the plateaus', for studies).

    The simulator is replayed as it is used: a command of u speed units drives its wheel at
    u times the speed unit of the fitted wheel radius (the ground speed the robot's wheel has),
    and its wheel speeds are compared with the measured ones in the same unit. The replays run
    on an open floor: the drive is measured without contacts.
    """

    def __init__(
        self,
        logs: Sequence[RobotLog],
        wheel_radius: float,
        base: Mapping[str, Any],
        progress: Progress,
        speed_noise: float | None = None,
    ) -> None:
        self.logs = list(logs)
        self.wheel_radius = wheel_radius
        self.base = dict(base)
        self.progress = progress
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
        self.noise = self._plateau_noise()
        if speed_noise is not None:
            self.noise = dataclasses.replace(self.noise, sigma=speed_noise, source="as given")
        self.rows = [np.arange(len(log)) > 0 for log in self.logs]
        self.labels = np.concatenate(
            [np.repeat(blocks(log, 100000 * k)[1:], 2) for k, log in enumerate(self.logs)]
        )
        self.expected = np.ones(len(self.labels))
        self.step, self.dt, self.substeps = self._step()

    def _plateau_noise(self) -> Noise:
        """The measured speeds' spread where the command has held long enough for the wheels
        to reach it (each plateau and wheel its own level)."""
        values, groups = [], []
        for k, log in enumerate(self.logs):
            inc = max(self.profile["acc_inc"], 1) if self.mode == "profile" else 1000
            ramp = 1200.0 / inc * 0.01 * (self.profile["acc_div"] + 1)
            settle = max(1, math.ceil((min(ramp, 2.0) + _SETTLE_S) / log.period))
            rows = plateau_rows(log.commands, log.phases, settle)
            labels = blocks(log, 100000 * k)
            for wheel in (0, 1):
                values.append(log.speeds[rows, wheel])
                groups.append(labels[rows] * 2 + wheel)
        noise, _ = robust_noise(
            np.concatenate(values), np.concatenate(groups), "the wheel speeds on the steps"
        )
        return noise

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
        """Unweighted residuals: measured minus simulated wheel speeds (speed units), of the
        rows chosen (all but the first; outliers set aside)."""
        unit = rp.speed_unit(self.wheel_radius)
        found = []
        for log, replay, rows in zip(self.logs, self.replays(accel, tau), self.rows, strict=True):
            found.append((log.speeds[rows] - replay.wheel_speeds[rows] / unit).ravel())
        return np.concatenate(found)

    def _set_expected(self, accel: float, tau: float) -> None:
        """Each residual's expected noise: the plateaus' spread and the simulated speed's
        change over the time the reading cannot be placed to: the firmware's 10 ms in which it
        was counted and the one the set point waited for, and the simulator's step."""
        sigma = max(self.noise.sigma, RESOLUTION) if self.noise.count >= 5 else 1.0
        unit = rp.speed_unit(self.wheel_radius)
        found, labels = [], []
        for k, (log, replay) in enumerate(zip(self.logs, self.replays(accel, tau), strict=True)):
            speeds = replay.wheel_speeds / unit
            rate = np.gradient(np.nan_to_num(speeds), axis=0) / row_intervals(log)[:, None]
            rows = self.rows[k]
            found.append(expected_sigma(sigma, rate[rows], "speed", step=self.step).ravel())
            labels.append(np.repeat(blocks(log, 100000 * k)[rows], 2))
        self.expected = np.concatenate(found)
        self.labels = np.concatenate(labels)

    def _solve(self, accel: float | None) -> tuple[npt.NDArray[np.float64], Any, Any]:
        """The best (accel, tau) scaled parameters: the lag for a given acceleration (profile)
        or both (speed mode); returns (values, result, scales)."""
        if accel is not None:
            start, scale = np.array([_TAU_START]), np.array([_TAU_SCALE])
            low, high = np.array([_TAU_BOUNDS[0]]), np.array([_TAU_BOUNDS[1]])

            def unpack(v: npt.NDArray[np.float64]) -> tuple[float, float]:
                return accel, float(v[0])
        else:
            start, scale = np.array([SPEED_MODE_ACCEL, _TAU_START]), np.array([0.5, _TAU_SCALE])
            low, high = np.array([0.05, _TAU_BOUNDS[0]]), np.array([20.0, _TAU_BOUNDS[1]])

            def unpack(v: npt.NDArray[np.float64]) -> tuple[float, float]:
                return float(v[0]), float(v[1])

        result = solve_scaled(
            lambda z: self.channel(*unpack(start + z * scale)) / self.expected,
            np.zeros(len(start)),
            (low - start) / scale,
            (high - start) / scale,
        )
        values = start + result.x * scale
        self.progress.replayed(float(2 * result.cost))
        return values, result, (scale, low, high, unpack)

    def fit(self) -> DriveResult:
        profile_chi2: dict[int, float] = {}
        fitted_acc_inc = (math.nan, math.nan)
        accel = float(self.profile["acc_inc"]) if self.mode == "profile" else SPEED_MODE_ACCEL
        self._set_expected(accel, _TAU_START)
        outliers = 0
        for attempt in range(2):
            given = float(self.profile["acc_inc"]) if self.mode == "profile" else None
            values, result, (scale, low, high, unpack) = self._solve(given)
            accel, tau = unpack(values)
            self._set_expected(accel, tau)
            if attempt == 0:
                outliers = self._drop_outliers(accel, tau)
        if self.mode == "profile":
            fitted_acc_inc = self._scan_profile(profile_chi2)
        residuals = self.channel(accel, tau)
        weighted = residuals / self.expected
        spread = uncertainty(result.jac, weighted, self.labels)
        # The rows at each time after a command changed pull the lag their own way where the
        # simulator cannot follow the robot's ramp: a jackknife over those times too.
        after = uncertainty(result.jac, weighted, self._since_change())
        sigmas = []
        for j in range(len(values)):
            stat = float(spread.stat[j]) * scale[j]
            sys = max(float(spread.sys[j]), float(after.sys[j])) * scale[j]
            sigmas.append((math.hypot(stat, sys), stat, sys))
        bounds = [
            abs(values[j] - low[j]) < 1e-3 * scale[j] or abs(high[j] - values[j]) < 1e-3 * scale[j]
            for j in range(len(values))
        ]
        step, dt, substeps = self.step, self.dt, self.substeps
        tau_estimate = Estimate(
            "robot.motor_time_constant",
            tau,
            *sigmas[-1][:1],
            "s",
            f"the simulator's effective lag at its step of {step * 1000:g} ms (physics.dt "
            f"{dt:g} s, {substeps} substeps): the logged wheel speeds against the replay of the "
            "logged commands. It holds the motors' lag and what the simulator leaves out (the "
            "firmware's 10 ms tick, the read latency, the speed counted over 10 ms, its own "
            "step): fit again for another physics.dt or physics.substeps",
            sigmas[-1][1],
            sigmas[-1][2],
        )
        if bounds[-1]:
            tau_estimate.flags.append("at the search's bound: the logs push it beyond")
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
                sigmas[0][0],
                "m/s²",
                "the measured wheel speeds against the replay (speed mode)",
                sigmas[0][1],
                sigmas[0][2],
            )
            if bounds[0]:
                accel_estimate.flags.append("at the search's bound: the logs push it beyond")
        dof = max(len(weighted) - len(values), 1)
        return DriveResult(
            mode=self.mode,
            accel=accel_estimate,
            motor_time_constant=tau_estimate,
            replays=self.replays(accel, tau),
            residuals=residuals,
            expected=self.expected,
            noise=self.noise,
            outliers=outliers,
            chi2=float(weighted @ weighted) / dof,
            fitted_acc_inc=fitted_acc_inc,
            profile=dict(sorted(profile_chi2.items())),
            step=step,
            dt=dt,
            substeps=substeps,
        )

    def _since_change(self) -> npt.NDArray[np.int64]:
        """Per residual: the rows since its log's command last changed (1 to 8, then 9 for
        the rest), the labels of the jackknife over the time after a change."""
        found = []
        for log, rows in zip(self.logs, self.rows, strict=True):
            since = np.zeros(len(log), dtype=np.int64)
            for row in range(1, len(log)):
                same = np.all(log.commands[row - 1] == log.commands[max(row - 2, 0)])
                since[row] = since[row - 1] + 1 if same and row > 1 else 1
            found.append(np.repeat(np.minimum(since, 9)[rows], 2))
        return np.concatenate(found)

    def _drop_outliers(self, accel: float, tau: float) -> int:
        """Sets aside the rows whose residual is beyond :data:`OUTLIER_SIGMA` expected widths
        (either wheel); returns how many readings."""
        weighted = np.abs(self.channel(accel, tau) / self.expected).reshape(-1, 2)
        bad = np.any(weighted > OUTLIER_SIGMA, axis=1)
        if bad.sum() > OUTLIER_SHARE * len(bad):
            # Too many to be spikes: the model is wrong, which the goodness of fit must see.
            return 0
        start = 0
        for k, rows in enumerate(self.rows):
            count = int(rows.sum())
            chosen = np.nonzero(rows)[0]
            self.rows[k] = rows.copy()
            self.rows[k][chosen[bad[start : start + count]]] = False
            start += count
        self._set_expected(accel, tau)
        return int(2 * bad.sum())

    def _step(self) -> tuple[float, float, int]:
        """The simulator's physics step (s), its dt and substeps, as the replays ran."""
        replay = self.replays(float(self.profile["acc_inc"]) or SPEED_MODE_ACCEL, _TAU_START)[0]
        physics = tomllib.loads(replay.scenario)["physics"]
        dt, substeps = float(physics["dt"]), int(physics["substeps"])
        return dt / substeps, dt, substeps

    def _scan_profile(self, chi2s: dict[int, float]) -> tuple[float, float]:
        """The acc_inc the measured speeds follow best: whole values tried from the program's,
        each with its best lag, walking downhill; the vertex of the parabola through the best
        and its neighbours, and the uncertainty from its curvature (chi-square + 1)."""
        chi2s.clear()

        def at(units: int) -> float:
            if units not in chi2s:
                _, result, _ = self._solve(float(units))
                chi2s[units] = float(2 * result.cost)
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
