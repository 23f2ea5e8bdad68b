"""The robot's numbers against K-Team's own sources: every constant the simulator, the exporter and
the calibration use that K-Team's libkhepera 2.1 also states, held to K-Team's value.

K-Team's values are literals here, each with the file it is read from: the library's headers
and sources (``include/khepera/kb_khepera4.h``, ``knet.h``, ``kb_error.h``, ``kb_khepera4.c``)
and its demo program ``khepera4_test.c`` (public in the repository ``foxybbb/khepera-dev-vscode``,
``libs/`` and ``examples/``). The simulator's come from ``khepera_gym._core`` and what it
simulates (sensor readings), the exporter's and the calibration's from their modules. Where the
simulator deliberately differs, the test states how, and docs/robot.md gives both values with
their sources. The fake libkhepera's header (tests/fake_libkhepera/) is held to the same
literals, compiled.

External in part: the literals are K-Team's; whether K-Team's firmware behaves as its library
says is not tested here.
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

import khepera_gym
from khepera_gym import _core
from khepera_gym.robot.calibrate import replay
from khepera_gym.robot.export import motors, robot

FAKE = Path(__file__).resolve().parent / "fake_libkhepera"

# kb_khepera4.h (libkhepera 2.1, "robot hardware constants").
#: mm between the wheels.
KH4_WHEELS_DISTANCE = 105.4
#: mm a wheel travels per encoder pulse.
KH4_PULSE_TO_MM = 0.006781
#: ms: the period of the speed unit (a speed unit is pulses per 10 ms).
KH4_TIME_BTWN = 10
#: mm/s per speed unit.
KH4_SPEED_TO_MM_S = 0.6781
#: deg/s per gyroscope count.
KH4_GYRO_DEG_S = 66.0 / 1000.0
#: The infrared sensors' span (10 bits: 0..1023).
KH4_MAX_IR_VALUE = 1024
#: Ultrasonic codes: sensor switched off, nothing within 25..250 cm, something nearer than 25 cm.
KH4_US_DISABLED_SENSOR = 2000
KH4_US_NO_OBJECT_IN_RANGE = 1000
KH4_US_OBJECT_NEAR = 0
#: kb_khepera4.h's motor modes (enum kh4RegType).
KH4_REG_TYPES = {
    "kh4RegIdle": 0,
    "kh4RegSpeed": 1,
    "kh4RegSpeedProfile": 2,
    "kh4RegPosition": 3,
    "kh4RegSOpenLoop": 4,
}
# knet.h.
KNET_BUS_I2C = 0
# kb_error.h: the codes kb_khepera4.c returns (positive).
KB_ERROR_KH4RCVERR = 55
KB_ERROR_KH4SENERR = 56
KB_ERROR_KH4KBNOTINIT = 58
# kb_khepera4.h's error codes (negative).
KH4_ERROR_KBINIT = -1
# khepera4_test.c (K-Team's demo), main(): the speed profile it sets before anything else,
# kh4_SetSpeedProfile(accinc, accdiv, minspacc, minspdec, maxsp), and its Braitenberg demo's.
KTEAM_PROFILE = {"acc_inc": 3, "acc_div": 0, "min_speed_acc": 20, "min_speed_dec": 1}
KTEAM_PROFILE_MAX_SPEED = 400
KTEAM_BRAITENBERG_ACC_INC = 10
#: The wheel (mm) and encoder of the K-Team manual (docs/robot.md §1): 42 mm wheels; 128 pulses a
#: motor turn, counted in quadrature (x4), through a 38:1 gear. kb_khepera4.h has no such
#: constants; its pulse and speed factors are these, truncated (see below).
MANUAL_WHEEL_RADIUS_MM = 21.0
MANUAL_PULSES_PER_WHEEL_TURN = 128 * 4 * 38


def truncated(value: float, decimals: int) -> float:
    """``value`` cut (not rounded) to ``decimals`` decimals, as K-Team wrote its factors."""
    return math.floor(value * 10**decimals) / 10**decimals


def test_the_wheel_distance_is_kteams() -> None:
    # The simulator, its scenario default and what the exporter and calibration program bake in.
    assert math.isclose(_core.AXLE_LENGTH, KH4_WHEELS_DISTANCE / 1000, abs_tol=1e-8)
    with gym.make(LATEST["nav"]) as env:
        exported = robot.robot_interface(env, 18, LATEST["nav"])
    assert exported.axle_length == pytest.approx(KH4_WHEELS_DISTANCE / 1000, abs=1e-8)
    assert "axle_length = 0.1054 " in _core.default_config("nav", None)


def test_the_encoder_pulse_is_kteams_factor_untruncated() -> None:
    # The exporter and the calibration count 19,456 pulses a turn of a 21 mm wheel, the manual's
    # gear; K-Team's KH4_PULSE_TO_MM is the same pulse cut to 6 decimals (0.0067818 mm).
    assert robot.PULSES_PER_WHEEL_TURN == replay.PULSES_PER_WHEEL_TURN
    assert robot.PULSES_PER_WHEEL_TURN == MANUAL_PULSES_PER_WHEEL_TURN
    assert math.isclose(_core.WHEEL_RADIUS, MANUAL_WHEEL_RADIUS_MM / 1000, abs_tol=1e-9)
    pulse_mm = replay.metres_per_pulse(MANUAL_WHEEL_RADIUS_MM / 1000) * 1000
    assert pulse_mm == pytest.approx(2 * math.pi * 21 / 19456, rel=1e-12)
    assert truncated(pulse_mm, 6) == KH4_PULSE_TO_MM


def test_the_speed_unit_is_kteams_factor_untruncated() -> None:
    # A speed unit is a pulse per KH4_TIME_BTWN ms: the simulator's 0.678181 mm/s (the manual's
    # figure, docs/robot.md §1) is 100 pulses a second, to the manual's 6 digits; K-Team's
    # header cuts it to 0.6781 (0.012 % less). The simulator and every Python module use the
    # manual's.
    unit_mm_s = khepera_gym.units_to_speed(1) * 1000
    assert unit_mm_s == pytest.approx(0.678181, rel=1e-6)
    pulse_mm = 2 * math.pi * 21 / MANUAL_PULSES_PER_WHEEL_TURN
    assert unit_mm_s == pytest.approx(pulse_mm * 1000 / KH4_TIME_BTWN, rel=1e-6)
    assert truncated(unit_mm_s, 4) == KH4_SPEED_TO_MM_S
    for python in (motors.SPEED_UNIT, replay.SPEED_UNIT, robot.MM_S_PER_SPEED_UNIT / 1000):
        assert python == pytest.approx(unit_mm_s / 1000, rel=1e-6)
    # The firmware's period: the profile adds acc_inc every acc_div + 1 periods of 10 ms.
    assert motors.CONTROL_PERIOD_S == KH4_TIME_BTWN / 1000


def test_the_gyroscope_count_is_kteams() -> None:
    # The simulated gyroscope reads whole counts and gives the rate in rad/s from them.
    env = gym.make(LATEST["nav"], carry=["ir", "us", "gyro"])
    env.reset(seed=0)
    raws, rates = [], []
    for _ in range(40):
        env.step(np.array([-0.4, 0.6], np.float32))
        readings = env.unwrapped.sensor_readings()
        raws.append(int(readings["gyro_raw"][0]))
        rates.append(float(readings["gyro_z"][0]))
    env.close()
    raw, rate = np.array(raws), np.array(rates)
    assert np.all(np.abs(raw) > 1000)  # it turned
    np.testing.assert_allclose(np.degrees(rate) / raw, KH4_GYRO_DEG_S, rtol=1e-6)
    assert replay.GYRO_DEG_S_PER_COUNT == KH4_GYRO_DEG_S


def test_the_infrared_span_and_the_ultrasonic_codes_are_kteams() -> None:
    # A wall 20 mm ahead, noisy infrared sensors: the ring saturates at K-Team's 10-bit top.
    overrides = {**replay.calibration_scene(0.02), "ir_noise_sigma": 100.0}
    env = gym.make(LATEST["nav"], **overrides)
    env.reset(seed=0)
    fronts = []
    for _ in range(30):
        env.step(np.zeros(2, np.float32))
        readings = env.unwrapped.sensor_readings()
        fronts.append(int(readings["ir_raw"][0][3]))
        assert np.all((readings["ir_raw"] >= 0) & (readings["ir_raw"] < KH4_MAX_IR_VALUE))
    assert max(fronts) == KH4_MAX_IR_VALUE - 1
    # The ultrasonic sensors: the front one too close (the wall at 20 mm), the left one seeing
    # nothing; switched off, any reads K-Team's disabled code.
    us = env.unwrapped.sensor_readings()["us_cm"][0]
    env.close()
    assert us[2] == KH4_US_OBJECT_NEAR and us[0] == KH4_US_NO_OBJECT_IN_RANGE
    overrides["us_enabled"] = [False, True, True, True, True]
    with gym.make(LATEST["nav"], **overrides) as env:
        env.reset(seed=0)
        env.step(np.zeros(2, np.float32))
        assert env.unwrapped.sensor_readings()["us_cm"][0][0] == KH4_US_DISABLED_SENSOR


def test_the_speed_profile_presets_are_kteams_demos() -> None:
    presets = {name: text for name, text, _ in _core.motor_presets()}
    default = dict(line.split(" = ") for line in presets["kteam_default"].splitlines())
    assert default.pop("mode") == '"profile"'
    assert {key: int(value) for key, value in default.items()} == KTEAM_PROFILE
    assert f"acc_inc = {KTEAM_BRAITENBERG_ACC_INC}\n" in presets["kteam_braitenberg"]
    # The exported programs and the calibration program pass K-Team's maximum speed and, where a
    # scenario has none, its minimum speeds.
    assert motors.PROFILE_MAX_SPEED == KTEAM_PROFILE_MAX_SPEED
    minimums = {
        "min_speed_acc": motors.KTEAM_MIN_SPEED_ACC,
        "min_speed_dec": motors.KTEAM_MIN_SPEED_DEC,
    }
    assert minimums == {key: KTEAM_PROFILE[key] for key in minimums}


def test_the_fake_libkheperas_header_holds_kteams_values(tmp_path: Path) -> None:
    names = {
        "KNET_BUS_I2C": KNET_BUS_I2C,
        "KB_ERROR_KH4RCVERR": KB_ERROR_KH4RCVERR,
        "KB_ERROR_KH4SENERR": KB_ERROR_KH4SENERR,
        "KB_ERROR_KH4KBNOTINIT": KB_ERROR_KH4KBNOTINIT,
        "KH4_ERROR_KBINIT": KH4_ERROR_KBINIT,
        "KH4_TIME_BTWN": KH4_TIME_BTWN,
        "KH4_MAX_IR_VALUE": KH4_MAX_IR_VALUE,
        "KH4_US_DISABLED_SENSOR": KH4_US_DISABLED_SENSOR,
        "KH4_US_NO_OBJECT_IN_RANGE": KH4_US_NO_OBJECT_IN_RANGE,
        "KH4_US_OBJECT_NEAR": KH4_US_OBJECT_NEAR,
        **KH4_REG_TYPES,
    }
    factors = {
        "KH4_WHEELS_DISTANCE": KH4_WHEELS_DISTANCE,
        "KH4_PULSE_TO_MM": KH4_PULSE_TO_MM,
        "KH4_SPEED_TO_MM_S": KH4_SPEED_TO_MM_S,
        "KH4_GYRO_DEG_S": KH4_GYRO_DEG_S,
    }
    lines = [f'    printf("{name} %d\\n", (int)({name}));' for name in names]
    lines += [f'    printf("{name} %.17g\\n", (double)({name}));' for name in factors]
    source = tmp_path / "constants.c"
    source.write_text(
        "#include <stdio.h>\n#include <khepera/khepera.h>\nint main(void)\n{\n"
        + "\n".join(lines)
        + '\n    printf("knet_dev_t %d\\n", (int)sizeof(knet_dev_t) > (int)sizeof(void *));\n'
        "    return 0;\n}\n"
    )
    program = tmp_path / "constants"
    subprocess.run(
        [
            "cc",
            "-std=gnu99",
            "-Wall",
            "-Wextra",
            "-Werror",
            f"-I{FAKE}",
            "-o",
            str(program),
            source,
        ],
        check=True,
        capture_output=True,
    )
    printed = dict(
        line.split()
        for line in subprocess.run(
            [str(program)], capture_output=True, text=True, check=True
        ).stdout.splitlines()
    )
    for name, value in names.items():
        assert int(printed[name]) == value, name
    for name, value in factors.items():
        assert float(printed[name]) == value, name
    assert printed["knet_dev_t"] == "1"  # a whole struct, as knet.h defines it, not opaque
