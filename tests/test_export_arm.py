"""The generated robot programs on the Khepera IV's own processor, and on K-Team's interface.

Every program (a policy without memory, a frame-stacked one, a recurrent one (an LSTM), one
sampling its actions, a ``led_action`` one, their ``export_check``, and the calibration program)
is cross-compiled for ARMv7-A, hard float, NEON, with the flags of K-Team's Poky toolchain and
warnings as errors (:mod:`khepera_gym.robot.export.toolchain`), linked with the simulated libkhepera
built for ARM, and run under ``qemu-arm`` against the simulated robot (tests/fake_libkhepera/).
The ARM builds must act as the Python policy does within the host build's tolerance over whole
episodes, and the ARM calibration log must calibrate as the host's. A failing libkhepera call,
made to fail in turn by the fake library, must stop the motors, say which call failed and close
the log, on both.

Where the cross compiler or the emulator is missing, the ARM tests skip saying so (.ci/run
installs ``gcc-arm-linux-gnueabihf`` and ``qemu-user``). Self-consistent, not external: the
fake library is our reading of K-Team's headers and sources; ``-k sdk`` compiles the programs
against K-Team's own headers, where a user points ``KHEPERA_SDK`` at them.
"""

from __future__ import annotations

import math
import re
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import pytest
import robot_programs as rp
import torch
from conftest import LATEST
from stable_baselines3 import PPO
from test_calibrate import SHORT_PHASES, WALL_DISTANCE
from test_export import ACTION_TOLERANCE, frame_stacked_ppo, nav_models, scale_output_layer
from test_export_recurrent import recurrent_ppo

from khepera_gym import cli
from khepera_gym.robot import export
from khepera_gym.robot.calibrate import calibrate, read_log, replay, write_calibration_program

pytestmark = pytest.mark.usefixtures("one_torch_thread")

#: The episode the robot programs run (Nav's truncation: 400 steps of 50 ms), toward a goal the
#: untrained policies reach by chance if at all.
EPISODE_STEPS = 400
GOAL = ("1.0", "0.5")
#: The seed of the sampled actions' draws.
SAMPLE_SEED = 5
#: The sampled policy's σ (one per wheel).
SIGMA = (0.15, 0.3)


def _plain() -> tuple[Any, dict[str, Any]]:
    return nav_models()["ppo"]()[0], {}


def _frame_stack() -> tuple[Any, dict[str, Any]]:
    return frame_stacked_ppo(3), {}


def _recurrent() -> tuple[Any, dict[str, Any]]:
    return recurrent_ppo(1), {}


def _sampled() -> tuple[Any, dict[str, Any]]:
    # Untrained, unscaled: a mean within ±1 that the draws move.
    model = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    with torch.no_grad():
        model.policy.log_std.copy_(torch.log(torch.tensor(SIGMA)))
    return model, {"sample_seed": SAMPLE_SEED}


def _led() -> tuple[Any, dict[str, Any]]:
    model = PPO(
        "MlpPolicy", gym.make(LATEST["nav"], led_action=True), seed=0, device="cpu", n_steps=64
    )
    scale_output_layer(model.policy.action_net, 300.0)
    return model, {"led_action": True}


#: The policies exported: name → () -> (model, export_policy's options).
POLICIES: dict[str, Callable[[], tuple[Any, dict[str, Any]]]] = {
    "plain": _plain,
    "frame_stack": _frame_stack,
    "recurrent": _recurrent,
    "sampled": _sampled,
    "led_action": _led,
}


def sampled_reference(
    mean: npt.NDArray[np.float32], std: npt.ArrayLike, seed: int
) -> npt.NDArray[np.float32]:
    """The sampled actions by their definition (policy.h, sampling.c), written again here: each
    step, each action value in turn, the unclipped mean plus σ times a Box–Muller normal draw of
    splitmix64's 53-bit uniforms, then the clip to [-1, 1]."""
    mask = 2**64 - 1
    state = seed

    def next_bits() -> int:
        nonlocal state
        state = (state + 0x9E3779B97F4A7C15) & mask
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return z ^ (z >> 31)

    out = np.empty_like(mean)
    for step, row in enumerate(mean):
        for i, value in enumerate(row):
            u1 = ((next_bits() >> 11) + 1) * 2.0**-53
            u2 = (next_bits() >> 11) * 2.0**-53
            draw = math.sqrt(-2.0 * math.log(u1)) * math.cos(6.283185307179586 * u2)
            out[step, i] = np.float32(float(value) + float(np.float32(std[i])) * draw)
    return np.clip(out, -1.0, 1.0)


def python_actions(
    kind: str, model: Any, observations: npt.NDArray[np.float32]
) -> npt.NDArray[np.float32]:
    """What the Python policy does over one episode of ``observations`` (a fresh memory at its
    start): its deterministic actions, or for ``sampled`` the draws around its unclipped mean."""
    starts = np.zeros(len(observations), bool)
    starts[0] = True
    if kind != "sampled":
        return np.asarray(export.reference_actions(model).sequence(observations, starts))
    with torch.no_grad():
        distribution = model.policy.get_distribution(torch.as_tensor(observations))
        mean = distribution.distribution.mean.numpy().astype(np.float32)
    return sampled_reference(mean, SIGMA, SAMPLE_SEED)


@pytest.fixture(scope="module")
def exports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Any, Any]]:
    """Every policy kind exported (with its host and ARM check, when ARM can be built):
    name → (folder, model, ExportResult)."""
    done = {}
    for kind, make in POLICIES.items():
        model, options = make()
        out = tmp_path_factory.mktemp(f"export_{kind}")
        result = export.export_policy(model, out, env_id=LATEST["nav"], check_arm=True, **options)
        done[kind] = (out, model, result)
    return done


@pytest.mark.parametrize("kind", list(POLICIES))
def test_the_arm_build_acts_as_the_python_policy_over_whole_episodes(
    kind: str, exports: dict[str, tuple[Path, Any, Any]], tmp_path: Path
) -> None:
    rp.target("arm")  # skips without the robot's toolchain
    out, model, result = exports[kind]
    # export_check built for ARM, run under qemu over the export check's 10 seeded episodes in
    # order (a fresh memory at each start): the host's tolerance, and the observations built
    # from the raw readings as the simulator built them.
    checks = result.checks
    assert checks["c_max_abs_error"] < ACTION_TOLERANCE
    assert checks["c_arm_max_abs_error"] < ACTION_TOLERANCE
    assert checks["observation_arm_max_abs_error"] < export.OBSERVATION_TOLERANCE
    assert checks["observations"] > 1000

    # The robot program on the simulated robot, a whole episode, on the host and on ARM: the
    # actions it logged are the Python policy's for the observations it logged, the commands it
    # sent the wheel units of those actions, the LED levels it printed their levels (both as
    # export_check built for the same target computes them: the host's equal the simulator's,
    # tests/test_export.py).
    sources = (*export.C_SOURCES, *export.ROBOT_SOURCES)
    figures = {}
    for name in ("host", "arm"):
        chosen = rp.target(name)
        program = rp.build_on_fake(chosen, out, "khepera_policy_main.c", sources, f"policy_{name}")
        check = rp.build_check(chosen, out, f"export_check_{name}")
        log_path = tmp_path / f"{name}.csv"
        run = rp.run(chosen, program, *GOAL, str(EPISODE_STEPS), "--log", str(log_path))
        log = read_log(log_path)
        lines = run.stdout.splitlines()
        # The episode: to its truncation, or to the goal (by odometry), as the env ends one.
        reached = f"goal reached (by odometry) after {len(log)} steps"
        assert len(log) == EPISODE_STEPS or (len(log) > 100 and lines[-1] == reached)
        observations = log.extra("obs").astype(np.float32)
        logged = log.extra("action")
        figures[name] = float(np.max(np.abs(logged - python_actions(kind, model, observations))))
        steps = len(log)
        assert figures[name] < ACTION_TOLERANCE, (name, figures[name])
        if kind == "sampled":  # the draws moved the actions away from the mean
            mean = python_actions("plain", model, observations)
            assert np.std(logged - mean) > 0.1
        wheels = export.run_check_program(check, "wheels", logged[:, :2], chosen.runner)
        np.testing.assert_array_equal(log.commands, wheels)
        # It drove, and what the policy saw changed all along: the goal's distance and bearing
        # (odometry) and the wheel speeds (observation indices 13 to 17 of Nav's layout).
        assert np.ptp(log.encoders[:, 0]) > 1000 and np.ptp(log.commands) > 1000
        assert np.all(np.ptp(observations[:, 13:18], axis=0) > 0.05)
        if kind == "led_action":
            printed = np.array([line.split()[8:] for line in lines[: len(log)]], int)
            levels = export.run_check_program(check, "leds", logged[:, 2:], chosen.runner)
            np.testing.assert_array_equal(printed, levels)
            assert np.ptp(levels) > 10
    print(
        f"\nparity {kind}: export check host {checks['c_max_abs_error']:.2g}, "
        f"arm {checks['c_arm_max_abs_error']:.2g} ({checks['observations']} observations; "
        f"observation host {checks['observation_max_abs_error']:.2g}, "
        f"arm {checks['observation_arm_max_abs_error']:.2g}); "
        f"robot program ({steps} steps) host {figures['host']:.2g}, "
        f"arm {figures['arm']:.2g}"
    )


# ------------------------------------------------------------------------------------------
# A libkhepera call that fails.

#: Every libkhepera call the programs make, with what libkhepera 2.1 returns when it fails on a
#: robot (kb_khepera4.c): a failed read KB_ERROR_KH4RCVERR (55), a failed write
#: KB_ERROR_KH4SENERR (56); kh4_init KH4_ERROR_KBINIT (-1); knet_open NULL (no code).
FAILURES = {
    "kh4_init": -1,
    "knet_open": 0,
    "kh4_revision": 55,
    "kh4_SetMode": 56,
    "kh4_ResetEncoders": 56,
    "kh4_activate_us": 56,
    "kh4_SetSpeedProfile": 56,
    "kh4_get_position": 55,
    "kh4_proximity_ir": 55,
    "kh4_measure_us": 55,
    "kh4_measure_acc": 55,
    "kh4_measure_gyro": 55,
    "kh4_get_speed": 55,
    "kh4_set_speed": 56,
    "kh4_SetRGBLeds": 56,
}
#: The calls a program makes every control step: they are also made to fail in the middle of a
#: run (their third call), when the log has rows.
EVERY_STEP = {
    "kh4_get_position",
    "kh4_proximity_ir",
    "kh4_measure_us",
    "kh4_measure_acc",
    "kh4_measure_gyro",
    "kh4_get_speed",
    "kh4_set_speed",
    "kh4_SetRGBLeds",
}


def failure_cases(calls: list[str]) -> list[tuple[str, int, int]]:
    """(call, code, from which call on it fails) for each call: its own failure from its first
    call, and K-Team's +58 (no device), from its first call or, for a call of every step, its
    third."""
    cases = []
    for call in calls:
        cases.append((call, FAILURES[call], 1))
        if call != "knet_open":
            cases.append((call, 58, 3 if call in EVERY_STEP else 1))
    return cases


@pytest.fixture(scope="module")
def calibration_program(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The calibration program (test_calibrate.py's short manoeuvre), written once."""
    out = tmp_path_factory.mktemp("calibration_program")
    write_calibration_program(out, env_id=LATEST["nav"], phases=SHORT_PHASES)
    return out


@pytest.mark.parametrize("program_name", ["policy", "calibrate"])
@pytest.mark.parametrize("target_name", ["host", "arm"])
def test_a_failing_libkhepera_call_stops_the_motors_says_which_and_closes_the_log(
    program_name: str,
    target_name: str,
    exports: dict[str, tuple[Path, Any, Any]],
    calibration_program: Path,
    tmp_path: Path,
) -> None:
    chosen = rp.target(target_name)
    if program_name == "policy":  # the LED policy: it makes every call
        out = exports["led_action"][0]
        sources = (*export.C_SOURCES, *export.ROBOT_SOURCES)
        program = rp.build_on_fake(chosen, out, "khepera_policy_main.c", sources, "fail_policy")
        calls = list(FAILURES)

        def arguments(log: Path) -> list[str]:
            return [*GOAL, "20", "--log", str(log)]

    else:
        out = calibration_program
        program = rp.build_on_fake(
            chosen, out, "khepera_calibrate_main.c", export.ROBOT_SOURCES, "fail_calibrate"
        )
        calls = [call for call in FAILURES if call != "kh4_SetRGBLeds"]

        def arguments(log: Path) -> list[str]:
            return [str(WALL_DISTANCE), str(log)]

    # Every call is made: the run without failures goes through, the motors stopped at its end.
    state = tmp_path / "state.txt"
    log_path = tmp_path / "ok.csv"
    environment = {"FAKE_EXIT_STATE": str(state)}
    rp.run(chosen, program, *arguments(log_path), environment=environment, stdin="\n")
    assert state.read_text().startswith("mode 0 target 0 0 leds 0 0 0 0 0 0 0 0 0 ")
    assert len(read_log(log_path)) > 10

    for index, (call, code, first) in enumerate(failure_cases(calls)):
        case = f"{call} returning {code} from its call {first}"
        log_path = tmp_path / f"case_{index}.csv"
        environment = {"FAKE_FAIL": f"{call}:{code}:{first}", "FAKE_EXIT_STATE": str(state)}
        run = rp.run(
            chosen, program, *arguments(log_path), environment=environment, check=False, stdin="\n"
        )
        assert run.returncode == 1, (case, run.returncode, run.stderr)
        said = f"{call} returned NULL" if code == 0 else f"{call} returned {code} ("
        assert f"libkhepera: {said}" in run.stderr, (case, run.stderr)
        # The motors: idle and a zero set point, whichever of the two the failing call allows
        # (a failing kh4_set_speed also fails to stop them, a failing kh4_SetMode to idle them,
        # and the program says so); the LEDs off.
        fields = state.read_text().split()
        mode, target, leds = int(fields[1]), fields[3:5], fields[6:15]
        assert call == "kh4_SetMode" or mode == 0, (case, fields)
        assert call == "kh4_set_speed" or target == ["0", "0"], (case, fields)
        assert call == "kh4_SetRGBLeds" or leds == ["0"] * 9, (case, fields)
        if call in ("kh4_set_speed", "kh4_SetMode") and first == 1:
            assert "while stopping the motors" in run.stderr, case
        # The log: closed with its end line, the failure noted before it.
        text = log_path.read_text()
        assert text.endswith(" rows\n") and "\n# end: " in text, (case, text[-200:])
        assert f"# note: libkhepera_error: {said}" in text, case
        if first > 1:  # rows of the steps before the failure: a log khepera-gym reads
            log = read_log(log_path)
            assert 1 <= len(log) <= first and log.notes[0].key == "libkhepera_error", case


# ------------------------------------------------------------------------------------------
# The calibration program.


def test_the_arm_calibration_log_calibrates_as_the_hosts(
    calibration_program: Path, tmp_path: Path
) -> None:
    arm = rp.target("arm")
    out = calibration_program
    # The fake's wall stands where the user says it is (test_calibrate.py's fake run).
    wall = {"FAKE_WALL_X": WALL_DISTANCE + replay.BODY_RADIUS}
    logs = {}
    true_gap = None
    for name, chosen in (("host", rp.target("host")), ("arm", arm)):
        program = rp.build_on_fake(
            chosen, out, "khepera_calibrate_main.c", export.ROBOT_SOURCES, f"cal_{name}", **wall
        )
        if true_gap is None:  # the gap the user would measure, from the host's first run
            trace = tmp_path / "trace.txt"
            first = tmp_path / "first.csv"
            rp.run(
                chosen,
                program,
                str(WALL_DISTANCE),
                str(first),
                stdin="\n",
                environment={"FAKE_TRACE": str(trace)},
            )
            gap_row = [n.after for n in read_log(first).notes if n.key == "wall_gap_end_m"][-1]
            times = np.loadtxt(trace)
            at = np.argmin(np.abs(times[:, 0] - read_log(first).time[gap_row]))
            true_gap = float(times[at, 4])
        path = tmp_path / f"{name}.csv"
        rp.run(chosen, program, str(WALL_DISTANCE), str(path), stdin=f"{true_gap * 1000:.1f}\n")
        logs[name] = read_log(path)
    host, arm_log = logs["host"], logs["arm"]
    assert len(arm_log) == len(host) > 500
    for column, values in host.values.items():
        np.testing.assert_array_equal(arm_log.values[column], values, err_msg=column)
    # `khepera-gym calibrate` reads the ARM log and fits it as the host's, estimate for estimate.
    fits = {
        name: calibrate([log], {"physics.substeps": 5}, progress=False)
        for name, log in logs.items()
    }
    estimates = {name: {e.key: e for e in fit.estimates()} for name, fit in fits.items()}
    assert estimates["arm"].keys() == estimates["host"].keys() and len(estimates["arm"]) >= 6
    for key, estimate in estimates["host"].items():
        other = estimates["arm"][key]
        # The same value and uncertainty (NaN where the fit gives none: a setting, not a fit).
        np.testing.assert_equal(
            (other.value, other.sigma), (estimate.value, estimate.sigma), err_msg=key
        )
        assert other.how == estimate.how, key


# ------------------------------------------------------------------------------------------
# The generated Makefiles, for the robot.


def test_the_generated_makefiles_build_every_program_for_the_robot(
    exports: dict[str, tuple[Path, Any, Any]], calibration_program: Path, tmp_path: Path
) -> None:
    arm = rp.target("arm")
    library = rp.fake_library(arm, tmp_path / "lib")
    # As a user runs them with a libkhepera install: its headers (INCPATH), its library
    # (LIBPATH), the libraries it needs (LIBS), K-Team's flags, warnings as errors.
    options = [
        f"CROSS_CC={arm.compiler}",
        f"INCPATH={rp.FAKE}",
        f"LIBPATH={library.parent}",
        "LIBS=-lpthread",
        "ROBOT_CFLAGS=" + " ".join((*arm.flags, rp.ROBOT_STD, *rp.WARNINGS)),
        "ROBOT_LDFLAGS=" + " ".join(arm.link_flags),
    ]
    built = []
    for out, _, _ in exports.values():
        make = subprocess.run(
            ["make", "-C", str(out), "check", "robot", "robot-check", *options],
            capture_output=True,
            text=True,
            check=True,
        )
        assert "-lkhepera -lpthread -lm" in make.stdout
        built += [out / "khepera_policy", out / "export_check_robot"]
    subprocess.run(["make", "-C", str(calibration_program), "robot", *options], check=True)
    built.append(calibration_program / "khepera_calibrate")
    readelf = rp.archiver(arm)[: -len("ar")] + "readelf"
    for binary in built:
        # 32-bit ARM, EABI 5, the hard-float ABI; ARMv7 with NEON.
        elf_class, machine, flags = rp.elf_machine(binary)
        assert (elf_class, machine, flags >> 24) == (1, 40, 5), binary
        assert flags & 0x400, f"{binary} is not built for the hard-float ABI"
        attributes = subprocess.run(
            [readelf, "-A", str(binary)], capture_output=True, text=True, check=True
        ).stdout
        assert "Tag_CPU_arch: v7" in attributes and "NEONv1" in attributes, binary

    # They run: the policy program with its own clock, two steps against the fake robot (which
    # stands still), and export_check_robot as the host's export_check.
    out = exports["plain"][0]
    run = rp.run(arm, out / "khepera_policy", *GOAL, "2")
    assert len(run.stdout.splitlines()) == 2
    observation = gym.make(LATEST["nav"]).reset(seed=0)[0]
    on_arm = export.run_check_program(
        out / "export_check_robot", "policy", [observation], arm.runner
    )
    on_host = export.run_check_program(out / "export_check", "policy", [observation])
    np.testing.assert_array_equal(on_arm, on_host)


def test_the_export_command_checks_on_arm_or_says_why_not(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "model.zip"
    PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64).save(path)
    base = ["export", str(path), "--env", LATEST["nav"], "--check-arm"]
    if rp.TARGETS["arm"].missing() is None:
        assert cli.main([*base, "--out", str(tmp_path / "arm")]) == 0
        printed = capsys.readouterr().out
        figures = re.findall(r"c (?:arm )?max abs error: (\S+)", printed)
        assert len(figures) == 2 and all(float(f) < ACTION_TOLERANCE for f in figures), printed
        assert "observation arm max abs error: 0\n" in printed
    # Without the cross compiler: the host's figures, and why the ARM check was skipped.
    monkeypatch.setattr(export.exporter, "arm_target", lambda: export.arm_target("no-such-gcc"))
    assert cli.main([*base, "--out", str(tmp_path / "none")]) == 0
    printed = capsys.readouterr().out
    assert "c max abs error" in printed and "c arm max abs error" not in printed
    assert (
        "C check on ARM skipped: no C compiler 'no-such-gcc' on PATH (Debian: apt-get install "
        "gcc-arm-linux-gnueabihf qemu-user)" in printed
    )
