"""The fit of ``khepera-gym calibrate``: the simulator's parameters that make it replay the
calibration logs as the robot ran them, with their uncertainties.

Two stages, each a nonlinear least-squares problem solved with :func:`scipy.optimize.
least_squares` on residuals that are replays of the logs through the simulator
(:mod:`~khepera_gym.calibrate.replay`), weighted by each channel's noise:

1. **The geometry and the sensors**, from the path the encoders measured
   (:func:`~khepera_gym.calibrate.replay.odometry_replay`): the wheel radius, the axle, the
   gyroscope's bias, the infrared response (K-Team's curve scaled by a gain in value and a factor
   in distance, and the floor value) and the ultrasonic offset. The gyroscope's yaw rate against
   the encoders' gives the axle relative to the wheels; the wall, whose gap at the start the
   user measured, gives the wheel radius: through the gap measured at the end of the approach
   (if given), the ultrasonic sensor and the infrared curve against the distance the encoders
   travelled.
2. **The drive**, from the wheel speeds the robot measured while the simulator is driven by the
   logged commands (:func:`~khepera_gym.calibrate.replay.command_replay`): the motors' lag
   (``robot.motor_time_constant``) and the acceleration of the mode the program set. In profile
   mode the firmware takes whole ``acc_inc`` units: each neighbouring whole value is tried with
   its best lag, and the best one kept (a profile likelihood); in speed mode
   ``motors.speed_accel`` is fitted with the lag.

Each stage is solved twice: first with the simulator's default noise as weights, then with each
channel's noise measured from the first fit's residuals; the noise keys of the scenario
(``gyro_noise_sigma``, ``ir_noise_sigma``, ``us_noise_sigma``) are those measurements, corrected
for the logs' and the simulator's rounding to whole counts. The uncertainty of each value is the
linearised one at the optimum: the covariance ``s² (JᵀJ)⁻¹`` of the weighted residuals'
Jacobian J, with s² their reduced chi-square; for ``acc_inc`` the curvature of the profile.

What is assumed (the sim-to-real page states it too): the wall's gap at the start is exact (a
ruler, ±1 mm), the final gap is measured to ±1 mm per reading, the gyroscope's scale is exact,
the infrared curve has K-Team's shape, the wall is flat, white and the only thing within reach.

Units: SI for every value written; counts, speed units and cm for the residuals.
Threading: the calling thread; a progress bar (tqdm) on standard error.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym.calibrate.replay as rp
from khepera_gym.calibrate.logformat import WALL_GAP_NOTE, RobotLog, note
from khepera_gym.calibrate.synthetic import ir_curve
from khepera_gym.errors import ConfigError

#: The extra that brings the optimiser.
CALIBRATE_EXTRA = "pip install 'khepera-gym[calibrate]'"
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
#: Where the speed mode's fit starts (m/s²): the simulator's estimate (motors.speed_accel).
SPEED_MODE_ACCEL = 2.74
#: The ultrasonic sensors echo from a surface within this angle of facing it (rad, the
#: simulator's ``sensors.us_acceptance``).
US_ACCEPTANCE = math.radians(22.5)
#: The infrared noise is measured where the curve is flat (less than this many counts a mm),
#: so that the replay's distance rounding (0.25 mm) does not add to it.
IR_FLAT_SLOPE = 3.0


def _least_squares() -> Callable[..., Any]:
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
        sigma: Its uncertainty (a list likewise); NaN when the data cannot tell.
        unit: Its unit.
        how: What in the logs determined it.
    """

    key: str
    value: float | list[float]
    sigma: float | list[float]
    unit: str
    how: str


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


def _solve(
    fun: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]],
    z0: npt.NDArray[np.float64],
    lower: npt.NDArray[np.float64],
    upper: npt.NDArray[np.float64],
) -> Any:
    """least_squares (trust region reflective) of scaled parameters within bounds."""
    least_squares = _least_squares()
    objective = _Objective(fun, JACOBIAN_STEP, lower, upper)
    return least_squares(
        objective, z0, jac=objective.jac, bounds=(lower, upper), method="trf", x_scale=1.0
    )


def _covariance(jacobian: npt.NDArray[np.float64], residuals: npt.NDArray[np.float64]) -> Any:
    """s² (JᵀJ)⁻¹ of weighted residuals (pseudo-inverse if singular)."""
    m, n = jacobian.shape
    dof = max(m - n, 1)
    s2 = float(residuals @ residuals) / dof
    return np.linalg.pinv(jacobian.T @ jacobian) * s2, s2


def _noise(residuals: npt.NDArray[np.float64], rounding: float) -> tuple[float, float]:
    """The noise (std) behind residuals that also carry ``rounding`` (a variance in the same
    units², from whole-count readings), with its uncertainty."""
    residuals = residuals[np.isfinite(residuals)]
    if len(residuals) < 3:
        return math.nan, math.nan
    variance = float(np.var(residuals, ddof=1)) - rounding
    sigma = math.sqrt(max(variance, 0.0))
    return sigma, sigma / math.sqrt(2.0 * (len(residuals) - 1))


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
            result = _solve(
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
        covariance, s2 = _covariance(result_jac, result.fun)
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
        gyro_noise = _noise(self._still_gyro(x), 1.0 / 12.0)
        us_noise = _noise(channels["us"], 1.0 / 12.0)
        flat = self._flat_ir(x, paths)
        ir_noise = _noise(flat, 1.0 / 12.0)
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
        result = _solve(
            lambda z: self.channel(accel, _TAU_START + z[0] * _TAU_SCALE) / self.sigma,
            np.zeros(1),
            np.array([(low - _TAU_START) / _TAU_SCALE]),
            np.array([(high - _TAU_START) / _TAU_SCALE]),
        )
        covariance, _ = _covariance(result.jac, result.fun)
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
                result = _solve(
                    lambda z, start=start, scale=scale: (
                        self.channel(*(start + z * scale)) / self.sigma
                    ),
                    np.zeros(2),
                    (np.array([0.05, _TAU_BOUNDS[0]]) - start) / scale,
                    (np.array([20.0, _TAU_BOUNDS[1]]) - start) / scale,
                )
                accel, tau = (float(v) for v in start + result.x * scale)
                chi2 = float(2 * result.cost)
                covariance, _ = _covariance(result.jac, result.fun)
                errors = np.sqrt(np.diag(covariance)) * scale
                accel_sigma, tau_sigma = float(errors[0]), float(errors[1])
            self.progress.replayed(chi2)
            residuals = self.channel(accel, tau)
            self.sigma = max(float(np.std(residuals)), 0.3)
        noise, _ = _noise(residuals, 1.0 / 12.0)
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


# --------------------------------------------------------------------------------------------
# Both stages.


@dataclasses.dataclass
class Calibration:
    """Everything ``khepera-gym calibrate`` found."""

    geometry: GeometryResult
    drive: DriveResult
    logs: list[RobotLog]
    #: The drive the programs set (from the logs' headers).
    motors: dict[str, Any]
    period: float

    def estimates(self) -> list[Estimate]:
        """Every value with a scenario key, in the order the TOML lists them."""
        g, d = self.geometry, self.drive
        return [
            g.wheel_radius,
            g.axle_length,
            d.motor_time_constant,
            d.accel,
            g.gyro_bias,
            g.gyro_noise_sigma,
            g.ir_curve,
            g.ir_floor_value,
            g.ir_noise_sigma,
            g.us_offset,
            g.us_noise_sigma,
        ]


def check_logs(logs: Sequence[RobotLog]) -> None:
    """The logs can be fitted together: calibration logs of one drive and control period.

    Raises:
        ConfigError: Not a calibration log, or logs of different drives or periods.
    """
    if not logs:
        raise ConfigError("calibrate needs at least one log of the calibration program")
    for log in logs:
        if log.program != "calibrate":
            raise ConfigError(
                f"{log.name}: a log of the {log.program} program; calibrate fits logs of the "
                "calibration program (khepera-gym robot-program calibrate); compare a policy's "
                "log with the simulator with khepera-gym replay"
            )
    first = logs[0]
    for log in logs[1:]:
        for key in ("control_period_s", "motors", "acc_inc", "acc_div", "min_speed_acc"):
            same = (
                log.metadata[key] == first.metadata[key]
                if key == "motors"
                else log.number(key) == first.number(key)
            )
            if not same:
                raise ConfigError(
                    f"{log.name}: its {key} ({log.metadata[key]}) differs from {first.name}'s "
                    f"({first.metadata[key]}): fit the logs of one drive and control period "
                    "together"
                )


def calibrate(
    logs: Sequence[RobotLog],
    base: Mapping[str, Any] | None = None,
    *,
    progress: bool = True,
) -> Calibration:
    """Fits the simulator to calibration logs (both stages).

    Args:
        logs: Logs of the calibration program (:func:`~khepera_gym.calibrate.logformat.read_log`).
        base: Scenario overrides of the simulator being calibrated (e.g. ``physics.substeps``);
            the fitted keys replace theirs.
        progress: Show a progress bar on standard error.

    Raises:
        ConfigError: The logs cannot be fitted together (:func:`check_logs`).
        ImportError: scipy is missing (the message names the extra).
    """
    check_logs(logs)
    _least_squares()
    bar = Progress(progress)
    try:
        bar.stage("geometry and sensors")
        geometry = GeometryFit(logs, bar).fit()
        bar.stage("drive")
        drive = DriveFit(logs, float(geometry.wheel_radius.value), base or {}, bar).fit()
    finally:
        bar.close()
    head = logs[0].metadata
    motors = {
        "mode": head["motors"],
        **{k: int(head[k]) for k in ("acc_inc", "acc_div", "min_speed_acc", "min_speed_dec")},
    }
    return Calibration(geometry, drive, list(logs), motors, logs[0].period)


__all__ = [
    "CALIBRATE_EXTRA",
    "Calibration",
    "DriveFit",
    "DriveResult",
    "Estimate",
    "GeometryFit",
    "GeometryResult",
    "Progress",
    "calibrate",
    "check_logs",
]
