"""Stage 1 of the calibration fit: the geometry and the sensors, along the path the encoders
measured (:class:`GeometryFit`; see :mod:`~khepera_gym.calibrate.fit` for the method).

Units: SI for the values; counts and cm for the residuals. Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym.calibrate.replay as rp
from khepera_gym.calibrate.logformat import WALL_GAP_NOTE, RobotLog, note
from khepera_gym.calibrate.solver import (
    Estimate,
    Progress,
    fit_covariance,
    residual_noise,
    solve_scaled,
)
from khepera_gym.calibrate.synthetic import ir_curve

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
#: The infrared noise is measured where the curve is flat (less than this many counts a mm),
#: so that the replay's distance rounding (0.25 mm) does not add to it.
IR_FLAT_SLOPE = 3.0


# --------------------------------------------------------------------------------------------
# Stage 1: the geometry and the sensors, along the encoders' path.


@dataclasses.dataclass
class _WallData:
    """What one calibration log contributes to stage 1."""

    log: RobotLog
    scene: dict[str, Any]
    wall_distance: float
    wall_rows: npt.NDArray[np.bool_]
    gap_row: int | None
    gap: float | None


@dataclasses.dataclass
class GeometryResult:
    """Stage 1's values (SI) with their uncertainties and what the report draws."""

    wheel_radius: Estimate
    axle_length: Estimate
    gyro_bias: Estimate
    gyro_noise_sigma: Estimate
    us_offset: Estimate
    us_noise_sigma: Estimate
    ir_gain: Estimate
    ir_scale: Estimate
    ir_floor_value: Estimate
    ir_noise_sigma: Estimate
    ir_curve: Estimate
    #: Per log: the path replay at the fitted geometry.
    paths: list[rp.PathReplay]
    #: Per channel: (residuals in its units, the reduced chi-square of the final fit).
    residuals: dict[str, npt.NDArray[np.float64]]
    chi2: float


#: Stage 1's parameters: (name, start, scale) — the scale is the real robots' spread, which sets
#: the optimiser's steps (least_squares works on value / scale).
_GEOMETRY = (
    ("wheel_radius", rp.NOMINAL_WHEEL_RADIUS, 0.0002),
    ("axle_length", 0.1054, 0.001),
    ("gyro_bias", 0.0, 0.5),
    ("us_offset", 0.0, 0.01),
    ("ir_gain", 1.0, 0.1),
    ("ir_scale", 1.0, 0.05),
    ("ir_floor_value", 100.0, 5.0),
)


class GeometryFit:
    """Stage 1 on the calibration logs."""

    def __init__(self, logs: Sequence[RobotLog], progress: Progress) -> None:
        self.data = [self._wall_data(log) for log in logs]
        self.progress = progress
        self._cache: dict[tuple[float, float], list[rp.PathReplay]] = {}
        self.sigma = {"gyro": 3.0, "ir": 10.0, "us": 1.0}

    @staticmethod
    def _wall_data(log: RobotLog) -> _WallData:
        wall = log.number("wall_distance_m")
        wall_rows = np.isin(log.phases, WALL_PHASES)
        gap_text = note(log, WALL_GAP_NOTE)
        gap = None
        gap_row = None
        if gap_text is not None and gap_text.lower() != "nan":
            gap = float(gap_text)
            after = [n.after for n in log.notes if n.key == WALL_GAP_NOTE][-1]
            gap_row = int(after)
        return _WallData(log, rp.calibration_scene(wall), wall, wall_rows, gap_row, gap)

    def paths(self, wheel_radius: float, axle_length: float) -> list[rp.PathReplay]:
        """The logs' path replays for this geometry (cached)."""
        key = (round(wheel_radius, 12), round(axle_length, 12))
        if key not in self._cache:
            self._cache[key] = [
                rp.odometry_replay(d.log, d.scene, wheel_radius, axle_length) for d in self.data
            ]
            self.progress.replayed()
        return self._cache[key]

    def selection(self, x: npt.NDArray[np.float64]) -> list[dict[str, Any]]:
        """Which readings each log's residuals hold at ``x``: the unsaturated infrared readings
        of the wall phases and the ultrasonic ones within range; kept fixed while a fit runs,
        so that the residual vector keeps its length."""
        radius, axle, _, offset, gain, scale, floor = (float(v) for v in x)
        curve = ir_curve(gain, scale)
        chosen = []
        for data, path in zip(self.data, self.paths(radius, axle), strict=True):
            log, rows = data.log, data.wall_rows
            distances = rp.wall_ir_distances(path.poses[rows], data.wall_distance)
            model = rp.ir_curve_mean(distances, curve, floor)
            # Chosen by the model alone: dropping the readings that came out high would bias
            # the curve down near saturation.
            ir = model < IR_SATURATED - 3.0 * self.sigma["ir"]
            us = log.us[:, 2]
            distance = rp.wall_ray_distance(path.poses, data.wall_distance)
            facing = np.abs(np.angle(np.exp(1j * path.poses[:, 2]))) < US_ACCEPTANCE
            even = np.arange(len(log)) % 2 == 0
            # Chosen by the modelled distance (three noise widths inside the measurable range),
            # and among those the readings that are distances (not codes).
            margin = 3.0 * self.sigma["us"] / 100.0
            modelled = distance + offset
            us_rows = (
                rows
                & even
                & facing
                & np.isfinite(distance)
                & (modelled > US_VALID_CM[0] / 100.0 + margin)
                & (modelled < US_VALID_CM[1] / 100.0 - margin)
                & (us > 0)
                & (us < 1000)
            )
            gap = data.gap is not None and bool(
                np.isfinite(
                    rp.wall_ray_distance(
                        path.poses[data.gap_row : data.gap_row + 1], data.wall_distance
                    )[0]
                )
            )
            chosen.append({"ir": ir, "us": us_rows, "gap": gap})
        return chosen

    def channels(
        self, x: npt.NDArray[np.float64], selection: list[dict[str, Any]]
    ) -> dict[str, npt.NDArray[np.float64]]:
        """Unweighted residuals of each channel (gyro counts, IR counts, US cm, gap m) of the
        readings ``selection`` holds."""
        radius, axle, bias, offset, gain, scale, floor = (float(v) for v in x)
        curve = ir_curve(gain, scale)
        out: dict[str, list[npt.NDArray[np.float64]]] = {"gyro": [], "ir": [], "us": [], "gap": []}
        paths = self.paths(radius, axle)
        for data, path, chosen in zip(self.data, paths, selection, strict=True):
            log = data.log
            out["gyro"].append(log.gyro_z[1:] - path.gyro_z[1:] - bias / rp.GYRO_DEG_S_PER_COUNT)
            rows = data.wall_rows
            distances = rp.wall_ir_distances(path.poses[rows], data.wall_distance)
            model = rp.ir_curve_mean(distances, curve, floor)
            out["ir"].append((log.ir[rows] - model)[chosen["ir"]])
            us_rows = chosen["us"]
            distance = rp.wall_ray_distance(path.poses[us_rows], data.wall_distance)
            out["us"].append(log.us[us_rows, 2] - 100.0 * (distance + offset))
            if chosen["gap"]:
                modelled = rp.wall_ray_distance(
                    path.poses[data.gap_row : data.gap_row + 1], data.wall_distance
                )
                out["gap"].append(modelled - data.gap)
        # A reading whose ray no longer meets the wall at a far-off trial point counts 0.
        return {k: np.nan_to_num(np.concatenate(v)) if v else np.zeros(0) for k, v in out.items()}

    def residuals(
        self, x: npt.NDArray[np.float64], selection: list[dict[str, Any]]
    ) -> npt.NDArray[np.float64]:
        """The weighted residuals of every channel, one vector."""
        channels = self.channels(x, selection)
        return np.concatenate(
            [
                channels["gyro"] / self.sigma["gyro"],
                channels["ir"] / self.sigma["ir"],
                channels["us"] / self.sigma["us"],
                channels["gap"] / RULER_SIGMA,
            ]
        )

    def fit(self) -> GeometryResult:
        names = [p[0] for p in _GEOMETRY]
        start = np.array([p[1] for p in _GEOMETRY])
        scale = np.array([p[2] for p in _GEOMETRY])
        # The gyroscope's bias starts at its mean at rest (the logs start with a rest).
        rest = [d.log.gyro_z[d.log.phases == "rest"] for d in self.data]
        start[2] = float(np.mean(np.concatenate(rest))) * rp.GYRO_DEG_S_PER_COUNT
        start[0] = self._radius_start()
        start[4:7] = self._ir_start(start)
        lower = np.array([0.015, 0.08, -50.0, -0.2, 0.3, 0.6, 0.0])
        upper = np.array([0.03, 0.13, 50.0, 0.2, 2.0, 1.6, 1023.0])
        x = start
        for _ in range(2):
            chosen = self.selection(x)
            result = solve_scaled(
                lambda z, chosen=chosen: self.residuals(start + z * scale, chosen),
                (x - start) / scale,
                (lower - start) / scale,
                (upper - start) / scale,
            )
            x = start + result.x * scale
            self.progress.replayed(float(2 * result.cost))
            channels = self.channels(x, chosen)
            self.sigma["gyro"] = max(float(np.std(channels["gyro"])), 0.3)
            self.sigma["ir"] = max(float(np.std(channels["ir"])), 1.0)
            self.sigma["us"] = max(float(np.std(channels["us"])), 0.3)
        result_jac = result.jac
        covariance, s2 = fit_covariance(result_jac, result.fun)
        sigma = np.sqrt(np.diag(covariance)) * scale
        values = dict(zip(names, x, strict=True))
        errors = dict(zip(names, sigma, strict=True))
        channels = self.channels(x, chosen)
        paths = self.paths(values["wheel_radius"], values["axle_length"])
        gaps = sum(d.gap is not None for d in self.data)
        radius_how = (
            f"the wall's gaps ({gaps} measured) and the ultrasonic and infrared readings against "
            "the encoders' travel"
            if gaps
            else "the ultrasonic and infrared readings against the encoders' travel (the final "
            "gap was not measured)"
        )
        # At rest the replay reads exactly 0: only the simulator's own rounding is taken off.
        gyro_noise = residual_noise(self._still_gyro(x), 1.0 / 12.0)
        us_noise = residual_noise(channels["us"], 1.0 / 12.0)
        flat = self._flat_ir(x, paths)
        ir_noise = residual_noise(flat, 1.0 / 12.0)
        curve, curve_sigma = self._curve_with_sigma(values, covariance, scale)
        count = rp.GYRO_DEG_S_PER_COUNT
        return GeometryResult(
            wheel_radius=Estimate(
                "robot.wheel_radius",
                values["wheel_radius"],
                errors["wheel_radius"],
                "m",
                radius_how,
            ),
            axle_length=Estimate(
                "robot.axle_length",
                values["axle_length"],
                errors["axle_length"],
                "m",
                "the gyroscope's yaw rate against the encoders' (spin and turns)",
            ),
            gyro_bias=Estimate(
                "sensors.gyro_bias",
                values["gyro_bias"],
                errors["gyro_bias"],
                "°/s",
                "the gyroscope against the encoders' yaw rate, every row",
            ),
            gyro_noise_sigma=Estimate(
                "sensors.gyro_noise_sigma",
                gyro_noise[0] * count,
                gyro_noise[1] * count,
                "°/s",
                "the gyroscope at rest (less the rounding to counts)",
            ),
            us_offset=Estimate(
                "sensors.us_offset",
                values["us_offset"],
                errors["us_offset"],
                "m",
                "the front ultrasonic sensor against the wall's distance by the encoders",
            ),
            us_noise_sigma=Estimate(
                "sensors.us_noise_sigma",
                us_noise[0] / 100.0,
                us_noise[1] / 100.0,
                "m",
                "the front ultrasonic sensor's residuals (less the rounding to cm)",
            ),
            ir_gain=Estimate(
                "ir_gain",
                values["ir_gain"],
                errors["ir_gain"],
                "",
                "the infrared ring near the wall: its curve's value against K-Team's",
            ),
            ir_scale=Estimate(
                "ir_scale",
                values["ir_scale"],
                errors["ir_scale"],
                "",
                "the infrared ring near the wall: its curve's distances against K-Team's",
            ),
            ir_floor_value=Estimate(
                "sensors.ir_floor_value",
                values["ir_floor_value"],
                errors["ir_floor_value"],
                "raw",
                "the infrared readings with nothing within 0.25 m",
            ),
            ir_noise_sigma=Estimate(
                "sensors.ir_noise_sigma",
                ir_noise[0],
                ir_noise[1],
                "raw",
                f"the infrared residuals where the curve is flat (< {IR_FLAT_SLOPE:g} a mm)",
            ),
            ir_curve=Estimate(
                "sensors.ir_curve",
                curve,
                curve_sigma,
                "raw",
                "K-Team's curve times the gain, its distances times the scale",
            ),
            paths=paths,
            residuals={
                "gyro": channels["gyro"] * count,
                "ir": channels["ir"],
                "us": channels["us"] / 100.0,
                "gap": channels["gap"],
            },
            chi2=s2,
        )

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
            rows = (
                (data.log.phases == "wall_approach")
                & (data.log.us[:, 2] > 25)
                & (data.log.us[:, 2] < 200)
            )
            if rows.sum() > 10:
                slope = np.polyfit(
                    pulses[rows] * rp.metres_per_pulse(1.0), data.log.us[rows, 2], 1
                )[0]
                estimates.append(-slope / 100.0)
        radius = float(np.median(estimates)) if estimates else rp.NOMINAL_WHEEL_RADIUS
        return float(np.clip(radius, 0.018, 0.024))

    def _ir_start(self, x: npt.NDArray[np.float64]) -> tuple[float, float, float]:
        """Where the infrared curve's fit starts: the (gain, scale) of a grid with the least
        squared residuals along the nominal path, and the floor value as the median of the
        readings with nothing in range (the gain and the scale trade off near saturation, and a
        start far from both may end in a local minimum)."""
        paths = self.paths(float(x[0]), float(x[1]))
        distances, logged = [], []
        for data, path in zip(self.data, paths, strict=True):
            rows = data.wall_rows
            distances.append(rp.wall_ir_distances(path.poses[rows], data.wall_distance))
            logged.append(data.log.ir[rows])
        distance = np.concatenate(distances)
        reading = np.concatenate(logged)
        far = ~np.isfinite(distance)
        floor = float(np.median(reading[far])) if far.any() else 100.0
        best = (math.inf, 1.0, 1.0)
        for gain in np.arange(0.6, 1.45, 0.05):
            for scale in np.arange(0.7, 1.35, 0.025):
                model = rp.ir_curve_mean(distance, ir_curve(gain, scale), floor)
                keep = model < IR_SATURATED - 30.0
                cost = float(np.sum((reading[keep] - model[keep]) ** 2))
                if cost < best[0]:
                    best = (cost, float(gain), float(scale))
        return best[1], best[2], floor

    def _still_gyro(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Gyroscope readings less the bias (counts) of the rows where the robot has been still
        for :data:`STILL_S` (not counting the log's first rows): the noise alone, without the
        replay's timing in the transients."""
        bias = float(x[2]) / rp.GYRO_DEG_S_PER_COUNT
        found = []
        for data in self.data:
            log = data.log
            moving = np.any(log.commands != 0, axis=1) | np.any(
                np.diff(log.encoders, axis=0, prepend=log.encoders[:1]) != 0, axis=1
            )
            window = max(1, round(STILL_S / log.period))
            recent = np.convolve(moving.astype(float), np.ones(window), mode="full")[: len(log)]
            still = (recent == 0) & (np.arange(len(log)) >= window)
            found.append(log.gyro_z[still] - bias)
        return np.concatenate(found)

    def _flat_ir(self, x: npt.NDArray[np.float64], paths: list[rp.PathReplay]) -> Any:
        """Infrared residuals where the fitted curve is flat, every row and sensor of the
        logs' wall phases and rests before the spin."""
        _, _, _, _, gain, scale, floor = (float(v) for v in x)
        curve = ir_curve(gain, scale)
        found = []
        for data, path in zip(self.data, paths, strict=True):
            before_spin = np.cumsum(data.log.phases == "spin") == 0
            rows = before_spin
            distance = rp.wall_ir_distances(path.poses[rows], data.wall_distance)
            model = rp.ir_curve_mean(distance, curve, floor)
            slope = np.abs(
                rp.ir_curve_mean(distance + 0.0005, curve, floor)
                - rp.ir_curve_mean(distance - 0.0005, curve, floor)
            )
            slope = np.where(np.isfinite(distance), slope, 0.0)
            logged = data.log.ir[rows]
            keep = (slope < IR_FLAT_SLOPE) & (model < IR_SATURATED - 3.0 * self.sigma["ir"])
            found.append((logged - model)[keep])
        return np.concatenate(found) if found else np.zeros(0)

    @staticmethod
    def _curve_with_sigma(
        values: Mapping[str, float], covariance: Any, scale: npt.NDArray[np.float64]
    ) -> tuple[list[float], list[float]]:
        """The fitted curve's 16 points and their uncertainties (through gain and scale)."""
        gain, stretch = values["ir_gain"], values["ir_scale"]
        curve = ir_curve(gain, stretch)
        step_g, step_s = 1e-4, 1e-4
        d_gain = (ir_curve(gain + step_g, stretch) - curve) / step_g
        d_scale = (ir_curve(gain, stretch + step_s) - curve) / step_s
        # covariance is in units of the parameters' scales; rows/cols 4 (gain), 5 (scale).
        sub = covariance[4:6, 4:6] * np.outer(scale[4:6], scale[4:6])
        grads = np.stack([d_gain, d_scale], axis=1)
        variance = np.einsum("ij,jk,ik->i", grads, sub, grads)
        return [float(v) for v in curve], [float(math.sqrt(max(v, 0.0))) for v in variance]


__all__ = [
    "IR_SATURATED",
    "RULER_SIGMA",
    "US_VALID_CM",
    "WALL_PHASES",
    "GeometryFit",
    "GeometryResult",
]
