"""The C writer: plain C99 sources of an exported policy for the real Khepera IV.

:func:`write_c` writes, from a :class:`~khepera_gym.robot.export.network.PolicyNetwork` and a
:class:`~khepera_gym.robot.export.robot.RobotInterface`:

* ``policy.c``/``policy.h``: the network (:mod:`~khepera_gym.robot.export.c_policy`), with the
  policy's memory (its frame stack, a recurrent policy's LSTM state) in ``policy_state``;
* ``observation.c``/``.h``: the simulator's normalisation of the raw IR and ultrasonic readings,
  wheel speeds and goal into the observation of the env the policy was trained on, block by
  block in the env's own layout (only the blocks it observes), with the scenario's constants
  baked in;
* ``wheel_command.c``/``.h``: the action to ``kh4_set_speed`` units, as the simulator turns
  actions into wheel speeds;
* the template program ``khepera_policy_main.c`` (libkhepera: sensors, dead reckoning, policy,
  wheel speeds every control period, and with ``--log FILE`` a robot log) with
  ``khepera_policy_config.h`` and the files it shares with the calibration program
  (:data:`ROBOT_SOURCES`: the readings, the log, the clock), ``export_check.c`` (runs the
  exported code on rows of numbers, for parity checks on a PC or on the robot), a Makefile and a
  README.

The fixed parts are files of ``khepera_gym/robot/export/templates/`` with ``$``-placeholders
(``string.Template``). Float constants are written so that they read back as the same float32
(or float64) value (:mod:`~khepera_gym.robot.export.c_text`). Threading: none.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import khepera_gym
from khepera_gym.errors import ConfigError
from khepera_gym.robot.export.c_policy import check_sampling, policy_c_sources
from khepera_gym.robot.export.c_text import c_double, c_float, load_template, wrap_comment
from khepera_gym.robot.export.motors import PROFILE_MAX_SPEED, MotorSetting
from khepera_gym.robot.export.network import PolicyNetwork
from khepera_gym.robot.export.robot import (
    MAX_SPEED_UNITS,
    MM_S_PER_SPEED_UNIT,
    PULSES_PER_WHEEL_TURN,
    RobotInterface,
)

#: The C files of the exported code that ``export_check`` and the robot program link.
C_SOURCES = ("policy.c", "observation.c", "wheel_command.c")
#: The C files every robot program links besides (libkhepera readings, the robot log, the
#: clock), with their headers: the same files in the export and in the calibration program.
ROBOT_SOURCES = ("khepera_sensors.c", "khepera_log.c", "khepera_clock.c")
ROBOT_HEADERS = ("khepera_sensors.h", "khepera_log.h", "khepera_clock.h")
#: The accelerometer and gyroscope sample at about 100 Hz (docs/robot.md §6).
IMU_RATE_HZ = 100.0
#: The nominal wheel radius (m) K-Team's speed unit refers to (docs/robot.md §1).
NOMINAL_WHEEL_RADIUS = 0.021


def imu_samples(control_period: float) -> int:
    """The newest IMU samples (of the 10 an axis libkhepera returns) a log row averages: those
    of one control period."""
    return min(10, max(1, round(control_period * IMU_RATE_HZ)))


def mm_s_per_unit(wheel_radius: float) -> float:
    """One ``kh4_set_speed`` unit (a pulse per 10 ms) in mm/s of ground speed for wheels of
    ``wheel_radius`` m: K-Team's 0.678181 at 21 mm, in proportion otherwise (a calibrated robot)."""
    if wheel_radius == NOMINAL_WHEEL_RADIUS:
        return MM_S_PER_SPEED_UNIT
    return MM_S_PER_SPEED_UNIT * wheel_radius / NOMINAL_WHEEL_RADIUS


def shared_robot_sources() -> dict[str, str]:
    """The files every robot program links (:data:`ROBOT_SOURCES`, :data:`ROBOT_HEADERS`)."""
    return {name: load_template(name).template for name in (*ROBOT_SOURCES, *ROBOT_HEADERS)}


def _indices(start: int, stop: int, dash: str) -> str:
    """A block's indices: "13", or "0-7" for a longer one."""
    return str(start) if stop - start == 1 else f"{start}{dash}{stop - 1}"


def _c_name(name: str) -> str:
    return re.sub(r"\W", "_", name)


def _input_fields(robot: RobotInterface) -> list[tuple[str, str, int, str]]:
    """Fields of ``observation_inputs``: (C name, C type, count, comment), in row order."""
    names = {name for name, _, _ in robot.layout}
    fields = []
    if "ir" in names:
        fields.append(
            (
                "ir_raw",
                "uint16_t",
                8,
                "kh4_proximity_ir's first 8 values: the ring in K-Team "
                "order (back-left, left, front-left, front, front-right, right, back-right, back), "
                "0..1023",
            )
        )
    if "us" in names:
        fields.append(
            (
                "us_cm",
                "int16_t",
                5,
                "kh4_measure_us: left, front-left, front, front-right, "
                "right, in cm, or 0 (too close), 1000 (nothing in range), 2000 (disabled)",
            )
        )
    if "wheel_speeds" in names:
        fields.append(
            (
                "wheel_speeds",
                "float",
                2,
                "left, right wheel speeds (m/s): wheel_units_to_speed() of kh4_get_speed's units",
            )
        )
    if robot.has_goal:
        fields.append(
            (
                "robot_pose",
                "float",
                3,
                "x, y (m) and heading (rad, counter-clockwise) of the "
                "robot, e.g. by dead reckoning",
            )
        )
        fields.append(("goal", "float", 2, "x, y (m) of the goal, in the frame of robot_pose"))
    for name, start, stop in robot.extra_blocks:
        fields.append(
            (
                _c_name(name),
                "float",
                stop - start,
                f"the observation's {name} block, as the "
                "simulator defines it (the env's documentation)",
            )
        )
    return fields


def _observation_statement(name: str, start: int, stop: int) -> str:
    """The C statement of ``observation_build`` filling one block."""
    target = f"observation[{start}]"
    if name == "ir":
        source = "observation_ir(inputs->ir_raw[i])"
    elif name == "us":
        source = "observation_us(inputs->us_cm[i])"
    elif name == "wheel_speeds":
        source = "clamp(inputs->wheel_speeds[i] / OBSERVATION_MAX_WHEEL_SPEED, -1.0f, 1.0f)"
    elif name == "goal_distance":
        return (
            f"    {target} = distance < OBSERVATION_ARENA_DIAGONAL ? distance"
            " : OBSERVATION_ARENA_DIAGONAL;"
        )
    elif name in ("goal_bearing_sin", "goal_bearing_cos"):
        axis, fallback = ("1", "0.0f") if name.endswith("sin") else ("0", "1.0f")
        return (
            f"    {target} = distance > 0.0f ? clamp(local[{axis}] / distance, -1.0f, 1.0f)"
            f" : {fallback};"
        )
    else:
        source = f"inputs->{_c_name(name)}[i]"
    return (
        f"    for (int i = 0; i < {stop - start}; ++i) {{\n"
        f"        observation[{start} + i] = {source};\n    }}"
    )


def observation_c_sources(robot: RobotInterface) -> dict[str, str]:
    """``observation.h``/``.c``: the simulator's observation from raw readings (name → text)."""
    fields = _input_fields(robot)
    names = {name for name, _, _ in robot.layout}
    randomised = "".join(
        f"\n * {key} is a range {list(bounds)} in the scenario (domain randomisation): its "
        "midpoint is used."
        for key, bounds in robot.randomised.items()
    )
    where = robot.env_id + (f" (one robot's block, as {robot.agent}'s)" if robot.agent else "")
    header = {
        "where": where,
        "version": khepera_gym.__version__,
        "layout": "\n".join(
            f" *   {_indices(start, stop, '-'):<7} {name}" for name, start, stop in robot.layout
        ),
        "obs_dim": robot.obs_dim,
        "input_count": sum(count for _, _, count, _ in fields),
        "has_ir": int("ir" in names),
        "has_us": int("us" in names),
        "has_wheel_speeds": int("wheel_speeds" in names),
        "has_goal": int(robot.has_goal),
        "extra_inputs": len(robot.extra_blocks),
        "randomised": randomised,
        "ir_floor_value": c_float(robot.ir_floor_value),
        "us_max_range": c_float(robot.us_max_range),
        "max_wheel_speed": c_float(robot.max_wheel_speed),
        "arena_diagonal": c_float(robot.arena_diagonal),
        "fields": "\n".join(
            f"{wrap_comment(comment + '.', '    ')}\n    {c_type} {name}[{count}];"
            for name, c_type, count, comment in fields
        ),
    }
    source = {
        "build": "\n".join(_observation_statement(*block) for block in robot.layout),
        "from_row": "\n".join(
            f"    for (int i = 0; i < {count}; ++i) {{\n"
            f"        inputs->{name}[i] = ({c_type})row[next++];\n    }}"
            for name, c_type, count, _ in fields
        ),
        "clear": "\n".join(
            f"    for (int i = 0; i < {stop - start}; ++i) {{\n"
            f"        inputs->{_c_name(name)}[i] = 0.0f;\n    }}"
            for name, start, stop in robot.extra_blocks
        ),
    }
    return {
        "observation.h": load_template("observation.h").substitute(header),
        "observation.c": load_template("observation.c").substitute(source),
    }


def robot_c_sources(
    robot: RobotInterface,
    network: PolicyNetwork,
    motors: MotorSetting,
    sample_seed: int | None = None,
) -> dict[str, str]:
    """The wheel command, the template program and its constants (the motor controller's
    setting among them; with ``sample_seed``, actions sampled from the policy's Gaussian with
    that seed, else its mean), the check program, the Makefile (name → text).

    Raises:
        ConfigError: The policy's width is not one robot's action, ``sample_seed`` is not a
            64-bit unsigned integer, or the network lacks the σ that sampling needs.
    """
    if sample_seed is not None:
        check_sampling(network, sample_seed)
    takes = 5 if robot.led_action else 2
    if network.action_dim != takes:
        what = "its wheels, then its LEDs' red, green, blue" if robot.led_action else "its wheels"
        hint = (
            " (a policy trained with task.led_action: export it with led_action=True)"
            if network.action_dim == 5
            else ""
        )
        raise ConfigError(
            f"the policy gives {network.action_dim} action values; one robot of this scenario "
            f"takes {takes} ({what}){hint}"
        )
    unicycle = robot.action_type == "unicycle"
    wheel_fields = {
        "action_type": robot.action_type,
        "env_id": robot.env_id,
        "action_meaning": "normalised (v, omega): v by the wheel speed limit, omega by 2 limit /"
        " axle; wheels over the limit are scaled down together."
        if unicycle
        else "normalised (left, right) wheel speeds, 1 = the wheel speed limit.",
        "unicycle": int(unicycle),
        "max_wheel_speed": c_float(robot.max_wheel_speed),
        "min_wheel_speed": c_float(robot.min_wheel_speed),
        "axle_length": c_float(robot.axle_length),
        "mm_s_per_unit": c_float(mm_s_per_unit(robot.wheel_radius)),
        "max_units": MAX_SPEED_UNITS,
    }
    config_fields = {
        "version": khepera_gym.__version__,
        "env_id": robot.env_id,
        "control_period": c_double(robot.control_period),
        "goal_radius": c_double(robot.goal_radius),
        "axle_length": c_double(robot.axle_length),
        "wheel_radius": c_double(robot.wheel_radius),
        "metres_per_pulse": c_double(2.0 * math.pi * robot.wheel_radius / PULSES_PER_WHEEL_TURN),
        "imu_samples": imu_samples(robot.control_period),
        # The real robot pings only when the policy sees the ultrasonic sensors.
        "us_mask": sum(1 << i for i, on in enumerate(robot.us_enabled) if on)
        if robot.observes("us")
        else 0,
        "led_action": int(robot.led_action),
        "sample_actions": int(sample_seed is not None),
        "sample_seed": 0 if sample_seed is None else sample_seed,
        "motor_profile": int(motors.mode == "profile"),
        "acc_inc": motors.acc_inc,
        "acc_div": motors.acc_div,
        "min_speed_acc": motors.min_speed_acc,
        "min_speed_dec": motors.min_speed_dec,
        "profile_max_speed": PROFILE_MAX_SPEED,
        "motor_note": wrap_comment(
            "The motor controller, as the policy was trained: " + motors.note + ".", ""
        ),
    }
    return {
        "wheel_command.h": load_template("wheel_command.h").substitute(wheel_fields),
        "wheel_command.c": load_template("wheel_command.c").template,
        "khepera_policy_config.h": load_template("khepera_policy_config.h").substitute(
            config_fields
        ),
        "khepera_policy_main.c": load_template("khepera_policy_main.c").template,
        **shared_robot_sources(),
        "export_check.c": load_template("export_check.c").template,
        "Makefile": load_template("Makefile").template,
    }


def readme(network: PolicyNetwork, robot: RobotInterface) -> str:
    """The README of an export: its files, the observation layout, building and checking."""
    return load_template("README.md").safe_substitute(
        env_id=robot.env_id,
        source=network.source,
        version=khepera_gym.__version__,
        layout="\n".join(
            f"| {_indices(start, stop, '–')} | `{name}` |" for name, start, stop in robot.layout
        ),
    )


def write_c(
    network: PolicyNetwork,
    robot: RobotInterface,
    motors: MotorSetting,
    out_dir: str | Path,
    provenance: str,
    sample_seed: int | None = None,
) -> list[Path]:
    """Writes the C sources, the Makefile and the README into ``out_dir``; returns their
    paths. With ``sample_seed`` the program samples its actions (:func:`robot_c_sources`).

    Raises:
        ConfigError: The policy does not give one robot's two wheel actions, a constant is
            not finite, or sampling is asked of a policy without a σ to sample with.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sources = {
        **policy_c_sources(network, provenance),
        **observation_c_sources(robot),
        **robot_c_sources(robot, network, motors, sample_seed),
        "README.md": readme(network, robot),
    }
    paths = []
    for name, text in sources.items():
        path = out / name
        path.write_text(text, encoding="utf-8")
        paths.append(path)
    return paths


__all__ = [
    "C_SOURCES",
    "ROBOT_HEADERS",
    "ROBOT_SOURCES",
    "c_double",
    "check_sampling",
    "imu_samples",
    "load_template",
    "mm_s_per_unit",
    "observation_c_sources",
    "policy_c_sources",
    "readme",
    "robot_c_sources",
    "shared_robot_sources",
    "wrap_comment",
    "write_c",
]
