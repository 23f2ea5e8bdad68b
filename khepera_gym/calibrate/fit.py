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

Stage 1 is :mod:`~khepera_gym.calibrate.geometry`, stage 2 :mod:`~khepera_gym.calibrate.drive_fit`,
both on :mod:`~khepera_gym.calibrate.solver`; this module runs them in turn (:func:`calibrate`).

Units: SI for every value written; counts, speed units and cm for the residuals.
Threading: the calling thread; a progress bar (tqdm) on standard error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from khepera_gym.calibrate.drive_fit import DriveFit, DriveResult
from khepera_gym.calibrate.geometry import RULER_SIGMA, WALL_PHASES, GeometryFit, GeometryResult
from khepera_gym.calibrate.logformat import RobotLog
from khepera_gym.calibrate.solver import CALIBRATE_EXTRA, Estimate, Progress, scipy_least_squares
from khepera_gym.errors import ConfigError

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
    return Calibration(geometry, drive, list(logs), motors, logs[0].period)


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
]
