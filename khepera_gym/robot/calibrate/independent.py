"""A second model of a Khepera IV on the calibration bench, written from K-Team's manual (docs/
robot.md's S1) and sharing no code with the simulator: the log the calibration program
(``khepera-gym robot-program calibrate``) would write on it (:func:`bench_calibration_log`).
``khepera-gym calibrate`` is tested on these logs, whose robot the simulator cannot represent
exactly, so that its uncertainties are tested against a model it does not contain.

What the robot is here, and where the simulator differs:

* **The firmware** (manual §4.14): the dsPIC runs every 10 ms on its own clock. In profile mode
  the order moves toward the set point by ``acc_inc`` every ``acc_div + 1`` ticks (a staircase),
  a non-zero order below ``min_speed_acc`` is raised to it; in speed mode it jumps. The wheel
  follows the order with a first-order lag (the motor and its PID) and a ripple of
  :data:`SPEED_RIPPLE` units a tick while it drives. ``kh4_get_speed`` returns the pulses
  counted over the last tick. A set point sent between ticks takes effect at the next.
* **The program's timing**: a row wakes 1 to 3 ms after its tick (:data:`WAKE_LATE_S`); its six
  reads (speed, encoders, infrared, ultrasonic, accelerometer, gyroscope) land 0.5 to 3 ms
  after the row's time stamp (:data:`READ_LATENCY_S`); the gap's question pauses the program
  for :data:`USER_PAUSE_S`.
* **The gyroscope** samples at 95 Hz on its own clock (manual §4.10), each sample the yaw rate
  plus the bias and noise, in whole counts of 0.066 °/s; a row averages the newest
  ``gyro_samples`` of them.
* **The infrared ring** refreshes every 5 ms (manual §4.1). Its curve is K-Team's fig. 10 with
  each point moved within the ±10 counts it was read to (docs/robot.md §3), joined by a monotone
  cubic (not straight lines), scaled in value and distance, on the floor's reflection, and flat
  at the floor's value beyond 20 cm (manual §4.1.2: nothing is seen beyond).
* **The ultrasonic sensors** fire in turn, 20 ms each, 100 ms for all five (manual §4.2); a
  reading is the distance when the sensor fired, with an offset and noise, in whole cm by
  truncation (an echo timer's integer division), 0 below 25 cm, 1000 beyond 200 cm or without
  an echo (a surface more than :data:`US_BEAM_HALF_ANGLE` from facing the sensor).
* **The user's ruler** reads to the nearest mm: both gaps are typed in whole mm.

The robot's true values in the simulator's terms are :meth:`BenchRobot.simulator_truth`.
Not modelled: wheel slip, a robot placed askew, a wall that is not flat and white, a sensor's
response to incidence, battery sag. Units: SI inside; the robot's own in the log. Threading:
the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym
from khepera_gym.robot.calibrate.independent_program import BenchProgram
from khepera_gym.robot.calibrate.logformat import Note, RobotLog, new_log
from khepera_gym.robot.calibrate.schedule import Phase
from khepera_gym.robot.calibrate.synthetic import SPREAD

#: Encoder pulses a wheel turn (manual §4.14).
PULSES_PER_TURN = 19456
#: The firmware's period (s, manual §4.14); a speed unit is a pulse per period.
FIRMWARE_PERIOD_S = 0.01
#: The gyroscope's sampling rate (Hz, manual §4.10) and its count (°/s, KH4_GYRO_DEG_S).
GYRO_RATE_HZ = 95.0
GYRO_COUNT_DEG_S = 0.066
#: The infrared ring's refresh (s, manual §4.1) and its largest value.
IR_REFRESH_S = 0.005
IR_MAX = 1023
#: K-Team's fig. 10 (white paper), read off the figure to ±10 counts (docs/robot.md §3).
FIG10_MM = (0, 10, 20, 30, 35, 40, 45, 50, 60, 70, 80, 90, 100, 120, 150, 200)
FIG10_RAW = (1018, 1012, 1002, 979, 889, 764, 597, 492, 380, 319, 254, 228, 199, 163, 133, 111)
FIG10_TOLERANCE = 10.0
#: The ring's bearings (°, K-Team order) and the ultrasonic sensors' (L, FL, F, FR, R).
IR_BEARINGS_DEG = (135.0, 90.0, 45.0, 0.0, -45.0, -90.0, -135.0, 180.0)
US_BEARINGS_DEG = (90.0, 45.0, 0.0, -45.0, -90.0)
#: One ultrasonic sensor's slot (s; five make the 100 ms sweep, manual §4.2), its range (cm).
US_SLOT_S = 0.02
US_RANGE_CM = (25, 200)
#: A surface echoes when it faces the sensor within this (rad): half the 50-60° cone docs/
#: robot.md §11 estimates for a 40 kHz transceiver [E].
US_BEAM_HALF_ANGLE = math.radians(27.5)
#: The shell's radius (m, manual §8: 140.8 mm across); sensors sit on it.
SHELL_RADIUS = 0.0704
#: Half the wall's length (m): a sheet of paper on a wall, longer than the robot sees.
WALL_HALF_LENGTH = 1.0
#: Timing of the program on Linux [E]: late wake-ups, the I²C reads' latency, the user's pause.
WAKE_LATE_S = (0.001, 0.003)
READ_LATENCY_S = (0.0005, 0.003)
USER_PAUSE_S = (5.0, 20.0)
#: The wheels' ripple while driven (speed units a tick, one standard deviation) [E].
SPEED_RIPPLE = 1.0
#: The accelerometer's noise (mg) [E] and the ground sensors' reading on a light floor [E].
ACC_NOISE_MG = 5.0
GROUND_RAW = 800.0
#: The physics' step (s): every clock's events fall on it to within this.
STEP_S = 0.001


@dataclasses.dataclass(frozen=True)
class BenchRobot:
    """The true robot of a bench log (SI; the infrared in raw counts)."""

    wheel_radius: float = 0.021
    axle_length: float = 0.1054
    motor_tau: float = 0.03
    gyro_bias: float = 0.0
    #: °/s, a row's noise (a sample's is √n times it).
    gyro_noise: float = 0.2
    ir_gain: float = 1.0
    ir_scale: float = 1.0
    ir_floor: float = 100.0
    ir_noise: float = 10.0
    #: Each fig. 10 point's offset (raw, within ±FIG10_TOLERANCE).
    ir_shape: tuple[float, ...] = (0.0,) * 16
    us_offset: float = 0.0
    us_noise: float = 0.01

    def curve_points(self) -> npt.NDArray[np.float64]:
        """Fig. 10 moved by :attr:`ir_shape`, made non-increasing."""
        raw = np.asarray(FIG10_RAW, float) + np.asarray(self.ir_shape, float)
        return np.minimum.accumulate(np.minimum(raw, IR_MAX))

    def ir_mean(self, distance: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The noise-free reading (raw) of a sensor ``distance`` m from the white wall (NaN:
        nothing ahead): the floor's reflection plus the wall's, which fades to nothing at
        20 cm of fig. 10's distances."""
        from scipy.interpolate import PchipInterpolator

        mm = np.asarray(distance, float) * 1000.0 / self.ir_scale
        points = self.curve_points()
        shape = PchipInterpolator(np.asarray(FIG10_MM, float), points, extrapolate=False)
        inside = np.isfinite(mm) & (mm < FIG10_MM[-1])
        wall = np.where(inside, shape(np.clip(np.nan_to_num(mm), 0, FIG10_MM[-1])) - points[-1], 0)
        return np.clip(self.ir_floor + self.ir_gain * wall, 0.0, IR_MAX)

    def simulator_truth(self, gyro_samples: int) -> dict[str, Any]:
        """The simulator's keys that reproduce this robot's readings (``robot.
        motor_time_constant`` is left out: the simulator's is an effective lag, see
        :mod:`~khepera_gym.robot.calibrate.drive_fit`).

        * The gyroscope's noise: a row's mean of ``gyro_samples`` whole-count samples has the
          variance (σ_s² + q²/12) / n; the simulator rounds its reading once, adding q²/12.
        * The ultrasonic offset: truncating to cm reads 0.5 cm less than rounding does.
        * The curve: this robot's mean reading at the simulator's 16 distances.
        """
        q = GYRO_COUNT_DEG_S
        sample = self.gyro_noise * math.sqrt(gyro_samples)
        row_variance = (sample**2 + q * q / 12.0) / gyro_samples
        return {
            "robot.wheel_radius": self.wheel_radius,
            "robot.axle_length": self.axle_length,
            "sensors.gyro_bias": self.gyro_bias,
            "sensors.gyro_noise_sigma": math.sqrt(max(row_variance - q * q / 12.0, 0.0)),
            "sensors.ir_curve": [float(v) for v in self.ir_mean(np.asarray(FIG10_MM) / 1000.0)],
            "sensors.ir_floor_value": self.ir_floor,
            "sensors.ir_noise_sigma": self.ir_noise,
            "sensors.us_offset": self.us_offset - 0.005,
            "sensors.us_noise_sigma": self.us_noise,
        }


def _uniform(rng: np.random.Generator, spread: Any, third: int | None) -> float:
    low, high = spread
    if third is None:
        return float(rng.uniform(low, high))
    width = (high - low) / 3.0
    return float(rng.uniform(low + third * width, low + (third + 1) * width))


def draw_bench_robot(
    rng: np.random.Generator, thirds: Mapping[str, int] | None = None
) -> BenchRobot:
    """A robot across the real robots' spread
    (:data:`~khepera_gym.robot.calibrate.synthetic.SPREAD`): each value uniform in its range (the
    relative ones within ±2 standard deviations), or in the third of it ``thirds`` names (0, 1, 2; a
    Latin hypercube over several robots)."""
    thirds = thirds or {}
    drawn: dict[str, float] = {}
    for name, spread in SPREAD.items():
        if isinstance(spread, tuple):
            drawn[name] = _uniform(rng, spread, thirds.get(name))
        else:
            drawn[name] = 1.0 + _uniform(rng, (-2.0 * spread, 2.0 * spread), thirds.get(name))
    gain = drawn["ir_gain"]
    return BenchRobot(
        wheel_radius=0.021 * drawn["wheel_radius"],
        axle_length=0.1054 * drawn["axle_length"],
        motor_tau=drawn["motor_time_constant"],
        gyro_bias=drawn["gyro_bias"],
        gyro_noise=drawn["gyro_noise_sigma"],
        ir_gain=gain,
        ir_scale=drawn["ir_scale"],
        ir_floor=drawn["ir_floor_fraction"] * gain * FIG10_RAW[-1],
        ir_noise=drawn["ir_noise_sigma"],
        ir_shape=tuple(float(v) for v in rng.uniform(-FIG10_TOLERANCE, FIG10_TOLERANCE, 16)),
        us_offset=drawn["us_offset"],
        us_noise=drawn["us_noise_sigma"],
    )


@dataclasses.dataclass(frozen=True)
class Drive:
    """The motor controller as the program set it (the log's header)."""

    mode: str = "profile"
    acc_inc: int = 40
    acc_div: int = 0
    min_speed_acc: int = 20
    min_speed_dec: int = 1


class _Bench:
    """The robot in front of its wall, stepped every :data:`STEP_S`; each clock's events at
    their own times, the state kept per step for the sensors that read the past."""

    def __init__(
        self,
        robot: BenchRobot,
        drive: Drive,
        wall_x: float,
        seconds: float,
        seed: np.random.SeedSequence,
    ) -> None:
        self.robot, self.drive, self.wall_x = robot, drive, wall_x
        self.rng = np.random.default_rng(seed)
        steps = int(seconds / STEP_S) + 10
        self.pose = np.zeros((steps, 3))
        self.wheel = np.zeros((steps, 2))
        self.pulses = np.zeros((steps, 2))
        self.k = 0
        self.order = [0.0, 0.0]
        self.target = [0.0, 0.0]
        self.pending: tuple[float, tuple[int, int]] | None = None
        self.ticks = 0
        self.speed_reading = np.zeros(2)
        self.tick_pulses = np.zeros(2)
        #: Each clock's phase (s): where its first event falls.
        self.firmware_phase = float(self.rng.uniform(0, FIRMWARE_PERIOD_S))
        self.gyro_phase = float(self.rng.uniform(0, 1.0 / GYRO_RATE_HZ))
        self.ir_phase = float(self.rng.uniform(0, IR_REFRESH_S))
        self.us_phase = float(self.rng.uniform(0, 5 * US_SLOT_S))
        self.us_noise = self.rng.standard_normal((int(seconds / (5 * US_SLOT_S)) + 10, 5))
        self.metres_per_pulse = 2.0 * math.pi * robot.wheel_radius / PULSES_PER_TURN
        self.ripple = SPEED_RIPPLE
        #: The true pose when each row's infrared reading was taken.
        self.ir_poses: list[npt.NDArray[np.float64]] = []

    @property
    def time(self) -> float:
        """The robot's time (s)."""
        return self.k * STEP_S

    def send(self, when: float, left: int, right: int) -> None:
        """kh4_set_speed at ``when``: the firmware takes it at its next tick."""
        self.pending = (when, (left, right))

    def advance(self, until: float) -> None:
        """Steps the robot to ``until`` (s)."""
        robot = self.robot
        tau = robot.motor_tau
        decay = math.exp(-STEP_S / tau) if tau > 0 else 0.0
        keep = tau * (1.0 - decay)
        scale = self.metres_per_pulse / FIRMWARE_PERIOD_S
        while self.k * STEP_S < until - 1e-12:
            k = self.k
            if k * STEP_S >= self.firmware_phase + self.ticks * FIRMWARE_PERIOD_S:
                self._tick(k * STEP_S)
            order_left, order_right = self.order
            left, right = self.wheel[k]
            # The lag from the order: exact over a step; the pulses are its integral.
            moved_left = order_left * STEP_S + (left - order_left) * keep
            moved_right = order_right * STEP_S + (right - order_right) * keep
            self.wheel[k + 1] = (
                order_left + (left - order_left) * decay,
                order_right + (right - order_right) * decay,
            )
            pulses = self.pulses[k]
            self.pulses[k + 1] = (
                pulses[0] + moved_left / FIRMWARE_PERIOD_S,
                pulses[1] + moved_right / FIRMWARE_PERIOD_S,
            )
            forward = 0.5 * (moved_left + moved_right) * scale
            turn = (moved_right - moved_left) * scale / robot.axle_length
            x, y, heading = self.pose[k]
            middle = heading + 0.5 * turn
            self.pose[k + 1] = (
                x + forward * math.cos(middle),
                y + forward * math.sin(middle),
                heading + turn,
            )
            self.k = k + 1

    def _tick(self, t: float) -> None:
        """One firmware period: the speed measured over the last one, the set point taken,
        the profile's step, the wheels' ripple."""
        counted = np.floor(self.pulses[self.k])
        self.speed_reading = counted - self.tick_pulses
        self.tick_pulses = counted
        if self.pending is not None and self.pending[0] <= t:
            self.target = [float(v) for v in self.pending[1]]
            self.pending = None
        drive = self.drive
        if drive.mode != "profile":
            self.order = list(self.target)
        elif self.ticks % (drive.acc_div + 1) == 0:
            self.order = [self._profile(o, g) for o, g in zip(self.order, self.target, strict=True)]
        for wheel in (0, 1):
            if self.order[wheel] != 0:
                self.wheel[self.k, wheel] += self.ripple * self.rng.standard_normal()
        self.ticks += 1

    def _profile(self, order: float, target: float) -> float:
        """One step of the speed profile (manual §4.14.2) from ``order`` toward ``target``."""
        least = float(self.drive.min_speed_acc)
        if target != 0 and abs(target) < least:
            target = math.copysign(least, target)
        step = float(self.drive.acc_inc)
        if order != 0 and (target == 0 or (order > 0) != (target > 0)):
            # Slowing toward a stop (or a reversal) first: below min_speed_acc it stops.
            order -= math.copysign(min(step, abs(order)), order)
            return 0.0 if abs(order) < least else order
        if order == 0 and target != 0:
            return math.copysign(min(least, abs(target)), target)
        return order + max(-step, min(step, target - order))

    # -- readings: each sensor on its own clock, from the state when it sampled --------------

    def _at(self, t: float) -> int:
        return min(math.ceil(t / STEP_S - 1e-9), self.k)

    def encoders(self, t: float) -> tuple[int, int]:
        left, right = np.floor(self.pulses[self._at(t)])
        return int(left), int(right)

    def _ray(self, k: int, bearing: float) -> tuple[float, float]:
        """(distance m from the shell along a ray at ``bearing``, its angle to the wall's
        normal); inf when it misses the wall."""
        x, y, heading = self.pose[k]
        angle = heading + bearing
        c = math.cos(angle)
        if c <= 1e-9:
            return math.inf, math.pi
        start_x = x + SHELL_RADIUS * c
        distance = (self.wall_x - start_x) / c
        hit_y = y + SHELL_RADIUS * math.sin(angle) + distance * math.sin(angle)
        if distance < 0 or abs(hit_y) > WALL_HALF_LENGTH:
            return math.inf, math.pi
        return distance, abs(math.atan2(math.sin(angle), c))

    def infrared(self, t: float, noise: npt.NDArray[np.float64]) -> list[int]:
        refreshed = self.ir_phase + math.floor((t - self.ir_phase) / IR_REFRESH_S) * IR_REFRESH_S
        k = self._at(max(refreshed, 0.0))
        self.ir_poses.append(self.pose[k].copy())
        distances = [self._ray(k, math.radians(b))[0] for b in IR_BEARINGS_DEG]
        mean = self.robot.ir_mean(np.where(np.isfinite(distances), distances, np.nan))
        raw = np.floor(mean + self.robot.ir_noise * noise + 0.5)
        return [int(v) for v in np.clip(raw, 0, IR_MAX)]

    def ultrasonic(self, t: float) -> list[int]:
        readings = []
        for index, bearing in enumerate(US_BEARINGS_DEG):
            # The last slot of this sensor that ended by t; it measured when it began.
            start = self.us_phase + index * US_SLOT_S
            sweeps = math.floor((t - start - US_SLOT_S) / (5 * US_SLOT_S))
            if sweeps < 0:
                readings.append(1000)
                continue
            fired = start + sweeps * 5 * US_SLOT_S
            distance, incidence = self._ray(self._at(fired), math.radians(bearing))
            if not math.isfinite(distance) or incidence > US_BEAM_HALF_ANGLE:
                readings.append(1000)
                continue
            noise = self.robot.us_noise * self.us_noise[sweeps, index]
            cm = math.floor((distance + self.robot.us_offset + noise) * 100.0)
            low, high = US_RANGE_CM
            readings.append(0 if cm < low else (1000 if cm > high else int(cm)))
        return readings

    def gyro(self, t: float, samples: int, noise: npt.NDArray[np.float64]) -> float:
        """The mean of the newest ``samples`` samples (counts) before ``t``."""
        period = 1.0 / GYRO_RATE_HZ
        newest = math.floor((t - self.gyro_phase) / period)
        total = 0.0
        sample_noise = self.robot.gyro_noise * math.sqrt(samples)
        for n in range(newest - samples + 1, newest + 1):
            k = self._at(max(self.gyro_phase + n * period, 0.0))
            rate = self._yaw_rate(k)
            deg_s = rate + self.robot.gyro_bias + sample_noise * noise[n % len(noise)]
            total += round(deg_s / GYRO_COUNT_DEG_S)
        return total / samples

    def _yaw_rate(self, k: int) -> float:
        wheels = self.wheel[k] * self.metres_per_pulse / FIRMWARE_PERIOD_S
        return math.degrees((wheels[1] - wheels[0]) / self.robot.axle_length)

    def accelerometer(self, t: float) -> tuple[float, float, float]:
        k = self._at(t)
        back = max(k - int(FIRMWARE_PERIOD_S / STEP_S), 0)
        speed = self.wheel[k].mean() * self.metres_per_pulse / FIRMWARE_PERIOD_S
        before = self.wheel[back].mean() * self.metres_per_pulse / FIRMWARE_PERIOD_S
        forward = (speed - before) / FIRMWARE_PERIOD_S / 9.80665 * 1000.0
        lateral = speed * math.radians(self._yaw_rate(k)) / 9.80665 * 1000.0
        noise = ACC_NOISE_MG * self.rng.standard_normal(3)
        return forward + noise[0], lateral + noise[1], -1000.0 + noise[2]

    def front_gap(self, t: float) -> float:
        """The true gap (m) between the shell's front and the wall."""
        return self._ray(self._at(t), 0.0)[0]


@dataclasses.dataclass
class BenchRun:
    """A bench log with what only the model knows: the true pose (x, y, heading in the start
    frame, the wall across x = its gap plus the shell's radius) when each row's infrared
    readings were taken."""

    log: RobotLog
    ir_poses: npt.NDArray[np.float64]
    wall_x: float


def bench_calibration_log(robot: BenchRobot, phases: Sequence[Phase], **options: Any) -> RobotLog:
    """The log the calibration program writes on ``robot`` (:func:`bench_calibration_run`)."""
    return bench_calibration_run(robot, phases, **options).log


def bench_calibration_run(
    robot: BenchRobot,
    phases: Sequence[Phase],
    *,
    wall_distance: float = 0.5,
    period: float = 0.05,
    drive: Drive = Drive(),
    seed: int = 0,
    measure_final_gap: bool = True,
    front_ir_fault: Callable[[int, int], int] | None = None,
    speed_ripple: float = SPEED_RIPPLE,
) -> BenchRun:
    """The calibration program's run on ``robot`` (this module's model).

    Args:
        robot: The true robot.
        phases: The program's phase table (``phases.json`` of ``khepera-gym robot-program
            calibrate``).
        wall_distance: The true gap (m) between the shell and the wall at the start; the user
            types it to the nearest mm.
        period: The program's control period (s).
        drive: The motor controller the program set.
        seed: The noise, the clocks' phases and the program's timing.
        measure_final_gap: Whether the user measures the final gap (to the nearest mm).
        front_ir_fault: A fault of the front infrared sensor: (row, reading) → what it reads
            instead (a stuck sensor, a glitch).
        speed_ripple: The wheels' ripple (speed units a tick; 0: none).
    """
    # Two independent streams (the program's timing and the user's; the robot's noise), from
    # the seed's own sequence: seeds n and n + 1 share nothing.
    program_stream, robot_stream = np.random.SeedSequence(seed).spawn(2)
    rng = np.random.default_rng(program_stream)
    typed_gap = round(wall_distance * 1000.0) / 1000.0
    samples = max(1, min(10, round(period * 100)))
    pause = float(rng.uniform(*USER_PAUSE_S))
    limit = sum(p.seconds for p in phases) + pause + 10.0
    bench = _Bench(robot, drive, SHELL_RADIUS + wall_distance, limit, robot_stream)
    bench.ripple = speed_ripple
    program = BenchProgram(phases, period, typed_gap, 0.021, 0.1054)
    gyro_noise = rng.standard_normal(int(limit * GYRO_RATE_HZ) + 20)
    rows: list[dict[str, float | str]] = []
    notes: list[Note] = []
    tick = 0.0
    while True:
        wake = tick + (float(rng.uniform(*WAKE_LATE_S)) if rows else 0.0)
        reads = wake + np.sort(rng.uniform(*READ_LATENCY_S, 6))
        bench.advance(float(reads[-1]) + STEP_S)
        enc = bench.encoders(float(reads[1]))
        ir = bench.infrared(float(reads[2]), rng.standard_normal(8))
        if front_ir_fault is not None:
            ir[3] = front_ir_fault(len(rows), ir[3])
        us = bench.ultrasonic(float(reads[3]))
        decision = program.next_command(enc[0], enc[1], ir[3], us[2])
        if decision is None:
            break
        phase, left, right, asks_gap = decision
        if asks_gap:
            gap = bench.front_gap(float(reads[-1]))
            measured = round(gap * 1000.0) / 1000.0 if measure_final_gap else math.nan
            notes.append(Note(len(rows) - 1, "wall_gap_end_m", f"{measured:.4f}"))
        speed = bench.speed_reading.copy()
        acc = bench.accelerometer(float(reads[4]))
        row: dict[str, float | str] = {
            "time": round(wake, 4),
            "phase": phase,
            "cmd_left": left,
            "cmd_right": right,
            "speed_left": float(speed[0]),
            "speed_right": float(speed[1]),
            "enc_left": enc[0],
            "enc_right": enc[1],
            **{f"ir_{i}": v for i, v in enumerate(ir)},
            **{f"ground_{i}": round(GROUND_RAW + 5 * rng.standard_normal()) for i in range(4)},
            **{f"us_{i}": v for i, v in enumerate(us)},
            "acc_x": round(acc[0], 2),
            "acc_y": round(acc[1], 2),
            "acc_z": round(acc[2], 2),
            "gyro_x": 0.0,
            "gyro_y": 0.0,
            "gyro_z": round(bench.gyro(float(reads[5]), samples, gyro_noise), 2),
        }
        rows.append(row)
        sent = float(reads[-1]) + 0.0002
        bench.send(sent, left, right)
        if asks_gap:
            bench.advance(sent + pause)
            tick = bench.time
        tick += period
        if tick > limit - 1.0:
            break
    metadata = {
        "program": "calibrate",
        "khepera_gym": khepera_gym.__version__,
        "firmware": "independent model",
        "control_period_s": repr(period),
        "wheel_radius_m": "0.021",
        "axle_length_m": "0.1054",
        "motors": drive.mode,
        "acc_inc": drive.acc_inc if drive.mode == "profile" else 0,
        "acc_div": drive.acc_div,
        "min_speed_acc": drive.min_speed_acc,
        "min_speed_dec": drive.min_speed_dec,
        "gyro_samples": samples,
        "wall_distance_m": repr(typed_gap),
    }
    log = new_log(metadata, rows)
    log.notes = notes
    return BenchRun(log, np.asarray(bench.ir_poses[: len(rows)]), bench.wall_x)


__all__ = [
    "BenchRobot",
    "BenchRun",
    "Drive",
    "bench_calibration_log",
    "bench_calibration_run",
    "draw_bench_robot",
]
