"""The ``khepera-gym`` command: ``demo``, ``compare``, ``train``, ``render``, ``export`` and
``bench``.

``train`` trains a stable-baselines3 agent on the Rust batch (:mod:`khepera_gym.train`; SB3 and
torch are imported only then). ``export`` writes a trained policy as C for the real robot or as
ONNX (:mod:`khepera_gym.export`).

``compare`` runs policies (the paper's controllers of :mod:`khepera_gym.baselines`, random, or a
stable-baselines3 model) on the same seeded episodes and prints a table with 95% intervals,
writing CSV, JSON and trajectory plots (:mod:`khepera_gym.compare`). ``demo`` runs that
comparison on the paper's Fig. 6 and Fig. 7 scenes and on every task, and says where the
plots are (``--out-dir``, demo_out/).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import khepera_gym
from khepera_gym import bench, compare, export, record, train

#: Episodes per policy of each comparison of the demo.
DEMO_EPISODES = 50


def demo(episodes: int = DEMO_EPISODES, out_dir: Path = Path("demo_out")) -> int:
    """Runs :func:`khepera_gym.compare.demo`: the baselines on the paper's scenes and the tasks."""
    print(f"khepera_gym {khepera_gym.__version__}")
    return compare.demo(episodes, out_dir)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``khepera-gym`` and its subcommands."""
    parser = argparse.ArgumentParser(
        prog="khepera-gym",
        description="Khepera IV simulator for Gymnasium: demo, baseline comparison, benchmark.",
    )
    parser.add_argument("--version", action="version", version=khepera_gym.__version__)
    commands = parser.add_subparsers(dest="command", required=True)

    demo_parser = commands.add_parser(
        "demo", help="compare the baselines on the paper's scenes and every task; plot them"
    )
    demo_parser.add_argument(
        "--episodes",
        type=int,
        default=DEMO_EPISODES,
        help=f"episodes per policy and comparison ({DEMO_EPISODES})",
    )
    demo_parser.add_argument(
        "--out-dir", type=Path, default=Path("demo_out"), help="where the files go (demo_out/)"
    )

    compare_parser = commands.add_parser(
        "compare", help="run policies on the same seeded episodes; table, CSV, JSON, plots"
    )
    compare.add_arguments(compare_parser)

    train_parser = commands.add_parser(
        "train", help="train a stable-baselines3 agent on the Rust batch (needs the sb3 extra)"
    )
    train.add_arguments(train_parser)

    render_parser = commands.add_parser(
        "render", help="record a seeded episode of a policy to a GIF or MP4"
    )
    record.add_arguments(render_parser)

    export_parser = commands.add_parser(
        "export", help="a trained policy as C for the real robot (libkhepera template) or ONNX"
    )
    export.add_arguments(export_parser)

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
    if args.command == "compare":
        return compare.run_from_args(args)
    if args.command == "train":
        return train.run_from_args(args)
    if args.command == "render":
        return record.run_from_args(args)
    if args.command == "export":
        return export.run_from_args(args)
    return bench.run_from_args(args)


if __name__ == "__main__":
    raise SystemExit(main())
