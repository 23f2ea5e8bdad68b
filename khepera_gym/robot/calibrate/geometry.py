"""Stage 1 of the calibration fit: the geometry and the sensors, along the path the encoders
measured (:class:`GeometryFit`; see :mod:`~khepera_gym.robot.calibrate.fit` for the method).

The parameters: the wheel radius, the axle, the gyroscope's bias, the ultrasonic offset, the
infrared floor value and the 16 points of the infrared curve (:mod:`~khepera_gym.robot.calibrate.
ir_curve`: each point free, so that the curve's shape cannot pull the wheel radius: the radius
comes from the wall's gaps and the ultrasonic sensor). The residuals: every gyroscope reading
against the path's yaw rate; every infrared reading of the wall phases and of the rests before
them against the simulator's curve at the path's distance (the floor's value where nothing is
in range); the front ultrasonic sensor near the wall; the measured final gap. Each is weighted
by its channel's expected noise (:mod:`~khepera_gym.robot.calibrate.noise`), outliers are set aside,
and the uncertainties have a statistical and a systematic part (:mod:`~khepera_gym.robot.calibrate.
uncertainty`).

Units: SI for the values; counts, raw, cm and m for the residuals. Threading: the calling
thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym.robot.calibrate.ir_curve as ic
import khepera_gym.robot.calibrate.replay as rp
from khepera_gym.robot.calibrate.geometry_result import GeometryResult, build_result
from khepera_gym.robot.calibrate.goodness import OUTLIER_SHARE
from khepera_gym.robot.calibrate.logformat import WALL_GAP_NOTE, RobotLog, note
from khepera_gym.robot.calibrate.noise import (
    OUTLIER_SIGMA,
    RESOLUTION,
    Noise,
    expected_sigma,
    robust_noise,
    still_rows,
)
from khepera_gym.robot.calibrate.solver import Progress, solve_scaled
from khepera_gym.robot.calibrate.synthetic import SPREAD
from khepera_gym.robot.calibrate.timing import row_intervals
from khepera_gym.robot.calibrate.uncertainty import blocks, identified, uncertainty

#: The phases whose infrared and ultrasonic readings are fitted: near the wall, where the
#: calibration scene is known (elsewhere the bench is not).
WALL_PHASES = ("wall_approach", "wall_retreat")
#: The user's ruler (m, one standard deviation): each of the two gaps is measured to ±1 mm, so
#: their difference, which the final gap's residual checks, to √2 mm [E].
RULER_SIGMA = math.sqrt(2.0) * 0.001
#: The infrared sensor saturates here (raw): readings whose modelled value is within three
#: noise widths of it are not fitted.
IR_SATURATED = 1023.0
#: The ultrasonic sensors measure 25..200 cm: readings whose modelled distance is three noise
#: widths inside are fitted, every second row (the five sensors take 100 ms, two rows at 50 ms:
#: a reading holds).
US_VALID_CM = (25.0, 200.0)
#: The gyroscope's noise is measured where the robot has been still this long (s).
STILL_S = 0.5
#: The ultrasonic sensors echo from a surface within this angle of facing it (rad, the
#: simulator's ``sensors.us_acceptance``).
US_ACCEPTANCE = math.radians(22.5)
#: The parameters: (name, nominal, scale, lower, upper, prior). The scale sets the optimiser's
#: steps; the prior is the real robots' spread (synthetic.SPREAD): a value whose uncertainty
#: from the logs is not below it is not identified, and keeps its nominal value.
_NAMED = (
    ("wheel_radius", rp.NOMINAL_WHEEL_RADIUS, 2e-4, 0.015, 0.03, 0.021 * SPREAD["wheel_radius"]),
    ("axle_length", 0.1054, 1e-3, 0.08, 0.13, 0.1054 * SPREAD["axle_length"]),
    ("gyro_bias", 0.0, 0.5, -50.0, 50.0, 1.5),
    ("us_offset", 0.0, 0.01, -0.2, 0.2, 0.02),
    ("ir_floor_value", 100.0, 5.0, 0.0, 1023.0, 50.0),
)
#: The curve's points: scale and bounds (raw); prior: 15 % of K-Team's value (SPREAD's gain).
_POINT_SCALE = 10.0
NAMES = [n[0] for n in _NAMED] + [f"ir_curve_{int(mm)}mm" for mm in rp.IR_CURVE_MM]
_FIRST_POINT = len(_NAMED)


@dataclasses.dataclass
class _LogData:
    """What one calibration log contributes to stage 1."""

    log: RobotLog
    scene: dict[str, Any]
    wall_distance: float
    wall_rows: npt.NDArray[np.bool_]
    #: Rows whose infrared readings are fitted: the wall phases and the rests before the spin.
    ir_rows: npt.NDArray[np.bool_]
    gap_row: int | None
    gap: float | None
    blocks: npt.NDArray[np.int64]


@dataclasses.dataclass
class _Selection:
    """Per log, which readings the residuals hold and their expected noise (fixed during a
    solve, so that the residual vector keeps its length and weights)."""

    gyro: npt.NDArray[np.bool_]
    gyro_sigma: npt.NDArray[np.float64]
    ir: npt.NDArray[np.bool_]
    ir_sigma: npt.NDArray[np.float64]
    us: npt.NDArray[np.bool_]
    us_sigma: npt.NDArray[np.float64]
    gap: bool


class GeometryFit:
    """Stage 1 on the calibration logs."""

    def __init__(self, logs: Sequence[RobotLog], progress: Progress) -> None:
        self.data = []
        offset = 0
        for log in logs:
            self.data.append(self._log_data(log, offset))
            offset = int(self.data[-1].blocks.max()) + 1
        self.progress = progress
        self._cache: dict[tuple[float, float], list[tuple[rp.PathReplay, Any]]] = {}
        self.nominal = np.array([n[1] for n in _NAMED] + list(rp.KTEAM_IR_CURVE))
        self.scale = np.array([n[2] for n in _NAMED] + [_POINT_SCALE] * 16)
        self.lower = np.array([n[3] for n in _NAMED] + [0.0] * 16)
        self.upper = np.array([n[4] for n in _NAMED] + [ic.IR_MAX] * 16)
        prior = [n[5] for n in _NAMED] + list(0.15 * rp.KTEAM_IR_CURVE)
        self.prior = np.array(prior) / self.scale
        #: Which parameters are fitted (the curve's points the logs see), and which are held
        #: at their nominal value by the real robots' spread (not identified).
        self.free = np.ones(len(NAMES), dtype=bool)
        self.pinned = np.zeros(len(NAMES), dtype=bool)
        self.noise: dict[str, tuple[Noise, float]] = {}
        self.names = NAMES
        self.first_point = _FIRST_POINT
        #: The parameters that reached a bound of the search in any solve.
        self.bounded = np.zeros(len(NAMES), dtype=bool)
        #: The channels the residuals hold (a stage's).
        self.in_use: tuple[str, ...] = ("gyro", "ir", "us", "gap")

    @staticmethod
    def _log_data(log: RobotLog, offset: int) -> _LogData:
        wall = log.number("wall_distance_m")
        wall_rows = np.isin(log.phases, WALL_PHASES)
        before_spin = np.cumsum(log.phases == "spin") == 0
        gap_text = note(log, WALL_GAP_NOTE)
        gap, gap_row = None, None
        if gap_text is not None and gap_text.lower() != "nan":
            gap = float(gap_text)
            gap_row = int([n.after for n in log.notes if n.key == WALL_GAP_NOTE][-1])
        return _LogData(
            log,
            rp.calibration_scene(wall),
            wall,
            wall_rows,
            wall_rows | (before_spin & (log.phases == "rest")),
            gap_row,
            gap,
            blocks(log, offset),
        )

    def paths(self, radius: float, axle: float) -> list[tuple[rp.PathReplay, Any]]:
        """Per log: the path replay for this geometry and its infrared distances (cached)."""
        key = (round(radius, 12), round(axle, 12))
        if key not in self._cache:
            found = []
            for d in self.data:
                path = rp.odometry_replay(d.log, d.scene, radius, axle)
                found.append((path, rp.wall_ir_distances(path.poses, d.wall_distance)))
            self._cache[key] = found
            self.progress.replayed()
        return self._cache[key]

    # -- the residuals ----------------------------------------------------------------------

    def _curve(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        return np.append(x[_FIRST_POINT:], x[4])

    def _channels(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> dict[str, tuple[list[Any], list[Any], list[Any]]]:
        """Per channel: (residuals, expected noise, block labels), per log."""
        radius, axle, bias, offset = (float(v) for v in x[:4])
        out: dict[str, tuple[list[Any], list[Any], list[Any]]] = {
            k: ([], [], []) for k in ("gyro", "ir", "us", "gap")
        }
        curve = self._curve(x)
        for data, (path, distances), chosen in zip(
            self.data, self.paths(radius, axle), selections, strict=True
        ):
            log = data.log
            gyro = log.gyro_z - path.gyro_z - bias / rp.GYRO_DEG_S_PER_COUNT
            self._add(out["gyro"], gyro[chosen.gyro], chosen.gyro_sigma, data.blocks[chosen.gyro])
            rows, sensors = np.nonzero(chosen.ir)
            model = ic.curve_basis(distances[rows, sensors]) @ curve
            self._add(out["ir"], log.ir[rows, sensors] - model, chosen.ir_sigma, data.blocks[rows])
            distance = rp.wall_ray_distance(path.poses[chosen.us], data.wall_distance)
            us = log.us[chosen.us, 2] - 100.0 * (distance + offset)
            self._add(out["us"], np.nan_to_num(us), chosen.us_sigma, data.blocks[chosen.us])
            if chosen.gap:
                row = data.gap_row
                modelled = rp.wall_ray_distance(path.poses[row : row + 1], data.wall_distance)
                self._add(out["gap"], np.nan_to_num(modelled - data.gap), [RULER_SIGMA], [-1])
        return out

    @staticmethod
    def _add(channel: tuple[list[Any], list[Any], list[Any]], r: Any, s: Any, b: Any) -> None:
        channel[0].append(np.asarray(r, float))
        channel[1].append(np.asarray(s, float))
        channel[2].append(np.asarray(b))

    def residuals(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
        """Every channel's residuals over their expected noise, one vector, with block labels
        (the gap's own, the priors' their own)."""
        parts, labels = [], []
        for name, (r, s, b) in self._channels(x, selections).items():
            if not r or name not in self.in_use:
                continue
            parts.append(np.concatenate(r) / np.concatenate(s))
            label = np.concatenate(b).astype(np.int64)
            if name == "gap":
                label = -1 - np.arange(len(label))
            labels.append(label)
        for i in np.nonzero(self.pinned & self.free)[0]:
            parts.append(np.array([(x[i] - self.nominal[i]) / (self.prior[i] * self.scale[i])]))
            labels.append(np.array([-1000 - i]))
        return np.concatenate(parts), np.concatenate(labels)

    # -- the fit ----------------------------------------------------------------------------

    def fit(self) -> GeometryResult:
        x = self.nominal.copy()
        x[0] = self._radius_start()
        noise = self._measure_noise(x)
        x[2] = noise["gyro"][1]
        x[4] = noise["ir"][1]
        selections = self._select(x, noise)
        x[_FIRST_POINT:] = self._curve_start(x, selections)
        # 1. The geometry, from the gyroscope, the ultrasonic sensor and the measured gap: the
        # infrared curve, whose shape is free, takes no part (a shape it cannot hold would pull
        # the wheel radius).
        geometry = np.zeros(len(x), dtype=bool)
        geometry[:4] = True
        x, selections, outliers = self._stage(x, selections, geometry, ("gyro", "us", "gap"))
        jac = self._jacobian(x, selections)
        weighted, labels = self.residuals(x, selections)
        spread = {"geometry": uncertainty(jac, weighted, labels)}
        # 2. The infrared curve and floor along the path of the fitted geometry (re-selected
        # there), each point seen by some reading free; those seen too little to be fitted
        # alone are held along K-Team's shape within the real robots' spread.
        selections = self._select(x, noise, selections)
        seen = self._points_seen(x, selections)
        fitted = seen >= ic.MIN_READINGS
        x[_FIRST_POINT:] = ic.extend_curve(self._curve_start(x, selections), fitted)
        self.nominal[_FIRST_POINT:] = x[_FIRST_POINT:]
        curve = np.zeros(len(x), dtype=bool)
        curve[4] = True
        curve[_FIRST_POINT:] = seen > 0
        self.pinned[_FIRST_POINT:] = curve[_FIRST_POINT:] & ~fitted
        x, selections, ir_outliers = self._stage(x, selections, curve, ("ir",))
        outliers.update(ir_outliers)
        jac = self._jacobian(x, selections)
        weighted, labels = self.residuals(x, selections)
        spread["curve"] = uncertainty(jac, weighted, labels)
        self.curve_radius_slope = self._curve_slope(x, selections)
        self.stages = {"geometry": geometry, "curve": curve}
        self.free = geometry | curve
        self.in_use = ("gyro", "ir", "us", "gap")
        return build_result(self, x, selections, spread, outliers)

    def _stage(
        self,
        x: npt.NDArray[np.float64],
        selections: list[_Selection],
        free: npt.NDArray[np.bool_],
        channels: tuple[str, ...],
    ) -> tuple[npt.NDArray[np.float64], list[_Selection], dict[str, int]]:
        """One stage: the ``free`` parameters fitted to ``channels``, outliers set aside and
        the fit made again, then the values the logs cannot tell held by the spread."""
        self.free = free.copy()
        self.in_use = channels
        x = self._solve(x, selections)
        selections, outliers = self._drop_outliers(x, selections, channels)
        x = self._solve(x, selections)
        for _ in range(3):
            # Held values move the others: what they leave unidentified is held in turn.
            unknown = self._unidentified(x, selections)
            if not unknown.any():
                break
            self.pinned |= unknown
            points = x[_FIRST_POINT:]
            kept = self.free[_FIRST_POINT:] & ~self.pinned[_FIRST_POINT:]
            nominal = self.nominal.copy()
            nominal[_FIRST_POINT:] = ic.extend_curve(points, kept)
            self.nominal = np.where(unknown, nominal, self.nominal)
            x = np.where(unknown, self.nominal, x)
            x = self._solve(x, selections)
        return x, selections, outliers

    def _curve_slope(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> npt.NDArray[np.float64]:
        """How the fitted curve and floor move with the wheel radius (raw a metre): the curve
        is read at the distances the radius gives, so its uncertainty carries the radius's."""
        step = 2e-5
        moved = x.copy()
        moved[0] += step
        saved = self.free.copy()
        shifted = self._solve(moved, selections)
        self.free = saved
        return (shifted - x) / step

    def _unidentified(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> npt.NDArray[np.bool_]:
        """The free parameters, not yet held, whose uncertainty from the readings alone (the
        held ones' spread left out) is not below the real robots' spread."""
        jac = self._jacobian(x, selections)
        readings = jac[: len(jac) - int((self.pinned & self.free).sum())]
        free = np.nonzero(self.free)[0]
        known = identified(readings, np.where(self.pinned[free], np.inf, self.prior[free]))
        unknown = np.zeros(len(x), dtype=bool)
        unknown[free] = ~known & ~self.pinned[free]
        # A point of the curve at 1023 (or 0) is saturated: the readings ask for more than the
        # sensor gives, and its uncertainty means nothing.
        points = np.zeros(len(x), dtype=bool)
        points[self.first_point :] = True
        unknown |= points & self._at_bounds(x)
        return unknown

    def _jacobian(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> npt.NDArray[np.float64]:
        """(m, free) of the weighted residuals, in units of each parameter's scale."""
        base = self.residuals(x, selections)[0]
        columns = []
        for i in np.nonzero(self.free)[0]:
            step = 0.1 * self.scale[i]
            moved = x.copy()
            moved[i] += step if x[i] + step <= self.upper[i] else -step
            columns.append(
                (self.residuals(moved, selections)[0] - base) / ((moved[i] - x[i]) / self.scale[i])
            )
        return np.stack(columns, axis=1)

    def _solve(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> npt.NDArray[np.float64]:
        """The free parameters fitted; those held keep their nominal value (their spread
        enters the uncertainty through the Jacobian's prior rows)."""
        free = np.nonzero(self.free & ~self.pinned)[0]
        x = np.where(self.pinned, self.nominal, x)
        self.bounded |= self._at_bounds(x)
        start = x.copy()
        scale = self.scale[free]

        def fun(z: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
            trial = start.copy()
            trial[free] = start[free] + z * scale
            return self.residuals(trial, selections)[0]

        result = solve_scaled(
            fun,
            np.zeros(len(free)),
            (self.lower[free] - start[free]) / scale,
            (self.upper[free] - start[free]) / scale,
        )
        self.progress.replayed(float(2 * result.cost))
        out = start.copy()
        out[free] = start[free] + result.x * scale
        self.bounded |= self._at_bounds(out)
        return out

    def _at_bounds(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
        """The free parameters at a bound of the search (a thousandth of their scale)."""
        near = (x - self.lower < 1e-3 * self.scale) | (self.upper - x < 1e-3 * self.scale)
        return near & self.free & ~self.pinned

    # -- the start, the noise, the selection ------------------------------------------------

    def _radius_start(self) -> float:
        """Where the wheel radius's fit starts: from the measured gaps (the wall's distance less
        the final gap over the pulses travelled straight), else from the front ultrasonic
        sensor's slope against the pulses, else the nominal 21 mm."""
        estimates = []
        for data in self.data:
            pulses = data.log.encoders.mean(axis=1)
            if data.gap is not None and data.gap_row is not None:
                travelled = (pulses[data.gap_row] - pulses[0]) * rp.metres_per_pulse(1.0)
                if travelled > 0.05:
                    estimates.append((data.wall_distance - data.gap) / travelled)
                    continue
            us = data.log.us[:, 2]
            rows = (data.log.phases == "wall_approach") & (us > 25) & (us < 200)
            if rows.sum() > 10 and np.ptp(pulses[rows]) > 0:
                slope = np.polyfit(pulses[rows] * rp.metres_per_pulse(1.0), us[rows], 1)[0]
                estimates.append(-slope / 100.0)
        radius = float(np.median(estimates)) if estimates else rp.NOMINAL_WHEEL_RADIUS
        return float(np.clip(radius, 0.018, 0.024))

    def _measure_noise(self, x: npt.NDArray[np.float64]) -> dict[str, tuple[Noise, float]]:
        """Per channel: its noise where nothing changes, and the level there (the gyroscope's
        bias in °/s, the infrared floor value)."""
        gyro, ir, us, us_groups = [], [], [], []
        for data, (_, distances) in zip(self.data, self.paths(x[0], x[1]), strict=True):
            log = data.log
            still = still_rows(log.commands, log.encoders, max(1, round(STILL_S / log.period)))
            gyro.append(log.gyro_z[still])
            far = ~np.isfinite(distances) & data.ir_rows[:, None]
            ir.append(log.ir[far])
            even = np.arange(len(log)) % 2 == 0
            rest = (log.phases == "rest") & even & (log.us[:, 2] > 0) & (log.us[:, 2] < 1000)
            us.append(log.us[rest, 2])
            us_groups.append(data.blocks[rest])
        found: dict[str, tuple[Noise, float]] = {}
        # One level for every still row: the bias does not change (a level per rest would
        # take off more than its share of variance, consecutive rows sharing samples).
        noise, outliers = robust_noise(np.concatenate(gyro), None, "the gyroscope, robot still")
        level = float(np.mean(np.concatenate(gyro)[~outliers])) if noise.count else 0.0
        found["gyro"] = (noise, level * rp.GYRO_DEG_S_PER_COUNT)
        readings = np.concatenate(ir)
        noise, outliers = robust_noise(readings, None, "the infrared sensors seeing nothing")
        floor = float(np.mean(readings[~outliers])) if noise.count else 100.0
        found["ir"] = (noise, floor)
        noise, _ = robust_noise(
            np.concatenate(us), np.concatenate(us_groups), "the front ultrasonic sensor at rest"
        )
        found["us"] = (noise, math.nan)
        self.noise = found
        return found

    def _fallback(self, channel: str, default: float) -> float:
        noise = self.noise[channel][0]
        if math.isfinite(noise.sigma) and noise.count >= 5:
            return max(noise.sigma, RESOLUTION)
        return default

    def _select(
        self,
        x: npt.NDArray[np.float64],
        noise: dict[str, tuple[Noise, float]],
        previous: list[_Selection] | None = None,
    ) -> list[_Selection]:
        """Which readings the residuals hold at ``x``, and their expected noise: its level
        where nothing changes plus the change over the sensor's own period. With ``previous``,
        only the infrared readings are chosen again."""
        sigma_gyro = self._fallback("gyro", 3.0)
        sigma_ir = self._fallback("ir", 10.0)
        sigma_us = self._fallback("us", 1.0)
        curve = self._curve(x)
        chosen = []
        for data, (path, distances) in zip(self.data, self.paths(x[0], x[1]), strict=True):
            log = data.log
            interval = row_intervals(log)
            gyro = np.arange(len(log)) > 0
            rate = np.gradient(path.gyro_z) / interval
            model = (ic.curve_basis(distances.ravel()) @ curve).reshape(distances.shape)
            near = np.isfinite(distances) & data.wall_rows[:, None]
            far = ~np.isfinite(distances) & data.ir_rows[:, None]
            ir = (near | far) & (model < IR_SATURATED - 3.0 * sigma_ir)
            ir_rate = np.gradient(model, axis=0) / interval[:, None]
            ray = rp.wall_ray_distance(path.poses, data.wall_distance)
            facing = np.abs(np.angle(np.exp(1j * path.poses[:, 2]))) < US_ACCEPTANCE
            even = np.arange(len(log)) % 2 == 0
            margin = 3.0 * sigma_us / 100.0
            modelled = ray + x[3]
            us_reading = log.us[:, 2]
            us = (
                data.wall_rows
                & even
                & facing
                & np.isfinite(ray)
                & (modelled > US_VALID_CM[0] / 100.0 + margin)
                & (modelled < US_VALID_CM[1] / 100.0 - margin)
                & (us_reading > 0)
                & (us_reading < 1000)
            )
            us_rate = 100.0 * np.gradient(np.nan_to_num(ray)) / interval
            gap = data.gap is not None and bool(
                np.isfinite(ray[data.gap_row]) if data.gap_row is not None else False
            )
            if previous is not None:
                kept = previous[len(chosen)]
                chosen.append(
                    dataclasses.replace(
                        kept, ir=ir, ir_sigma=expected_sigma(sigma_ir, ir_rate[ir], "ir")
                    )
                )
                continue
            chosen.append(
                _Selection(
                    gyro=gyro,
                    gyro_sigma=expected_sigma(
                        sigma_gyro, rate[gyro], "gyro", path.gyro_z[gyro], interval[gyro]
                    ),
                    ir=ir,
                    ir_sigma=expected_sigma(sigma_ir, ir_rate[ir], "ir"),
                    us=us,
                    us_sigma=expected_sigma(sigma_us, us_rate[us], "us"),
                    gap=gap,
                )
            )
        return chosen

    def _ir_design(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(basis, readings, expected noise) of every selected infrared reading at ``x``."""
        bases, readings, sigmas = [], [], []
        for data, (_, distances), chosen in zip(
            self.data, self.paths(x[0], x[1]), selections, strict=True
        ):
            rows, sensors = np.nonzero(chosen.ir)
            bases.append(ic.curve_basis(distances[rows, sensors]))
            readings.append(data.log.ir[rows, sensors])
            sigmas.append(chosen.ir_sigma)
        return np.concatenate(bases), np.concatenate(readings), np.concatenate(sigmas)

    def _points_seen(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> npt.NDArray[np.float64]:
        return ic.points_seen(self._ir_design(x, selections)[0])

    def _curve_start(
        self, x: npt.NDArray[np.float64], selections: list[_Selection]
    ) -> npt.NDArray[np.float64]:
        """The curve's points that fit the readings best along the starting path (the model
        is linear in them), the floor value held; K-Team's where nothing is seen."""
        basis, readings, sigma = self._ir_design(x, selections)
        seen = ic.points_seen(basis) >= ic.MIN_READINGS
        points = rp.KTEAM_IR_CURVE.copy()
        if seen.any():
            target = (readings - basis[:, -1] * x[4]) / sigma
            design = basis[:, :-1][:, seen] / sigma[:, None]
            points[seen] = np.linalg.lstsq(design, target, rcond=None)[0]
        return ic.extend_curve(np.clip(points, 0.0, ic.IR_MAX), seen)

    def _drop_outliers(
        self, x: npt.NDArray[np.float64], selections: list[_Selection], channels: Sequence[str]
    ) -> tuple[list[_Selection], dict[str, int]]:
        """The selections without the readings of ``channels`` beyond :data:`OUTLIER_SIGMA`
        expected widths, and their count per channel."""
        found = self._channels(x, selections)
        counts = {name: 0 for name in ("gyro", "ir", "us") if name in channels}
        out = []
        for k, chosen in enumerate(selections):
            fields = dataclasses.asdict(chosen)
            for name in counts:
                residual, sigma, _ = (part[k] for part in found[name])
                bad = np.abs(residual) > OUTLIER_SIGMA * sigma
                if bad.sum() > OUTLIER_SHARE * len(bad):
                    # Too many to be spikes: the model (or the sensor) is wrong, which the
                    # goodness of fit must see; they stay.
                    bad[:] = False
                counts[name] += int(bad.sum())
                mask = fields[name].copy()
                where = np.nonzero(mask)
                mask[tuple(w[bad] for w in where)] = False
                fields[name] = mask
                fields[f"{name}_sigma"] = fields[f"{name}_sigma"][~bad]
            out.append(_Selection(**fields))
        return out, counts


__all__ = [
    "IR_SATURATED",
    "NAMES",
    "RULER_SIGMA",
    "US_VALID_CM",
    "WALL_PHASES",
    "GeometryFit",
    "GeometryResult",
]
