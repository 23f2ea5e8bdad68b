"""``khepera-gym robot-program calibrate``: the calibration program for the real robot, as C.

:func:`write_calibration_program` writes ``khepera_calibrate_main.c`` with its constants and
phases (``khepera_calibrate_config.h``, from :func:`~khepera_gym.robot.calibrate.schedule.
calibration_phases`), the files it shares with an exported policy (the readings, the robot log,
the clock: :data:`khepera_gym.robot.export.ROBOT_SOURCES`), a Makefile whose ``make robot`` builds
it as the export's does, a README and ``phases.json``. The program sets the motor controller to the
drive of the scenario the policy is trained on (:func:`khepera_gym.robot.export.motor_setting`), so
that the log measures that drive.

Units: the robot's (speed units, pulses); the scenario's SI values are converted when written.
Threading: the calling thread.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import gymnasium as gym

import khepera_gym
import khepera_gym.robot.calibrate.schedule as schedule
from khepera_gym.registration import resolve_env_id
from khepera_gym.robot.calibrate.replay import metres_per_pulse
from khepera_gym.robot.export.c_writer import (
    c_double,
    imu_samples,
    load_template,
    shared_robot_sources,
    wrap_comment,
)
from khepera_gym.robot.export.motors import PROFILE_MAX_SPEED, MotorSetting, motor_setting
from khepera_gym.robot.export.robot import toml_loads

#: The programs ``khepera-gym robot-program`` writes.
PROGRAMS = ("calibrate",)
#: The largest gap to the wall (m) the phases' time limits allow for.
MAX_WALL_DISTANCE_M = 1.0
#: The phase table written beside the program.
PHASES_FILE = "phases.json"


@dataclasses.dataclass(frozen=True)
class CalibrationProgram:
    """What :func:`write_calibration_program` wrote."""

    out_dir: Path
    files: list[Path]
    env_id: str
    motors: MotorSetting
    phases: tuple[schedule.Phase, ...]
    control_period: float


def _drive_accel(motors: MotorSetting, scenario: dict[str, Any]) -> float:
    """The acceleration (m/s²) the manoeuvre's steps plan with."""
    if motors.mode == "profile":
        return motors.accel
    value = scenario["motors"]["speed_accel"]
    return float(sum(value) / 2 if isinstance(value, list) else value)


def _phase_initialiser(phase: schedule.Phase) -> str:
    kind = "PHASE_" + phase.kind.upper()
    return (
        f'    {{"{phase.name}", {kind}, {phase.left}, {phase.right}, '
        f"{c_double(phase.seconds)}, {c_double(phase.limit)}}}"
    )


def _phase_row(phase: schedule.Phase) -> str:
    if phase.kind == "timed":
        what = f"{phase.seconds:g} s"
    elif phase.kind == "approach":
        what = (
            f"until IR front ≥ {phase.limit:g} ({schedule.APPROACH_DEBOUNCE} rows) or "
            f"{schedule.APPROACH_CLEARANCE_M * 1000:g} mm left for wheels "
            f"{schedule.RADIUS_TOLERANCE:.0%} larger"
        )
    elif phase.kind == "spin":
        what = f"until {phase.limit / (2 * math.pi):g} turns"
    elif phase.kind == "return":
        what = "until back at the approach's start"
    else:
        what = "asks for the measured gap (one row: the pause)"
    return f"| `{phase.name}` | {phase.kind} | {phase.left}, {phase.right} | {what} |"


def write_calibration_program(
    out_dir: str | Path,
    *,
    env_id: str = "KheperaIV-Nav",
    config: str | Path | None = None,
    drive: str = "trained",
    phases: tuple[schedule.Phase, ...] | None = None,
    **overrides: Any,
) -> CalibrationProgram:
    """Writes the calibration program for the drive of ``env_id``'s scenario.

    Args:
        out_dir: The folder (created).
        env_id: The env whose scenario (drive, control period, wheel radius and axle) the
            program takes; the latest version when unversioned.
        config: A scenario file or built-in name, as for the env.
        drive: "trained" (the scenario's drive exactly) or "nominal" (its nearest firmware
            setting), as for ``khepera-gym export``.
        phases: The manoeuvre (default: :func:`~khepera_gym.robot.calibrate.schedule.
            calibration_phases` for the drive); a shorter one makes a quicker test.
        **overrides: Scenario keys, as for the env.

    Raises:
        ConfigError: The scenario's drive cannot be set on the robot (and ``drive`` is not
            "nominal"), or a bad scenario.
    """
    env_id = resolve_env_id(env_id)
    kwargs: dict[str, Any] = dict(overrides)
    if config is not None:
        kwargs["config"] = str(config)
    env = gym.make(env_id, **kwargs)
    try:
        scenario_text = env.unwrapped.config_toml()
    finally:
        env.close()
    scenario = toml_loads(scenario_text)
    motors = motor_setting(scenario, drive)
    period = float(scenario["physics"]["dt"])
    wheel_radius = float(scenario["robot"]["wheel_radius"])
    axle = scenario["robot"]["axle_length"]
    axle_length = float(sum(axle) / 2 if isinstance(axle, list) else axle)
    if phases is None:
        phases = schedule.calibration_phases(_drive_accel(motors, scenario), MAX_WALL_DISTANCE_M)
    config_fields = {
        "version": khepera_gym.__version__,
        "env_id": env_id,
        "control_period": c_double(period),
        "wheel_radius": c_double(wheel_radius),
        "axle_length": c_double(axle_length),
        "metres_per_pulse": c_double(metres_per_pulse(wheel_radius)),
        "imu_samples": imu_samples(period),
        "front_ir": schedule.FRONT_IR,
        "front_us": schedule.FRONT_US,
        "approach_slow_units": schedule.APPROACH_SLOW_UNITS,
        "approach_slow_ir": schedule.APPROACH_SLOW_IR,
        "approach_slow_gap": c_double(schedule.APPROACH_SLOW_GAP_M),
        "approach_debounce": schedule.APPROACH_DEBOUNCE,
        "approach_clearance": c_double(schedule.APPROACH_CLEARANCE_M),
        "radius_tolerance": c_double(schedule.RADIUS_TOLERANCE),
        "us_tolerance": c_double(schedule.US_TOLERANCE_M),
        "us_min": c_double(schedule.US_MIN_M),
        "max_wall_distance": c_double(MAX_WALL_DISTANCE_M),
        "motor_note": wrap_comment("The motor controller: " + motors.note + ".", ""),
        "motor_text": motors.call().replace('"', "'"),
        "motor_profile": int(motors.mode == "profile"),
        "acc_inc": motors.acc_inc,
        "acc_div": motors.acc_div,
        "min_speed_acc": motors.min_speed_acc,
        "min_speed_dec": motors.min_speed_dec,
        "profile_max_speed": PROFILE_MAX_SPEED,
        "phase_count": len(phases),
        "phases": ",\n".join(_phase_initialiser(phase) for phase in phases),
    }
    # The timed phases, and the approach and the way back from half a metre.
    seconds = sum(p.seconds for p in phases if p.kind == "timed") + sum(
        0.5 / (abs(p.left) * schedule.SPEED_UNIT)
        for p in phases
        if p.kind in ("approach", "return")
    )
    readme_fields = {
        "version": khepera_gym.__version__,
        "env_id": env_id,
        "motor_text": motors.note,
        "period_ms": f"{period * 1000:g}",
        "approach_mm_s": f"{schedule.APPROACH_UNITS * schedule.SPEED_UNIT * 1000:.0f}",
        "stop_ir": schedule.APPROACH_STOP_IR,
        "slow_mm_s": f"{schedule.APPROACH_SLOW_UNITS * schedule.SPEED_UNIT * 1000:.0f}",
        "debounce": schedule.APPROACH_DEBOUNCE,
        "clearance_mm": f"{schedule.APPROACH_CLEARANCE_M * 1000:g}",
        "radius_tolerance": f"{schedule.RADIUS_TOLERANCE:.0%}",
        "us_tolerance_cm": f"{schedule.US_TOLERANCE_M * 100:g}",
        "spin_turns": f"{schedule.SPIN_TURNS:g}",
        "minutes": f"{math.ceil(seconds / 60)}",
        "phase_table": "\n".join(_phase_row(phase) for phase in phases),
    }
    sources = {
        "khepera_calibrate_main.c": load_template("khepera_calibrate_main.c").template,
        "khepera_calibrate_config.h": load_template("khepera_calibrate_config.h").substitute(
            config_fields
        ),
        **shared_robot_sources(),
        "Makefile": load_template("Makefile.calibrate").template,
        "README.md": load_template("README.calibrate.md").substitute(readme_fields),
        PHASES_FILE: json.dumps(
            {
                "control_period_s": period,
                "motors": motors.as_dict(),
                "phases": [dataclasses.asdict(phase) for phase in phases],
            },
            indent=2,
        )
        + "\n",
    }
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name, text in sources.items():
        path = out / name
        path.write_text(text, encoding="utf-8")
        files.append(path)
    return CalibrationProgram(out, files, env_id, motors, phases, period)


__all__ = ["PROGRAMS", "CalibrationProgram", "write_calibration_program"]
