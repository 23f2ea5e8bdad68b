"""The ``khepera-gym render`` command: one seeded episode of a policy recorded to a GIF or MP4.

Frames are drawn in software by the Rust core (no display); the episode is run by the shared
loop :func:`khepera_gym.rollout.run_episodes` on a one-world native vector env.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym

from khepera_gym.compare import make_policy
from khepera_gym.render import DEFAULT_FRAME_SIZE, save_video
from khepera_gym.rollout import run_episodes


def record_video(
    env_id: str,
    policy: str,
    out: str | Path,
    seed: int = 0,
    config: str | None = None,
    max_steps: int | None = None,
    frame_size: Sequence[int] = DEFAULT_FRAME_SIZE,
    fps: int = 20,
    algo: str | None = None,
) -> tuple[Path, int]:
    """Records one seeded episode of ``policy`` (a baseline name or ``sb3:model.zip``, as for
    ``khepera-gym compare``) on ``env_id`` to a GIF or MP4; returns the path and frame count.

    The episode runs until it terminates or truncates, or for ``max_steps`` steps.
    """
    envs = gym.make_vec(
        env_id,
        num_envs=1,
        num_threads=1,
        render_mode="rgb_array",
        frame_size=frame_size,
        config=config,
        render_worlds=1,
    )
    act = make_policy(policy, envs, seed=seed, algo=algo)
    frames = []

    def on_step(_step: int, _obs: Any, _rewards: Any, ended: Any, _done: Any) -> None:
        if not ended[0]:  # the frame after the last step would show the next episode's start
            frames.append(envs.render())

    run_episodes(
        envs.unwrapped._batch,
        act,
        seed,
        on_reset=lambda _obs: frames.append(envs.render()),
        on_step=on_step,
        max_steps=max_steps,
    )
    envs.close()
    return save_video(frames, out, fps=fps), len(frames)


def add_arguments(parser: Any) -> None:
    """The options of ``khepera-gym render``."""
    parser.add_argument("--env", default="KheperaIV-Nav-v1", help="environment id")
    parser.add_argument(
        "--policy", default="position_control", help="baseline name or sb3:path/to/model.zip"
    )
    parser.add_argument("--algo", default=None, help="SB3 algorithm of an sb3: model")
    parser.add_argument("--config", default=None, help="built-in scenario name or TOML path")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (0)")
    parser.add_argument("--steps", type=int, default=None, help="stop after this many steps")
    parser.add_argument(
        "--size",
        type=int,
        nargs=2,
        default=list(DEFAULT_FRAME_SIZE),
        metavar=("WIDTH", "HEIGHT"),
        help="frame size in pixels (480 480)",
    )
    parser.add_argument("--fps", type=int, default=20, help="frames per second (20)")
    parser.add_argument("--out", default="run.gif", help="output file, .gif or .mp4 (run.gif)")


def run_from_args(args: Any) -> int:
    """Runs ``khepera-gym render`` with parsed arguments."""
    path, count = record_video(
        args.env,
        args.policy,
        args.out,
        seed=args.seed,
        config=args.config,
        max_steps=args.steps,
        frame_size=args.size,
        fps=args.fps,
        algo=args.algo,
    )
    print(f"wrote {count} frames of {args.env} ({args.policy}, seed {args.seed}) to {path}")
    return 0


__all__ = ["add_arguments", "record_video", "run_from_args"]
