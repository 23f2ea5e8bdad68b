"""The whole export of a trained policy: :func:`export_policy`.

It loads the model (:mod:`~khepera_gym.robot.export.describe`), finds the env it was trained on
(``run.json`` of ``khepera-gym train`` beside an SB3 zip, the RLlib checkpoint's config, or the
caller's id, resolved with :func:`khepera_gym.registration.resolve_env_id`), makes that env with
the scenario of training, reads the robot side from it (:mod:`~khepera_gym.robot.export.robot`),
writes the requested formats (:mod:`~khepera_gym.robot.export.onnx_writer`,
:mod:`~khepera_gym.robot.export.c_writer`) with the observation layout, the resolved scenario and a
manifest, and checks the files against the Python policy (:mod:`~khepera_gym.robot.export.checks`).

Threading: everything runs in the calling thread (the env's batch releases the GIL while
stepping).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym

import khepera_gym
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.registration import resolve_env_id
from khepera_gym.robot.export.c_policy import check_sampling
from khepera_gym.robot.export.c_writer import write_c
from khepera_gym.robot.export.checks import check_export
from khepera_gym.robot.export.describe import (
    as_policy,
    describe_policy,
    load_model,
    reference_actions,
)
from khepera_gym.robot.export.from_rllib import RllibPolicy
from khepera_gym.robot.export.motors import MotorSetting, motor_setting
from khepera_gym.robot.export.network import PolicyNetwork
from khepera_gym.robot.export.onnx_writer import ONNX_FILE, build_onnx, import_onnx
from khepera_gym.robot.export.robot import RobotInterface, robot_interface, toml_loads
from khepera_gym.robot.export.toolchain import arm_target

#: Output formats of :func:`export_policy`.
FORMATS = ("c", "onnx")
#: Files written next to the exported code.
LAYOUT_FILE = "obs_layout.json"
SCENARIO_FILE = "scenario.toml"
MANIFEST_FILE = "export.json"


@dataclasses.dataclass
class ExportResult:
    """What :func:`export_policy` wrote and measured."""

    out_dir: Path
    files: list[Path]
    network: PolicyNetwork
    robot: RobotInterface
    #: What the exported program sets on the motor controller (the trained drive).
    motors: MotorSetting
    #: Check figures: "onnx_max_abs_error", "c_max_abs_error", "observation_max_abs_error",
    #: "observations" (rows checked), or a "<name>_skipped" reason.
    checks: dict[str, Any]


def _env_of(model_path: Path | None, model: Any, env_id: str | None) -> tuple[str, dict[str, Any]]:
    """The env id and scenario overrides a model was trained with (``run.json`` of
    ``khepera-gym train``, or the RLlib config), unless ``env_id`` is given.

    Raises:
        ConfigError: Nothing says which env, or the id is not one of khepera_gym's.
    """
    overrides: dict[str, Any] = {}
    if model_path is not None:
        run_file = model_path.parent / "run.json"
        if run_file.is_file():
            run = json.loads(run_file.read_text(encoding="utf-8"))
            overrides = dict(run.get("hyperparams", {}).get("env_kwargs", {}))
            env_id = env_id or run.get("env_id")
    if env_id is None and isinstance(model, RllibPolicy) and model.env_id is not None:
        env_id = model.env_id
        overrides = dict(model.env_config)
    if env_id is None:
        raise ConfigError(
            "cannot tell which env the policy was trained on (no run.json next to the model): "
            "pass env_id (--env), and the scenario (--config) if it was not the default"
        )
    return resolve_env_id(env_id), overrides


def _write_json(path: Path, value: Any) -> Path:
    path.write_text(json.dumps(value, indent=2) + "\n", encoding="utf-8")
    return path


def export_policy(
    model: Any,
    out_dir: str | Path,
    *,
    formats: Sequence[str] = ("c",),
    env_id: str | None = None,
    config: str | Path | None = None,
    action_type: str | None = None,
    normalizer: Any = None,
    check: bool = True,
    compiler: str = "cc",
    check_arm: bool = False,
    drive: str = "trained",
    sample_seed: int | None = None,
    **overrides: Any,
) -> ExportResult:
    """Exports a policy with its observation pipeline for the real robot.

    Writes into ``out_dir``: ``policy.onnx`` (format "onnx"), the C sources, Makefile and README
    (format "c", see :func:`~khepera_gym.robot.export.c_writer.write_c`), ``obs_layout.json`` (the
    policy's observation blocks: name → [start, stop)), ``scenario.toml`` (the resolved
    scenario) and ``export.json`` (what was exported, the constants used and the check figures).

    Args:
        model: What :func:`~khepera_gym.robot.export.describe.describe_policy` takes (an SB3 model
        or
            zip, :func:`khepera_gym.learning.sb3.load_policy`'s result, an RLlib checkpoint...).
        out_dir: Output folder (created).
        formats: Any of "c" and "onnx".
        env_id: The env the policy was trained on; read from ``run.json`` next to an SB3 zip
            (``khepera-gym train``) or from the RLlib checkpoint when None.
        config: Its scenario (built-in name or TOML path), None for the env's default.
        action_type: "wheels" or "unicycle" as in training (None: the env's default).
        normalizer: The SB3 ``VecNormalize`` used in training, if not next to a zip.
        check: Measure the exported files against the Python policy on recorded observations
            (ONNX with onnxruntime; C compiled with ``compiler``, skipped if there is none).
        compiler: The C compiler of the check.
        check_arm: Also build the check for the robot's processor (ARMv7-A, hard float, NEON:
            K-Team's flags, :func:`~khepera_gym.robot.export.toolchain.arm_target`) and run it
            under ``qemu-arm`` (skipped, with the reason in the figures, when the cross
            compiler or the emulator is missing).
        drive: "trained": the program sets the motor controller exactly as the scenario's
            ``[motors]`` drove the simulated robot (an error if the robot cannot be set so:
            v0's and v1's ramp, or a randomised profile); "nominal": its nearest firmware
            setting (:func:`~khepera_gym.robot.export.motors.motor_setting`).
        sample_seed: None: the program acts on the policy's mean (its deterministic action);
            an int in [0, 2^64): it samples its actions from the policy's Gaussian as in
            training, its generator seeded with it (PPO and A2C only; the C format; ONNX
            gives the mean either way).
        **overrides: Scenario keys as in training (``max_steps=200``, ``observe=["ir"]``).

    Raises:
        ConfigError: Unsupported model or format, or an env that does not fit the policy.
        ImportError: A needed extra is missing (the message names the pip command).
        KheperaError: A check failed (an exported action differs by more than
            :data:`~khepera_gym.robot.export.checks.PARITY_TOLERANCE`); the files and the manifest
            with the figures are written first.
    """
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise ConfigError(f"unknown export formats {unknown or list(formats)}; known: {FORMATS}")
    if "onnx" in formats:
        import_onnx()
    model_path = Path(model) if isinstance(model, (str, Path)) else None
    if model_path is not None:
        model, loaded_normalizer = load_model(model_path)
        normalizer = normalizer if normalizer is not None else loaded_normalizer
    model = as_policy(model)
    network = describe_policy(model, normalizer)
    if sample_seed is not None:  # before anything is written
        if "c" not in formats:
            raise ConfigError("sampled actions are a feature of the C program: export format 'c'")
        check_sampling(network, sample_seed)
    env_id, trained_overrides = _env_of(model_path, model, env_id)
    env_kwargs: dict[str, Any] = {**trained_overrides, **overrides}
    if config is not None:
        env_kwargs["config"] = str(config)
    if action_type is not None:
        env_kwargs["action_type"] = action_type
    env = gym.make(env_id, **env_kwargs)
    try:
        robot = robot_interface(env, network.obs_dim, env_id)
        motors = motor_setting(toml_loads(robot.scenario_toml), drive)
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        provenance = str(model_path) if model_path is not None else f"a {network.source} model"
        layout = {name: [start, stop] for name, start, stop in robot.layout}
        files = [_write_json(out / LAYOUT_FILE, layout), out / SCENARIO_FILE]
        (out / SCENARIO_FILE).write_text(robot.scenario_toml, encoding="utf-8")
        if "onnx" in formats:
            metadata = {
                "source": network.source,
                "env_id": env_id,
                "obs_layout": json.dumps(layout),
                "frame_stack": str(network.frame_stack),
                "khepera_gym_version": khepera_gym.__version__,
            }
            (out / ONNX_FILE).write_bytes(build_onnx(network, metadata).SerializeToString())
            files.append(out / ONNX_FILE)
        if "c" in formats:
            files += write_c(network, robot, motors, out, provenance, sample_seed)
        checks: dict[str, Any] = {}
        failures: list[str] = []
        if check:
            reference = reference_actions(model, normalizer)
            cross = (arm_target(),) if check_arm else ()
            checks, failures = check_export(
                reference, network, env, robot, out, formats, compiler, cross
            )
        manifest = {
            "khepera_gym_version": khepera_gym.__version__,
            "model": provenance,
            "source": network.source,
            "env_id": env_id,
            "env_kwargs": {k: str(v) for k, v in env_kwargs.items()},
            "agent": robot.agent,
            "obs_dim": network.obs_dim,
            "frame_stack": network.frame_stack,
            "lstm": {"layers": len(network.lstm), "hidden_size": network.lstm_hidden_size},
            "action_dim": network.action_dim,
            "action_type": robot.action_type,
            "layers": [
                {"inputs": x.inputs, "outputs": x.outputs, "activation": x.activation}
                for x in network.layers
            ],
            "vecnormalize": network.normalization is not None,
            "randomised_constants_at_midpoint": {k: list(v) for k, v in robot.randomised.items()},
            "motors": motors.as_dict(),
            "actions": {
                "sampled": sample_seed is not None,
                "seed": sample_seed,
                "std": None if network.action_std is None else network.action_std.tolist(),
            },
            "formats": list(formats),
            "checks": checks,
        }
        files.append(_write_json(out / MANIFEST_FILE, manifest))
    finally:
        env.close()
    if failures:
        raise KheperaError(
            f"{out}: the exported {', '.join(failures)} differ from the Python policy and the "
            f"simulator by more than the tolerance: {checks}"
        )
    return ExportResult(out, files, network, robot, motors, checks)


__all__ = [
    "FORMATS",
    "LAYOUT_FILE",
    "MANIFEST_FILE",
    "SCENARIO_FILE",
    "ExportResult",
    "export_policy",
]
