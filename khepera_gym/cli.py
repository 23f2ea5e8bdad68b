"""The ``khepera-gym`` command: ``list``, ``demo``, ``compare``, ``train``, ``render``,
``export``, ``robot-program``, ``calibrate``, ``replay``, ``bench``, ``benchmark`` and ``tune``.

``list`` prints what the package has, read from the registries (:mod:`khepera_gym.registry`):
the Gymnasium ids, the PettingZoo modules, the built-in scenes, the sensors and the policies
``compare`` and ``render`` take.

``train`` trains a stable-baselines3 agent on the Rust batch (:mod:`khepera_gym.learning.train`; SB3
and torch are imported only then). ``export`` writes a trained policy as C for the real robot or as
ONNX (:mod:`khepera_gym.robot.export`). ``robot-program calibrate`` writes the calibration program
for the robot, ``calibrate`` fits the simulator to its logs and ``replay`` compares a robot log with
the simulator (:mod:`khepera_gym.robot.calibrate`; a malformed log or scenario is a one-line error).

``compare`` runs policies (the paper's controllers of :mod:`khepera_gym.baselines`, random, or a
stable-baselines3 model) on the same seeded episodes and prints a table with 95% intervals,
writing CSV, JSON and trajectory plots (:mod:`khepera_gym.analysis.compare`). ``demo`` runs that
comparison on the paper's Fig. 6 and Fig. 7 scenes and on every task, and says where the
plots are (``--out-dir``, demo_out/). ``benchmark`` trains every task's learners over several
seeds and reports them on held-out episodes beside the baselines
(:mod:`khepera_gym.learning.benchmark`).

Every subcommand checks its arguments (ids, counts, seeds, output formats and folders, which it
creates) before it simulates anything, shows a progress bar on work longer than a moment, and
ends a user error with one line on stderr and a non-zero status
(:func:`khepera_gym.tooling.arguments.run_command`), never a traceback.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import khepera_gym
from khepera_gym import pettingzoo, registry
from khepera_gym.analysis import compare, record, throughput
from khepera_gym.config import check_version
from khepera_gym.errors import KheperaError
from khepera_gym.learning import train
from khepera_gym.learning.benchmark import command as benchmark_command
from khepera_gym.learning.benchmark import tune
from khepera_gym.learning.policies import BASELINES, DEFAULT_POLICIES, POLICY_NAMES, VARIANTS
from khepera_gym.registration import registered_ids
from khepera_gym.robot import export
from khepera_gym.robot.calibrate import command as calibrate_command
from khepera_gym.tooling import arguments, provenance

#: What ``khepera-gym list`` can print.
LIST_TOPICS = ("envs", "pettingzoo", "scenes", "sensors", "policies")

#: Episodes per policy of each comparison of the demo.
DEMO_EPISODES = 50


def demo(
    episodes: int = DEMO_EPISODES, out_dir: Path = Path("demo_out"), version: int | None = None
) -> int:
    """Runs :func:`khepera_gym.analysis.compare.demo`: the baselines on the paper's scenes and the
    tasks, on behaviour ``version`` (None: each task's latest)."""
    print(f"khepera_gym {khepera_gym.__version__}")
    return compare.demo(episodes, out_dir, version=version)


def _policy_tasks(name: str) -> str:
    """The tasks a policy of ``compare`` is a default for (random: every task)."""
    if name == "random":
        return "every task"
    tasks = [task for task, names in DEFAULT_POLICIES.items() if name in names]
    return ", ".join(tasks) if tasks else "tasks whose observation it reads"


def list_catalog(topics: Sequence[str] = LIST_TOPICS) -> str:
    """The text of ``khepera-gym list``: one section per topic, from the registries."""
    sections = []
    if "envs" in topics:
        lines = ["Gymnasium ids (gym.make; without -vN: the latest):"]
        for task, ids in registered_ids().items():
            lines.append(f"  {', '.join(ids):<52} task {task}")
        sections.append("\n".join(lines))
    if "pettingzoo" in topics:
        lines = ["PettingZoo modules (khepera_gym.pettingzoo.<name>.parallel_env()):"]
        for module in pettingzoo.module_infos():
            lines.append(f"  {module.name:<20} task {module.task}")
        sections.append("\n".join(lines))
    if "scenes" in topics:
        lines = ["Built-in scenes (config=NAME; also every task's name for its defaults):"]
        lines += [f"  {name:<12} {summary}" for name, summary in registry.scenes().items()]
        sections.append("\n".join(lines))
    if "sensors" in topics:
        lines = ["Sensors (scenario keys sensors.carry and sensors.observe):"]
        for sensor in registry.sensors():
            default = "observed" if sensor.observed else "carried" if sensor.carried else "off"
            values = f"{sensor.values} value{'s' if sensor.values > 1 else ''}"
            lines.append(f"  {sensor.name:<8} {values:>10}   default: {default}")
        sections.append("\n".join(lines))
    if "policies" in topics:
        lines = [
            "Policies (khepera-gym compare --policy on the Gymnasium tasks; render --policy and"
            " khepera-gym benchmark on the multi-agent ones too, every robot acting):"
        ]
        for name in POLICY_NAMES:
            controller = VARIANTS.get(name, (name, {}))[0]
            cls = BASELINES.get(controller)
            what = f"baselines.{cls.__name__}" if cls is not None else "uniform random actions"
            if name in VARIANTS and VARIANTS[name][1]:
                what += "(" + ", ".join(f"{k}={v!r}" for k, v in VARIANTS[name][1].items()) + ")"
            lines.append(f"  {name:<24} {what}; for {_policy_tasks(name)}")
        lines.append("  sb3:PATH.zip             a stable-baselines3 model (the sb3 extra)")
        sections.append("\n".join(lines))
    return "\n\n".join(sections)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``khepera-gym`` and its subcommands."""
    parser = argparse.ArgumentParser(
        prog="khepera-gym",
        description="Khepera IV simulator for Gymnasium: demo, baseline comparison, benchmark.",
    )
    parser.add_argument("--version", action="version", version=khepera_gym.__version__)
    commands = parser.add_subparsers(dest="command", required=True)

    list_parser = commands.add_parser(
        "list", help="the envs, PettingZoo modules, scenes, sensors and policies there are"
    )
    list_parser.add_argument(
        "topics",
        nargs="*",
        metavar="TOPIC",
        help=f"what to list: {', '.join(LIST_TOPICS)} (default: all)",
    )

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
    demo_parser.add_argument(
        "--version",
        type=int,
        default=None,
        help="behaviour version of every run (default: each task's latest)",
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

    program_parser = commands.add_parser(
        "robot-program", help="a program for the real robot: the calibration manoeuvre, as C"
    )
    calibrate_command.add_program_arguments(program_parser)

    calibrate_parser = commands.add_parser(
        "calibrate",
        help="fit the simulator to the calibration program's logs; write a scenario and a report "
        "(needs the calibrate extra)",
    )
    calibrate_command.add_calibrate_arguments(calibrate_parser)

    replay_parser = commands.add_parser(
        "replay", help="a robot log against the simulator driven by its commands"
    )
    calibrate_command.add_replay_arguments(replay_parser)

    bench_parser = commands.add_parser("bench", help="env-steps/s and memory per world")
    throughput.add_arguments(bench_parser)

    benchmark_parser = commands.add_parser(
        "benchmark",
        help="the learning benchmark: every task's learners over seeds, held-out, beside the "
        "baselines (needs the sb3 extra; benchmarl for mappo/ippo)",
    )
    benchmark_command.add_arguments(benchmark_parser)
    tune_parser = commands.add_parser(
        "tune",
        help="search a learner's recipe for a task (Ray Tune, ASHA), never on held-out seeds",
    )
    tune.add_arguments(tune_parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``khepera-gym`` console script.

    Raises:
        SystemExit: On a user error, with one line naming it (status 1); argparse's own errors
            exit with status 2.
    """
    args = build_parser().parse_args(argv)
    if argv is None:
        return arguments.run_command(args.command, lambda: _run(args))
    with provenance.running_command(["khepera-gym", *argv]):
        return arguments.run_command(args.command, lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    """Runs the parsed subcommand."""
    if args.command == "list":
        unknown = sorted(set(args.topics) - set(LIST_TOPICS))
        if unknown:
            raise SystemExit(
                f"khepera-gym list: unknown topic {unknown[0]!r}; known: {LIST_TOPICS}"
            )
        print(list_catalog(args.topics or LIST_TOPICS))
        return 0
    if args.command == "demo":
        arguments.at_least(args.episodes, 1, "--episodes")
        arguments.output_folder(args.out_dir, "--out-dir")
        try:
            check_version(args.version)
        except KheperaError as error:
            raise SystemExit(f"khepera-gym demo: --version: {arguments.one_line(error)}") from error
        return demo(args.episodes, args.out_dir, args.version)
    if args.command == "compare":
        return compare.run_from_args(args)
    if args.command == "train":
        return train.run_from_args(args)
    if args.command == "render":
        return record.run_from_args(args)
    if args.command == "export":
        return export.run_from_args(args)
    loop_commands = {
        "robot-program": calibrate_command.run_program_from_args,
        "calibrate": calibrate_command.run_calibrate_from_args,
        "replay": calibrate_command.run_replay_from_args,
    }
    if args.command in loop_commands:
        return loop_commands[args.command](args)
    if args.command == "benchmark":
        return benchmark_command.run_from_args(args)
    if args.command == "tune":
        return tune.run_from_args(args)
    return throughput.run_from_args(args)


if __name__ == "__main__":
    raise SystemExit(main())
