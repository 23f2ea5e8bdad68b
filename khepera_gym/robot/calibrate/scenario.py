"""The calibrated scenario: the fitted values as a TOML file that any env loads with
``config=``, each value with its standard uncertainty in a comment, and optionally a
domain-randomisation range of ± k uncertainties around it for the keys that take a
``[low, high]`` range (:func:`calibrated_toml`).

The file holds ``[robot]``, ``[motors]`` and ``[sensors]`` keys (and ``[physics]`` ones when the
robot's control period or the scenario the fit was made for differ from the defaults); every
other key keeps the env's default, so it overlays any task. Before it is written it is loaded by
the simulator (:func:`check_scenario`), so a file that an env would refuse is never written.

Units: SI, raw counts and speed units, as the scenario keys. Threading: none.
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Mapping
from typing import Any

import khepera_gym
from khepera_gym import _core
from khepera_gym.config import toml_value, tomllib
from khepera_gym.errors import ConfigError
from khepera_gym.robot.calibrate.fit import Calibration, Estimate

#: The keys of the estimates that take a [low, high] range, with the least value the range may
#: reach (None: any).
RANGE_KEYS: Mapping[str, float | None] = {
    "robot.axle_length": 1e-4,
    "motors.speed_accel": 1e-3,
    "sensors.gyro_bias": None,
    "sensors.ir_floor_value": 0.0,
    "sensors.ir_noise_sigma": 0.0,
    "sensors.us_offset": None,
    "sensors.us_noise_sigma": 0.0,
}
#: The task whose defaults the file is checked against (every task shares these sections).
CHECK_TASK = "nav"
#: How the header states the step the drive was fitted at (``khepera-gym replay`` reads it).
FITTED_AT = "Fitted at"
#: The order of the file's sections.
SECTIONS = ("robot", "motors", "sensors", "physics")


def _number(value: float, sigma: float) -> str:
    """A value with the digits its uncertainty warrants (two significant ones of it, at least
    four significant ones of the value)."""
    if not math.isfinite(sigma) or sigma <= 0:
        return repr(float(f"{value:.6g}"))
    decimals = max(0, 1 - math.floor(math.log10(sigma)))
    digits = max(4, decimals + (math.floor(math.log10(abs(value))) + 1 if value else 1))
    return repr(float(f"{value:.{digits}g}"))


def _sigma_text(estimate: Estimate) -> str:
    """ "± total (stat ±, sys ±) unit", or "not identified"."""
    sigma = float(estimate.sigma)  # type: ignore[arg-type]
    if estimate.identified is False or not math.isfinite(sigma):
        return "not identified"
    text = f"± {sigma:.2g} {estimate.unit}".rstrip()
    stat, sys = float(estimate.sigma_stat), float(estimate.sigma_sys)  # type: ignore[arg-type]
    if math.isfinite(stat) and math.isfinite(sys):
        systematic = f"systematic ± {sys:.2g}" if sys > 0 else "no systematic part found"
        text += f" (statistical ± {stat:.2g}, {systematic})"
    return text


def _default(key: str) -> Any:
    """The simulator's default of a scenario key."""
    section, _, leaf = key.partition(".")
    return tomllib.loads(_core.default_config(CHECK_TASK))[section][leaf]


def _leaf_sections() -> dict[str, str]:
    """Leaf key → its section, from the latest defaults of a task."""
    table = tomllib.loads(_core.default_config(CHECK_TASK))
    sections: dict[str, str] = {}
    for section, keys in table.items():
        if isinstance(keys, dict):
            for key in keys:
                sections.setdefault(key, section)
    return sections


def dotted(overrides: Mapping[str, Any]) -> dict[str, Any]:
    """Scenario overrides with every key as ``section.key`` (leaf names looked up).

    Raises:
        ConfigError: An unknown leaf name.
    """
    sections = _leaf_sections()
    out: dict[str, Any] = {}
    for key, value in overrides.items():
        if "." in key:
            out[key] = value
            continue
        if key not in sections:
            raise ConfigError(f"--set {key}: no scenario key of that name")
        out[f"{sections[key]}.{key}"] = value
    return out


def calibrated_toml(
    calibration: Calibration,
    *,
    randomise: float | None = None,
    base: Mapping[str, Any] | None = None,
    command: str = "khepera-gym calibrate",
) -> str:
    """The calibrated scenario as TOML text.

    Args:
        calibration: The fit (:func:`~khepera_gym.robot.calibrate.fit.calibrate`).
        randomise: Write ``[value - k σ, value + k σ]`` ranges with this k for the keys that
            take ranges (domain randomisation around the fitted values); None: single values.
        base: The scenario overrides the fit was made with (``--set``), written too.
        command: The command, for the header.
    """
    if randomise is not None and not (math.isfinite(randomise) and randomise > 0):
        raise ConfigError(
            f"--randomise must be a number > 0 of standard deviations, got {randomise}"
        )
    lines: dict[str, list[str]] = {section: [] for section in SECTIONS}
    values: dict[str, tuple[Any, str]] = {}
    for key, value in dotted(base or {}).items():
        values[key] = (value, "as given to the fit (--set)")
    drive = calibration.drive
    values["physics.dt"] = (calibration.period, "the programs' control period (the logs')")
    values["physics.substeps"] = (
        drive.substeps,
        f"the step ({drive.step * 1000:g} ms) the drive's lag was fitted at: it is an effective "
        "lag at that step, fit again if you change physics.dt or physics.substeps",
    )
    motors = calibration.motors
    values["motors.mode"] = (motors["mode"], f"the mode the program set ({motors['mode']})")
    curve_estimate = calibration.geometry.ir_curve
    curve = [round(v, 1) for v in curve_estimate.value]  # type: ignore[union-attr]
    # The floor is written with its own digits: the curve's 200 mm point, rounded to 0.1, must
    # stay at or above it (the simulator requires it).
    floor = calibration.geometry.ir_floor_value
    if math.isfinite(float(floor.value)):  # type: ignore[arg-type]
        written = float(_number(float(floor.value), float(floor.sigma)))  # type: ignore[arg-type]
        curve[-1] = max(curve[-1], math.ceil(written * 10.0) / 10.0)
        for i in range(len(curve) - 2, -1, -1):
            curve[i] = max(curve[i], curve[i + 1])
    for estimate in calibration.estimates():
        key = estimate.key
        if key == "sensors.ir_curve":
            sigmas = ", ".join(
                f"{s:.1f}" if known else "n.i."
                for s, known in zip(estimate.sigma, estimate.identified, strict=True)  # type: ignore[arg-type]
            )
            values[key] = (
                curve,
                f"raw, each point fitted near the wall; ± [{sigmas}] (n.i.: not identified, "
                f"extended along K-Team's shape){_flags(estimate)}",
            )
            continue
        if key == "motors.acc_inc":
            fitted, fitted_sigma = calibration.drive.fitted_acc_inc
            values[key] = (
                int(motors["acc_inc"]),
                f"the program's setting, which the firmware follows exactly (not randomised); "
                f"the logged wheel speeds are followed best at {fitted:.2f} ± {fitted_sigma:.2g}",
            )
            for name in ("acc_div", "min_speed_acc", "min_speed_dec"):
                values[f"motors.{name}"] = (motors[name], "as the program set it")
            continue
        value = float(estimate.value)  # type: ignore[arg-type]
        sigma = float(estimate.sigma)  # type: ignore[arg-type]
        comment = f"{_sigma_text(estimate)}: {estimate.how}{_flags(estimate)}"
        if not math.isfinite(value):
            value = float(_default(key))
            comment = f"the simulator's default, kept: {comment}"
        elif estimate.identified is False:
            comment = f"the nominal value, kept: {comment}"
        text = _number(value, sigma)
        if randomise is not None and key in RANGE_KEYS and math.isfinite(sigma):
            least = RANGE_KEYS[key]
            low, high = value - randomise * sigma, value + randomise * sigma
            if least is not None:
                low = max(low, least)
            if key == "sensors.ir_floor_value":
                high = min(high, curve[-1])
                low = min(low, high)
            values[key] = (
                [float(_number(low, sigma)), float(_number(high, sigma))],
                f"randomised over ± {randomise:g} sigma around {text}; " + comment,
            )
            continue
        if randomise is not None and key not in RANGE_KEYS:
            comment += " (a single value: the key takes no range)"
        values[key] = (float(text), comment)
    for key, (value, comment) in values.items():
        section, _, leaf = key.partition(".")
        if section not in lines:
            lines[section] = []
        lines[section].append(f"{leaf} = {toml_value(value, 'the scenario file')}  # {comment}")
    when = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat()
    logs = ", ".join(log.name for log in calibration.logs)
    header = [
        f"# A Khepera IV calibrated by khepera-gym calibrate (khepera_gym "
        f"{khepera_gym.__version__}), {when}",
        f"# from {logs}",
        f"# command: {command}",
        "# Each value is followed by its standard uncertainty (one standard deviation) from the",
        '# fit and what in the logs determined it. Load with config="<this file>" in any env, or',
        "# copy the sections into your scenario. Only the simulator's own keys are written; the",
        "# rest keeps the env's defaults.",
        f"# {FITTED_AT} physics.dt = {calibration.period!r} s, physics.substeps = "
        f"{calibration.drive.substeps}",
        "# (the drive's lag is the simulator's effective one at that step: fit again for another).",
        f"# Fit: {calibration.goodness.summary()}.",
    ]
    body = []
    for section in lines:
        if lines[section]:
            body += ["", f"[{section}]", *lines[section]]
    return "\n".join(header + body) + "\n"


def _flags(estimate: Estimate) -> str:
    return "".join(f"; {flag}" for flag in estimate.flags)


def fitted_step(text: str) -> tuple[float, int] | None:
    """(physics.dt, physics.substeps) a calibrated scenario's drive was fitted at, from its
    header; None if the text has none."""
    for line in text.splitlines():
        if line.startswith(f"# {FITTED_AT} physics.dt = "):
            parts = line.split("=")
            try:
                return float(parts[1].split()[0]), int(parts[2].split()[0])
            except (IndexError, ValueError):
                return None
    return None


def check_scenario(text: str, origin: str) -> None:
    """Loads the scenario text as an env would (the Rust core validates every key).

    Raises:
        ConfigError: The core refuses it (the message names the key).
    """
    _core.Batch(CHECK_TASK, 1, config_text=text, config_name=origin, num_threads=1)


def table_rows(calibration: Calibration) -> list[tuple[str, str, str]]:
    """(key, value ± sigma, how) of every estimate, for printing."""
    rows = []
    for estimate in calibration.estimates():
        if estimate.key == "motors.acc_inc":
            fitted, sigma = calibration.drive.fitted_acc_inc
            text = f"{int(estimate.value)} as set (followed best at {fitted:.2f} ± {sigma:.2g})"  # type: ignore[arg-type]
            rows.append((estimate.key, text, estimate.how))
            continue
        if isinstance(estimate.value, list):
            cells = [
                f"{v:.0f} ± {s:.1f}" if known else f"{v:.0f} (n.i.)"
                for v, s, known in zip(
                    estimate.value,
                    estimate.sigma,
                    estimate.identified,
                    strict=True,  # type: ignore[arg-type]
                )
            ]
            rows.append((estimate.key, "[" + ", ".join(cells) + "]", estimate.how))
            continue
        value = float(estimate.value)  # type: ignore[arg-type]
        if not math.isfinite(value):
            rows.append((estimate.key, "not identified", estimate.how))
            continue
        text = _number(value, float(estimate.sigma))  # type: ignore[arg-type]
        rows.append((estimate.key, f"{text} {_sigma_text(estimate)}", estimate.how))
    return rows


__all__ = [
    "FITTED_AT",
    "RANGE_KEYS",
    "calibrated_toml",
    "check_scenario",
    "dotted",
    "fitted_step",
    "table_rows",
]
