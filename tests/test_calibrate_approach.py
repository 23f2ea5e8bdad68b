"""The calibration run cannot hit the wall: the approach of the calibration program
(``khepera-gym robot-program calibrate``, ``schedule.PhaseRunner``), run against robots whose
infrared sensor reads low, whose wheels are larger than the program assumes, whose front
infrared sensor is stuck, or whose user gave the wrong gap.

* The C program is built against the simulated libkhepera (tests/fake_libkhepera/) with the
  fake's own settings changed by -D (its wheel radius, its infrared gain, where its wall
  stands), and a stuck sensor is a wrapper around ``kh4_proximity_ir`` that overwrites the front
  sensor's value (the fake itself is not changed). The fake's trace (FAKE_TRACE) gives the true
  gap between the shell and the wall at every read of the encoders.
* The Python state machine drives the simulator (``synthetic.synthetic_calibration_log``) on the
  same kind of robot.

What "never touches" means here, from the program's rules: the approach ends when the wall may
be ``APPROACH_CLEARANCE_M`` away for wheels ``RADIUS_TOLERANCE`` larger than nominal, and
after its last decision the robot still travels for a control period, its motors' lag and its
profile's ramp down; at the approach's full speed that is at most
(0.05 + 0.06 + 0.1) s x 20 mm/s = 4.2 mm (the lag at the real robots' largest, 60 ms; a ramp of
20 units at the slowest profile, 3 units a 10 ms). So the gap never falls below
``APPROACH_CLEARANCE_M - 4.2 mm``; and every approach must reach the wall's neighbourhood (a
useful log), within ``APPROACH_CLEARANCE_M`` plus the 3 % of the travel the margin allows plus
the infrared stop's own distance (about 50 mm at the highest gain).
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import LATEST

from khepera_gym.robot import export
from khepera_gym.robot.calibrate import replay, schedule, synthetic, write_calibration_program
from khepera_gym.robot.calibrate.logformat import note, read_log

#: The simulated libkhepera.
FAKE = Path(__file__).resolve().parent / "fake_libkhepera"
#: Flags of the test builds: warning-free C99.
C_FLAGS = ("-O2", "-std=c99", "-Wall", "-Wextra", "-Werror")
#: The largest gap the program accepts (m): the odometry's margin is widest there.
FAR = 1.0
#: The nearest the shell may come to the wall (m), from the program's rules (module docstring).
LEAST_GAP = schedule.APPROACH_CLEARANCE_M - (0.05 + 0.06 + 0.1) * 0.020
#: A wrapper that makes the front infrared sensor read a constant (a stuck sensor).
STUCK_WRAPPER = """
#include <khepera/khepera.h>
int stuck_proximity_ir(char *buffer, knet_dev_t *device)
{
    const int status = kh4_proximity_ir(buffer, device);
    buffer[2 * STUCK_INDEX] = (char)(STUCK_VALUE & 0xff);
    buffer[2 * STUCK_INDEX + 1] = (char)((STUCK_VALUE >> 8) & 0xff);
    return status;
}
"""


def _approach_phases() -> tuple[schedule.Phase, ...]:
    """The program's own phases up to the gap's question (rest, approach, rest, gap)."""
    phases = schedule.calibration_phases(2.7, FAR)
    end = next(i for i, p in enumerate(phases) if p.kind == "gap")
    return phases[: end + 1]


def _build(
    out: Path,
    stuck: int | None,
    phases: tuple[schedule.Phase, ...] | None = None,
    **fake: float,
) -> Path:
    """The calibration program (``phases``: the approach's by default) on the fake robot (its
    settings ``fake``), with the front infrared sensor stuck at ``stuck`` (raw) if given."""
    write_calibration_program(out, env_id=LATEST["nav"], phases=phases or _approach_phases())
    defines = [f"-D{key}={value}" for key, value in fake.items()]
    objects = []
    program_defines = []
    if stuck is not None:
        (out / "stuck.c").write_text(STUCK_WRAPPER, encoding="utf-8")
        extra = [f"-DSTUCK_INDEX={schedule.FRONT_IR}", f"-DSTUCK_VALUE={stuck}"]
        objects.append(_compile(out, out / "stuck.c", extra))
        program_defines = ["-Dkh4_proximity_ir=stuck_proximity_ir"]
    for source in ("khepera_calibrate_main.c", *export.ROBOT_SOURCES):
        if source != "khepera_clock.c":
            objects.append(_compile(out, out / source, program_defines))
    objects.append(_compile(out, FAKE / "fake_khepera4.c", defines))
    objects.append(_compile(out, FAKE / "fake_clock.c", []))
    program = out / "khepera_calibrate_fake"
    subprocess.run(
        ["cc", "-o", str(program), *map(str, objects), "-lm"], check=True, capture_output=True
    )
    return program


def _compile(out: Path, source: Path, flags: list[str]) -> Path:
    target = out / (source.stem + ".o")
    subprocess.run(
        ["cc", *C_FLAGS, *flags, f"-I{FAKE}", f"-I{out}", "-c", "-o", str(target), str(source)],
        check=True,
        capture_output=True,
        text=True,
    )
    return target


def run_on_fake(
    out: Path,
    *,
    gap_given: float,
    gap_true: float,
    stuck: int | None,
    phases: tuple[schedule.Phase, ...] | None = None,
    **fake: float,
) -> tuple[np.ndarray, Any]:
    """Runs the program (the approach by default); returns the fake's trace (time, x, y,
    heading, gap) and the log."""
    program = _build(out, stuck, phases, FAKE_WALL_X=gap_true + replay.BODY_RADIUS, **fake)
    trace = out / "trace.txt"
    subprocess.run(
        [str(program), repr(gap_given), str(out / "approach.csv")],
        input="\n",
        env={"FAKE_TRACE": str(trace), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    return np.loadtxt(trace), read_log(out / "approach.csv")


#: (the gap the user gives, the true gap, the front sensor stuck at (raw) or None, the fake's
#: settings): each a robot of or beyond the real robots' spread.
FAKE_CASES = {
    # The lowest infrared gain of the spread, with wheels 3 % larger than the program's 21 mm
    # (three times the spread's 1 %), from the farthest gap the program accepts.
    "ir_gain_0.85_wheels_3%_larger": (FAR, FAR, None, {"FAKE_IR_GAIN": 0.85}),
    # A front sensor stuck at the floor's reflection: only the odometry can stop the robot.
    "stuck_ir_wheels_3%_larger": (FAR, FAR, 95, {}),
    # A stuck sensor and a user who gave a gap 10 cm too large: the ultrasonic sensor, while
    # the wall is beyond its 25 cm, finds it nearer than the odometry believes.
    "stuck_ir_gap_given_10cm_too_large": (0.6, 0.5, 95, {}),
}


@pytest.mark.parametrize("case", list(FAKE_CASES))
def test_the_calibration_program_stops_short_of_the_wall(case: str, tmp_path: Path) -> None:
    gap_given, gap_true, stuck, settings = FAKE_CASES[case]
    radius = replay.NOMINAL_WHEEL_RADIUS * (1.0 + schedule.RADIUS_TOLERANCE)
    trace, log = run_on_fake(
        tmp_path,
        gap_given=gap_given,
        gap_true=gap_true,
        stuck=stuck,
        FAKE_WHEEL_RADIUS=radius,
        **settings,
    )
    gaps = trace[:, 4]
    assert gaps.min() >= LEAST_GAP, f"{case}: the shell came {gaps.min() * 1000:.1f} mm close"
    # It did approach: the gap at the end is within what the margin and the sensors allow.
    allowed = schedule.APPROACH_CLEARANCE_M + schedule.RADIUS_TOLERANCE * gap_given + 0.05
    if stuck is not None and gap_given != gap_true:
        allowed += schedule.US_TOLERANCE_M + 0.02  # the fake's ultrasonic offset is 1.5 cm
    assert gaps.min() <= allowed, f"{case}: stopped {gaps.min() * 1000:.1f} mm away"
    approach = log.phases == "wall_approach"
    assert approach.sum() > 20
    # It slowed down near the wall: its last commands are the slow speed.
    assert np.all(log.commands[approach][-3:] == schedule.APPROACH_SLOW_UNITS)


def test_the_calibration_program_stops_at_once_on_an_infrared_sensor_stuck_high(
    tmp_path: Path,
) -> None:
    trace, log = run_on_fake(tmp_path, gap_given=0.5, gap_true=0.5, stuck=1023)
    # Three rows of 1023 (the debounce) and the robot stops: a few millimetres travelled.
    approach = log.phases == "wall_approach"
    assert approach.sum() == schedule.APPROACH_DEBOUNCE - 1
    assert trace[:, 4].min() > 0.49


def test_one_infrared_glitch_does_not_stop_the_approach() -> None:
    # The program's approach (and what follows), from its first row; 1 mm a row.
    approach = _approach_phases()[1:]
    runner = schedule.PhaseRunner(
        approach, 0.05, 0.5, replay.metres_per_pulse(replay.NOMINAL_WHEEL_RADIUS), 0.1054
    )
    pulses_per_row = round(0.001 / replay.metres_per_pulse(replay.NOMINAL_WHEEL_RADIUS))
    readings = [100] * 60 + [1023] + [100] * 10 + [1023, 1023] + [100] * 10
    phases = []
    for row, ir in enumerate(readings):
        enc = row * pulses_per_row
        phases.append(runner.next_command(enc, enc, ir, 1000)[0].name)
    assert phases[-1] == "wall_approach", "a glitch of one or two rows stopped the approach"
    for _ in range(schedule.APPROACH_DEBOUNCE):
        row += 1
        enc = row * pulses_per_row
        phase = runner.next_command(enc, enc, 1023, 1000)[0].name
    assert phase == "rest", "three rows above the threshold did not stop it"


@pytest.mark.parametrize("wheel_scale", [1.0 - schedule.RADIUS_TOLERANCE, 1.0 + 0.03])
def test_the_python_state_machine_stops_the_simulated_robot_short_of_the_wall(
    wheel_scale: float,
) -> None:
    # The simulator as the robot: the lowest infrared gain of the spread and the shortest
    # distance scale (its curve then reaches 700 nearest the wall), wheels 3 % off.
    robot = synthetic.TrueRobot(
        wheel_radius=replay.NOMINAL_WHEEL_RADIUS * wheel_scale,
        ir_gain=0.85,
        ir_scale=0.9,
        ir_floor_value=80.0,
        motor_time_constant=0.06,
    )
    log = synthetic.synthetic_calibration_log(
        robot, wall_distance=0.6, seed=3, ruler_sigma=0.0, phases=_approach_phases()
    )
    final = float(note(log, "wall_gap_end_m"))
    assert LEAST_GAP <= final <= 0.06, f"stopped {final * 1000:.1f} mm from the wall"
    assert math.isfinite(final)
