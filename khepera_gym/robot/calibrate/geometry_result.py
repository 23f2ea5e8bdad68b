"""Stage 1's result: the fitted parameters of :class:`~khepera_gym.robot.calibrate.geometry.
GeometryFit` as :class:`~khepera_gym.robot.calibrate.solver.Estimate` values, each with its
statistical and systematic parts, "not identified" where the logs cannot tell, flagged at the
search's bounds; the noise keys from :mod:`~khepera_gym.robot.calibrate.noise`; K-Team's gain and
distance scale nearest the fitted curve, for the report.

Units: SI for the values (raw counts for the infrared). Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import numpy.typing as npt

import khepera_gym.robot.calibrate.ir_curve as ic
import khepera_gym.robot.calibrate.replay as rp
from khepera_gym.robot.calibrate.noise import Noise
from khepera_gym.robot.calibrate.solver import Estimate
from khepera_gym.robot.calibrate.synthetic import ir_curve
from khepera_gym.robot.calibrate.uncertainty import Uncertainty

#: What determines each named value, for the report.
HOW = {
    "wheel_radius": "the wall: the gap at the start, the final gap measured and the front "
    "ultrasonic sensor against the encoders' travel",
    "axle_length": "the gyroscope's yaw rate against the encoders' (spin and turns)",
    "gyro_bias": "the gyroscope against the encoders' yaw rate, every row",
    "us_offset": "the front ultrasonic sensor against the wall's distance by the encoders",
    "ir_floor_value": "the infrared sensors with nothing within 0.25 m",
}
KEYS = {
    "wheel_radius": ("robot.wheel_radius", "m"),
    "axle_length": ("robot.axle_length", "m"),
    "gyro_bias": ("sensors.gyro_bias", "°/s"),
    "us_offset": ("sensors.us_offset", "m"),
    "ir_floor_value": ("sensors.ir_floor_value", "raw"),
}


@dataclasses.dataclass
class GeometryResult:
    """Stage 1's values (SI) with their uncertainties and what the report draws."""

    wheel_radius: Estimate
    axle_length: Estimate
    gyro_bias: Estimate
    gyro_noise_sigma: Estimate
    us_offset: Estimate
    us_noise_sigma: Estimate
    #: K-Team's curve's gain and distance scale nearest the fitted curve (for the report).
    ir_gain: Estimate
    ir_scale: Estimate
    ir_floor_value: Estimate
    ir_noise_sigma: Estimate
    ir_curve: Estimate
    #: Per log: the path replay at the fitted geometry.
    paths: list[rp.PathReplay]
    #: Per channel: the residuals (°/s, raw, m, m) and their expected noise.
    residuals: dict[str, npt.NDArray[np.float64]]
    expected: dict[str, npt.NDArray[np.float64]]
    #: Per channel: the noise the log shows where nothing changes.
    noise: dict[str, Noise]
    #: Per channel: the readings set aside as outliers.
    outliers: dict[str, int]
    #: The residuals' sum of squares over their expected noise, per residual (all channels).
    chi2: float


def _bound_flags(value: float, low: float, high: float, scale: float) -> list[str]:
    if value - low < 1e-3 * scale:
        return [f"at the search's lower bound ({low:g}): the logs push it beyond"]
    if high - value < 1e-3 * scale:
        return [f"at the search's upper bound ({high:g}): the logs push it beyond"]
    return []


def build_result(
    fit: Any,
    x: npt.NDArray[np.float64],
    selections: list[Any],
    spread: dict[str, Uncertainty],
    outliers: dict[str, int],
) -> GeometryResult:
    """The estimates of a finished :class:`~khepera_gym.robot.calibrate.geometry.GeometryFit`
    (``fit``): its two stages' uncertainties (``spread``, by stage), the curve's and the
    floor's with the wheel radius's carried into them (they are read at the distances it
    gives)."""
    names, first_point = fit.names, fit.first_point

    column = {}
    for stage, mask in fit.stages.items():
        column.update({int(i): (stage, j) for j, i in enumerate(np.nonzero(mask)[0])})
    radius = column[0][1]

    def parts(i: int) -> tuple[float, float, float]:
        stage, j = column[i]
        found = spread[stage]
        scale = fit.scale[i]
        stat, sys = found.stat[j] * scale, found.sys[j] * scale
        if stage == "curve":
            slope = abs(float(fit.curve_radius_slope[i]))
            geometry = spread["geometry"]
            stat = math.hypot(stat, slope * geometry.stat[radius] * fit.scale[0])
            sys = math.hypot(sys, slope * geometry.sys[radius] * fit.scale[0])
        return math.hypot(stat, sys), stat, sys

    named: dict[str, Estimate] = {}
    for i, name in enumerate(names[:first_point]):
        key, unit = KEYS[name]
        total, stat, sys = parts(i)
        estimate = Estimate(key, float(x[i]), total, unit, HOW[name], stat, sys)
        if fit.pinned[i]:
            estimate.sigma = estimate.sigma_stat = estimate.sigma_sys = math.nan
            estimate.identified = False
            estimate.flags.append(
                f"not identified: the logs tell it less well than the real robots' spread "
                f"(± {fit.prior[i] * fit.scale[i]:.3g} {unit}); the nominal value is kept"
            )
        elif fit.bounded[i]:
            estimate.flags += _bound_flags(x[i], fit.lower[i], fit.upper[i], fit.scale[i]) or [
                "reached a bound of the search on the way"
            ]
        named[name] = estimate
    curve, curve_estimate = _curve_estimate(fit, x, parts)
    count = rp.GYRO_DEG_S_PER_COUNT
    gyro_noise, ir_noise, us_noise = (fit.noise[k][0] for k in ("gyro", "ir", "us"))
    gyro_sigma = gyro_noise.less_rounding(1.0)
    ir_sigma = ir_noise.less_rounding(1.0)
    us_sigma = us_noise.less_rounding(1.0)
    gain, scale = _nearest_kteam(curve_estimate)
    channels = fit._channels(x, selections)
    units = {"gyro": count, "ir": 1.0, "us": 0.01, "gap": 1.0}
    residuals = {
        k: np.concatenate(v[0]) * units[k] if v[0] else np.zeros(0) for k, v in channels.items()
    }
    expected = {
        k: np.concatenate(v[1]) * units[k] if v[1] else np.zeros(0) for k, v in channels.items()
    }
    weighted, _ = fit.residuals(x, selections)
    del curve
    return GeometryResult(
        wheel_radius=named["wheel_radius"],
        axle_length=named["axle_length"],
        gyro_bias=named["gyro_bias"],
        gyro_noise_sigma=_noise_estimate(
            "sensors.gyro_noise_sigma",
            gyro_noise,
            gyro_sigma,
            count,
            "°/s",
            "the gyroscope where the robot stands still (less the rounding to counts)",
        ),
        us_offset=named["us_offset"],
        us_noise_sigma=_noise_estimate(
            "sensors.us_noise_sigma",
            us_noise,
            us_sigma,
            0.01,
            "m",
            "the front ultrasonic sensor at rest before the wall (less the rounding to cm)",
        ),
        ir_gain=gain,
        ir_scale=scale,
        ir_floor_value=named["ir_floor_value"],
        ir_noise_sigma=_noise_estimate(
            "sensors.ir_noise_sigma",
            ir_noise,
            ir_sigma,
            1.0,
            "raw",
            "the infrared sensors seeing nothing (less the rounding to counts)",
        ),
        ir_curve=curve_estimate,
        paths=[path for path, _ in fit.paths(x[0], x[1])],
        residuals=residuals,
        expected=expected,
        noise={k: v[0] for k, v in fit.noise.items()},
        outliers=outliers,
        chi2=float(weighted @ weighted) / max(len(weighted) - int(fit.free.sum()), 1),
    )


def _noise_estimate(
    key: str, noise: Noise, less: tuple[float, float], unit_scale: float, unit: str, how: str
) -> Estimate:
    value, error = less
    estimate = Estimate(
        key, value * unit_scale, error * unit_scale, unit, how, error * unit_scale, 0.0
    )
    if not (noise.count >= 5 and math.isfinite(value)):
        estimate.value, estimate.sigma = math.nan, math.nan
        estimate.identified = False
        estimate.flags.append(f"not identified: {noise.count} readings of {noise.source}")
    if noise.outliers:
        estimate.flags.append(f"{noise.outliers} outlier(s) of {noise.source} set aside")
    return estimate


def _curve_estimate(fit: Any, x: npt.NDArray[np.float64], parts: Any) -> tuple[Any, Estimate]:
    first = fit.first_point
    fitted = fit.free[first:].copy()
    points = ic.extend_curve(x[first:], fitted)
    written, notes = ic.writable_curve(points, float(x[4]))
    sigma, stat, sys = [], [], []
    for k in range(16):
        if fitted[k]:
            total, s, y = parts(first + k)
            sigma.append(float(total))
            stat.append(float(s))
            sys.append(float(y))
        else:
            sigma.append(math.nan)
            stat.append(math.nan)
            sys.append(math.nan)
    unseen = [f"{rp.IR_CURVE_MM[k]:g}" for k in range(16) if not fitted[k]]
    how = "each point fitted to the infrared readings near the wall (straight lines between them)"
    estimate = Estimate(
        "sensors.ir_curve",
        [float(v) for v in written],
        sigma,
        "raw",
        how,
        stat,
        sys,
        [bool(v) for v in fitted],
    )
    if unseen:
        estimate.flags.append(
            f"not identified at {', '.join(unseen)} mm (the robot did not come so near, or the "
            "sensor saturated there): extended along K-Team's shape from the nearest fitted point"
        )
    estimate.flags += notes
    return points, estimate


def _nearest_kteam(curve: Estimate) -> tuple[Estimate, Estimate]:
    """K-Team's curve's gain and distance scale nearest the fitted points (weighted by their
    uncertainty), with the uncertainty the points give them (as if independent)."""
    from scipy.optimize import least_squares

    values = np.asarray(curve.value, float)
    sigma = np.asarray(curve.sigma, float)
    seen = np.isfinite(sigma) & (sigma > 0)
    nan = (math.nan, math.nan)
    if seen.sum() < 3:
        found = [nan, nan]
    else:

        def residuals(p: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
            return (ir_curve(p[0], p[1])[seen] - values[seen]) / sigma[seen]

        result = least_squares(
            residuals, np.array([1.0, 1.0]), bounds=([0.3, 0.6], [2.0, 1.6]), diff_step=1e-4
        )
        covariance = np.linalg.pinv(result.jac.T @ result.jac)
        found = [(float(result.x[k]), float(math.sqrt(max(covariance[k, k], 0.0)))) for k in (0, 1)]
    how = "K-Team's curve nearest the fitted points: {} (for the report; the points are written)"
    return (
        Estimate("ir_gain", found[0][0], found[0][1], "", how.format("its value's factor")),
        Estimate("ir_scale", found[1][0], found[1][1], "", how.format("its distances' factor")),
    )


__all__ = ["GeometryResult", "build_result"]
