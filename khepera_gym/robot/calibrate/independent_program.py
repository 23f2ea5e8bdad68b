"""The calibration program's state machine as the C program runs it (``next_command``,
``phase_done`` and ``approach_done`` of ``khepera_calibrate_main.c``), transcribed from the C for
the independent bench model (:mod:`~khepera_gym.robot.calibrate.independent`) rather than taken from
:class:`~khepera_gym.robot.calibrate.schedule.PhaseRunner`: the test that both play the C program's
log row for row (tests/test_calibrate_independent.py) then checks the two transcriptions against
each other. The constants are the program's (``khepera_calibrate_config.h``, from
:mod:`~khepera_gym.robot.calibrate.schedule`).

Units: speed units, pulses, raw counts, cm, m. Threading: none.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import khepera_gym.robot.calibrate.schedule as config
from khepera_gym.robot.calibrate.schedule import Phase

#: Pulses a wheel turn (manual §4.14).
PULSES_PER_TURN = 19456


class BenchProgram:
    """``next_command`` of the C program.

    Args:
        phases: The phase table.
        period: The control period (s).
        wall_distance: The gap typed on the command line (m).
        wheel_radius: The program's nominal wheel radius (m).
        axle_length: The program's nominal axle (m).
    """

    def __init__(
        self,
        phases: Sequence[Phase],
        period: float,
        wall_distance: float,
        wheel_radius: float,
        axle_length: float,
    ) -> None:
        self.phases = list(phases)
        self.period = period
        self.wall_distance = wall_distance
        self.metres_per_pulse = 2.0 * math.pi * wheel_radius / PULSES_PER_TURN
        self.axle_length = axle_length
        self.index = 0
        self.step = 0
        self.start = (0, 0)
        self.approach_start = 0.0
        self.wall = 0.0
        self.ir_rows = self.near_rows = self.close_rows = 0
        self.slow = False

    def next_command(
        self, left_pulses: int, right_pulses: int, ir_front: int, us_front: int
    ) -> tuple[str, int, int, bool] | None:
        """(phase name, left, right, whether this row asks for the gap), or None at the end."""
        while self.index < len(self.phases):
            phase = self.phases[self.index]
            if self.step == 0:
                self.start = (left_pulses, right_pulses)
                if phase.kind == "approach":
                    self.approach_start = 0.5 * (left_pulses + right_pulses)
                    self.wall = self.wall_distance
                    self.ir_rows = self.near_rows = self.close_rows = 0
            if phase.kind == "gap":
                self.index += 1
                return phase.name, phase.left, phase.right, True
            if self._phase_done(phase, left_pulses, right_pulses, ir_front, us_front):
                self.index += 1
                self.step = 0
                continue
            self.step += 1
            if phase.kind == "approach" and self.slow:
                slow = config.APPROACH_SLOW_UNITS
                return phase.name, slow, slow, False
            return phase.name, phase.left, phase.right, False
        return None

    def _phase_done(
        self, phase: Phase, left_pulses: int, right_pulses: int, ir_front: int, us_front: int
    ) -> bool:
        timed_out = self.step >= math.floor(phase.seconds / self.period + 0.5)
        mean = 0.5 * (left_pulses + right_pulses)
        if phase.kind == "timed" or timed_out:
            return timed_out
        if phase.kind == "approach":
            start = 0.5 * (self.start[0] + self.start[1])
            return self._approach_done(
                phase, (mean - start) * self.metres_per_pulse, ir_front, us_front
            )
        if phase.kind == "return":
            return mean <= self.approach_start
        turned = (
            ((right_pulses - self.start[1]) - (left_pulses - self.start[0]))
            * self.metres_per_pulse
            / self.axle_length
        )
        return abs(turned) >= phase.limit

    def _approach_done(self, phase: Phase, travel: float, ir_front: int, us_front: int) -> bool:
        reach = travel * (1.0 + config.RADIUS_TOLERANCE)
        believed = self.wall - travel
        us_m = us_front / 100.0
        if 0 < us_front < 1000 and us_m + config.US_TOLERANCE_M < believed:
            self.near_rows += 1
        else:
            self.near_rows = 0
        if (
            self.near_rows >= config.APPROACH_DEBOUNCE
            and us_m - config.US_TOLERANCE_M + reach < self.wall
        ):
            self.wall = us_m - config.US_TOLERANCE_M + reach
        if us_front == 0 and believed > config.US_MIN_M + config.US_TOLERANCE_M:
            self.close_rows += 1
        else:
            self.close_rows = 0
        self.ir_rows = self.ir_rows + 1 if ir_front >= phase.limit else 0
        least_gap = self.wall - reach
        self.slow = ir_front >= config.APPROACH_SLOW_IR or least_gap < config.APPROACH_SLOW_GAP_M
        return (
            self.ir_rows >= config.APPROACH_DEBOUNCE
            or self.close_rows >= config.APPROACH_DEBOUNCE
            or least_gap <= config.APPROACH_CLEARANCE_M
        )


__all__ = ["BenchProgram"]
