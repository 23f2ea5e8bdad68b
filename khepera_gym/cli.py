"""The ``khepera-gym`` command: ``demo`` (heuristic Nav episodes and a plot) and ``bench``."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np

import khepera_gym
from khepera_gym import bench
from khepera_gym.envs import nav_heuristic
from khepera_gym.plot import plot_trajectories

NAV_ID = "KheperaIV-Nav-v0"


def demo(episodes: int = 5, out_dir: Path = Path("demo_out")) -> int:
    """Runs seeded Nav episodes (seeds 0, 1, ...) with the position controller; plots the paths."""
    env = gym.make(NAV_ID)
    print(
        f"khepera_gym {khepera_gym.__version__}: {NAV_ID}, position controller (paper eqs. 1-4)\n"
    )
    header = (
        f"{'episode':>7} {'seed':>4} {'outcome':>9} {'steps':>5} {'return':>8} "
        f"{'path (m)':>8} {'collisions':>10}"
    )
    print(header)
    print("-" * len(header))
    trajectories, goals, stats = [], [], []
    for episode in range(episodes):
        observation, _ = env.reset(seed=episode)
        path = [env.unwrapped.poses()[0]]
        goals.append(env.unwrapped.goals()[0])
        while True:
            observation, _, terminated, truncated, info = env.step(nav_heuristic(observation))
            path.append(env.unwrapped.poses()[0])
            if terminated or truncated:
                break
        trajectories.append(np.array(path))
        result = info["episode_stats"]
        stats.append(result)
        outcome = "success" if result["success"] else "timeout"
        print(
            f"{episode:>7} {episode:>4} {outcome:>9} {result['length']:>5} "
            f"{result['return']:>8.2f} {result['path_length']:>8.2f} {result['collisions']:>10}"
        )
    scene = env.unwrapped.scene()
    env.close()

    successes = sum(result["success"] for result in stats)
    print("-" * len(header))
    print(
        f"success rate {successes}/{episodes} ({100 * successes / episodes:.0f} %), "
        f"mean steps {np.mean([r['length'] for r in stats]):.1f}, "
        f"mean path length {np.mean([r['path_length'] for r in stats]):.2f} m, "
        f"collisions {sum(r['collisions'] for r in stats)}"
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    figure_path = out_dir / "nav_trajectories.png"
    figure = plot_trajectories(
        trajectories,
        scene,
        goals=goals,
        title=f"{NAV_ID}: position controller, seeds 0-{episodes - 1}",
    )
    figure.savefig(figure_path, dpi=120)
    print(f"\ntrajectory plot saved to {figure_path.resolve()}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``khepera-gym`` and its subcommands."""
    parser = argparse.ArgumentParser(
        prog="khepera-gym", description="Khepera IV simulator for Gymnasium: demo and benchmark."
    )
    parser.add_argument("--version", action="version", version=khepera_gym.__version__)
    commands = parser.add_subparsers(dest="command", required=True)

    demo_parser = commands.add_parser(
        "demo", help="run seeded Nav episodes with the heuristic policy and plot them"
    )
    demo_parser.add_argument("--episodes", type=int, default=5, help="number of episodes (5)")
    demo_parser.add_argument(
        "--out-dir", type=Path, default=Path("demo_out"), help="where the plot goes (demo_out/)"
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
