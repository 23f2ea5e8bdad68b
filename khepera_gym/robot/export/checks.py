"""The checks of an export: the exported files against the Python policy and the simulator, on
observations recorded from seeded env rollouts.

:func:`record_rollouts` plays seeded episodes with :func:`khepera_gym.rollout.run_episodes` (the
one episode loop of the package) on the env's batch, driven by the policy with a share of
seeded random actions, and records at every step the policy's observation and what the real
robot would have measured then (its raw readings, pose and goal: a row of the C
``observation_inputs``). :func:`check_export` compares, on those rows, the ONNX file's actions
(onnxruntime) and the C code's actions and observations (``export_check`` compiled with the
system C compiler, and on request for the robot's ARM processor and run under emulation:
:mod:`~khepera_gym.robot.export.toolchain`) with the reference, against :data:`PARITY_TOLERANCE` and
:data:`OBSERVATION_TOLERANCE`.

Threading: the batch steps its worlds with the GIL released; the compiler and ``export_check``
run as child processes, one at a time.
"""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym.errors import KheperaError
from khepera_gym.robot.export.c_writer import C_SOURCES
from khepera_gym.robot.export.network import PolicyNetwork
from khepera_gym.robot.export.onnx_writer import ONNX_FILE, onnx_sequence_actions
from khepera_gym.robot.export.robot import RobotInterface
from khepera_gym.robot.export.toolchain import Target, host_target
from khepera_gym.rollout import run_episodes

#: Largest absolute difference between an exported policy's action and the Python policy's that
#: the checks accept.
PARITY_TOLERANCE = 1e-5
#: Largest difference between the C observation and the simulator's (float32 rounding of the
#: goal bearing's sine and cosine; the sensor blocks match exactly).
OBSERVATION_TOLERANCE = 1e-6
#: Flags of the native build of ``export_check`` in the export's check (the tests add -Wextra
#: -Werror: the code is warning-free C99 with gcc).
C_FLAGS = ("-O2", "-std=c99", "-Wall")


def compile_check_program(
    out_dir: str | Path,
    compiler: str = "cc",
    flags: Sequence[str] = C_FLAGS,
    link_flags: Sequence[str] = (),
) -> Path:
    """Compiles ``export_check`` from the exported sources with the system C compiler (or
    another: a cross compiler with its ``flags`` and ``link_flags``).

    Raises:
        KheperaError: The compiler is missing or the sources do not compile (its output).
    """
    out = Path(out_dir)
    binary = out / "export_check"
    command = [
        compiler,
        *flags,
        "-o",
        str(binary),
        *(str(out / name) for name in ("export_check.c", *C_SOURCES)),
        *link_flags,
        "-lm",
    ]
    try:
        result = subprocess.run(command, capture_output=True, text=True, check=False)
    except FileNotFoundError as error:
        raise KheperaError(f"no C compiler {compiler!r} on PATH") from error
    if result.returncode != 0:
        raise KheperaError(f"{' '.join(command)} failed:\n{result.stderr}")
    return binary


def run_check_program(
    binary: str | Path, mode: str, rows: npt.ArrayLike, runner: Sequence[str] = ()
) -> npt.NDArray[Any]:
    """Feeds rows to ``export_check MODE`` (run by ``runner``, e.g. an emulator, if given) and
    parses its output rows: float32 (the C values exactly) for "policy", "sequence" and
    "observation", integers for "wheels".

    Raises:
        KheperaError: The program failed or printed something else than rows of numbers.
    """
    values = np.atleast_2d(np.asarray(rows, np.float64))
    text = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in values) + "\n"
    result = subprocess.run(
        [*runner, str(binary), mode], input=text, capture_output=True, text=True, check=False
    )
    if result.returncode != 0:
        raise KheperaError(f"{binary} {mode} exited with {result.returncode}: {result.stderr}")
    try:
        parsed = np.array([[float(v) for v in line.split()] for line in result.stdout.splitlines()])
    except ValueError as error:
        raise KheperaError(f"{binary} {mode} printed {result.stdout[:200]!r}") from error
    return parsed.astype(np.int64 if mode == "wheels" else np.float32)


@dataclasses.dataclass
class Recording:
    """Observations of seeded rollouts with what the robot would have measured at each step."""

    #: Policy observations (N, obs_dim), float32, in the order of the steps.
    observations: npt.NDArray[np.float32]
    #: Rows of ``observation_inputs`` (N, OBSERVATION_INPUT_COUNT) for ``export_check``.
    input_rows: npt.NDArray[np.float64]
    #: (N,) True at each episode's first observation (where a policy's memory starts empty).
    starts: npt.NDArray[np.bool_]


def input_row(
    robot: RobotInterface,
    readings: Mapping[str, npt.NDArray[Any]],
    pose: npt.ArrayLike,
    goal: npt.ArrayLike,
    observation: npt.NDArray[np.float32],
) -> list[float]:
    """One robot's ``observation_inputs`` as a row, in the order of the C struct's fields: the
    raw readings of the blocks the observation has, pose and goal (when it has goal blocks), and
    the blocks the robot cannot measure (taken from ``observation``, the policy's own block).

    Args:
        robot: The export's robot side.
        readings: ``sensor_readings()`` of a face of one world (a robot axis first).
        pose: That robot's ground-truth pose (x, y, θ).
        goal: Its goal (x, y).
        observation: Its observation block.
    """
    index = robot.robot_index
    row: list[float] = []
    for block, channel in (("ir", "ir_raw"), ("us", "us_cm"), ("wheel_speeds", "wheel_speeds")):
        if robot.observes(block):
            row += [float(v) for v in readings[channel][index]]
    if robot.has_goal:
        row += [float(v) for v in np.asarray(pose)[:3]]
        row += [float(v) for v in np.asarray(goal)[:2]]
    for _, start, stop in robot.extra_blocks:
        row += [float(v) for v in observation[start:stop]]
    return row


def record_rollouts(
    env: gym.Env[Any, Any],
    robot: RobotInterface,
    act: Callable[[npt.NDArray[np.float32]], npt.ArrayLike],
    seeds: Sequence[int] = tuple(range(10)),
    steps: int = 150,
    random_fraction: float = 0.3,
) -> Recording:
    """Observations and raw inputs of seeded episodes of ``env`` driven by ``act``.

    Each episode runs through :func:`khepera_gym.rollout.run_episodes` on the env's batch, for
    at most ``steps`` steps; its first observation and those after every step (the last one
    included) are recorded with the robot's raw readings at that moment.

    Args:
        env: A single env (one world) of khepera_gym, as :func:`robot_interface` read it.
        robot: The export's robot side (which agent's block, which inputs).
        act: Maps the policy's observations (M, obs_dim) to actions (M, 2), or (M, 5) for a
            policy that also sets the LEDs (``robot.led_action``). In a multi-robot
            env it drives every agent whose block has the policy's width (a shared policy);
            other agents stand still. It sees every observation, in order (even where a random
            action replaces its own), and its ``reset()``, if it has one, is called before each
            episode: a policy with memory is driven as in training.
        seeds: One episode per seed.
        steps: Largest number of steps of an episode.
        random_fraction: The share of steps, drawn from a generator seeded with ``seeds[0]``,
            whose actions are uniform in [-1, 1] instead, so the rollouts visit more states.
    """
    unwrapped = env.unwrapped
    batch = unwrapped._batch
    width = robot.obs_dim
    # (block start, first action column) of every agent the policy drives: agent i's action is
    # joint columns k i to k i + k - 1, k its action's width (its wheels, then its LEDs').
    per_agent = 5 if robot.led_action else 2
    driven = [
        (int(start), per_agent * i)
        for i, (_, _, start, stop, _) in enumerate(batch.agents())
        if stop - start == width
    ]
    rng = np.random.default_rng(seeds[0] if seeds else 0)
    observations: list[npt.NDArray[np.float32]] = []
    rows: list[list[float]] = []
    starts: list[bool] = []
    reset = getattr(act, "reset", None)

    def start(joint: npt.NDArray[np.float32]) -> None:
        if callable(reset):
            reset()
        starts.append(True)
        record(joint)

    def record(joint: npt.NDArray[np.float32]) -> None:
        own = np.array(joint[0, robot.offset : robot.offset + width], np.float32)
        goals = unwrapped.goals()
        goal = goals[min(robot.robot_index, len(goals) - 1)] if len(goals) else np.zeros(2)
        pose = unwrapped.poses()[robot.robot_index]
        observations.append(own)
        rows.append(input_row(robot, unwrapped.sensor_readings(), pose, goal, own))

    def policy(joint: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        blocks = np.stack([joint[0, start : start + width] for start, _ in driven])
        agent_actions = np.asarray(act(blocks), np.float32).reshape(len(driven), per_agent)
        if rng.random() < random_fraction:
            return rng.uniform(-1.0, 1.0, (1, batch.act_dim)).astype(np.float32)
        actions = np.zeros((1, batch.act_dim), np.float32)
        for (_, column), action in zip(driven, agent_actions, strict=True):
            actions[0, column : column + per_agent] = action
        return actions

    def on_step(
        _step: int,
        joint: npt.NDArray[np.float32],
        _rewards: npt.NDArray[np.float32],
        _ended: npt.NDArray[np.bool_],
        done: npt.NDArray[np.bool_],
    ) -> None:
        if not done[0]:  # the episode's last observation is recorded, nothing after it
            starts.append(False)
            record(joint)

    for seed in seeds:
        run_episodes(batch, policy, seed, on_reset=start, on_step=on_step, max_steps=steps)
    return Recording(
        np.array(observations, np.float32), np.array(rows, np.float64), np.array(starts, bool)
    )


def _c_figures(
    target: Target, out: Path, recording: Recording, expected: npt.NDArray[np.float64]
) -> dict[str, float]:
    """The C actions' and observations' largest differences from ``expected`` and from the
    simulator, with ``export_check`` built and run on ``target``."""
    with tempfile.TemporaryDirectory() as build:
        for name in ("export_check.c", *C_SOURCES):
            shutil.copy(out / name, build)
        for name in out.glob("*.h"):
            shutil.copy(name, build)
        flags = (*target.flags, *C_FLAGS)
        binary = compile_check_program(build, target.compiler, flags, target.link_flags)
        rows = np.column_stack([recording.starts.astype(np.float64), recording.observations])
        got = run_check_program(binary, "sequence", rows, target.runner)
        built = run_check_program(binary, "observation", recording.input_rows, target.runner)
    return {
        "c_max_abs_error": float(np.max(np.abs(got - expected))),
        "observation_max_abs_error": float(np.max(np.abs(built - recording.observations))),
    }


def check_export(
    reference: Callable[[npt.NDArray[np.float32]], npt.ArrayLike],
    network: PolicyNetwork,
    env: gym.Env[Any, Any],
    robot: RobotInterface,
    out: Path,
    formats: Sequence[str],
    compiler: str,
    cross: Sequence[Target] = (),
) -> tuple[dict[str, Any], list[str]]:
    """Measures the exported files in ``out`` against ``reference`` (the Python policy's
    deterministic actions: a :class:`~khepera_gym.robot.export.describe.ReferencePolicy`, or any
    function of observations for a policy without memory) on recorded rollouts of ``env``:
    whole episodes, so that a policy with memory (a frame stack, an LSTM) is checked as it runs.

    The C policy runs ``policy_step`` over the recorded episodes in order, starting a fresh
    ``policy_state`` at each episode's start; the ONNX graph gets each step's frame stack, and
    a recurrent one its state, fed back step by step and zeroed at each episode's start
    (:func:`~khepera_gym.robot.export.onnx_writer.onnx_sequence_actions`). The C is built with
    ``compiler`` and run here, then for each target of ``cross`` (the robot's ARM:
    :func:`~khepera_gym.robot.export.toolchain.arm_target`) built and run there.

    Returns:
        (figures, failures): "observations" (rows checked), "onnx_max_abs_error",
        "c_max_abs_error", "observation_max_abs_error" or "c_skipped" (no compiler), and the
        same C figures of each cross target with its name ("c_arm_max_abs_error",
        "observation_arm_max_abs_error" or "c_arm_skipped"); and what exceeds its tolerance
        ("C actions", "C actions on arm", ...).

    Raises:
        KheperaError: The C code does not compile or ``export_check`` fails.
    """
    recording = record_rollouts(env, robot, reference)
    starts = recording.starts
    sequence = getattr(reference, "sequence", None)
    if callable(sequence):
        expected = np.asarray(sequence(recording.observations, starts), np.float64)
    else:
        expected = np.asarray(reference(recording.observations), np.float64)
    checks: dict[str, Any] = {"observations": len(recording.observations)}
    failures = []
    if "onnx" in formats:
        got = onnx_sequence_actions(out / ONNX_FILE, network, recording.observations, starts)
        checks["onnx_max_abs_error"] = float(np.max(np.abs(got - expected)))
        if checks["onnx_max_abs_error"] > PARITY_TOLERANCE:
            failures.append("ONNX actions")
    if "c" in formats:
        for target in (host_target(compiler, ()), *cross):
            host = target.name == "host"
            infix, where = ("", "") if host else (f"_{target.name}", f" on {target.name}")
            reason = target.missing()
            if reason is not None:
                checks[f"c{infix}_skipped"] = reason
                continue
            figures = _c_figures(target, out, recording, expected)
            actions, observations = figures["c_max_abs_error"], figures["observation_max_abs_error"]
            checks[f"c{infix}_max_abs_error"] = actions
            checks[f"observation{infix}_max_abs_error"] = observations
            if actions > PARITY_TOLERANCE:
                failures.append(f"C actions{where}")
            if observations > OBSERVATION_TOLERANCE:
                failures.append(f"C observations{where}")
    return checks, failures


__all__ = [
    "C_FLAGS",
    "OBSERVATION_TOLERANCE",
    "PARITY_TOLERANCE",
    "Recording",
    "check_export",
    "compile_check_program",
    "input_row",
    "record_rollouts",
    "run_check_program",
]
