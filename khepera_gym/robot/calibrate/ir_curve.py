"""The infrared response curve as the fit sees it: the simulator's own curve, 16 points
(``sensors.ir_curve``) joined by straight lines, then falling to the floor value between
200 mm and the range (src/sensors/ir.rs), each point free.

The simulator's reading is linear in the 16 points and the floor value, so for given distances
it is a matrix (:func:`curve_basis`) times those 17 numbers. A point is fitted where the logs
hold enough readings about it (:func:`points_seen`, :data:`MIN_READINGS`); the others (nearer
than the approach came, or saturated) are not identified: they are written along K-Team's
shape from the nearest fitted point (:func:`extend_curve`), with no uncertainty. Before a curve
is written it is made non-increasing and not below the floor, as the simulator requires
(:func:`writable_curve`).

No shape is assumed: K-Team's curve, a robot's smoother one and one of another sensor all fit.
The uncertainty of a point covers the curve the simulator can hold, 16 points and straight
lines, not the robot's own between the points (the report shows both).

Units: raw counts, m. Threading: none.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from khepera_gym.robot.calibrate.replay import IR_CURVE_MM, IR_RANGE, KTEAM_IR_CURVE

#: The readings a point needs (in units of readings at the point itself: each reading counts
#: the square of its weight on the point) to be fitted: with four, its noise alone is half a
#: reading's [E: a design choice]; fewer, and it is held along K-Team's shape.
MIN_READINGS = 4.0
#: The largest raw reading.
IR_MAX = 1023.0


def curve_basis(distance: npt.ArrayLike, range_m: float = IR_RANGE) -> npt.NDArray[np.float64]:
    """(n, 17): each reading's weight on the 16 points and the floor value, for readings at
    ``distance`` m (NaN: nothing in range), as ``IrModel::mean_raw`` interpolates."""
    mm = np.asarray(distance, dtype=np.float64) * 1000.0
    basis = np.zeros((len(mm), len(IR_CURVE_MM) + 1))
    far = ~np.isfinite(mm) | (mm >= range_m * 1000.0)
    basis[far, -1] = 1.0
    tail = ~far & (mm >= IR_CURVE_MM[-1])
    fraction = (mm[tail] - IR_CURVE_MM[-1]) / (range_m * 1000.0 - IR_CURVE_MM[-1])
    basis[tail, -2] = 1.0 - fraction
    basis[tail, -1] = fraction
    inside = ~far & ~tail
    d = np.clip(mm[inside], 0.0, None)
    upper = np.clip(np.searchsorted(IR_CURVE_MM, d, side="right"), 1, len(IR_CURVE_MM) - 1)
    low, high = IR_CURVE_MM[upper - 1], IR_CURVE_MM[upper]
    weight = (d - low) / (high - low)
    rows = np.nonzero(inside)[0]
    basis[rows, upper - 1] = 1.0 - weight
    basis[rows, upper] = weight
    return basis


def points_seen(basis: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Per point of the curve: the readings about it, each counting its weight squared."""
    return np.sum(basis[:, :-1] ** 2, axis=0)


def extend_curve(
    points: npt.NDArray[np.float64], fitted: npt.NDArray[np.bool_]
) -> npt.NDArray[np.float64]:
    """The 16 points with the unfitted ones along K-Team's shape: nearer than the first fitted
    point, its value times K-Team's ratio; farther than the last, likewise (within 0..1023)."""
    out = np.asarray(points, dtype=np.float64).copy()
    if not fitted.any():
        return KTEAM_IR_CURVE.copy()
    first, last = np.nonzero(fitted)[0][[0, -1]]
    for i in range(first):
        out[i] = out[first] * KTEAM_IR_CURVE[i] / KTEAM_IR_CURVE[first]
    for i in range(last + 1, len(out)):
        out[i] = out[last] * KTEAM_IR_CURVE[i] / KTEAM_IR_CURVE[last]
    return np.clip(out, 0.0, IR_MAX)


def writable_curve(
    points: npt.NDArray[np.float64], floor: float
) -> tuple[npt.NDArray[np.float64], list[str]]:
    """The curve as the simulator takes it: non-increasing with distance (pooled where the
    fitted points rise) and its 200 mm point not below the floor value; with what was changed."""
    out = np.clip(np.asarray(points, dtype=np.float64), 0.0, IR_MAX)
    notes = []
    # Pool adjacent violators: a rise between two points becomes their mean.
    values = list(out)
    weights = [1.0] * len(values)
    spans = [[i] for i in range(len(values))]
    i = 0
    while i < len(values) - 1:
        if values[i] < values[i + 1]:
            total = weights[i] + weights[i + 1]
            values[i] = (values[i] * weights[i] + values[i + 1] * weights[i + 1]) / total
            weights[i] = total
            spans[i] += spans.pop(i + 1)
            values.pop(i + 1)
            weights.pop(i + 1)
            i = max(i - 1, 0)
        else:
            i += 1
    pooled = np.empty_like(out)
    for value, span in zip(values, spans, strict=True):
        pooled[span] = value
    if np.any(np.abs(pooled - out) > 1e-9):
        moved = [f"{IR_CURVE_MM[i]:g} mm" for i in np.nonzero(np.abs(pooled - out) > 1e-9)[0]]
        notes.append(f"points at {', '.join(moved)} pooled: the fitted curve rose there")
    if pooled[-1] < floor:
        notes.append(
            f"the 200 mm point raised from {pooled[-1]:.1f} to the floor value {floor:.1f} (the "
            "simulator needs the curve at 0.2 m not below the floor)"
        )
        pooled = np.maximum(pooled, floor)
    return pooled, notes


__all__ = ["IR_MAX", "MIN_READINGS", "curve_basis", "extend_curve", "points_seen", "writable_curve"]
