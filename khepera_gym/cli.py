"""The ``khepera-gym`` command: ``demo`` (heuristic episodes of every task, plots) and ``bench``.

``demo`` runs seeded episodes with the heuristic policies that live next to the envs: Nav with
the position controller, Avoid with position control + Braitenberg (and the paper's Fig. 6 scene),
Formation on the paper's Fig. 7 scene with proportional followers; it prints their statistics and
saves trajectory plots to ``--out-dir`` (demo_out/).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from matplotlib.figure import Figure

import khepera_gym
from khepera_gym import bench
from khepera_gym.envs import avoid_heuristic, formation_heuristic, nav_heuristic
from khepera_gym.plot import plot_trajectories

NAV_ID = "KheperaIV-Nav-v0"
AVOID_ID = "KheperaIV-Avoid-v0"
FORMATION_ID = "KheperaIV-Formation-v0"
#: Resolution of the saved plots (dots per inch).
PLOT_DPI = 120


def _run_episode(
    env: gym.Env, policy: Callable[[np.ndarray], np.ndarray], seed: int
) -> tuple[np.ndarray, dict[str, Any], dict[str, Any]]:
    """One seeded episode; returns the poses of every step (T, n_robots, 3), its goals/targets
    and the final ``episode_stats``."""
    observation, _ = env.reset(seed=seed)
    unwrapped = env.unwrapped
    record_targets = hasattr(unwrapped, "formation_targets")
    poses = [unwrapped.poses()]
    targets = [unwrapped.formation_targets()] if record_targets else []
    extras = {"goals": unwrapped.goals(), "scene": unwrapped.scene()}
    while True:
        observation, _, terminated, truncated, info = env.step(policy(observation))
        poses.append(unwrapped.poses())
        if record_targets:
            targets.append(unwrapped.formation_targets())
        if terminated or truncated:
            break
    if record_targets:
        extras["targets"] = np.array(targets)
    return np.array(poses), extras, info["episode_stats"]


def _print_table(rows: list[tuple[int, dict[str, Any]]], extra: str | None = None) -> None:
    header = (
        f"{'seed':>4} {'outcome':>9} {'steps':>5} {'return':>8} {'path (m)':>8} "
        f"{'collisions':>10}" + (f" {extra:>14}" if extra else "")
    )
    print(header)
    print("-" * len(header))
    for seed, result in rows:
        outcome = "success" if result["success"] else "timeout"
        line = (
            f"{seed:>4} {outcome:>9} {result['length']:>5} {result['return']:>8.2f} "
            f"{result['path_length']:>8.2f} {result['collisions']:>10}"
        )
        if extra:
            line += f" {result[extra]:>14.3f}"
        print(line)
    print("-" * len(header))
    successes = sum(result["success"] for _, result in rows)
    print(
        f"success rate {successes}/{len(rows)} ({100 * successes / len(rows):.0f} %), "
        f"mean steps {np.mean([r['length'] for _, r in rows]):.1f}, "
        f"mean path length {np.mean([r['path_length'] for _, r in rows]):.2f} m, "
        f"collisions {sum(r['collisions'] for _, r in rows)}"
    )


def _save(figure: Any, path: Path) -> None:
    figure.savefig(path, dpi=PLOT_DPI)
    print(f"plot saved to {path.resolve()}")


def nav_demo(episodes: int, out_dir: Path) -> list[dict[str, Any]]:
    """Seeded Nav episodes (seeds 0, 1, ...) with the position controller; plots the paths."""
    print(f"{NAV_ID}: position controller (paper eqs. 1-4)\n")
    env = gym.make(NAV_ID)
    trajectories, goals, rows = [], [], []
    for seed in range(episodes):
        poses, extras, result = _run_episode(env, nav_heuristic, seed)
        trajectories.append(poses[:, 0])
        goals.append(extras["goals"][0])
        rows.append((seed, result))
    scene = env.unwrapped.scene()
    env.close()
    _print_table(rows)
    figure = plot_trajectories(
        trajectories,
        scene,
        goals=goals,
        title=f"{NAV_ID}: position controller, seeds 0-{episodes - 1}",
    )
    _save(figure, out_dir / "nav_trajectories.png")
    return [result for _, result in rows]


def avoid_demo(episodes: int, out_dir: Path) -> list[dict[str, Any]]:
    """Seeded Avoid episodes with position control + Braitenberg, one plot each (first three),
    and the paper's Fig. 6 scene with and without the Braitenberg block."""
    print(f"\n{AVOID_ID}: position control + Braitenberg avoidance (paper eqs. 1-7)\n")
    env = gym.make(AVOID_ID)
    rows, plotted = [], []
    for seed in range(episodes):
        poses, extras, result = _run_episode(env, avoid_heuristic, seed)
        rows.append((seed, result))
        if len(plotted) < 3:
            plotted.append((seed, poses, extras))
    env.close()
    _print_table(rows)
    figure = Figure(figsize=(6 * len(plotted), 6), layout="constrained")
    for ax, (seed, poses, extras) in zip(
        figure.subplots(1, len(plotted), squeeze=False)[0], plotted, strict=True
    ):
        plot_trajectories(
            [poses[:, 0]], extras["scene"], goals=[extras["goals"][0]], ax=ax, title=f"seed {seed}"
        )
    figure.suptitle(f"{AVOID_ID}: position control + Braitenberg, new obstacles every episode")
    _save(figure, out_dir / "avoid_trajectories.png")
    _save(fig6_figure(), out_dir / "paper_fig6.png")
    return [result for _, result in rows]


def fig6_figure(seed: int = 0) -> Figure:
    """The paper's Fig. 6 scene on Avoid: position control alone vs with Braitenberg."""
    env = gym.make(AVOID_ID, config="paper_fig6")
    trajectories, labels = [], []
    for name, policy in (
        ("position control + Braitenberg", avoid_heuristic),
        ("position control only", nav_heuristic),
    ):
        poses, extras, result = _run_episode(env, policy, seed)
        trajectories.append(poses[:, 0])
        outcome = "reached" if result["success"] else "stuck"
        labels.append(f"{name}: {outcome} in {result['length']} steps")
    scene, goal = extras["scene"], extras["goals"][0]
    env.close()
    return plot_trajectories(
        trajectories,
        scene,
        goals=[goal, None],
        labels=labels,
        title=f'{AVOID_ID}, config="paper_fig6" (paper Fig. 6)',
    )


def formation_demo(out_dir: Path, seed: int = 0) -> dict[str, Any]:
    """A Formation episode on the paper's Fig. 7 scene with proportional followers; plots it."""
    print(f"\n{FORMATION_ID}, paper_fig7: scripted leader, proportional followers\n")
    figure, result = fig7_figure(seed)
    _print_table([(seed, result)], extra="formation_error_mean")
    print(f"largest formation error {result['formation_error_max']:.3f} m")
    _save(figure, out_dir / "paper_fig7.png")
    return result


def fig7_figure(seed: int = 0) -> tuple[Figure, dict[str, Any]]:
    """The paper's Fig. 7 scene: the cross formation's traces, targets and snapshots."""
    env = gym.make(FORMATION_ID, config="paper_fig7")
    poses, extras, result = _run_episode(env, formation_heuristic, seed)
    n_followers = poses.shape[1] - 1
    env.close()
    figure = plot_trajectories(
        [poses],
        extras["scene"],
        goals=[extras["goals"]],
        targets=[extras["targets"]],
        leader=0,
        robot_names=["leader"] + [f"follower_{k}" for k in range(n_followers)],
        snapshots=3,
        title=(
            f'{FORMATION_ID}, config="paper_fig7"\nscripted leader, proportional followers: '
            f"mean formation error {result['formation_error_mean'] * 100:.1f} cm"
        ),
    )
    return figure, result


def demo(episodes: int = 5, out_dir: Path = Path("demo_out")) -> int:
    """Runs the heuristic policies of every task on seeded episodes and saves their plots."""
    print(f"khepera_gym {khepera_gym.__version__}\n")
    out_dir.mkdir(parents=True, exist_ok=True)
    nav_demo(episodes, out_dir)
    avoid_demo(episodes, out_dir)
    formation_demo(out_dir)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``khepera-gym`` and its subcommands."""
    parser = argparse.ArgumentParser(
        prog="khepera-gym", description="Khepera IV simulator for Gymnasium: demo and benchmark."
    )
    parser.add_argument("--version", action="version", version=khepera_gym.__version__)
    commands = parser.add_subparsers(dest="command", required=True)

    demo_parser = commands.add_parser(
        "demo", help="run seeded episodes of every task with the heuristic policies; plot them"
    )
    demo_parser.add_argument(
        "--episodes", type=int, default=5, help="Nav and Avoid episodes each (5)"
    )
    demo_parser.add_argument(
        "--out-dir", type=Path, default=Path("demo_out"), help="where the plots go (demo_out/)"
    )

    bench_parser = commands.add_parser("bench", help="env-steps/s and memory per world")
    bench.add_arguments(bench_parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``khepera-gym`` console script."""
    args = build_parser().parse_args(argv)
    if args.command == "demo":
        if args.episodes < 1:
            raise SystemExit("khepera-gym demo: --episodes must be >= 1")
        return demo(args.episodes, args.out_dir)
    return bench.run_from_args(args)


if __name__ == "__main__":
    raise SystemExit(main())
