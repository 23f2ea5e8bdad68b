"""What the exported program sets on the robot's motor controller: the drive the policy was
trained with (the scenario's ``[motors]``), so that the robot on the bench is the robot of the
simulator.

K-Team's firmware has two modes a program drives in (K-Team Khepera IV User Manual 3.0, §4.14;
``docs/drive.md``): the speed profile (``kh4_SetSpeedProfile(acc_inc, acc_div, min_speed_acc,
min_speed_dec, max_speed)`` then ``kh4_SetMode(kh4RegSpeedProfile)``), which the simulator
follows exactly, and the speed mode (``kh4_SetMode(kh4RegSpeed)``), whose acceleration the
simulator only estimates. A drive the robot cannot be set to (the ``ramp`` mode of v0 and v1, or a
profile randomised over a range) is exported only when asked for its nominal setting
(``drive="nominal"``, ``--drive nominal``); otherwise it is a :class:`ConfigError` saying why.

Units: K-Team speed units (0.678181 mm/s) and 10 ms control periods, as the firmware takes them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from khepera_gym.errors import ConfigError

#: One speed unit in m/s (``KH4_SPEED_TO_MM_S``, src/robot.rs).
SPEED_UNIT = 0.678181e-3
#: The motor controller's period (s): the profile adds ``acc_inc`` every ``acc_div + 1`` of them.
CONTROL_PERIOD_S = 0.01
#: ``kh4_SetSpeedProfile``'s ``max_speed``: position mode's travel speed (manual §4.14.3); the
#: speed and profile modes do not use it, so it keeps K-Team's default.
PROFILE_MAX_SPEED = 400
#: The profile's defaults that a nominal setting takes where the scenario has none: K-Team's
#: library defaults (manual §4.14.2).
KTEAM_MIN_SPEED_ACC = 20
KTEAM_MIN_SPEED_DEC = 1
#: The choices of ``drive``: the trained drive exactly, or its nominal setting.
DRIVE_CHOICES = ("trained", "nominal")


@dataclasses.dataclass(frozen=True)
class MotorSetting:
    """The motor controller's setting an exported program makes."""

    #: "profile" (kh4RegSpeedProfile) or "speed" (kh4RegSpeed).
    mode: str
    acc_inc: int
    acc_div: int
    min_speed_acc: int
    min_speed_dec: int
    #: Whether the robot is set exactly as the policy was trained (False: a nominal setting).
    exact: bool
    #: What is set and how it relates to the training drive, for the user.
    note: str

    @property
    def accel(self) -> float:
        """The profile's acceleration (m/s²), or NaN in speed mode (not settable)."""
        if self.mode != "profile":
            return math.nan
        return profile_accel(self.acc_inc, self.acc_div)

    def call(self) -> str:
        """The libkhepera calls, as C."""
        if self.mode == "speed":
            return "kh4_SetMode(kh4RegSpeed)"
        return (
            f"kh4_SetSpeedProfile({self.acc_inc}, {self.acc_div}, {self.min_speed_acc}, "
            f"{self.min_speed_dec}, {PROFILE_MAX_SPEED}); kh4_SetMode(kh4RegSpeedProfile)"
        )

    def as_dict(self) -> dict[str, Any]:
        """The setting for the export's manifest."""
        return {**dataclasses.asdict(self), "calls": self.call()}


def profile_accel(acc_inc: float, acc_div: int) -> float:
    """The speed profile's acceleration (m/s²): ``acc_inc`` units every ``acc_div + 1`` periods."""
    return acc_inc * SPEED_UNIT / ((acc_div + 1) * CONTROL_PERIOD_S)


def _number(value: Any, key: str, randomised: list[str]) -> float:
    """A scenario value; a [low, high] range gives its midpoint and is noted in ``randomised``."""
    if isinstance(value, list):
        low, high = float(value[0]), float(value[1])
        if high > low:
            randomised.append(f"{key} = {[low, high]}")
        return 0.5 * (low + high)
    return float(value)


def motor_setting(scenario: Mapping[str, Any], drive: str = "trained") -> MotorSetting:
    """The motor controller's setting for a resolved scenario (``env.unwrapped.config_toml()``,
    parsed).

    Args:
        scenario: The scenario as a dict (its ``[motors]`` and ``[robot]`` tables are read).
        drive: "trained" (the trained drive, exactly) or "nominal" (its nearest firmware setting,
            when the trained one cannot be set exactly).

    Raises:
        ConfigError: ``drive`` is unknown, or the trained drive cannot be set exactly and
            ``drive`` is not "nominal" (the message says why and what nominal would set).
    """
    if drive not in DRIVE_CHOICES:
        raise ConfigError(f"drive must be one of {DRIVE_CHOICES}, got {drive!r}")
    motors = scenario["motors"]
    mode = str(motors["mode"])
    randomised: list[str] = []
    min_acc = int(motors.get("min_speed_acc", KTEAM_MIN_SPEED_ACC))
    min_dec = int(motors.get("min_speed_dec", KTEAM_MIN_SPEED_DEC))
    if mode == "profile":
        inc = _number(motors["acc_inc"], "motors.acc_inc", randomised)
        div = int(motors["acc_div"])
        units = min(255, max(1, round(inc)))
        nominal = MotorSetting(
            "profile",
            units,
            div,
            min_acc,
            min_dec,
            exact=not randomised,
            note=(
                f"K-Team's speed profile at Acc_Inc {units}, Acc_Div {div}: "
                f"{profile_accel(units, div):.3g} m/s², minimum order {min_acc} units"
            ),
        )
        if randomised and drive != "nominal":
            raise ConfigError(
                f"the policy was trained on a randomised drive ({', '.join(randomised)}); the "
                f"robot runs one profile: export with drive='nominal' (--drive nominal) to set "
                f"its midpoint, {nominal.note}"
            )
        if randomised:
            return dataclasses.replace(
                nominal, note=nominal.note + f" (the midpoint of {', '.join(randomised)})"
            )
        return dataclasses.replace(nominal, note=nominal.note + ", as trained")
    if mode == "speed":
        accel = _number(motors["speed_accel"], "motors.speed_accel", randomised)
        return MotorSetting(
            "speed",
            0,
            0,
            min_acc,
            min_dec,
            exact=True,
            note=(
                f"K-Team's speed mode (kh4RegSpeed), as trained; the simulator's acceleration in "
                f"it, {accel:.3g} m/s², is an estimate [E]: the robot's own is not measured"
            ),
        )
    # mode "ramp": a plain acceleration limit (v0, v1), which no firmware mode gives.
    accel = _number(scenario["robot"]["wheel_accel_limit"], "robot.wheel_accel_limit", randomised)
    if math.isinf(accel):
        nominal = MotorSetting(
            "speed",
            0,
            0,
            min_acc,
            min_dec,
            exact=False,
            note="K-Team's speed mode (kh4RegSpeed): the nearest the robot has to the trained "
            "wheels, which reached any speed within a step",
        )
    else:
        inc = accel * CONTROL_PERIOD_S / SPEED_UNIT
        units = min(255, max(1, round(inc)))
        nominal = MotorSetting(
            "profile",
            units,
            0,
            KTEAM_MIN_SPEED_ACC,
            KTEAM_MIN_SPEED_DEC,
            exact=False,
            note=(
                f"K-Team's speed profile at Acc_Inc {units} ({profile_accel(units, 0):.4g} m/s², "
                f"for the trained ramp of {accel:.4g} m/s²), with the firmware's minimum order "
                f"of {KTEAM_MIN_SPEED_ACC} units, which the ramp did not simulate"
            ),
        )
    if drive != "nominal":
        raise ConfigError(
            f"the policy was trained with motors.mode = 'ramp' (robot.wheel_accel_limit = "
            f"{accel:g} m/s², the drive of the v0 and v1 envs), which no mode of the robot's "
            f"firmware gives exactly: retrain on a v2 or later env (K-Team's profile) or export "
            f"with drive='nominal' (--drive nominal) to set {nominal.note}"
        )
    return nominal


__all__ = [
    "DRIVE_CHOICES",
    "PROFILE_MAX_SPEED",
    "MotorSetting",
    "motor_setting",
    "profile_accel",
]
