"""The ``khepera-gym compare`` command and ``khepera-gym demo``: arguments, and the demo's
comparisons on the paper's scenes and the tasks.
"""

from __future__ import annotations

import argparse
import inspect
import warnings
from pathlib import Path
from typing import Any

from khepera_gym import registry
from khepera_gym.analysis.compare.consensus import TASK as CONSENSUS
from khepera_gym.analysis.compare.consensus import check_version as check_consensus_version
from khepera_gym.analysis.compare.consensus import report as consensus_report
from khepera_gym.analysis.compare.consensus import sweep as consensus_sweep
from khepera_gym.analysis.compare.metrics import task_metrics
from khepera_gym.analysis.compare.report import report
from khepera_gym.analysis.compare.run import compare, resolve_env_id
from khepera_gym.config import check_version, parse_key_values
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.learning.policies import DEFAULT_POLICIES, POLICY_NAMES
from khepera_gym.registration import ENV_CLASSES, latest_ids, task_of
from khepera_gym.tooling import arguments

#: Registered id (latest version) of each task name of ``--task``.
TASK_IDS = latest_ids()
#: Worlds drawn per policy by default on a task with a moving reference (overlaid in a panel).
PLOT_WORLDS_OVERLAID = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the options of ``khepera-gym compare`` to a parser."""
    target = parser.add_mutually_exclusive_group(required=True)
    tasks = sorted([*TASK_IDS, "consensus"])
    target.add_argument(
        "--task",
        choices=tasks,
        help=", ".join(tasks) + " (consensus: the consensus law under a range of message "
        "triggers, error against messages; --policy does not apply)",
    )
    target.add_argument(
        "--env",
        help="a registered id, e.g. KheperaIV-Avoid-v1, or consensus_vN for the consensus sweep",
    )
    parser.add_argument(
        "--version",
        type=int,
        default=None,
        help="behaviour version of --task (default: the latest; --env names its own)",
    )
    parser.add_argument("--config", help="built-in scenario (e.g. paper_fig6) or TOML path")
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="scenario key overriding the config, as gym.make's keywords (repeatable): "
        "reference=square, track.speed=0.1; VALUE is a TOML value, or else a string",
    )
    parser.add_argument(
        "--policy",
        nargs="+",
        action="extend",
        metavar="NAME",
        help=f"policies to compare: {', '.join(POLICY_NAMES)}, sb3:path/to/model.zip or your "
        "own function as module:function or file.py:function (default: those that fit the task)",
    )
    parser.add_argument("--algo", help="stable-baselines3 algorithm of sb3: models (PPO, SAC, ...)")
    parser.add_argument(
        "--sample-actions",
        action="store_true",
        help="sb3: models sample their actions (seeded with --seed) instead of taking the mode",
    )
    parser.add_argument("--episodes", type=int, default=100, help="episodes per policy (100)")
    parser.add_argument("--seed", type=int, default=0, help="world i is reset with seed + i (0)")
    parser.add_argument(
        "--out", type=Path, default=Path("compare_out"), help="output folder (compare_out/)"
    )
    parser.add_argument("--num-threads", type=int, default=None, help="threads (all cores)")
    parser.add_argument(
        "--plot", action=argparse.BooleanOptionalAction, default=True, help="save trajectories"
    )
    parser.add_argument(
        "--plot-worlds",
        type=int,
        default=None,
        help="worlds drawn per policy (the first ones; 1, or 3 overlaid on Track)",
    )
    parser.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=True, help="progress bars"
    )


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``--set`` items ``KEY=VALUE`` as ``gym.make`` keywords: VALUE read as a TOML value
    (``0.1``, ``true``, ``[1, 2]``, ``"ccw"``), or else taken as a string (``square``).

    Raises:
        ConfigError: An item without ``=`` or with an empty key, or a key given twice.
    """
    return parse_key_values(items, "--set")


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym compare`` from parsed arguments.

    Raises:
        SystemExit: With a message naming the problem (unknown policy, missing extra, ...).
    """
    try:
        consensus = _consensus_version(args)
    except KheperaError as error:
        raise SystemExit(f"khepera-gym compare: {arguments.one_line(error)}") from error
    if consensus is not None:
        return _run_consensus(args, consensus)
    try:
        _check_counts(args)
        env_id = resolve_env_id(args.task, args.env, getattr(args, "version", None))
        task = task_of(env_id)  # any version's id: v0 and v1 compare their task's baselines too
        policies = args.policy or list(DEFAULT_POLICIES.get(task or "", ("random",)))
        overrides = parse_overrides(getattr(args, "overrides", None) or [])
        worlds = args.plot_worlds
        if worlds is None:  # a moving reference's panels overlay a few episodes
            worlds = PLOT_WORLDS_OVERLAID if task_metrics(task).moving_reference else 1
        comparison = compare(
            env_id,
            policies,
            episodes=args.episodes,
            seed=args.seed,
            config=args.config,
            num_threads=args.num_threads,
            record_worlds=worlds if args.plot else 0,
            progress=args.progress,
            algo=args.algo,
            sample_actions=args.sample_actions,
            overrides=overrides,
            before_running=lambda: arguments.output_folder(args.out, "--out"),
        )
    except (ValueError, ImportError, OSError, KheperaError) as error:
        raise SystemExit(f"khepera-gym compare: {arguments.one_line(error)}") from error
    report(comparison, args.out, plot=args.plot)
    return 0


def _check_counts(args: argparse.Namespace) -> None:
    """The numeric options of ``compare``, before anything is built.

    Raises:
        ConfigError: A count below its least value or a seed out of range.
    """
    arguments.at_least(args.episodes, 1, "--episodes")
    arguments.seed(args.seed)
    arguments.at_least(args.num_threads, 1, "--num-threads")
    arguments.at_least(args.plot_worlds, 0, "--plot-worlds")


def _consensus_version(args: argparse.Namespace) -> int | None:
    """The behaviour version of consensus that ``--task consensus [--version N]`` or
    ``--env consensus_vN`` asks for, or None when they ask for another task.

    Raises:
        ConfigError: ``--version`` beside ``--env``, or a version consensus does not have.
    """
    version = getattr(args, "version", None)
    if args.task == CONSENSUS:
        return check_consensus_version(version)
    family, _, number = (args.env or "").rpartition("_v")
    if family != CONSENSUS:
        return None
    if version is not None:
        raise ConfigError(f"--env {args.env} names its version; do not add --version")
    if not number.isdigit():
        raise ConfigError(f"--env {args.env!r}: write consensus_vN, e.g. {CONSENSUS}_v1")
    return check_consensus_version(int(number))


def _run_consensus(args: argparse.Namespace, version: int) -> int:
    """``compare --task consensus`` (or ``--env consensus_vN``): the trigger sweep of
    :mod:`khepera_gym.analysis.compare.consensus` on behaviour ``version``."""
    try:
        _check_counts(args)
        if args.policy:
            raise ConfigError(
                "--task consensus runs the consensus law (ConsensusLaw) under every trigger "
                "setting; --policy does not apply"
            )
        overrides = parse_overrides(getattr(args, "overrides", None) or [])
        arguments.output_folder(args.out, "--out")
        rows = consensus_sweep(
            episodes=args.episodes,
            seed=args.seed,
            config=args.config,
            overrides=overrides,
            num_threads=args.num_threads,
            progress=args.progress,
            version=version,
        )
    except (ValueError, OSError, KheperaError) as error:
        raise SystemExit(f"khepera-gym compare: {arguments.one_line(error)}") from error
    consensus_report(rows, args.out, plot=args.plot)
    return 0


#: Worlds whose trajectories the demo plots per policy, for tasks where one does not show enough
#: (Avoid's obstacles change every episode; Track's references are overlaid); others plot one.
DEMO_PLOTTED_WORLDS = {"avoid": 2, "track": 3}


def _task_title(task: str, env_id: str) -> str:
    """A demo section's title: the id and the first sentence of its env class's manual."""
    doc = inspect.getdoc(ENV_CLASSES[task]) or task
    first = " ".join(doc.split("\n\n", 1)[0].split())
    return f"{env_id}: {first}"


#: A comparison of the demo: (title, env id, config, policies, episodes cap, plotted worlds).
DemoRun = tuple[str, str, str | None, tuple[str, ...], int | None, int]


def demo_runs(version: int | None = None) -> tuple[DemoRun, ...]:
    """The demo's comparisons on behaviour ``version`` (None: each task's latest): the paper's
    two scenes, then every task with a Gymnasium env that exists in that version, with the
    task's default policies (all from the registries: a new task joins the demo by itself).

    Raises:
        ConfigError: A version that does not exist.
    """
    if version is not None:
        check_version(version)

    def env_id(task: str) -> str | None:
        info = registry.task(task)
        if version is not None and version not in info.versions:
            return None
        return info.env_id_of(version)

    paper = [
        (
            "Paper Fig. 6: Braitenberg vs VFH past a wall and an obstacle",
            "avoid",
            "paper_fig6",
            ("braitenberg", "vfh", "position_control"),
        ),
        (
            "Paper Fig. 7: cross formation of four LeaderFollower followers past obstacles",
            "formation",
            "paper_fig7",
            ("leader_follower",),
        ),
    ]
    runs: list[DemoRun] = []
    for title, task, config, policies in paper:
        paper_id = env_id(task)
        if paper_id is not None:
            runs.append((title, paper_id, config, policies, None, 1))
    for task in TASK_IDS:
        task_id = env_id(task)
        if task_id is not None:
            runs.append(
                (
                    _task_title(task, task_id),
                    task_id,
                    None,
                    tuple(DEFAULT_POLICIES[task]),
                    None,
                    DEMO_PLOTTED_WORLDS.get(task, 1),
                )
            )
    return tuple(runs)


#: The demo's comparisons on each task's latest version (:func:`demo_runs`).
DEMO_RUNS: tuple[DemoRun, ...] = demo_runs()


def demo(
    episodes: int = 50,
    out_dir: Path = Path("demo_out"),
    progress: bool = True,
    version: int | None = None,
) -> int:
    """Runs the comparison on the paper's scenes and every task, then the consensus trigger
    sweep; prints the tables.

    Args:
        episodes: Episodes per policy and comparison.
        out_dir: Where the CSV, JSON and PNG files go.
        progress: Show progress bars.
        version: The behaviour version to run (None: each task's latest); a task that does not
            exist in it is left out, with a line saying so.

    Returns:
        0.

    Raises:
        ConfigError: A version that does not exist.
    """
    runs = demo_runs(version)
    if version is not None:
        left = [t for t in registry.task_names() if version not in registry.task_versions(t)]
        if left:
            print(f"behaviour version {version}: {', '.join(left)} did not exist yet, left out")
    saved: list[Path] = []
    for title, env_id, config, policies, cap, worlds in runs:
        print(f"\n== {title}\n")
        with warnings.catch_warnings():
            # Gymnasium's "out of date" notice for the v0 ids: the demo picks v0 on purpose.
            warnings.filterwarnings("ignore", message=".*is out of date.*")
            comparison = compare(
                env_id,
                policies,
                episodes=episodes if cap is None else min(episodes, cap),
                config=config,
                record_worlds=worlds,
                progress=progress,
            )
        saved += report(comparison, out_dir)
    if version is None or version in registry.task_versions(CONSENSUS):
        consensus_version = check_consensus_version(version)
        print(
            f"\n== {CONSENSUS}_v{consensus_version}: four robots on a ring agree on a square "
            "formation from their neighbours' messages, periodic vs event-triggered\n"
        )
        rows = consensus_sweep(episodes=episodes, progress=progress, version=consensus_version)
        saved += consensus_report(rows, out_dir)
    print(
        f"\nplots (trajectories of the first worlds, one panel per policy) in {out_dir.resolve()}:"
    )
    for path in saved:
        if path.suffix == ".png":
            print(f"  {path.resolve()}")
    return 0


__all__ = [
    "DEMO_RUNS",
    "DemoRun",
    "add_arguments",
    "demo",
    "demo_runs",
    "parse_overrides",
    "run_from_args",
]
