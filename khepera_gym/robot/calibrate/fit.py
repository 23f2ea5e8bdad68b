"""The fit of ``khepera-gym calibrate``: the simulator's parameters that make it replay the
calibration logs as the robot ran them, with uncertainties that hold when the simulator is not
the robot, and a verdict that can say the fit failed.

Two stages, each nonlinear least squares (:func:`scipy.optimize.least_squares`) on residuals
that are replays of the logs through the simulator (:mod:`~khepera_gym.robot.calibrate.replay`, on
the logged times, :mod:`~khepera_gym.robot.calibrate.timing`):

1. **The geometry and the sensors** (:mod:`~khepera_gym.robot.calibrate.geometry`), along the path
   the encoders measured (:func:`~khepera_gym.robot.calibrate.replay.odometry_replay`). First the
   wheel radius, the axle, the gyroscope's bias and the ultrasonic offset: the gyroscope's yaw
   rate against the encoders' gives the axle relative to the wheels; the wall, whose gap at the
   start the user measured, gives the wheel radius through the gap measured at the end of the
   approach and the ultrasonic sensor against the distance the encoders travelled. Then the
   infrared curve, each of its 16 points free (:mod:`~khepera_gym.robot.calibrate.ir_curve`), and
   the floor value, read at the distances that geometry gives: a curve of another shape than
   K-Team's cannot pull the radius, and the radius's uncertainty is carried into the curve.
2. **The drive** (:mod:`~khepera_gym.robot.calibrate.drive_fit`), from the wheel speeds the robot
   measured while the simulator is driven by the logged commands
   (:func:`~khepera_gym.robot.calibrate.replay.command_replay`): the simulator's effective lag at
   its step (``robot.motor_time_constant``) and, in speed mode, ``motors.speed_accel``; in profile
   mode the firmware's ``acc_inc`` is the program's, and the one the speeds follow best is shown
   as a check.

Every residual is weighted by its channel's *expected* noise, measured in the log where nothing
changes (:mod:`~khepera_gym.robot.calibrate.noise`: the gyroscope at rest, the infrared sensors
seeing nothing, the ultrasonic sensor at rest, the wheel speeds on the steps' plateaus), plus what
the sensor's own period leaves unknown; readings beyond five of those widths are set aside and
counted. The noise keys written are those measurements. Each value's uncertainty has a
statistical part (that noise carried through the fit) and a systematic part (how far the
manoeuvre's parts disagree, a jackknife over its blocks: :mod:`~khepera_gym.robot.calibrate.
uncertainty`); a value the logs cannot tell better than the real robots' spread is "not
identified" and keeps its nominal value. Each channel's residuals are then compared with their
expected noise (:mod:`~khepera_gym.robot.calibrate.goodness`).

What is assumed (the sim-to-real page states it too): the wall's gap at the start is measured
with a ruler (±1 mm), the final gap likewise, the gyroscope's scale is exact, all eight
infrared sensors share one curve, the wall is flat, white and the only thing within reach, the
wheels do not slip.

Units: SI for every value written; counts, speed units and cm for the residuals.
Threading: the calling thread; a progress bar (tqdm) on standard error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from khepera_gym.errors import ConfigError
from khepera_gym.robot.calibrate.drive_fit import DriveFit, DriveResult
from khepera_gym.robot.calibrate.geometry import (
    RULER_SIGMA,
    WALL_PHASES,
    GeometryFit,
    GeometryResult,
)
from khepera_gym.robot.calibrate.goodness import Goodness, channel_fit
from khepera_gym.robot.calibrate.logformat import RobotLog
from khepera_gym.robot.calibrate.solver import (
    CALIBRATE_EXTRA,
    Estimate,
    Progress,
    scipy_least_squares,
)
from khepera_gym.robot.calibrate.timing import TimeGap, time_gaps

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
    #: Each channel's residuals against its expected noise.
    goodness: Goodness
    #: Per log: the intervals of its time column longer than 1.5 periods.
    gaps: list[list[TimeGap]]

    def warnings(self) -> list[str]:
        """What the report must flag: time gaps, outliers, values not identified or at a
        bound of the search, changes made to write a value."""
        found = []
        for log, gaps in zip(self.logs, self.gaps, strict=True):
            found += [f"{log.name}: time gap at {g.describe(log.period)}" for g in gaps]
        for channel in self.goodness.channels:
            if channel.outliers:
                found.append(
                    f"{channel.name}: {channel.outliers} reading(s) beyond five times the "
                    "expected noise set aside (outliers)"
                )
        for estimate in self.estimates():
            found += [f"{estimate.key}: {flag}" for flag in estimate.flags]
        return found

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
        logs: Logs of the calibration program
        (:func:`~khepera_gym.robot.calibrate.logformat.read_log`). base: Scenario overrides of the
        simulator being calibrated (e.g. ``physics.substeps``);
            the fitted keys replace theirs.
        progress: Show a progress bar on standard error.

    Raises:
        ConfigError: The logs cannot be fitted together (:func:`check_logs`).
        ImportError: scipy is missing (the message names the extra).
    """
    check_logs(logs)
    scipy_least_squares()
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
    return Calibration(
        geometry,
        drive,
        list(logs),
        motors,
        logs[0].period,
        goodness(geometry, drive),
        [time_gaps(log) for log in logs],
    )


def goodness(geometry: GeometryResult, drive: DriveResult) -> Goodness:
    """Every channel's residuals against its expected noise."""
    g = geometry
    return Goodness(
        (
            channel_fit(
                "gyroscope",
                g.residuals["gyro"],
                g.expected["gyro"],
                "°/s",
                g.outliers.get("gyro", 0),
            ),
            channel_fit(
                "infrared", g.residuals["ir"], g.expected["ir"], "raw", g.outliers.get("ir", 0)
            ),
            channel_fit(
                "ultrasonic", g.residuals["us"], g.expected["us"], "m", g.outliers.get("us", 0)
            ),
            channel_fit("final gap", g.residuals["gap"], g.expected["gap"], "m"),
            channel_fit(
                "wheel speeds", drive.residuals, drive.expected, "speed units", drive.outliers
            ),
        )
    )


__all__ = [
    "CALIBRATE_EXTRA",
    "RULER_SIGMA",
    "WALL_PHASES",
    "Calibration",
    "DriveFit",
    "DriveResult",
    "Estimate",
    "GeometryFit",
    "GeometryResult",
    "Progress",
    "calibrate",
    "check_logs",
    "goodness",
]
