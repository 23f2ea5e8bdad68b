"""The time column of a robot log: which simulator step each row stands for, and the gaps.

A program wakes every control period, a few milliseconds late (Linux's scheduling), and a row
can go missing (an overrun, a dropped write); the calibration program also waits for the user
to measure the final gap (the ``wall_gap`` row). The replays (:mod:`~khepera_gym.robot.calibrate.
replay`) step the simulator on the logged times: row k stands for step n_k, where each interval
counts as many whole periods as it lasts, at least one (:func:`row_steps`); so a jitter of a
few ms changes nothing and a missing row leaves the simulator two steps between its neighbours.
Intervals beyond :data:`GAP_PERIODS` periods are reported (:func:`time_gaps`); the one after
the gap's question is expected.

Units: s. Threading: none.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from khepera_gym.robot.calibrate.logformat import RobotLog

#: An interval longer than this many control periods is a gap.
GAP_PERIODS = 1.5
#: The phase whose row stands for the user's measurement of the final gap (schedule.py).
PAUSE_PHASE = "wall_gap"


@dataclasses.dataclass(frozen=True)
class TimeGap:
    """An interval of the time column longer than :data:`GAP_PERIODS` periods.

    Attributes:
        row: The row after the interval.
        seconds: The interval (s).
        expected: Whether it follows the gap's question (the user's pause).
    """

    row: int
    seconds: float
    expected: bool

    def describe(self, period: float) -> str:
        """One line for the report."""
        if self.expected:
            return f"row {self.row}: {self.seconds:.2f} s after the gap's question (the pause)"
        return (
            f"row {self.row}: {self.seconds * 1000:.0f} ms since the row before "
            f"({self.seconds / period:.1f} control periods: rows missing or a late wake-up)"
        )


def row_steps(log: RobotLog) -> npt.NDArray[np.int64]:
    """The simulator's step of each row (row 0: step 0), from the logged times."""
    intervals = np.diff(log.time) / log.period
    steps = np.maximum(np.rint(intervals), 1).astype(np.int64)
    return np.concatenate([[0], np.cumsum(steps)])


def row_intervals(log: RobotLog) -> npt.NDArray[np.float64]:
    """The time (s) since the row before, per row (row 0: one period)."""
    return np.concatenate([[log.period], np.diff(log.time)])


def time_gaps(log: RobotLog) -> list[TimeGap]:
    """The intervals of the time column longer than :data:`GAP_PERIODS` periods."""
    intervals = np.diff(log.time)
    found = []
    for index in np.nonzero(intervals > GAP_PERIODS * log.period)[0]:
        expected = bool(log.phases[index] == PAUSE_PHASE)
        found.append(TimeGap(int(index) + 1, float(intervals[index]), expected))
    return found


__all__ = ["GAP_PERIODS", "PAUSE_PHASE", "TimeGap", "row_intervals", "row_steps", "time_gaps"]
