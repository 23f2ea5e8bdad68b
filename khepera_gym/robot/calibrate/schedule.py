"""The calibration manoeuvre: the phases the calibration program drives through on the bench, as
data (:func:`calibration_phases`), and the one state machine that runs them
(:class:`PhaseRunner`).

The C program (``khepera_calibrate_main.c``, written by :mod:`~khepera_gym.robot.calibrate.program`)
gets the same table and runs the same state machine, step for step; the synthetic robot of
:mod:`~khepera_gym.robot.calibrate.synthetic` runs this one in the simulator. The manoeuvre, about
two minutes:

1. rest (the gyroscope's bias, the infrared floor);
2. a slow approach to a white wall, from the measured gap given on the command line (the
   infrared curve and the ultrasonic offset against distance by the encoders), that cannot hit
   the wall (:class:`ApproachWatch`): it stops when the front infrared sensor reads
   :data:`APPROACH_STOP_IR` on :data:`APPROACH_DEBOUNCE` rows in a row, or when the wall may be
   :data:`APPROACH_CLEARANCE_M` away for wheels :data:`RADIUS_TOLERANCE` larger than nominal, and
   slows down near the wall; the front ultrasonic sensor, where it is in range, checks the gap
   the user gave; a pause in which the user may measure the final gap (the wheel radius);
3. back to the start (the same readings, moving away);
4. a spin in place of :data:`SPIN_TURNS` turns, which leaves the robot facing away from the wall
   (the axle against the gyroscope);
5. steps forward and backward at several speeds, then turns in place both ways (the drive's
   acceleration and lag), each followed by a rest.

Units: commands in K-Team speed units (0.678181 mm/s at 21 mm wheels), times in s, distances in
m, angles in rad. Threading: none.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

#: The phase kinds (the C program's ``phase_kind`` values, in this order).
KINDS = ("timed", "approach", "return", "spin", "gap")
#: Rest at the start and end (s): at the start, the gyroscope's bias and noise and the front
#: ultrasonic sensor's noise (50 of its 100 ms sweeps: a standard deviation from 50 readings
#: is good to a tenth) are measured with the robot still.
REST_LONG_S = 5.0
#: Rest after a step or a turn (s).
REST_S = 1.0
#: Speed of the wall approach (speed units, 20 mm/s at 21 mm wheels): slow, so that the infrared
#: curve is sampled every millimetre at 20 Hz ...
APPROACH_UNITS = 30
#: ... and near the wall (14 mm/s): K-Team's default min_speed_acc, below which the profile
#: raises an order (manual §4.14.2, docs/drive.md), so that the robot does slow down.
APPROACH_SLOW_UNITS = 20
#: The approach stops when the front infrared sensor reads at least this (raw) on
#: APPROACH_DEBOUNCE consecutive rows (one glitch does not stop it). Every robot of the real
#: robots' spread reaches it (synthetic.SPREAD, ir_gain >= 0.85): K-Team's curve reads 764 at
#: 40 mm and 889 at 35 mm (docs/robot.md §3), 0.85 of which is 650 and 756; 700 is about 38 mm
#: from the wall at gain 0.85 and 45 mm at gain 1.15.
APPROACH_STOP_IR = 700
#: Consecutive rows (50 ms each at the default period) a stop condition must hold: a glitch of
#: one or two readings passes [E: a design choice], at the approach's 20 mm/s 3 mm of travel.
APPROACH_DEBOUNCE = 3
#: The approach slows down when the front infrared sensor reads this (raw; about 70 mm on
#: K-Team's curve) or the wall may be APPROACH_SLOW_GAP_M away (the last few centimetres, where
#: the stops act [E: a design choice]).
APPROACH_SLOW_IR = 300
APPROACH_SLOW_GAP_M = 0.06
#: The odometry's stop: the approach ends when the wall may be this close (m) for wheels
#: RADIUS_TOLERANCE larger than the program's nominal ones. Stopping then takes a few
#: millimetres at most (a period, the motors' lag and the profile's ramp, tests/
#: test_calibrate_approach.py).
APPROACH_CLEARANCE_M = 0.010
#: The wheel radius may differ from nominal by this fraction: three times the real robots'
#: spread of 1 % (synthetic.SPREAD["wheel_radius"], one standard deviation).
RADIUS_TOLERANCE = 0.03
#: The front ultrasonic sensor's reading (cm) is trusted to this (m): K-Team's ±2 cm tolerance
#: (manual §4.2) and three standard deviations of 1 cm of noise [E].
US_TOLERANCE_M = 0.05
#: The ultrasonic sensors measure from 25 cm; code 0 means nearer (manual §4.2, docs/robot.md §5).
US_MIN_M = 0.25
#: The front ultrasonic sensor's index (L, FL, F, FR, R).
FRONT_US = 2
#: Speed back to the start (speed units).
RETREAT_UNITS = 60
#: Wheel speed of the spin in place (speed units) and its turns: 2.5 turns leave the robot
#: facing away from the wall, with the space of the steps ahead of it.
SPIN_UNITS = 150
SPIN_TURNS = 2.5
#: Speeds of the forward and backward steps, and of the turns in place (speed units).
STEP_UNITS = (100, 300, 600)
TURN_UNITS = (100, 300)
#: A step lasts at least this long (s), and 1.5 times the drive's time to reach its speed.
STEP_MIN_S = 1.0
#: Steps that would carry the robot farther than this (m) are left out (slow profiles).
STEP_MAX_TRAVEL_M = 0.6
#: One speed unit at the nominal 21 mm wheels (m/s).
SPEED_UNIT = 0.678181e-3
#: The front infrared sensor's index (K-Team order).
FRONT_IR = 3


@dataclasses.dataclass(frozen=True)
class Phase:
    """One phase of the manoeuvre.

    Attributes:
        name: Its name in the log's ``phase`` column.
        kind: One of :data:`KINDS`: "timed" drives (left, right) for ``seconds``; "approach"
            drives until the front IR reads ``limit`` (debounced) or the wall may be near
            (:class:`PhaseRunner`), slower near the wall;
            "return" drives until the encoders are back where the last approach started;
            "spin" drives until the encoders have turned ``limit`` rad; "gap" stops and asks
            for the measured gap (one row, the pause's, with the readings from before it). The
            approach, the return and the spin stop after ``seconds`` at most.
        left: Left wheel command (speed units).
        right: Right wheel command (speed units).
        seconds: Its duration (timed) or time limit (the others).
        limit: The approach's IR threshold (raw) or the spin's angle (rad); else 0.
    """

    name: str
    kind: str
    left: int
    right: int
    seconds: float
    limit: float = 0.0


def step_seconds(units: int, accel: float) -> float:
    """How long a step of ``units`` lasts (s) for a drive of ``accel`` m/s²."""
    return max(STEP_MIN_S, 1.5 * units * SPEED_UNIT / accel)


def calibration_phases(accel: float, wall_distance_guess: float = 0.6) -> tuple[Phase, ...]:
    """The phases of the manoeuvre for a drive of ``accel`` m/s² (the profile's, or the speed
    mode's estimate): steps last long enough to reach their speed.

    Args:
        accel: The drive's acceleration (m/s²).
        wall_distance_guess: The largest gap to the wall the time limits allow for (m).
    """
    rest = Phase("rest", "timed", 0, 0, REST_S)
    approach_s = wall_distance_guess / (APPROACH_UNITS * SPEED_UNIT) * 1.5 + 5.0
    retreat_s = wall_distance_guess / (RETREAT_UNITS * SPEED_UNIT) * 1.5 + 5.0
    spin_angle = SPIN_TURNS * 2.0 * math.pi
    spin_s = spin_angle * 0.1054 / (2.0 * SPIN_UNITS * SPEED_UNIT) * 1.5 + 5.0
    phases = [
        Phase("rest", "timed", 0, 0, REST_LONG_S),
        Phase(
            "wall_approach",
            "approach",
            APPROACH_UNITS,
            APPROACH_UNITS,
            approach_s,
            APPROACH_STOP_IR,
        ),
        rest,
        Phase("wall_gap", "gap", 0, 0, 0.0),
        Phase("wall_retreat", "return", -RETREAT_UNITS, -RETREAT_UNITS, retreat_s),
        rest,
        Phase("spin", "spin", -SPIN_UNITS, SPIN_UNITS, spin_s, spin_angle),
        rest,
    ]
    for units in STEP_UNITS:
        seconds = step_seconds(units, accel)
        if units * SPEED_UNIT * seconds > STEP_MAX_TRAVEL_M:
            continue
        phases += [
            Phase(f"forward_{units}", "timed", units, units, seconds),
            rest,
            Phase(f"backward_{units}", "timed", -units, -units, seconds),
            rest,
        ]
    for units in TURN_UNITS:
        seconds = step_seconds(units, accel)
        phases += [
            Phase(f"left_{units}", "timed", -units, units, seconds),
            rest,
            Phase(f"right_{units}", "timed", units, -units, seconds),
            rest,
        ]
    phases.append(Phase("rest", "timed", 0, 0, REST_LONG_S))
    return tuple(phases)


def phase_steps(seconds: float, period: float) -> int:
    """Control steps of ``seconds`` (rounded half up, as the C program does)."""
    return math.floor(seconds / period + 0.5)


class PhaseRunner:
    """Runs the phases one control step at a time, from the encoders, the front infrared sensor
    and the front ultrasonic sensor; the C program's ``next_command`` does exactly the same.

    The approach (:meth:`_approach`) keeps the least gap to the wall that the readings allow:
    the wall at the gap the user gave (or nearer, when the ultrasonic sensor says so beyond its
    tolerance), less the travel by the encoders for wheels :data:`RADIUS_TOLERANCE` larger than
    nominal. It stops when that gap is :data:`APPROACH_CLEARANCE_M`, when the front infrared
    sensor reads :data:`APPROACH_STOP_IR` on :data:`APPROACH_DEBOUNCE` rows in a row, or when the
    ultrasonic sensor says "nearer than 25 cm" as many rows while the wall is believed farther; it
    drives at :data:`APPROACH_SLOW_UNITS` while that gap is under :data:`APPROACH_SLOW_GAP_M` or
    the infrared sensor reads :data:`APPROACH_SLOW_IR`.

    Args:
        phases: The manoeuvre.
        period: The control period (s).
        wall_distance: The measured gap to the wall at the start (m).
        metres_per_pulse: The program's nominal wheel travel per encoder pulse (m).
        axle_length: The program's nominal axle length (m).
        ask_gap: Called at a "gap" phase; returns the measured gap (m) or None.
    """

    def __init__(
        self,
        phases: tuple[Phase, ...],
        period: float,
        wall_distance: float,
        metres_per_pulse: float,
        axle_length: float,
        ask_gap: Callable[[], float | None] = lambda: None,
    ) -> None:
        self.phases = phases
        self.period = period
        self.wall_distance = wall_distance
        self.metres_per_pulse = metres_per_pulse
        self.axle_length = axle_length
        self.ask_gap = ask_gap
        self.index = 0
        self.step = 0
        self.start = (0, 0)
        self.approach_start = 0.0
        #: The approach's state: the nearest the wall may be (m of travel from the approach's
        #: start, for the largest wheels), rows in a row of each stop condition, slow or not.
        self.wall = wall_distance
        self.ir_rows = 0
        self.near_rows = 0
        self.close_rows = 0
        self.slow = False
        #: Gaps measured at "gap" phases, with the number of rows logged before each.
        self.gaps: list[float | None] = []

    @property
    def finished(self) -> bool:
        """Whether every phase has run."""
        return self.index >= len(self.phases)

    def next_command(
        self, enc_left: int, enc_right: int, ir_front: int, us_front: int = 1000
    ) -> tuple[Phase, int, int]:
        """The phase and command of this step, given the readings taken at its start (the
        encoders, the front infrared sensor's raw value and the front ultrasonic sensor's cm or
        code).

        Raises:
            StopIteration: Every phase has run.
        """
        while self.index < len(self.phases):
            phase = self.phases[self.index]
            if self.step == 0:
                self.start = (enc_left, enc_right)
                if phase.kind == "approach":
                    self.approach_start = 0.5 * (enc_left + enc_right)
                    self.wall = self.wall_distance
                    self.ir_rows = self.near_rows = self.close_rows = 0
            if phase.kind == "gap":
                # This row stands for the pause (its readings were taken before it); the next
                # phase starts on the next row.
                self.gaps.append(self.ask_gap())
                self.index += 1
                return phase, phase.left, phase.right
            if self._done(phase, enc_left, enc_right, ir_front, us_front):
                self.index += 1
                self.step = 0
                continue
            self.step += 1
            if phase.kind == "approach" and self.slow:
                return phase, APPROACH_SLOW_UNITS, APPROACH_SLOW_UNITS
            return phase, phase.left, phase.right
        raise StopIteration

    def _done(
        self, phase: Phase, enc_left: int, enc_right: int, ir_front: int, us_front: int
    ) -> bool:
        timed_out = self.step >= phase_steps(phase.seconds, self.period)
        if phase.kind == "timed" or timed_out:
            return timed_out
        mean = 0.5 * (enc_left + enc_right)
        if phase.kind == "approach":
            travel = (mean - 0.5 * (self.start[0] + self.start[1])) * self.metres_per_pulse
            return self._approach(phase, travel, ir_front, us_front)
        if phase.kind == "return":
            return mean <= self.approach_start
        # spin
        turned = (
            ((enc_right - self.start[1]) - (enc_left - self.start[0]))
            * self.metres_per_pulse
            / self.axle_length
        )
        return abs(turned) >= phase.limit

    def _approach(self, phase: Phase, travel: float, ir_front: int, us_front: int) -> bool:
        """Whether the approach is over after ``travel`` m by the nominal odometry; sets
        :attr:`slow` for the command."""
        reach = travel * (1.0 + RADIUS_TOLERANCE)
        believed = self.wall - travel
        us_m = us_front / 100.0
        # The ultrasonic sensor measures a distance (not a code) nearer than the gap believed
        # allows: the wall is nearer than the user said.
        contradicts = 0 < us_front < 1000 and us_m + US_TOLERANCE_M < believed
        self.near_rows = self.near_rows + 1 if contradicts else 0
        if self.near_rows >= APPROACH_DEBOUNCE:
            self.wall = min(self.wall, us_m - US_TOLERANCE_M + reach)
        too_close = us_front == 0 and believed > US_MIN_M + US_TOLERANCE_M
        self.close_rows = self.close_rows + 1 if too_close else 0
        self.ir_rows = self.ir_rows + 1 if ir_front >= phase.limit else 0
        least_gap = self.wall - reach
        self.slow = ir_front >= APPROACH_SLOW_IR or least_gap < APPROACH_SLOW_GAP_M
        return (
            self.ir_rows >= APPROACH_DEBOUNCE
            or self.close_rows >= APPROACH_DEBOUNCE
            or least_gap <= APPROACH_CLEARANCE_M
        )


__all__ = [
    "APPROACH_CLEARANCE_M",
    "APPROACH_DEBOUNCE",
    "APPROACH_SLOW_GAP_M",
    "APPROACH_SLOW_IR",
    "APPROACH_SLOW_UNITS",
    "APPROACH_STOP_IR",
    "APPROACH_UNITS",
    "FRONT_IR",
    "FRONT_US",
    "KINDS",
    "RADIUS_TOLERANCE",
    "US_MIN_M",
    "US_TOLERANCE_M",
    "Phase",
    "PhaseRunner",
    "calibration_phases",
    "phase_steps",
    "step_seconds",
]
