"""How far a replay strays from the logged run: after given times from the start
(:func:`time_divergences`, for a policy's log), and over each moving phase of the calibration
manoeuvre (:func:`phase_divergences`): where the simulator's drive differs from the robot's,
the steps and turns show it, while the rest and the slow approach at the start of a
calibration log would read nothing whatever the fit.

A phase's divergence compares what the robot and the simulator did *during* it, each from
where it was at the phase's start (in that pose's frame), over the phase and the rest after it
(the robot comes to a stop), so that an earlier phase's error is not counted again: the
farthest apart they came, and the most their headings differed, on the way.

Units: m and rad. Threading: none.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from khepera_gym.robot.calibrate.logformat import RobotLog

#: When ``khepera-gym replay`` measures how far the simulated robot has gone from the logged
#: one (s after the start).
DIVERGENCE_TIMES = (1.0, 5.0, 10.0)
#: The phases in which the calibration program holds the robot still.
STILL_PHASES = ("rest", "wall_gap")


@dataclasses.dataclass(frozen=True)
class Divergence:
    """How far the simulated robot is from the logged one ``time`` s after the start: the
    distance between their positions (m) and the difference of their headings (rad); NaN when
    the log is shorter."""

    time: float
    position: float
    heading: float


@dataclasses.dataclass(frozen=True)
class PhaseDivergence:
    """What the simulated robot did differently over one moving phase (and the rest after it).

    Attributes:
        phase: Its name.
        rows: (first, last) rows compared.
        travel: How far the logged robot went (m) and ...
        turn: ... turned (rad) over them.
        position: The farthest apart (m) the two came over them, from a common start.
        heading: The largest difference of their turns (rad).
    """

    phase: str
    rows: tuple[int, int]
    travel: float
    turn: float
    position: float
    heading: float


def _wrap(angle: float) -> float:
    return float(np.angle(np.exp(1j * angle)))


def time_divergences(
    log: RobotLog,
    logged: npt.NDArray[np.float64],
    simulated: npt.NDArray[np.float64],
    rows_replayed: int,
    times: Sequence[float] = DIVERGENCE_TIMES,
) -> list[Divergence]:
    """The divergence after each of ``times`` (s, on the logged times) of the simulated path
    from the logged one (both (rows, 3), world frame)."""
    found = []
    for time in times:
        row = int(np.argmin(np.abs(log.time - log.time[0] - time)))
        if time > log.time[-1] - log.time[0] + 0.5 * log.period or row >= rows_replayed:
            found.append(Divergence(time, math.nan, math.nan))
            continue
        gap = float(np.hypot(*(logged[row, :2] - simulated[row, :2])))
        found.append(Divergence(time, gap, _wrap(logged[row, 2] - simulated[row, 2])))
    return found


def _relative(path: npt.NDArray[np.float64], first: int, last: int) -> npt.NDArray[np.float64]:
    """The move from row ``first`` to ``last`` in the frame of the pose at ``first``."""
    start, end = path[first], path[last]
    c, s = math.cos(start[2]), math.sin(start[2])
    dx, dy = end[0] - start[0], end[1] - start[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, end[2] - start[2]])


def phase_divergences(
    log: RobotLog,
    logged: npt.NDArray[np.float64],
    simulated: npt.NDArray[np.float64],
    rows_replayed: int,
) -> list[PhaseDivergence]:
    """Per moving phase of the log (commands not all zero), in order: its divergence."""
    starts = [0] + [r for r in range(1, len(log)) if log.phases[r] != log.phases[r - 1]]
    moving = [
        r
        for r in starts
        if log.phases[r] not in STILL_PHASES
        and np.any(log.commands[r : _end(starts, r, len(log))] != 0)
    ]
    found = []
    for k, first in enumerate(moving):
        last = moving[k + 1] if k + 1 < len(moving) else len(log) - 1
        last = min(last, rows_replayed - 1)
        if last <= first:
            continue
        moves = [
            (_relative(logged, first, row), _relative(simulated, first, row))
            for row in range(first, last + 1)
        ]
        apart = max(float(np.hypot(m[0] - t[0], m[1] - t[1])) for m, t in moves)
        turned = max((_wrap(m[2] - t[2]) for m, t in moves), key=abs)
        mine = moves[-1][0]
        found.append(
            PhaseDivergence(
                phase=str(log.phases[first]),
                rows=(first, last),
                travel=float(np.hypot(mine[0], mine[1])),
                turn=float(mine[2]),
                position=apart,
                heading=turned,
            )
        )
    return found


def _end(starts: Sequence[int], start: int, rows: int) -> int:
    later = [s for s in starts if s > start]
    return later[0] if later else rows


__all__ = [
    "DIVERGENCE_TIMES",
    "STILL_PHASES",
    "Divergence",
    "PhaseDivergence",
    "phase_divergences",
    "time_divergences",
]
