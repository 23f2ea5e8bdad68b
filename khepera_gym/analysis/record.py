"""The ``khepera-gym render`` command: one seeded episode of a policy recorded to a GIF or MP4.

Frames are drawn in software by the Rust core (no display); the episode is run by the shared
loop :func:`khepera_gym.rollout.run_episodes` on a one-world native vector env. A PettingZoo
module (``multinav_v3``) or a task without a Gymnasium env (``multinav``, ``platoon``,
``consensus``) is recorded on one world of the core's batch, every agent acting with the policy
on its own observation (:func:`khepera_gym.learning.policies.make_agents_policy`). Every
argument (the env, the policy, the output's format and folder, the frame's size and view) is
checked before the first step, and a progress bar counts the steps.
"""

from __future__ import annotations

import argparse
import difflib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
from tqdm import tqdm

from khepera_gym.analysis.compare import make_policy
from khepera_gym.config import make_batch
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import make_agents_policy
from khepera_gym.pettingzoo import modules
from khepera_gym.registration import registered_ids, resolve_env_id, task_and_version
from khepera_gym.render import (
    VIDEO_SUFFIXES,
    Renderer,
    check_frame_size,
    check_video,
    check_view,
    save_video,
)
from khepera_gym.rollout import run_episodes
from khepera_gym.tooling import arguments

#: The env ``khepera-gym render`` records without ``--env`` (its latest version).
DEFAULT_ENV = "KheperaIV-Nav"


def record_video(
    env_id: str,
    policy: str,
    out: str | Path,
    seed: int = 0,
    config: str | None = None,
    max_steps: int | None = None,
    frame_size: Sequence[int] | None = None,
    fps: int = 20,
    algo: str | None = None,
    *,
    zoom: float = 1.0,
    center: Sequence[float] | None = None,
    progress: bool = False,
) -> tuple[Path, int]:
    """Records one seeded episode of ``policy`` (a baseline name, ``sb3:model.zip`` or a function
    of one's own as ``module:function``, as for ``khepera-gym compare``) on ``env_id`` to a GIF or
    MP4; returns the path and frame count.

    The episode runs until it terminates or truncates, or for ``max_steps`` steps. The output
    (its format, its folder, created if needed), the frame's size and view and the policy are
    checked before the first step.

    Args:
        env_id: A khepera_gym id (without its version: the latest), a PettingZoo module's name
            (``multinav_v3``) or a task of the core without a Gymnasium id (``multinav``: its
            latest version), whose agents all act with ``policy``.
        policy: A baseline's name, "random", ``sb3:path/to/model.zip``, or a function of one's
            own as ``module:function`` or ``path/to/file.py:function`` that maps observations
            (N, D) to actions (N, A).
        out: The video file, ``.gif`` or ``.mp4``.
        seed: The episode's seed.
        config: A built-in scenario name or a TOML path.
        max_steps: Stop after this many steps.
        frame_size: (width, height) pixels; None: from the arena's size (480 x 480 up to 4 m).
        fps: Frames per second of the video.
        algo: The SB3 algorithm of an ``sb3:`` model.
        zoom: Magnification (1: the whole arena).
        center: The world point (x, y in m) at the frames' centre; None: the arena's centre.
        progress: Show a progress bar of the steps.

    Raises:
        ConfigError: An unknown env or policy, a bad format, size, view or frame rate, or an
            output folder that cannot be written.
        KheperaError: MP4 without its writer installed.
    """
    agents_of = _agents_task(env_id)
    if agents_of is None:
        try:
            env_id = resolve_env_id(env_id)
        except ConfigError as error:
            near = difflib.get_close_matches(env_id, [*modules(), *_tasks()], n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ConfigError(
                f"{error}; or a PettingZoo module ({', '.join(modules())}){hint}"
            ) from None
    out = arguments.output_file(out, VIDEO_SUFFIXES, "output")
    check_video(out, fps)
    if frame_size is not None:
        frame_size = check_frame_size(frame_size)
    zoom, center = check_view(zoom, center)
    if agents_of is not None:
        frames = _agents_episode(
            *agents_of, policy, seed, config, max_steps, frame_size, zoom, center, progress, algo
        )
        return save_video(frames, out, fps=fps), len(frames)
    envs = gym.make_vec(
        env_id,
        num_envs=1,
        num_threads=1,
        render_mode="rgb_array",
        frame_size=frame_size,
        config=config,
        render_worlds=1,
    )
    try:
        envs.unwrapped.set_render_view(zoom, center)
        act = make_policy(policy, envs, seed=seed, algo=algo)
        frames = []
        total = envs.unwrapped.max_episode_steps
        total = total if max_steps is None else min(total, max_steps)
        bar = tqdm(total=total, desc=f"render {env_id}", unit="step", disable=not progress)

        def on_step(_step: int, _obs: Any, _rewards: Any, ended: Any, _done: Any) -> None:
            bar.update(1)
            if not ended[0]:  # the frame after the last step would show the next episode's start
                frames.append(envs.render())

        with bar:
            run_episodes(
                envs.unwrapped._batch,
                act,
                seed,
                on_reset=lambda _obs: frames.append(envs.render()),
                on_step=on_step,
                max_steps=max_steps,
            )
    finally:
        envs.close()
    return save_video(frames, out, fps=fps), len(frames)


def _agents_task(name: str) -> tuple[str, int] | None:
    """(task, version) when ``name`` is a PettingZoo module or a task without a Gymnasium id
    (recorded on the core's batch, every agent acting), else None."""
    with_ids = registered_ids()
    if name in modules() or (name not in with_ids and name in _tasks()):
        return task_and_version(name)
    return None


def _tasks() -> list[str]:
    from khepera_gym import registry

    return registry.task_names()


def _agents_episode(
    task: str,
    version: int,
    policy: str,
    seed: int,
    config: str | None,
    max_steps: int | None,
    frame_size: Sequence[int] | None,
    zoom: float,
    center: Sequence[float] | None,
    progress: bool,
    algo: str | None,
) -> list[Any]:
    """One seeded episode of one world of ``task`` (every agent acting with ``policy``): its
    frames, from the reset to the last step."""
    batch = make_batch(task, 1, config, {}, num_threads=1, autoreset=False, version=version)
    act = make_agents_policy(policy, batch, seed=seed, algo=algo)
    renderer = Renderer(batch, "rgb_array", frame_size, zoom=zoom, center=center)
    total = int(batch.max_episode_steps)
    total = total if max_steps is None else min(total, max_steps)
    frames = []
    with tqdm(
        total=total, desc=f"render {task}_v{version}", unit="step", disable=not progress
    ) as bar:

        def on_step(_step: int, _obs: Any, _rewards: Any, _ended: Any, _done: Any) -> None:
            # Without autoreset the last step's frame shows the episode's end, not a new start.
            bar.update(1)
            frames.append(renderer.frame())

        run_episodes(
            batch,
            act,
            seed,
            on_reset=lambda _obs: frames.append(renderer.frame()),
            on_step=on_step,
            max_steps=max_steps,
        )
    return frames


def add_arguments(parser: Any) -> None:
    """The options of ``khepera-gym render``."""
    parser.add_argument(
        "--env",
        default=DEFAULT_ENV,
        help=f"environment id ({DEFAULT_ENV}, the latest version), or a PettingZoo module or "
        "task (multinav_v3, multinav: every robot acts with --policy)",
    )
    parser.add_argument(
        "--policy",
        default="position_control",
        help="baseline name, sb3:path/to/model.zip, or your own function as module:function or "
        "file.py:function (observations (N, D) to actions (N, 2))",
    )
    parser.add_argument("--algo", default=None, help="SB3 algorithm of an sb3: model")
    parser.add_argument("--config", default=None, help="built-in scenario name or TOML path")
    parser.add_argument("--seed", type=int, default=0, help="episode seed (0)")
    parser.add_argument("--steps", type=int, default=None, help="stop after this many steps")
    parser.add_argument(
        "--size",
        type=int,
        nargs=2,
        default=None,
        metavar=("WIDTH", "HEIGHT"),
        help="frame size in pixels (480 480; more for an arena over 4 m, e.g. a swarm's)",
    )
    parser.add_argument(
        "--zoom",
        type=float,
        default=1.0,
        help="magnification about --center (1: the whole arena; 5: a fifth of its width)",
    )
    parser.add_argument(
        "--center",
        type=float,
        nargs=2,
        default=None,
        metavar=("X", "Y"),
        help="the point (m) at the frames' centre (the arena's centre)",
    )
    parser.add_argument("--fps", type=int, default=20, help="frames per second (20)")
    parser.add_argument("--out", default="run.gif", help="output file, .gif or .mp4 (run.gif)")
    parser.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=True, help="progress bar"
    )


def run_from_args(args: Any) -> int:
    """Runs ``khepera-gym render`` with parsed arguments: checks them all, then records.

    Raises:
        ConfigError: A bad argument (before anything is simulated).
    """
    arguments.seed(args.seed)
    arguments.at_least(args.steps, 1, "--steps")
    arguments.at_least(args.fps, 1, "--fps")
    arguments.at_least(args.zoom, 1, "--zoom")
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
        zoom=args.zoom,
        center=args.center,
        progress=args.progress,
    )
    print(f"wrote {count} frames of {args.env} ({args.policy}, seed {args.seed}) to {path}")
    return 0


__all__ = ["DEFAULT_ENV", "add_arguments", "record_video", "run_from_args"]
