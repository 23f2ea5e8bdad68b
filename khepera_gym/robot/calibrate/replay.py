"""Replaying a robot log through the simulator, two ways:

* :func:`command_replay`: the simulated robot is driven by the logged wheel commands, as the
  robot was, through the scenario's drive (its motor controller, lag, tyres and contacts); what
  it does is compared with what the robot did (wheel speeds, trajectory, readings). Used to fit
  the drive and by ``khepera-gym replay``.
* :func:`odometry_replay`: the simulated robot is moved along the path the robot's own encoders
  measured (the wheel travel of every row, with a candidate wheel radius and axle, imposed
  exactly), so that its sensors read the scene from where the robot was. A linear probe
  response curve makes the infrared ring report each ray's distance to the millimetre; the
  gyroscope reports the yaw rate of that path. Used to fit the geometry and the sensors.

Row k of a log holds the readings taken at the start of a control step and the command sent
then. Both replays step the simulator on the logged times (:mod:`~khepera_gym.robot.calibrate.
timing`): row k stands for step n_k, its command is held until the next row's step, and the
readings after those steps belong to row k + 1 (row 0's are those of the reset); a missing row
or the user's pause leaves the simulator several steps between two rows.

The calibration scene (:func:`calibration_scene`): an open floor, the robot at the origin facing
+x, a white wall (a fixed segment of reflectance 1) across its path at the logged gap.

Units: SI in the simulator (m, m/s, rad); the robot's units in logs (speed units, pulses,
counts). Threading: the calling thread (the batch steps in its own one-thread pool).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.config import make_batch, tomllib
from khepera_gym.errors import ConfigError
from khepera_gym.robot.calibrate.divergence import (
    DIVERGENCE_TIMES,
    Divergence,
    PhaseDivergence,
    phase_divergences,
    time_divergences,
)
from khepera_gym.robot.calibrate.logformat import RobotLog
from khepera_gym.robot.calibrate.timing import row_intervals, row_steps

#: The nominal wheel radius (m) K-Team's speed unit and pulse refer to (docs/robot.md §1).
NOMINAL_WHEEL_RADIUS = 0.021
#: Encoder pulses a wheel turn (docs/robot.md §1).
PULSES_PER_WHEEL_TURN = 19456
#: One speed unit at the nominal wheel radius (m/s).
SPEED_UNIT = 0.678181e-3
#: One gyroscope count (°/s), ``KH4_GYRO_DEG_S``.
GYRO_DEG_S_PER_COUNT = 0.066
#: The robot's body radius (m): the wall's gap is measured from the front of the shell.
BODY_RADIUS = 0.0704
#: Half the length of the calibration wall (m).
WALL_HALF_LENGTH = 1.5
#: The task replays run in (any task would do: a Nav episode with an unreachable goal).
REPLAY_TASK = "nav"
#: Distances (mm) of the infrared response curve's points (``sensors.ir_curve``, src/sensors/ir.rs).
IR_CURVE_MM = np.array(
    [0, 10, 20, 30, 35, 40, 45, 50, 60, 70, 80, 90, 100, 120, 150, 200], dtype=np.float64
)
#: K-Team's curve on white paper (docs/robot.md §3): the default ``sensors.ir_curve``.
KTEAM_IR_CURVE = np.array(
    [1018, 1012, 1002, 979, 889, 764, 597, 492, 380, 319, 254, 228, 199, 163, 133, 111],
    dtype=np.float64,
)
#: The infrared ring's bearings (rad, counter-clockwise from forward), K-Team order
#: (src/sensors/ir.rs, docs/robot.md §2).
IR_BEARINGS = np.radians([135.0, 90.0, 45.0, 0.0, -45.0, -90.0, -135.0, 180.0])
#: The infrared sensors' range (m, ``sensors.ir_range``).
IR_RANGE = 0.25
#: The linear probe curves: raw = slope * (range - distance), in mm.
#: (range m, slope raw per mm) of the probe: the infrared ring's own range, 0.25 mm a count.
FINE_PROBE = (0.25, 4.0)


def speed_unit(wheel_radius: float) -> float:
    """One speed unit (pulses per 10 ms) in m/s of ground speed, for wheels of this radius."""
    return SPEED_UNIT * wheel_radius / NOMINAL_WHEEL_RADIUS


def metres_per_pulse(wheel_radius: float) -> float:
    """Ground travel (m) of one encoder pulse."""
    return 2.0 * math.pi * wheel_radius / PULSES_PER_WHEEL_TURN


def calibration_scene(wall_distance: float) -> dict[str, Any]:
    """Scenario overrides of the calibration scene: an open floor, the robot at the origin facing
    +x, a white wall ``wall_distance`` m ahead of its front."""
    if not 0.0 < wall_distance < 1.5:
        raise ConfigError(f"the wall's gap must be in (0, 1.5) m, got {wall_distance}")
    wall_x = BODY_RADIUS + wall_distance
    return {
        "arena.walls": False,
        "arena.width": 5.0,
        "arena.height": 5.0,
        "obstacles.count": 0,
        "obstacles.fixed": [
            {
                "kind": "segment",
                "a": [wall_x, -WALL_HALF_LENGTH],
                "b": [wall_x, WALL_HALF_LENGTH],
            }
        ],
        "obstacles.spawn_clearance": 0.0,
        "spawn.start": [0.0, 0.0, 0.0],
        "spawn.goal": [-2.0, -2.0],
    }


def replay_settings(
    rows: int, period: float, carry: Sequence[str] = ("ir", "us", "gyro")
) -> dict[str, Any]:
    """Overrides every replay needs: the log's control period, an episode longer than the log,
    a goal that is never reached, and the sensors ``carry`` (those a log has by default; fewer
    are faster)."""
    return {
        "physics.dt": period,
        "task.max_steps": rows + 10,
        "task.goal_radius": 0.001,
        "task.terminate_on_collision": False,
        "sensors.carry": list(carry),
        "sensors.observe": ["ir"] if "ir" in carry else [],
    }


@dataclasses.dataclass
class Replay:
    """What the simulated robot did and read, row by row, aligned with the log.

    Rows after an episode ended early (``rows_replayed``) are NaN.
    """

    #: (rows, 3): true pose x, y (m), heading (rad) in the scenario's world frame.
    poses: npt.NDArray[np.float64]
    #: (rows, 2): wheel speeds (m/s).
    wheel_speeds: npt.NDArray[np.float64]
    #: (rows, 2): encoders (pulses).
    encoders: npt.NDArray[np.float64]
    #: (rows,): gyroscope yaw rate (counts of 0.066 °/s).
    gyro_z: npt.NDArray[np.float64]
    #: (rows, 8): infrared raw values.
    ir: npt.NDArray[np.float64]
    #: (rows, 5): ultrasonic readings (cm or codes).
    us: npt.NDArray[np.float64]
    #: Rows the simulator reached before its episode ended (all of them, normally).
    rows_replayed: int
    #: The resolved scenario of the replay (TOML text).
    scenario: str
    #: Its geometry for plots (``Batch.scene()``).
    scene: dict[str, Any] = dataclasses.field(default_factory=dict)


def _empty(rows: int, width: int | None = None) -> npt.NDArray[np.float64]:
    shape = (rows,) if width is None else (rows, width)
    return np.full(shape, np.nan)


def _run(
    steps: npt.NDArray[np.int64],
    overrides: Mapping[str, Any],
    speeds_of_row: npt.NDArray[np.float64],
    seed: int,
    config: str | None = None,
    task: str = REPLAY_TASK,
) -> Replay:
    """Steps a one-world batch with wheel speeds (m/s) given per row, each held from its row's
    step to the next row's (:func:`~khepera_gym.robot.calibrate.timing.row_steps`), recording every
    row."""
    rows = len(steps)
    batch = make_batch(task, 1, config, dict(overrides), autoreset=False, num_threads=1)
    scenario = batch.config_toml()
    max_speed = _max_wheel_speed(scenario)
    replay = Replay(
        _empty(rows, 3),
        _empty(rows, 2),
        _empty(rows, 2),
        _empty(rows),
        _empty(rows, 8),
        _empty(rows, 5),
        0,
        scenario,
    )
    batch.reset(seed)
    replay.scene = dict(batch.scene(0))
    action = np.zeros((1, 2), np.float32)
    ended = False
    for row in range(rows):
        if row > 0:
            action[0] = speeds_of_row[row - 1] / max_speed
            for _ in range(int(steps[row] - steps[row - 1])):
                _, _, terminated, truncated = batch.step(action)
                ended = bool(terminated[0] or truncated[0])
                if ended:
                    break
        readings = batch.sensor_readings()
        replay.poses[row] = batch.poses()[0, 0]
        replay.wheel_speeds[row] = readings["wheel_speeds"][0, 0]
        replay.encoders[row] = readings["encoders"][0, 0]
        replay.gyro_z[row] = readings["gyro_raw"][0, 0]
        if "ir_raw" in readings:
            replay.ir[row] = readings["ir_raw"][0, 0]
        if "us_cm" in readings:
            replay.us[row] = readings["us_cm"][0, 0]
        replay.rows_replayed = row + 1
        if ended:
            break
    return replay


def _max_wheel_speed(scenario: str) -> float:
    value = tomllib.loads(scenario)["robot"]["max_wheel_speed"]
    return float(value[0] if isinstance(value, list) else value)


def command_replay(
    log: RobotLog,
    overrides: Mapping[str, Any],
    wheel_radius: float,
    *,
    seed: int = 0,
    config: str | None = None,
    task: str = REPLAY_TASK,
    carry: Sequence[str] = ("ir", "us", "gyro"),
) -> Replay:
    """The simulated robot driven by the log's commands.

    Args:
        log: The robot log.
        overrides: The scenario: the robot and drive being tested and the scene (e.g.
            :func:`calibration_scene` plus the calibrated keys), as scenario overrides.
        wheel_radius: The robot's wheel radius (m): a command of u speed units (pulses per
            10 ms) drives the wheel at u * :func:`speed_unit` m/s.
        seed: The simulator's seed (its sensor noise).
        config: A scenario file the overrides apply to (None: the task's defaults).
        task: The task of the scenario.
        carry: The sensors simulated (the others' readings are NaN).
    """
    steps = row_steps(log)
    settings = {**replay_settings(int(steps[-1]) + 1, log.period, carry), **overrides}
    speeds = log.commands * speed_unit(wheel_radius)
    return _run(steps, settings, speeds, seed, config, task)


def probe_curve(range_m: float, slope: float) -> list[float]:
    """A linear ``ir_curve`` for ``ir_range = range_m``: raw = slope · (range − distance) in mm,
    0 at the range (then the floor value, 0)."""
    top = slope * range_m * 1000.0
    return [float(top - slope * mm) for mm in IR_CURVE_MM]


def _probe(range_m: float, slope: float) -> dict[str, Any]:
    return {
        "sensors.ir_range": range_m,
        "sensors.ir_curve": probe_curve(range_m, slope),
        "sensors.ir_floor_value": 0.0,
        "sensors.ir_noise_sigma": 0.0,
    }


def probe_distance(raw: npt.ArrayLike, range_m: float, slope: float) -> npt.NDArray[np.float64]:
    """The distance (m) a probe reading stands for: NaN when nothing is within its range."""
    raw = np.asarray(raw, dtype=np.float64)
    distance = range_m - raw / slope / 1000.0
    return np.where(raw > 0, distance, np.nan)


@dataclasses.dataclass
class PathReplay:
    """The simulator's readings along the path the encoders measured (:func:`odometry_replay`)."""

    #: (rows, 8): each infrared ray's distance to what it meets (m), NaN beyond 0.25 m,
    #: to 0.25 mm.
    ir_distance: npt.NDArray[np.float64]
    #: (rows,): the path's yaw rate over the interval before each row (its logged time), in
    #: gyroscope counts
    #: (0.066 °/s), unrounded: what a noise-free, unbiased gyroscope reads (the simulated one
    #: rounds it to whole counts); 0 at row 0.
    gyro_z: npt.NDArray[np.float64]
    #: (rows, 3): the path (world frame).
    poses: npt.NDArray[np.float64]


def odometry_replay(
    log: RobotLog,
    overrides: Mapping[str, Any],
    wheel_radius: float,
    axle_length: float,
) -> PathReplay:
    """The simulated robot moved along the path of the log's encoders.

    Each step imposes the wheel travel the encoders counted between two rows (pulses times
    ``2 pi wheel_radius / 19456``) on a robot of axle ``axle_length``, with no drive dynamics
    (``physics.drive = "kinematic"``, unlimited acceleration, no dead band), so that the simulated
    path is the odometry's for these dimensions; the infrared ring reads the scene along it with
    the linear probe curve :data:`FINE_PROBE`, and the gyroscope (noise-free, unbiased) the
    path's yaw rate.

    Args:
        log: The robot log.
        overrides: The scene (e.g. :func:`calibration_scene`).
        wheel_radius: Candidate wheel radius (m).
        axle_length: Candidate axle length (m).
    """
    steps = row_steps(log)
    travel = np.diff(log.encoders, axis=0) * metres_per_pulse(wheel_radius)
    speeds = travel / (np.diff(steps)[:, None] * log.period)
    peak = float(np.max(np.abs(speeds))) if len(speeds) else 0.0
    path = {
        **replay_settings(int(steps[-1]) + 1, log.period, ("ir", "gyro")),
        **overrides,
        "physics.drive": "kinematic",
        "motors.mode": "ramp",
        "robot.wheel_accel_limit": math.inf,
        "robot.motor_time_constant": 0.0,
        "robot.min_wheel_speed": 0.0,
        "robot.max_wheel_speed": max(1.0, 2.0 * peak),
        "robot.axle_length": axle_length,
        "robot.wheel_radius": wheel_radius,
        "sensors.gyro_noise_sigma": 0.0,
        "sensors.gyro_bias": 0.0,
        **_probe(*FINE_PROBE),
    }
    fine = _run(steps, path, speeds, 0)
    turn = np.diff(np.unwrap(fine.poses[:, 2]), prepend=fine.poses[0, 2])
    return PathReplay(
        ir_distance=probe_distance(fine.ir, *FINE_PROBE),
        gyro_z=np.degrees(turn / row_intervals(log)) / GYRO_DEG_S_PER_COUNT,
        poses=fine.poses,
    )


def wall_ir_distances(poses: npt.ArrayLike, wall_distance: float) -> npt.NDArray[np.float64]:
    """(rows, 8): each infrared ray's distance to the calibration wall (m), NaN beyond the
    sensors' range: :func:`wall_ray_distance` for the ring's bearings. Exact along the path,
    where the probe (:func:`odometry_replay`) reads the simulator's ray casts to 0.25 mm."""
    distances = np.stack(
        [wall_ray_distance(poses, wall_distance, bearing) for bearing in IR_BEARINGS], axis=1
    )
    return np.where(distances < IR_RANGE, distances, np.nan)


def wall_ray_distance(
    poses: npt.ArrayLike, wall_distance: float, bearing: float = 0.0
) -> npt.NDArray[np.float64]:
    """The distance (m) from the rim along the ray at ``bearing`` (rad, robot frame) to the
    calibration scene's wall (:func:`calibration_scene`), for poses of its world frame; NaN
    where the ray misses it. The ultrasonic sensors' ranges reach past the infrared probe's, so
    their distances come from the replayed path and the wall's geometry."""
    poses = np.asarray(poses, dtype=np.float64)
    angle = poses[:, 2] + bearing
    c, s = np.cos(angle), np.sin(angle)
    origin_x = poses[:, 0] + BODY_RADIUS * c
    origin_y = poses[:, 1] + BODY_RADIUS * s
    wall_x = BODY_RADIUS + wall_distance
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wall_x - origin_x) / c
    hit_y = origin_y + t * s
    ok = (c > 1e-9) & (t >= 0.0) & (np.abs(hit_y) <= WALL_HALF_LENGTH)
    return np.where(ok, t, np.nan)


def ir_curve_mean(
    distance: npt.ArrayLike, curve: npt.ArrayLike, floor: float, range_m: float = 0.25
) -> npt.NDArray[np.float64]:
    """The simulator's noise-free infrared reading at ``distance`` (m; NaN = nothing in range)
    for a response curve (raw counts at :data:`IR_CURVE_MM`) and floor value, as
    ``IrModel::mean_raw`` computes it (src/sensors/ir.rs), unrounded."""
    d = np.asarray(distance, dtype=np.float64) * 1000.0
    curve = np.asarray(curve, dtype=np.float64)
    inside = np.interp(d, IR_CURVE_MM, curve)
    span = range_m * 1000.0 - IR_CURVE_MM[-1]
    tail = curve[-1] + (d - IR_CURVE_MM[-1]) / span * (floor - curve[-1])
    mean = np.where(d >= IR_CURVE_MM[-1], tail, inside)
    return np.where(np.isfinite(d) & (d < range_m * 1000.0), np.maximum(mean, 0.0), floor)


def odometry_path(
    encoders: npt.ArrayLike, wheel_radius: float, axle_length: float
) -> npt.NDArray[np.float64]:
    """The dead-reckoned path (rows, 3) from encoders, midpoint integration (as the exported
    program's odometry), starting at the origin facing +x."""
    travel = np.diff(np.asarray(encoders, dtype=np.float64), axis=0) * metres_per_pulse(
        wheel_radius
    )
    poses = np.zeros((len(travel) + 1, 3))
    for k, (left, right) in enumerate(travel):
        x, y, heading = poses[k]
        turn = (right - left) / axle_length
        middle = heading + 0.5 * turn
        forward = 0.5 * (left + right)
        poses[k + 1] = (
            x + forward * math.cos(middle),
            y + forward * math.sin(middle),
            heading + turn,
        )
    return poses


def to_world(poses: npt.ArrayLike, start: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Poses in the robot's start frame moved into the world frame of a start pose (x, y, θ)."""
    poses = np.asarray(poses, dtype=np.float64)
    x0, y0, heading = (float(v) for v in start)
    c, s = math.cos(heading), math.sin(heading)
    out = np.empty_like(poses)
    out[:, 0] = x0 + c * poses[:, 0] - s * poses[:, 1]
    out[:, 1] = y0 + s * poses[:, 0] + c * poses[:, 1]
    out[:, 2] = poses[:, 2] + heading
    return out


def scenario_start(scenario: str) -> tuple[float, float, float]:
    """The fixed start pose of a resolved scenario, or the reset pose if it has none."""
    table = tomllib.loads(scenario)
    start = table.get("spawn", {}).get("start", [])
    if len(start) == 3:
        return float(start[0]), float(start[1]), float(start[2])
    raise ConfigError(
        "the replay needs the robot's start pose in the scene: give spawn.start = [x, y, heading] "
        "in --config or --set start=[x, y, heading]"
    )


@dataclasses.dataclass
class ReplayComparison:
    """A log and its command replay, side by side (``khepera-gym replay``)."""

    log: RobotLog
    replay: Replay
    #: (rows, 3): the logged run's path by odometry (its encoders, the scenario's wheel radius
    #: and axle), in the scenario's world frame from its start pose.
    logged_path: npt.NDArray[np.float64]
    #: After 1, 5 and 10 s (:data:`DIVERGENCE_TIMES`).
    divergences: list[Divergence]
    #: Over each moving phase (a calibration log's; empty for a policy's).
    phase_divergences: list[PhaseDivergence]
    #: The scenario's wheel radius (m): speed units to m/s.
    wheel_radius: float
    #: RMS of the measured minus the simulated wheel speeds (speed units).
    wheel_rms: float
    #: RMS of the logged minus the simulated infrared readings (raw).
    ir_rms: float


def _scenario_number(table: Mapping[str, Any], section: str, key: str) -> float:
    value = table[section][key]
    return float(sum(value) / 2 if isinstance(value, list) else value)


def compare_with_simulator(
    log: RobotLog,
    *,
    config: str | None = None,
    overrides: Mapping[str, Any] | None = None,
    task: str = REPLAY_TASK,
    seed: int = 0,
) -> ReplayComparison:
    """Replays a log's commands in a scenario and measures the divergence.

    A calibration log is replayed in its calibration scene (the wall at its logged gap); a
    policy's log in the scenario given, which must fix the start pose (``spawn.start``) where the
    robot started on the bench and hold the bench's obstacles.

    Args:
        log: The robot log.
        config: The scenario file (e.g. the calibrated one), or None for the defaults.
        overrides: Scenario keys over it.
        task: The task whose defaults the scenario overlays.
        seed: The simulator's seed.

    Raises:
        ConfigError: A policy's log and a scenario without a fixed start pose.
    """
    overrides = dict(overrides or {})
    if log.program == "calibrate":
        overrides = {**calibration_scene(log.number("wall_distance_m")), **overrides}
    settings = {**replay_settings(len(log), log.period), **overrides}
    probe = make_batch(task, 1, config, settings, autoreset=False, num_threads=1)
    table = tomllib.loads(probe.config_toml())
    wheel_radius = _scenario_number(table, "robot", "wheel_radius")
    axle_length = _scenario_number(table, "robot", "axle_length")
    start = scenario_start(probe.config_toml())
    result = command_replay(log, overrides, wheel_radius, seed=seed, config=config, task=task)
    path = to_world(odometry_path(log.encoders, wheel_radius, axle_length), start)
    divergences = time_divergences(log, path, result.poses, result.rows_replayed)
    phases = (
        phase_divergences(log, path, result.poses, result.rows_replayed)
        if log.program == "calibrate"
        else []
    )
    unit = speed_unit(wheel_radius)
    speed_error = log.speeds[1:] - result.wheel_speeds[1:] / unit
    ir_error = log.ir - result.ir
    return ReplayComparison(
        log=log,
        replay=result,
        logged_path=path,
        divergences=divergences,
        phase_divergences=phases,
        wheel_radius=wheel_radius,
        wheel_rms=float(np.sqrt(np.nanmean(speed_error**2))),
        ir_rms=float(np.sqrt(np.nanmean(ir_error**2))),
    )


__all__ = [
    "BODY_RADIUS",
    "DIVERGENCE_TIMES",
    "FINE_PROBE",
    "GYRO_DEG_S_PER_COUNT",
    "IR_BEARINGS",
    "IR_CURVE_MM",
    "IR_RANGE",
    "KTEAM_IR_CURVE",
    "NOMINAL_WHEEL_RADIUS",
    "PULSES_PER_WHEEL_TURN",
    "SPEED_UNIT",
    "Divergence",
    "PathReplay",
    "PhaseDivergence",
    "Replay",
    "ReplayComparison",
    "calibration_scene",
    "command_replay",
    "compare_with_simulator",
    "ir_curve_mean",
    "metres_per_pulse",
    "odometry_path",
    "odometry_replay",
    "probe_curve",
    "probe_distance",
    "replay_settings",
    "scenario_start",
    "speed_unit",
    "to_world",
    "wall_ir_distances",
    "wall_ray_distance",
]
