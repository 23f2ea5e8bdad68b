"""The loop back from the robot: the robot programs' logs, ``khepera-gym calibrate`` and
``khepera-gym replay``, tested without a robot.

* Synthetic logs come from the simulator (:mod:`khepera_gym.robot.calibrate.synthetic`): a robot
whose
  parameters are drawn within the real robots' spread runs the calibration manoeuvre with the
  simulator's noise, and the fit must find each parameter within its tolerance.
* The generated C programs are built as ``make robot`` builds them and run against a simulated
  libkhepera (tests/fake_libkhepera/: a robot with its own settings, whose clock runs only when
  the program sleeps); the calibration program's log must parse and calibrate to the fake's own
  settings, and the policy program's log must hold its observations and actions.
* Malformed logs must give an error naming the file, the line and the column, and write
  nothing.

How the tolerances are derived. Every fitted value comes with its standard uncertainty σ: the
linearised covariance s²(JᵀJ)⁻¹ of the residuals, each weighted by its channel's noise as
measured in the fit, so σ is the noise propagated through the fit. A value passes when it is
within 4σ of the truth (a Gaussian error beyond that: 6 in 100,000). So that a large σ cannot
make that easy, each σ must also be below a bound that the noise alone sets, without the fit:

==========================  ============================================================
value                       σ at most
==========================  ============================================================
gyroscope bias              2 σ_g / √N: the mean of N gyroscope residuals of noise σ_g
ultrasonic offset           2 σ_u / √N_u: the mean of N_u ultrasonic residuals (the radius,
                            its line's slope, is pinned by the measured gap)
infrared floor value        2 σ_i / √N_f: the mean of the N_f readings with nothing in range
wheel radius                r σ_ruler / travel: the measured gap alone (√2 mm over the
                            approach); the sensors only add information
axle length                 L √((σ_r/r)² + (2 σ_g / (ω_rms √N))²): the gyroscope against
                            the encoders' yaw rate ω, and the radius
infrared gain and scale     a twentieth of the real robots' spread (15 % and 10 %)
motors' lag                 a tenth of the real robots' spread (10 to 60 ms)
noise levels (σ of σ)       their own standard error σ/√(2(N - 1)) (3 of them allowed)
==========================  ============================================================

The fake robot is not the simulator: its profile is the firmware's staircase of 10 ms and its
sensors sample on their own clocks, so its own settings are recovered within 4σ plus a stated
allowance for those differences (:data:`FAKE_ALLOWANCE`).
"""

from __future__ import annotations

import itertools
import json
import math
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

pytest.importorskip(
    "scipy", reason="needs the calibrate extra: pip install 'khepera-gym[calibrate]'"
)

from khepera_gym import cli
from khepera_gym.errors import ConfigError
from khepera_gym.registration import latest_ids
from khepera_gym.robot import export
from khepera_gym.robot.calibrate import (
    LogFormatError,
    calibrate,
    ir_curve,
    parse_log,
    read_log,
    synthetic,
    write_calibration_program,
    write_log,
)
from khepera_gym.robot.calibrate import fit as fitting
from khepera_gym.robot.calibrate import replay as rp
from khepera_gym.robot.calibrate.logformat import COLUMNS, format_log, note
from khepera_gym.robot.calibrate.schedule import Phase, PhaseRunner

#: The simulated libkhepera of these tests.
FAKE = Path(__file__).resolve().parent / "fake_libkhepera"
#: Flags of the test builds: warning-free C99 (the Makefile's robot build uses gnu99).
C_FLAGS = ("-O2", "-std=c99", "-Wall", "-Wextra", "-Werror")
#: A short manoeuvre (about 37 s of robot time, 750 rows): the wall from 0.35 m, a spin of a
#: turn and a half, one step each way and one turn each way; the program's own lasts 72 s.
SHORT_PHASES = (
    Phase("rest", "timed", 0, 0, 1.0),
    Phase("wall_approach", "approach", 30, 30, 40.0, 950),
    Phase("rest", "timed", 0, 0, 0.5),
    Phase("wall_gap", "gap", 0, 0, 0.0),
    Phase("wall_retreat", "return", -60, -60, 30.0),
    Phase("rest", "timed", 0, 0, 0.5),
    Phase("spin", "spin", -150, 150, 20.0, 1.5 * 2 * math.pi),
    Phase("rest", "timed", 0, 0, 0.5),
    Phase("forward_300", "timed", 300, 300, 1.0),
    Phase("rest", "timed", 0, 0, 0.5),
    Phase("backward_300", "timed", -300, -300, 1.0),
    Phase("rest", "timed", 0, 0, 0.5),
    Phase("left_300", "timed", -300, 300, 1.0),
    Phase("rest", "timed", 0, 0, 0.5),
    Phase("right_300", "timed", 300, -300, 1.0),
    Phase("rest", "timed", 0, 0, 1.0),
)
#: The gap to the wall at the start of the short manoeuvre (m).
WALL_DISTANCE = 0.35
#: The synthetic robot of the recovery tests (a draw of perturbed_robot).
ROBOT_SEED = 12
#: The fake robot's own settings (tests/fake_libkhepera/fake_khepera4.c's defaults, SI).
FAKE_SETTINGS = {
    "robot.wheel_radius": 0.0213,
    "robot.axle_length": 0.1047,
    "robot.motor_time_constant": 0.03,
    "sensors.gyro_bias": 1.2,
    "sensors.ir_floor_value": 95.0,
    "sensors.us_offset": 0.015,
}
#: What the fake robot does differently from the simulator, per value (its unit): the lag
#: is fitted with the simulator stepping 10 ms (its substeps) as the firmware does, and the
#: fake still integrates the motors every 1 ms (0.5 ms); the ultrasonic sweep holds 100 ms at
#: 20 to 40 mm/s (2 mm); the rest none.
FAKE_ALLOWANCE = {
    "robot.wheel_radius": 0.0,
    "robot.axle_length": 0.0,
    "robot.motor_time_constant": 0.0005,
    "sensors.gyro_bias": 0.0,
    "sensors.ir_floor_value": 0.0,
    "sensors.us_offset": 0.002,
}


def assert_within(
    name: str, value: float, truth: float, sigma: float, allowance: float = 0.0
) -> None:
    """``value`` is within 4 sigma (plus an allowance) of ``truth``."""
    assert math.isfinite(sigma) and sigma > 0, f"{name}: uncertainty {sigma}"
    assert abs(value - truth) <= 4.0 * sigma + allowance, (
        f"{name}: fitted {value:.6g} ± {sigma:.3g}, true {truth:.6g} "
        f"({(value - truth) / sigma:+.1f} sigma, allowance {allowance:g})"
    )


@pytest.fixture(scope="module")
def synthetic_case() -> tuple[synthetic.TrueRobot, Any, fitting.Calibration]:
    """A perturbed robot, its short calibration log (simulated) and the fit of the log."""
    robot = synthetic.perturbed_robot(np.random.default_rng(ROBOT_SEED))
    log = synthetic.synthetic_calibration_log(
        robot, wall_distance=WALL_DISTANCE, seed=ROBOT_SEED, phases=SHORT_PHASES
    )
    return robot, log, calibrate([log], progress=False)


# ------------------------------------------------------------------------------------------
# The log format.


def test_a_written_log_reads_back_the_same(tmp_path: Path) -> None:
    robot = synthetic.TrueRobot()
    commands = synthetic.step_commands([(0, 0), (200, 200), (-100, 100)], 0.5)
    log = synthetic.synthetic_command_log(robot, commands, seed=3)
    back = read_log(write_log(tmp_path / "run.csv", log))
    assert back.columns == tuple(c.name for c in COLUMNS)
    assert back.metadata == log.metadata and back.program == "policy"
    for name in back.values:
        np.testing.assert_allclose(back.values[name], log.values[name], atol=5e-3, err_msg=name)
    np.testing.assert_array_equal(back.commands, commands)
    assert len(back) == len(commands) and back.period == 0.05


def _valid_text() -> str:
    log = synthetic.synthetic_command_log(
        synthetic.TrueRobot(), synthetic.step_commands([(0, 0), (300, 300)], 0.3), seed=1
    )
    return format_log(log)


def _column_line(text: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if line.startswith("time,"))


def _missing_column(text: str) -> tuple[str, int, int]:
    lines = text.splitlines()
    header = _column_line(text) - 1
    drop = lines[header].split(",").index("gyro_z")
    out = []
    for number, line in enumerate(lines):
        if number >= header and not line.startswith("#"):
            fields = line.split(",")
            del fields[drop]
            line = ",".join(fields)
        out.append(line)
    return "\n".join(out) + "\n", header + 1, drop + 1


def _wrong_version(text: str) -> tuple[str, int, int | None]:
    return text.replace("format 1\n", "format 2\n", 1), 1, None


def _nan(text: str) -> tuple[str, int, int]:
    lines = text.splitlines()
    row = _column_line(text) + 3  # the fourth row
    fields = lines[row - 1].split(",")
    column = lines[_column_line(text) - 1].split(",").index("ir_3")
    fields[column] = "nan"
    lines[row - 1] = ",".join(fields)
    return "\n".join(lines) + "\n", row, column + 1


def _truncated(text: str) -> tuple[str, int, int]:
    lines = text.splitlines()
    row = _column_line(text) + 5
    cut = lines[row - 1][: len(lines[row - 1]) // 2]  # the copy stopped in the middle of a row
    fields = cut.split(",")
    return "\n".join([*lines[: row - 1], cut]), row, len(fields) + 1


def _time_backwards(text: str) -> tuple[str, int, int]:
    lines = text.splitlines()
    row = _column_line(text) + 4
    fields = lines[row - 1].split(",")
    fields[0] = "0.0100"
    lines[row - 1] = ",".join(fields)
    return "\n".join(lines) + "\n", row, 1


MALFORMED = {
    "missing_column": (_missing_column, "missing column 'gyro_z'"),
    "wrong_format_version": (_wrong_version, "format version '2'; this khepera_gym reads format 1"),
    "nan": (_nan, "'nan' is not a finite number"),
    "truncated": (_truncated, "truncated"),
    "time_backwards": (_time_backwards, "time goes backwards"),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_a_malformed_log_is_an_error_naming_the_file_line_and_column(
    case: str, tmp_path: Path
) -> None:
    make, what = MALFORMED[case]
    text, line, column = make(_valid_text())
    path = tmp_path / f"{case}.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(LogFormatError) as error:
        read_log(path)
    message = str(error.value)
    assert isinstance(error.value, ConfigError)
    assert message.startswith(f"{path}, line {line}"), message
    assert error.value.line == line and error.value.column == column, message
    if column is not None:
        assert f", column {column}" in message, message
    assert what in message, message


def test_a_log_cut_between_rows_is_truncated_too(tmp_path: Path) -> None:
    text = _valid_text()
    lines = text.splitlines()
    with pytest.raises(LogFormatError, match="truncated: the log has no '# end: N rows' line"):
        parse_log("\n".join(lines[:-3]) + "\n", tmp_path / "cut.csv")


@pytest.mark.parametrize("command", ["calibrate", "replay"])
def test_a_malformed_log_writes_nothing(command: str, tmp_path: Path) -> None:
    text, line, column = _nan(_valid_text())
    bad = tmp_path / "bad.csv"
    bad.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    if command == "calibrate":
        arguments = ["calibrate", str(bad), "--out", str(out / "calibrated.toml"), "--quiet"]
    else:
        arguments = ["replay", str(bad), "--out", str(out)]
    with pytest.raises(SystemExit) as exit_:
        cli.main(arguments)
    assert f"{bad}, line {line}, column {column} (ir_3)" in str(exit_.value.code)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_calibrate_refuses_a_policy_log_and_logs_of_different_drives(tmp_path: Path) -> None:
    policy = synthetic.synthetic_command_log(synthetic.TrueRobot(), [[0, 0]] * 5)
    with pytest.raises(ConfigError, match="compare a policy's log with the simulator"):
        calibrate([policy], progress=False)
    a = synthetic.synthetic_calibration_log(
        synthetic.TrueRobot(), wall_distance=0.3, phases=SHORT_PHASES[:2]
    )
    b = synthetic.synthetic_calibration_log(
        synthetic.TrueRobot(acc_inc=10), wall_distance=0.3, phases=SHORT_PHASES[:2]
    )
    with pytest.raises(ConfigError, match=r"acc_inc .* differs"):
        calibrate([a, b], progress=False)


# ------------------------------------------------------------------------------------------
# Recovery from synthetic logs.


def test_calibrate_recovers_the_geometry_and_the_sensors_of_a_perturbed_robot(
    synthetic_case: tuple[synthetic.TrueRobot, Any, fitting.Calibration],
) -> None:
    robot, log, calibration = synthetic_case
    g = calibration.geometry
    n_gyro = len(g.residuals["gyro"])
    gyro_rms = float(np.sqrt(np.mean(g.residuals["gyro"] ** 2)))
    # The gyroscope against the encoders' yaw rate: each row also carries the timing of the
    # encoders' reads (noise.READ_TIMING_S), so the axle's bound uses each row's expected noise.
    gyro_expected = float(np.sqrt(np.mean(g.expected["gyro"] ** 2)))
    us_rms = float(np.sqrt(np.mean(g.residuals["us"] ** 2)))
    path = g.paths[0]
    yaw_rms = float(np.sqrt(np.mean((path.gyro_z * rp.GYRO_DEG_S_PER_COUNT) ** 2)))
    approach = log.phases == "wall_approach"
    travel = (log.encoders[approach][-1] - log.encoders[approach][0]).mean() * rp.metres_per_pulse(
        robot.wheel_radius
    )
    far = ~np.isfinite(rp.wall_ir_distances(path.poses, WALL_DISTANCE))
    n_far = int(far[np.isin(log.phases, fitting.WALL_PHASES)].sum())
    radius_bound = robot.wheel_radius * fitting.RULER_SIGMA / travel
    bounds = {
        "robot.wheel_radius": radius_bound,
        "robot.axle_length": robot.axle_length
        * math.hypot(
            radius_bound / robot.wheel_radius,
            2 * gyro_expected / (yaw_rms * math.sqrt(n_gyro)),
        ),
        "sensors.gyro_bias": 2 * gyro_rms / math.sqrt(n_gyro),
        "sensors.us_offset": 2 * us_rms / math.sqrt(len(g.residuals["us"])),
        "sensors.ir_floor_value": 2 * robot.ir_noise_sigma / math.sqrt(n_far),
    }
    truth = {
        "robot.wheel_radius": robot.wheel_radius,
        "robot.axle_length": robot.axle_length,
        "sensors.gyro_bias": robot.gyro_bias,
        "sensors.us_offset": robot.us_offset,
        "sensors.ir_floor_value": robot.ir_floor_value,
        "ir_gain": robot.ir_gain,
        "ir_scale": robot.ir_scale,
    }
    found = {
        e.key: e
        for e in (
            g.wheel_radius,
            g.axle_length,
            g.gyro_bias,
            g.us_offset,
            g.ir_floor_value,
            g.ir_gain,
            g.ir_scale,
        )
    }
    for key, estimate in found.items():
        sigma = float(estimate.sigma)
        if key in bounds:
            assert sigma <= bounds[key], (
                f"{key}: σ {sigma:.3g} above the noise's bound {bounds[key]:.3g}"
            )
        assert_within(key, float(estimate.value), truth[key], sigma)
    # The curve written: each point the approach came near is fitted, within 4 σ of the robot's
    # (K-Team's curve scaled, as the simulator holds it), and its σ is at most twice the noise
    # over the readings about it plus the shift of the curve that the ruler's error of the
    # wheel radius makes (its slope times RULER_SIGMA, twice); the points nearer than the
    # approach came are not identified. (The gain and the scale above are K-Team's curve nearest
    # the points, for the report: the curve takes no part in the radius.)
    curve = synthetic.ir_curve(robot.ir_gain, robot.ir_scale)
    distances = rp.wall_ir_distances(path.poses[np.isin(log.phases, fitting.WALL_PHASES)], 0.35)
    seen = ir_curve.points_seen(ir_curve.curve_basis(distances.ravel()))
    slope = np.abs(np.gradient(curve, rp.IR_CURVE_MM / 1000.0))
    for point, (value, sigma, known) in enumerate(
        zip(g.ir_curve.value, g.ir_curve.sigma, g.ir_curve.identified, strict=True)
    ):
        if seen[point] < ir_curve.MIN_READINGS:
            assert not known, f"ir_curve[{point}] identified with {seen[point]:.1f} readings"
            continue
        bound = 2 * robot.ir_noise_sigma / math.sqrt(seen[point])
        bound += 2 * slope[point] * fitting.RULER_SIGMA
        assert sigma <= bound, f"ir_curve[{point}]: σ {sigma:.3g} above its bound {bound:.3g}"
        assert_within(f"ir_curve[{point}]", value, float(curve[point]), sigma)
    assert 0.8 < g.chi2 < 1.2


def test_calibrate_measures_the_noise_of_each_sensor(
    synthetic_case: tuple[synthetic.TrueRobot, Any, fitting.Calibration],
) -> None:
    robot, _, calibration = synthetic_case
    g = calibration.geometry
    for estimate, truth in (
        (g.gyro_noise_sigma, robot.gyro_noise_sigma),
        (g.ir_noise_sigma, robot.ir_noise_sigma),
        (g.us_noise_sigma, robot.us_noise_sigma),
    ):
        assert_within(estimate.key, float(estimate.value), truth, float(estimate.sigma))


def test_calibrate_recovers_the_motors_lag_and_confirms_the_profile(
    synthetic_case: tuple[synthetic.TrueRobot, Any, fitting.Calibration],
) -> None:
    robot, _, calibration = synthetic_case
    drive = calibration.drive
    tau = drive.motor_time_constant
    assert float(tau.sigma) <= 0.05 / 10
    assert_within(tau.key, float(tau.value), robot.motor_time_constant, float(tau.sigma))
    # The program's profile is written as set; the speeds follow it within 4 sigma of its value.
    assert drive.accel.key == "motors.acc_inc" and drive.accel.value == robot.acc_inc
    fitted, sigma = drive.fitted_acc_inc
    assert_within("acc_inc followed", fitted, robot.acc_inc, sigma)
    assert set(drive.profile) >= {robot.acc_inc - 1, robot.acc_inc, robot.acc_inc + 1}
    assert 0.8 < drive.chi2 < 1.2


def test_the_speed_modes_acceleration_and_lag_are_recovered() -> None:
    robot = synthetic.perturbed_robot(
        np.random.default_rng(7), motors="speed", speed_accel=1.6, acc_inc=0
    )
    steps = tuple(p for p in SHORT_PHASES if p.kind == "timed")
    log = synthetic.synthetic_calibration_log(robot, seed=7, phases=steps)
    drive = fitting.DriveFit([log], robot.wheel_radius, {}, fitting.Progress(False)).fit()
    assert drive.accel.key == "motors.speed_accel"
    assert float(drive.accel.sigma) <= 0.5 / 10  # a tenth of the [1, 5] m/s² one could expect
    assert_within("speed_accel", float(drive.accel.value), 1.6, float(drive.accel.sigma))
    tau = drive.motor_time_constant
    assert_within(tau.key, float(tau.value), robot.motor_time_constant, float(tau.sigma))


def test_calibrate_writes_a_scenario_every_env_loads_with_its_uncertainties_and_a_report(
    synthetic_case: tuple[synthetic.TrueRobot, Any, fitting.Calibration],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    robot, log, _ = synthetic_case
    log_path = write_log(tmp_path / "calibration.csv", log)
    out = tmp_path / "calibrated.toml"
    status = cli.main(["calibrate", str(log_path), "--out", str(out), "--randomise", "2"])
    assert status == 0
    captured = capsys.readouterr()
    assert "calibrate: drive" in captured.err and "replays" in captured.err  # the progress bar
    assert "robot.wheel_radius" in captured.out and "reduced chi-square" in captured.out
    text = out.read_text()
    from khepera_gym.config import tomllib

    table = tomllib.loads(text)
    # Ranges around the fitted values where a key takes one; single values elsewhere; every
    # value carries its uncertainty in its comment.
    low, high = table["sensors"]["gyro_bias"]
    assert low < robot.gyro_bias < high
    assert isinstance(table["robot"]["wheel_radius"], float)
    assert table["motors"]["acc_inc"] == robot.acc_inc and table["motors"]["mode"] == "profile"
    assert len(table["sensors"]["ir_curve"]) == 16
    for line in text.splitlines():
        if " = " in line and not line.startswith("#"):
            assert "#" in line, line
    assert "± " in text and "randomised over ± 2 sigma" in text
    for env_id in latest_ids().values():
        env = gym.make(env_id, config=str(out))
        env.reset(seed=0)
        env.step(env.action_space.sample())
        loaded = tomllib.loads(env.unwrapped.config_toml())
        assert loaded["robot"]["wheel_radius"] == pytest.approx(table["robot"]["wheel_radius"])
        env.close()
    report = tmp_path / "calibrated_report"
    for name in ("drive.png", "gyro.png", "ir.png", "us.png", "report.json", "report.md"):
        assert (report / name).is_file(), name
    numbers = json.loads((report / "report.json").read_text())
    keys = {p["key"] for p in numbers["parameters"]}
    assert {"robot.wheel_radius", "robot.axle_length", "sensors.ir_curve"} <= keys
    assert numbers["residuals"]["ir_raw"]["count"] > 1000
    assert numbers["meta"]["command"].startswith("khepera-gym calibrate")


# ------------------------------------------------------------------------------------------
# Replay.


def test_replay_reports_the_divergence_after_1_5_and_10_s(tmp_path: Path) -> None:
    # A robot whose program set K-Team's Braitenberg profile (acc_inc 10, 0.68 m/s²) and whose
    # motors lag 30 ms drives a sequence of steps and turns for 12 s. Replayed with its own
    # drive the simulator stays with it (to the odometry's rounding); with the defaults
    # (acc_inc 40, no lag) it falls behind at every step and turns late: decimetres at 10 s.
    robot = synthetic.TrueRobot(acc_inc=10, motor_time_constant=0.03)
    commands = synthetic.step_commands(
        [(300, 300), (200, 400), (0, 0), (-300, 300), (400, 400), (0, 0)], 2.0
    )
    log = synthetic.synthetic_command_log(robot, commands, seed=5)
    scene = {
        "spawn.start": [0.0, 0.0, 0.0],
        "arena.walls": False,
        "arena.width": 8.0,
        "arena.height": 8.0,
    }
    truth = {"motors.acc_inc": 10, "robot.motor_time_constant": 0.03}
    own = rp.compare_with_simulator(log, overrides={**scene, **truth})
    default = rp.compare_with_simulator(log, overrides=scene)
    assert [d.time for d in own.divergences] == [1.0, 5.0, 10.0]
    for mine in own.divergences:
        assert mine.position < 0.002 and abs(mine.heading) < 0.002
    assert default.divergences[-1].position > 0.05
    # The speed sensor's noise is 2 units (TrueRobot.speed_noise): the own replay's RMS is that.
    assert own.wheel_rms < 3.0 < default.wheel_rms

    # What an odometry replay cannot see: the wheels and the axle. The commands are in encoder
    # pulses per 10 ms, and the logged path is the same pulses through the same geometry, so a
    # robot with 2 % larger wheels and a 2 % shorter axle replays within the same 2 mm with
    # the nominal geometry (calibrate finds them from the gyroscope and the wall instead).
    geometry = synthetic.TrueRobot(
        wheel_radius=0.0214, axle_length=0.1030, motor_time_constant=0.03
    )
    nominal = rp.compare_with_simulator(
        synthetic.synthetic_command_log(geometry, commands, seed=5),
        overrides={**scene, "robot.motor_time_constant": 0.03},
    )
    assert all(d.position < 0.002 for d in nominal.divergences)

    path = write_log(tmp_path / "run.csv", log)
    config = tmp_path / "own.toml"
    config.write_text(
        "[robot]\nmotor_time_constant = 0.03\n[motors]\nacc_inc = 10\n"
        "[spawn]\nstart = [0.0, 0.0, 0.0]\n[arena]\nwalls = false\nwidth = 8.0\nheight = 8.0\n"
    )
    assert (
        cli.main(["replay", str(path), "--config", str(config), "--out", str(tmp_path / "r")]) == 0
    )
    numbers = json.loads((tmp_path / "r" / "replay.json").read_text())
    assert [d["time_s"] for d in numbers["divergence"]] == [1.0, 5.0, 10.0]
    assert all(d["position_m"] < 0.002 for d in numbers["divergence"])
    assert (tmp_path / "r" / "replay.png").is_file()


def test_replay_of_a_policy_log_needs_its_start_pose(tmp_path: Path) -> None:
    log = synthetic.synthetic_command_log(synthetic.TrueRobot(), [[100, 100]] * 10)
    with pytest.raises(ConfigError, match=r"spawn\.start"):
        rp.compare_with_simulator(log)


# ------------------------------------------------------------------------------------------
# The C programs on the simulated libkhepera.


def _fake_build(
    out_dir: Path, main: str, sources: tuple[str, ...], name: str, **defines: float
) -> Path:
    """A program built against the simulated robot, with its simulated clock (fast)."""
    flags = [f"-D{key}={value}" for key, value in defines.items()]
    program = out_dir / name
    subprocess.run(
        [
            "cc",
            *C_FLAGS,
            *flags,
            f"-I{FAKE}",
            f"-I{out_dir}",
            "-o",
            str(program),
            str(out_dir / main),
            *(str(out_dir / s) for s in sources if s != "khepera_clock.c"),
            str(FAKE / "fake_khepera4.c"),
            str(FAKE / "fake_clock.c"),
            "-lm",
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    return program


def _make_robot(out_dir: Path) -> subprocess.CompletedProcess[str]:
    """``make robot`` as a user runs it, with the simulated libkhepera as libkhepera.a (the
    programs' own clock: the simulated robot then stands still) and the test's C flags."""
    lib = out_dir / "lib"
    lib.mkdir()
    subprocess.run(
        [
            "cc",
            *C_FLAGS,
            "-c",
            f"-I{FAKE}",
            "-o",
            str(lib / "fake.o"),
            str(FAKE / "fake_khepera4.c"),
        ],
        check=True,
        capture_output=True,
    )
    subprocess.run(["ar", "rcs", str(lib / "libkhepera.a"), str(lib / "fake.o")], check=True)
    return subprocess.run(
        [
            "make",
            "-C",
            str(out_dir),
            "robot",
            "CROSS_CC=cc",
            f"INCPATH={FAKE}",
            f"LIBPATH={lib}",
            "ROBOT_CFLAGS=" + " ".join(C_FLAGS),
        ],
        check=True,
        capture_output=True,
        text=True,
    )


@pytest.fixture(scope="module")
def fake_calibration_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, Any]]:
    """The calibration program (short manoeuvre) run on the simulated robot twice: first to
    find the final gap the user would measure (the robot's true pose, FAKE_TRACE), then with
    that gap typed in."""
    out = tmp_path_factory.mktemp("calibration_program")
    written = write_calibration_program(out, env_id=LATEST["nav"], phases=SHORT_PHASES)
    # The fake's wall stands where the user says it is: the gap plus the body's radius ahead
    # of the robot's centre (its default is the policy test's 0.5 m).
    program = _fake_build(
        out,
        "khepera_calibrate_main.c",
        export.ROBOT_SOURCES,
        "khepera_calibrate_fake",
        FAKE_WALL_X=WALL_DISTANCE + rp.BODY_RADIUS,
    )
    trace = out / "trace.txt"
    log_path = out / "first.csv"
    environment = {**os.environ, "FAKE_TRACE": str(trace)}
    subprocess.run(
        [str(program), str(WALL_DISTANCE), str(log_path)],
        input="\n",
        env=environment,
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    first = read_log(log_path)
    gap_row = [n.after for n in first.notes if n.key == "wall_gap_end_m"][-1]
    times = np.loadtxt(trace)
    true_gap = float(times[np.argmin(np.abs(times[:, 0] - first.time[gap_row])), 4])
    log_path = out / "calibration.csv"
    run = subprocess.run(
        [str(program), str(WALL_DISTANCE), str(log_path)],
        input=f"{true_gap * 1000:.1f}\n",
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    assert "Measure the gap" in run.stderr
    yield out, (written, read_log(log_path), true_gap)


def test_the_calibration_program_builds_with_make_robot(fake_calibration_run: Any) -> None:
    out, _ = fake_calibration_run
    built = _make_robot(out)
    assert "khepera_calibrate_main.c" in built.stdout and (out / "khepera_calibrate").is_file()


def test_the_calibration_programs_log_is_the_manoeuvre_pythons_runner_plays(
    fake_calibration_run: Any,
) -> None:
    _, (written, log, true_gap) = fake_calibration_run
    # The header records the program, the drive it set and the firmware's revision.
    assert log.program == "calibrate" and log.metadata["firmware"] == "C.3"
    assert log.metadata["motors"] == "profile" and int(log.metadata["acc_inc"]) == 40
    assert log.number("wall_distance_m") == WALL_DISTANCE
    assert float(note(log, "wall_gap_end_m")) == pytest.approx(true_gap, abs=1e-4)
    # The same phases and commands, row by row, as the Python state machine decides from the
    # logged readings.
    gaps = iter([true_gap])
    runner = PhaseRunner(
        written.phases,
        log.period,
        WALL_DISTANCE,
        rp.metres_per_pulse(0.021),
        0.1054,
        lambda: next(gaps),
    )
    for row in range(len(log)):
        phase, left, right = runner.next_command(
            int(log.encoders[row, 0]),
            int(log.encoders[row, 1]),
            int(log.ir[row, 3]),
            int(log.us[row, 2]),
        )
        assert (phase.name, left, right) == (
            log.phases[row],
            log.commands[row, 0],
            log.commands[row, 1],
        ), row
    with pytest.raises(StopIteration):
        runner.next_command(int(log.encoders[-1, 0]), int(log.encoders[-1, 1]), 0)
    # Every phase has rows; the gap's question has one, the pause's.
    assert set(log.phases) == {p.name for p in SHORT_PHASES}
    assert (log.phases == "wall_gap").sum() == 1


def test_a_log_of_the_calibration_program_calibrates_to_the_fakes_own_settings(
    fake_calibration_run: Any, tmp_path: Path
) -> None:
    _, (_, log, _) = fake_calibration_run
    # The fake's firmware updates the profile every 10 ms: the simulator steps 10 ms too
    # (physics.substeps = 5 at dt = 0.05), as the scenario written then says.
    calibration = calibrate([log], {"physics.substeps": 5}, progress=False)
    estimates = {e.key: e for e in calibration.estimates()}
    for key, truth in FAKE_SETTINGS.items():
        estimate = estimates[key]
        assert_within(key, float(estimate.value), truth, float(estimate.sigma), FAKE_ALLOWANCE[key])
    # The fake's infrared curve: K-Team's × 0.9 in value, its distances × 1.05.
    for estimate, truth in (
        (calibration.geometry.ir_gain, 0.9),
        (calibration.geometry.ir_scale, 1.05),
    ):
        assert_within(estimate.key, float(estimate.value), truth, float(estimate.sigma))
    assert calibration.drive.accel.value == 40


def test_the_policy_program_logs_every_step_with_its_observation_and_action(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    widths = [18, 16, 2]
    layers = tuple(
        export.DenseLayer(
            rng.normal(0, 1.0 / math.sqrt(n_in), (n_out, n_in)).astype(np.float32),
            rng.normal(0, 0.3, n_out).astype(np.float32),
            "tanh",
            0.0,
        )
        for n_in, n_out in itertools.pairwise(widths)
    )
    network = export.PolicyNetwork(
        "hand-written",
        18,
        2,
        None,
        layers,
        export.ActionTransform(np.ones(2), np.zeros(2), None, None),
    )
    with gym.make(LATEST["nav"]) as env:
        robot = export.robot_interface(env, 18, LATEST["nav"])
    motors = export.motor_setting(export.toml_loads(robot.scenario_toml))
    export.write_c(network, robot, motors, tmp_path, "a test")
    sources = (*export.C_SOURCES, *export.ROBOT_SOURCES)
    program = _fake_build(tmp_path, "khepera_policy_main.c", sources, "khepera_policy_fake")
    run = subprocess.run(
        [str(program), "1.0", "0.0", "30", "--log", str(tmp_path / "run.csv")],
        capture_output=True,
        text=True,
        check=True,
        timeout=30,
    )
    assert len(run.stdout.splitlines()) == 30
    log = read_log(tmp_path / "run.csv")
    assert log.program == "policy" and log.metadata["env_id"] == LATEST["nav"]
    assert log.metadata["motors"] == "profile" and log.metadata["acc_inc"] == "40"
    assert log.period == 0.05 and len(log) == 30
    np.testing.assert_allclose(np.diff(log.time), 0.05, atol=1e-3)
    observations, actions = log.extra("obs"), log.extra("action")
    assert observations.shape == (30, 18) and actions.shape == (30, 2)
    # The logged actions are the policy's for the logged observations, and the commands the
    # wheel units of those actions (export_check runs the exported C on them).
    check = tmp_path / "export_check"
    subprocess.run(
        [
            "cc",
            *C_FLAGS,
            "-o",
            str(check),
            str(tmp_path / "export_check.c"),
            *(str(tmp_path / s) for s in export.C_SOURCES),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )

    def run_check(mode: str, rows: np.ndarray) -> np.ndarray:
        text = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in rows) + "\n"
        out = subprocess.run(
            [str(check), mode], input=text, capture_output=True, text=True, check=True
        )
        return np.array([[float(v) for v in line.split()] for line in out.stdout.splitlines()])

    np.testing.assert_allclose(run_check("policy", observations), actions, atol=1e-6)
    np.testing.assert_array_equal(run_check("wheels", actions), log.commands)
    # The robot moved as commanded (the simulated one drives; this policy backs away), and the
    # readings are its.
    travelled = log.encoders[-1] - log.encoders[0]
    assert np.all(np.abs(travelled) > 100), travelled
    np.testing.assert_array_equal(np.sign(travelled), np.sign(log.commands[-1]))
    assert np.all(log.values["acc_z"][2:] == -1000)
    # Its replay in the scene of the fake (a wall 0.5 m ahead), with the fake's motors (a 30 ms
    # lag, the profile stepped every 10 ms), follows it to a centimetre; the log lasts 1.5 s.
    # (The fake's wheels and axle do not show in an odometry replay, test_replay_reports_...)
    fake_drive = {
        "robot.motor_time_constant": FAKE_SETTINGS["robot.motor_time_constant"],
        "physics.substeps": 5,
    }
    comparison = rp.compare_with_simulator(
        log, overrides={**rp.calibration_scene(0.5), **fake_drive}
    )
    assert comparison.divergences[0].position < 0.01
    assert all(math.isnan(d.position) for d in comparison.divergences[1:])


def test_the_policy_program_builds_with_make_robot_and_runs_on_the_fake(tmp_path: Path) -> None:
    with gym.make(LATEST["nav"]) as env:
        robot = export.robot_interface(env, 18, LATEST["nav"])
    layer = export.DenseLayer(
        np.zeros((2, 18), np.float32), np.full(2, 0.2, np.float32), "identity", 0.0
    )
    network = export.PolicyNetwork(
        "constant",
        18,
        2,
        None,
        (layer,),
        export.ActionTransform(np.ones(2), np.zeros(2), None, None),
    )
    export.write_c(
        network, robot, export.motor_setting(export.toml_loads(robot.scenario_toml)), tmp_path, "t"
    )
    _make_robot(tmp_path)
    run = subprocess.run(
        [str(tmp_path / "khepera_policy"), "1.0", "0.0", "2", "--log", str(tmp_path / "run.csv")],
        capture_output=True,
        text=True,
        check=True,
        timeout=30,
    )
    assert len(run.stdout.splitlines()) == 2 and len(read_log(tmp_path / "run.csv")) == 2


def test_robot_program_command_writes_the_calibration_program(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "calibrate"
    assert (
        cli.main(["robot-program", "calibrate", "--out", str(out), "--set", "preset=kteam_default"])
        == 0
    )
    printed = capsys.readouterr().out
    assert "kh4_SetSpeedProfile(3, 0, 20, 1, 400)" in printed
    config = (out / "khepera_calibrate_config.h").read_text()
    assert "#define CALIBRATE_ACC_INC 3" in config and '"wall_approach", PHASE_APPROACH' in config
    phases = json.loads((out / "phases.json").read_text())["phases"]
    # At K-Team's default 0.20 m/s² the steps last long enough to reach their speed (1.5 times
    # the 1.0 s of 300 units), and those that would carry the robot beyond 0.6 m are left out
    # (600 units for 3.0 s: 1.2 m).
    steps = {p["name"]: p["seconds"] for p in phases if p["name"].startswith("forward")}
    assert steps["forward_300"] == pytest.approx(1.5) and "forward_600" not in steps
    assert "make robot" in (out / "README.md").read_text()


def test_export_converts_speeds_with_the_calibrated_wheel_radius(tmp_path: Path) -> None:
    # A calibrated wheel of 21.42 mm: a speed unit (a pulse per 10 ms) is 2 % more ground speed.
    with gym.make(LATEST["nav"], wheel_radius=0.02142) as env:
        robot = export.robot_interface(env, 18, LATEST["nav"])
    layer = export.DenseLayer(
        np.zeros((2, 18), np.float32), np.zeros(2, np.float32), "identity", 0.0
    )
    network = export.PolicyNetwork(
        "constant",
        18,
        2,
        None,
        (layer,),
        export.ActionTransform(np.ones(2), np.zeros(2), None, None),
    )
    export.write_c(
        network, robot, export.motor_setting(export.toml_loads(robot.scenario_toml)), tmp_path, "t"
    )
    header = (tmp_path / "wheel_command.h").read_text()
    expected = np.float32(0.678181 * 0.02142 / 0.021)
    assert f"#define WHEEL_MM_S_PER_UNIT {float(expected):.9g}f" in header
    assert (
        "#define KHEPERA_WHEEL_RADIUS 0.02142" in (tmp_path / "khepera_policy_config.h").read_text()
    )
