"""Synthetic robot logs from the simulator: a robot whose true parameters are known
(:class:`TrueRobot`), perturbed within the real robots' spread (:func:`perturbed_robot`), runs
the calibration manoeuvre (:func:`synthetic_calibration_log`) or a sequence of wheel commands
(:func:`synthetic_command_log`) in the simulator, and its readings are written as the robot
programs write them, with their noise. This is how ``khepera-gym calibrate`` is tested without a
robot: it must find the parameters the log was made with.

What is simulated and what is assumed: the simulator is the robot here, so a synthetic log says
nothing about how well the simulator models a real Khepera IV; it tests that the fit recovers
parameters the simulator can represent, from noisy data of the amount a real log has.

Units: the robot's in the log (speed units, pulses, counts, cm); SI for the parameters.
Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym
import khepera_gym.robot.calibrate.schedule as schedule
from khepera_gym.config import make_batch, tomllib
from khepera_gym.robot.calibrate.logformat import POLICY_PHASE, RobotLog, new_log
from khepera_gym.robot.calibrate.logformat import Note as LogNote
from khepera_gym.robot.calibrate.replay import (
    BODY_RADIUS,
    IR_CURVE_MM,
    KTEAM_IR_CURVE,
    NOMINAL_WHEEL_RADIUS,
    calibration_scene,
    metres_per_pulse,
    replay_settings,
    speed_unit,
)

#: The spread of real robots each parameter of :func:`perturbed_robot` is drawn from, with
#: where it comes from: (low, high) for a uniform draw, or a relative standard deviation.
SPREAD: Mapping[str, tuple[float, float] | float] = {
    # relative, 1 sigma: the simulator's odometry.radius_error [E]
    "wheel_radius": 0.01,
    # relative, 1 sigma: the EPFL toolbox's calibrated 104.7 mm against 105.4 mm [D]
    "axle_length": 0.007,
    # s: the PID's response behind the profile [E]
    "motor_time_constant": (0.01, 0.06),
    # °/s: a MEMS gyroscope's zero-rate offset [E]
    "gyro_bias": (-1.5, 1.5),
    # °/s per reading [E]
    "gyro_noise_sigma": (0.1, 0.4),
    # the curve's value and distance scale against K-Team's (the surface, the sensor) [E]
    "ir_gain": (0.85, 1.15),
    "ir_scale": (0.9, 1.1),
    # the floor value as a fraction of the curve's value at 0.2 m (K-Team's: 100 of 111) [E]
    "ir_floor_fraction": (0.8, 0.97),
    # raw counts [E]
    "ir_noise_sigma": (5.0, 15.0),
    # m: K-Team's ±2 cm tolerance [C]
    "us_offset": (-0.02, 0.02),
    "us_noise_sigma": (0.005, 0.015),
}


def ir_curve(gain: float, scale: float) -> npt.NDArray[np.float64]:
    """K-Team's response curve scaled by ``gain`` in value and ``scale`` in distance, at the
    curve's 16 distances (``sensors.ir_curve``), within [0, 1023]."""
    stretched = np.interp(
        IR_CURVE_MM / scale,
        IR_CURVE_MM,
        KTEAM_IR_CURVE,
        right=np.nan,
    )
    beyond = IR_CURVE_MM / scale > IR_CURVE_MM[-1]
    if np.any(beyond):
        slope = (KTEAM_IR_CURVE[-1] - KTEAM_IR_CURVE[-2]) / (IR_CURVE_MM[-1] - IR_CURVE_MM[-2])
        stretched[beyond] = KTEAM_IR_CURVE[-1] + slope * (IR_CURVE_MM[beyond] / scale - 200.0)
    return np.clip(gain * stretched, 0.0, 1023.0)


@dataclasses.dataclass(frozen=True)
class TrueRobot:
    """The parameters a synthetic log is made with (SI; the drive in K-Team's units)."""

    wheel_radius: float = NOMINAL_WHEEL_RADIUS
    axle_length: float = 0.1054
    motor_time_constant: float = 0.0
    motors: str = "profile"
    acc_inc: int = 40
    acc_div: int = 0
    min_speed_acc: int = 20
    min_speed_dec: int = 1
    speed_accel: float = 2.74
    gyro_bias: float = 0.0
    gyro_noise_sigma: float = 0.2
    ir_gain: float = 1.0
    ir_scale: float = 1.0
    ir_floor_value: float = 100.0
    ir_noise_sigma: float = 10.0
    us_offset: float = 0.0
    us_noise_sigma: float = 0.01
    #: Noise of the measured wheel speeds (speed units) [E].
    speed_noise: float = 2.0

    def overrides(self) -> dict[str, Any]:
        """The simulator's scenario keys of this robot."""
        drive: dict[str, Any] = {"motors.mode": self.motors}
        if self.motors == "profile":
            drive.update(
                {
                    "motors.acc_inc": self.acc_inc,
                    "motors.acc_div": self.acc_div,
                    "motors.min_speed_acc": self.min_speed_acc,
                    "motors.min_speed_dec": self.min_speed_dec,
                }
            )
        else:
            drive["motors.speed_accel"] = self.speed_accel
        return {
            **drive,
            "robot.wheel_radius": self.wheel_radius,
            "robot.axle_length": self.axle_length,
            "robot.motor_time_constant": self.motor_time_constant,
            "sensors.gyro_bias": self.gyro_bias,
            "sensors.gyro_noise_sigma": self.gyro_noise_sigma,
            "sensors.ir_curve": [float(v) for v in ir_curve(self.ir_gain, self.ir_scale)],
            "sensors.ir_floor_value": self.ir_floor_value,
            "sensors.ir_noise_sigma": self.ir_noise_sigma,
            "sensors.us_offset": self.us_offset,
            "sensors.us_noise_sigma": self.us_noise_sigma,
        }


def perturbed_robot(rng: np.random.Generator, **fixed: Any) -> TrueRobot:
    """A robot whose parameters are drawn within :data:`SPREAD` around the simulator's
    defaults; ``fixed`` sets some of them (e.g. the drive)."""
    drawn: dict[str, Any] = {}
    nominal = TrueRobot()
    for name, spread in SPREAD.items():
        if isinstance(spread, tuple):
            drawn[name] = float(rng.uniform(*spread))
        else:
            drawn[name] = float(getattr(nominal, name) * (1.0 + spread * rng.standard_normal()))
    fraction = drawn.pop("ir_floor_fraction")
    drawn["ir_floor_value"] = fraction * float(ir_curve(drawn["ir_gain"], drawn["ir_scale"])[-1])
    drawn.update(fixed)
    return dataclasses.replace(nominal, **drawn)


def _metadata(
    robot: TrueRobot, program: str, period: float, program_radius: float, program_axle: float
) -> dict[str, Any]:
    return {
        "program": program,
        "khepera_gym": khepera_gym.__version__,
        "firmware": "simulated",
        "control_period_s": repr(period),
        "wheel_radius_m": repr(program_radius),
        "axle_length_m": repr(program_axle),
        "motors": robot.motors,
        "acc_inc": robot.acc_inc if robot.motors == "profile" else 0,
        "acc_div": robot.acc_div if robot.motors == "profile" else 0,
        "min_speed_acc": robot.min_speed_acc,
        "min_speed_dec": robot.min_speed_dec,
        "gyro_samples": max(1, min(10, round(period * 100))),
    }


class _SimulatedRobot:
    """A one-world batch standing for the robot: commands in, readings in the robot's units."""

    def __init__(
        self, robot: TrueRobot, scene: Mapping[str, Any], rows: int, period: float, seed: int
    ) -> None:
        overrides = {
            **replay_settings(rows, period),
            **scene,
            **robot.overrides(),
            "sensors.carry": ["ir", "us", "gyro", "imu", "ground"],
        }
        self.batch = make_batch("nav", 1, None, overrides, autoreset=False, num_threads=1)
        self.max_speed = float(tomllib.loads(self.batch.config_toml())["robot"]["max_wheel_speed"])
        self.robot = robot
        self.unit = speed_unit(robot.wheel_radius)
        self.rng = np.random.default_rng(seed + 1)
        self.batch.reset(seed)
        self.action = np.zeros((1, 2), np.float32)

    def readings(self) -> dict[str, float]:
        r = self.batch.sensor_readings()
        speeds = r["wheel_speeds"][0, 0] / self.unit
        noisy = np.round(speeds + self.robot.speed_noise * self.rng.standard_normal(2))
        row: dict[str, float] = {
            "speed_left": float(noisy[0]),
            "speed_right": float(noisy[1]),
            "enc_left": float(r["encoders"][0, 0, 0]),
            "enc_right": float(r["encoders"][0, 0, 1]),
        }
        row.update({f"ir_{i}": float(v) for i, v in enumerate(r["ir_raw"][0, 0])})
        row.update({f"ground_{i}": float(v) for i, v in enumerate(r["ground_raw"][0, 0])})
        row.update({f"us_{i}": float(v) for i, v in enumerate(r["us_cm"][0, 0])})
        acc = r["accel_raw"][0, 0]
        gyro = r["imu_gyro_raw"][0, 0]
        row.update({"acc_x": acc[0], "acc_y": acc[1], "acc_z": acc[2]})
        row.update({"gyro_x": gyro[0], "gyro_y": gyro[1], "gyro_z": float(r["gyro_raw"][0, 0])})
        return row

    def step(self, left: int, right: int) -> None:
        self.action[0] = (left * self.unit / self.max_speed, right * self.unit / self.max_speed)
        self.batch.step(self.action)

    def front_gap(self, wall_x: float) -> float:
        """The true gap (m) between the robot's front and the wall ahead."""
        x = float(self.batch.poses()[0, 0, 0])
        return wall_x - x - BODY_RADIUS


def synthetic_calibration_log(
    robot: TrueRobot,
    *,
    wall_distance: float = 0.5,
    period: float = 0.05,
    seed: int = 0,
    ruler_sigma: float | None = 0.001,
    phases: Sequence[schedule.Phase] | None = None,
) -> RobotLog:
    """The log the calibration program would write on ``robot`` (simulated).

    Args:
        robot: The true parameters.
        wall_distance: The gap between the robot's front and the wall at the start (m), exact.
        period: The control period (s).
        seed: The simulator's seed (its sensor noise) and the measured speeds' noise.
        ruler_sigma: The user's measurement of the final gap: the true gap plus Gaussian noise
            of this many metres; None: not measured.
        phases: The manoeuvre (the program's for this drive when None).
    """
    accel = (
        robot.acc_inc * speed_unit(NOMINAL_WHEEL_RADIUS) / ((robot.acc_div + 1) * 0.01)
        if robot.motors == "profile"
        else robot.speed_accel
    )
    phases = tuple(phases) if phases is not None else schedule.calibration_phases(accel, 1.0)
    limit = sum(schedule.phase_steps(p.seconds, period) + 1 for p in phases) + 10
    simulated = _SimulatedRobot(robot, calibration_scene(wall_distance), limit, period, seed)
    wall_x = BODY_RADIUS + wall_distance
    ruler = np.random.default_rng(seed + 2)
    notes: list[LogNote] = []
    rows: list[dict[str, float | str]] = []

    def ask_gap() -> float | None:
        gap = simulated.front_gap(wall_x)
        measured = None if ruler_sigma is None else gap + ruler_sigma * ruler.standard_normal()
        notes.append(
            LogNote(
                len(rows) - 1, "wall_gap_end_m", "nan" if measured is None else f"{measured:.4f}"
            )
        )
        return measured

    runner = schedule.PhaseRunner(
        phases,
        period,
        wall_distance,
        metres_per_pulse(NOMINAL_WHEEL_RADIUS),
        0.1054,
        ask_gap,
    )
    for step in range(limit):
        row: dict[str, float | str] = {"time": step * period, **simulated.readings()}
        try:
            phase, left, right = runner.next_command(
                int(row["enc_left"]),
                int(row["enc_right"]),
                int(row[f"ir_{schedule.FRONT_IR}"]),
                int(row[f"us_{schedule.FRONT_US}"]),
            )
        except StopIteration:
            break
        row.update({"phase": phase.name, "cmd_left": left, "cmd_right": right})
        rows.append(row)
        simulated.step(left, right)
    metadata = _metadata(robot, "calibrate", period, NOMINAL_WHEEL_RADIUS, 0.1054)
    metadata["wall_distance_m"] = repr(wall_distance)
    log = new_log(metadata, rows)
    log.notes = notes
    return log


def synthetic_command_log(
    robot: TrueRobot,
    commands: npt.ArrayLike,
    *,
    scene: Mapping[str, Any] | None = None,
    env_id: str = f"KheperaIV-Nav-v{khepera_gym.registry.LATEST_VERSION}",
    period: float = 0.05,
    seed: int = 0,
) -> RobotLog:
    """The log the policy program would write while sending ``commands`` (rows of left, right
    speed units) to ``robot`` (simulated) in ``scene`` (scenario overrides with ``spawn.start``;
    an open floor when None)."""
    commands = np.asarray(commands, dtype=np.int64).reshape(-1, 2)
    scene = (
        dict(scene)
        if scene is not None
        else {
            "arena.walls": False,
            "arena.width": 5.0,
            "arena.height": 5.0,
            "spawn.start": [0.0, 0.0, 0.0],
            "spawn.goal": [-2.0, -2.0],
        }
    )
    simulated = _SimulatedRobot(robot, scene, len(commands) + 1, period, seed)
    rows: list[dict[str, float | str]] = []
    for step, (left, right) in enumerate(commands):
        row: dict[str, float | str] = {"time": step * period, **simulated.readings()}
        row.update({"phase": POLICY_PHASE, "cmd_left": int(left), "cmd_right": int(right)})
        rows.append(row)
        simulated.step(int(left), int(right))
    metadata = _metadata(robot, "policy", period, NOMINAL_WHEEL_RADIUS, 0.1054)
    metadata["env_id"] = env_id
    return new_log(metadata, rows)


def step_commands(
    levels: Sequence[tuple[int, int]], seconds: float, period: float = 0.05
) -> npt.NDArray[np.int64]:
    """Wheel commands holding each (left, right) level for ``seconds``."""
    per = max(1, round(seconds / period))
    return np.repeat(np.asarray(levels, dtype=np.int64), per, axis=0)


__all__ = [
    "SPREAD",
    "TrueRobot",
    "ir_curve",
    "perturbed_robot",
    "step_commands",
    "synthetic_calibration_log",
    "synthetic_command_log",
]

del math
