"""``khepera-gym export``: the command line of
:func:`~khepera_gym.robot.export.exporter.export_policy`.

Examples::

    khepera-gym export runs/ppo_nav/model.zip                 # C, beside the model in export/
    khepera-gym export runs/ppo_nav/model.zip --format c onnx --out robot/
    khepera-gym export checkpoint_dir --env KheperaIV-Nav --set ir_floor_value=110
    khepera-gym export runs/ppo_nav/model.zip --check-arm     # the check on the robot's ARM too

It prints the files written, the scenario constants given as ranges (their midpoint is baked
in) and the check figures. Threading: the calling thread.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from khepera_gym.config import parse_key_values
from khepera_gym.errors import ConfigError
from khepera_gym.robot.export.exporter import FORMATS, export_policy
from khepera_gym.robot.export.motors import DRIVE_CHOICES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym export``."""
    parser.add_argument(
        "model",
        help="an SB3 model.zip (vecnormalize.pkl and run.json beside it are used) or an "
        "RLlib checkpoint directory",
    )
    parser.add_argument(
        "--format",
        nargs="+",
        choices=FORMATS,
        default=["c"],
        help="c (policy.c, observation.c, a libkhepera program template) and/or onnx (c)",
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (export/ beside the model)"
    )
    parser.add_argument("--env", default=None, help="env id trained on (from run.json if absent)")
    parser.add_argument("--config", default=None, help="scenario trained on (name or TOML path)")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario override as in training (VALUE in TOML syntax), e.g. ir_floor_value=110",
    )
    parser.add_argument(
        "--action-type", choices=("wheels", "unicycle"), default=None, help="as in training"
    )
    parser.add_argument(
        "--no-check",
        action="store_true",
        help="skip measuring the exported files against the Python policy",
    )
    parser.add_argument("--cc", default="cc", help="C compiler of the check (cc)")
    parser.add_argument(
        "--check-arm",
        action="store_true",
        help="also build the check for the robot's ARM processor (arm-linux-gnueabihf-gcc with "
        "K-Team's flags) and run it under qemu-arm",
    )
    parser.add_argument(
        "--drive",
        choices=DRIVE_CHOICES,
        default="trained",
        help="the motor controller's setting: the trained drive exactly (default; an error when "
        "the robot cannot be set to it), or its nominal firmware setting",
    )
    parser.add_argument(
        "--sample-actions",
        action="store_true",
        help="the program samples its actions from the policy's Gaussian, as in training, "
        "instead of acting on its mean (PPO, A2C)",
    )
    parser.add_argument(
        "--sample-seed",
        type=int,
        default=None,
        help="seed of the sampled actions' draws (0; with --sample-actions)",
    )


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym export`` with parsed arguments."""
    model = Path(args.model)
    out = args.out if args.out is not None else model.resolve().parent / "export"
    overrides = parse_key_values(args.set, "--set")
    if args.sample_seed is not None and not args.sample_actions:
        raise ConfigError("--sample-seed sets the draws of --sample-actions: give both")
    sample_seed = (args.sample_seed or 0) if args.sample_actions else None
    result = export_policy(
        model,
        out,
        formats=args.format,
        env_id=args.env,
        config=args.config,
        action_type=args.action_type,
        check=not args.no_check,
        compiler=args.cc,
        check_arm=args.check_arm,
        drive=args.drive,
        sample_seed=sample_seed,
        **overrides,
    )
    agent = f" (one agent's block, as {result.robot.agent})" if result.robot.agent else ""
    print(
        f"exported the {result.network.source} policy for {result.robot.env_id}{agent} "
        f"to {result.out_dir}:"
    )
    for path in result.files:
        print(f"  {path.name}")
    if result.network.frame_stack > 1:
        print(
            f"memory: the policy acts on its last {result.network.frame_stack} observations; "
            "the program keeps them in a policy_state, emptied at its start"
        )
    if result.network.recurrent:
        print(
            f"memory: the policy's {len(result.network.lstm)} LSTM layer(s) carry a hidden and a "
            f"cell state of {result.network.lstm_hidden_size} values from step to step; the "
            "program keeps them in a policy_state, zeroed at its start (ONNX: the inputs "
            "lstm_hidden and lstm_cell, zeros at an episode's start, fed the outputs "
            "next_lstm_hidden and next_lstm_cell)"
        )
    std = result.network.action_std
    if args.sample_actions and std is not None:
        sigma = ", ".join(f"{value:.3g}" for value in std)
        print(f"actions: sampled from the policy's Gaussian (sigma {sigma}), seed {sample_seed}")
    elif "c" in args.format:
        print("actions: the policy's mean (its deterministic action)")
    exact = "" if result.motors.exact else " (nominal: not the trained drive exactly)"
    print(f"motors: {result.motors.note}{exact}; the program calls {result.motors.call()}")
    for key, bounds in result.robot.randomised.items():
        print(f"note: {key} is a range {list(bounds)} in the scenario; the midpoint is baked in")
    checks = result.checks
    if "observations" in checks:
        print(f"checked on {checks['observations']} observations of seeded rollouts:")
    for key in (
        "onnx_max_abs_error",
        "c_max_abs_error",
        "observation_max_abs_error",
        "c_arm_max_abs_error",
        "observation_arm_max_abs_error",
    ):
        if key in checks:
            print(f"  {key.replace('_', ' ')}: {checks[key]:.3g}")
    for key, what in (("c_skipped", "C check"), ("c_arm_skipped", "C check on ARM")):
        if key in checks:
            print(f"  {what} skipped: {checks[key]}")
    return 0


__all__ = ["add_arguments", "run_from_args"]
