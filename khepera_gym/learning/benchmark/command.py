"""``khepera-gym benchmark``: train every task's learners over several seeds, evaluate them on
held-out episodes beside the baselines, and print and write the tables.

    khepera-gym benchmark                                  # the whole suite, 5 seeds
    khepera-gym benchmark --tasks track seek --seeds 5     # a part of it
    khepera-gym benchmark --tasks avoid --learners ppo --seed-list 5 6 7
    khepera-gym benchmark --tasks avoid --ray HEAD_IP:6379  # each run a Ray task on a cluster
    khepera-gym benchmark --list                           # what the suite holds

It shows its progress, writes each run's results file as the run ends (so after an
interruption the same command resumes without repeating a finished run, and says which it
skips; Ctrl-C stops with one line saying so, status 130), and ends with one table per task and
the command that reproduces each row. With ``--ray [ADDRESS]`` every run is a Ray task
(:mod:`khepera_gym.learning.benchmark.cluster`), its files written here as a local run's.
``--device`` and ``--num-threads`` are honoured by every learner; ``--timesteps`` and
``--hp KEY=VALUE`` change every recipe (the results then record the recipe they ran).
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from khepera_gym import registry
from khepera_gym.config import parse_key_values, toml_value
from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark.learners import learner as make_learner
from khepera_gym.learning.benchmark.runner import Settings, finished, run_baselines, run_one
from khepera_gym.learning.benchmark.suite import load_suite
from khepera_gym.learning.benchmark.tables import load_records, markdown, task_rows
from khepera_gym.tooling import arguments
from khepera_gym.tooling.provenance import current_command, portable_command, provenance

#: Where the results go without ``--out``.
DEFAULT_OUT = Path("benchmark_out")
#: Seeds of each (task, learner) without ``--seeds``.
DEFAULT_SEEDS = 5
#: Held-out episodes of every run and baseline without ``--episodes``.
DEFAULT_EPISODES = 200
#: First held-out episode's seed without ``--heldout-seed``.
DEFAULT_HELDOUT_SEED = 0
#: Episodes of each evaluation while training without ``--eval-episodes``.
DEFAULT_EVAL_EPISODES = 50
#: Exit status after Ctrl-C (128 + SIGINT, as a shell reports it).
INTERRUPTED = 130


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym benchmark``."""
    parser.add_argument("--tasks", nargs="+", metavar="TASK", help="tasks (all in the suite)")
    parser.add_argument(
        "--learners", nargs="+", metavar="NAME", help="learners (each task's in the suite)"
    )
    parser.add_argument(
        "--seeds", type=int, default=None, help=f"training seeds 0..N-1 ({DEFAULT_SEEDS})"
    )
    parser.add_argument(
        "--seed-list", type=int, nargs="+", metavar="SEED", help="these training seeds instead"
    )
    parser.add_argument("--version", type=int, default=None, help="behaviour version (the latest)")
    parser.add_argument(
        "--episodes",
        type=int,
        default=DEFAULT_EPISODES,
        help=f"held-out episodes, seeds --heldout-seed + i ({DEFAULT_EPISODES})",
    )
    parser.add_argument(
        "--heldout-seed",
        type=int,
        default=DEFAULT_HELDOUT_SEED,
        help=f"first held-out seed ({DEFAULT_HELDOUT_SEED})",
    )
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=DEFAULT_EVAL_EPISODES,
        help="episodes of each evaluation while training, seeds 10000 + i "
        f"({DEFAULT_EVAL_EPISODES})",
    )
    parser.add_argument(
        "--timesteps", type=int, default=None, help="environment steps of every run (each recipe's)"
    )
    parser.add_argument(
        "--hp",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a recipe key in every run, VALUE in TOML (repeatable)",
    )
    parser.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help=f"results folder ({DEFAULT_OUT})"
    )
    parser.add_argument(
        "--suite", type=Path, default=None, help="suite file (configs/benchmark.toml)"
    )
    parser.add_argument("--device", default="cpu", help="torch device: cpu, cuda, cuda:1 (cpu)")
    parser.add_argument(
        "--num-threads", type=int, default=None, help="threads of the Rust batches (all cores)"
    )
    parser.add_argument(
        "--restart",
        action="store_true",
        help="run everything again, replacing the folder's results",
    )
    parser.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        metavar="ADDRESS",
        help="run each (task, learner, seed) as a Ray task asking for --num-threads CPUs (1) "
        "and a GPU with --device cuda: on the cluster whose head is at ADDRESS (host:port), "
        "or without ADDRESS on a Ray started on this machine",
    )
    parser.add_argument("--list", action="store_true", help="print the suite and stop")
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar, the learners' own (BenchMARL's) included",
    )


def check_device(device: str, here: bool = True) -> str:
    """``device`` if torch can use it (``here``: on this machine; else a name the learners take,
    the cluster's GPUs checked once joined).

    Raises:
        ConfigError: An unknown device, or CUDA asked for where torch has none.
    """
    import torch

    try:
        parsed = torch.device(device)
    except (RuntimeError, TypeError) as error:
        raise ConfigError(f"--device {device!r} is not a torch device: {error}") from None
    if here and parsed.type == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"--device {device}: torch sees no CUDA device on this machine")
    if parsed.type not in ("cpu", "cuda"):
        raise ConfigError(f"--device {device}: the learners run on cpu or cuda")
    return device


def _selection(args: argparse.Namespace, suite: dict[str, Any]) -> list[tuple[Any, list[str]]]:
    """(entry, learners) of every task to run, after checking every name."""
    tasks = registry.task_names()
    chosen = list(suite)
    if args.tasks:
        chosen = list(dict.fromkeys(_task_name(name, tasks) for name in args.tasks))
    for task in chosen:
        if task not in suite:
            raise ConfigError(
                f"the suite has no entry for {task!r} (entries: {', '.join(suite)}): add one to "
                "configs/benchmark.toml with its learners and criterion"
            )
    selection = []
    for task in chosen:
        entry = suite[task]
        learners = [n for n in entry.learners if not args.learners or n in args.learners]
        selection.append((entry, learners))
    for name in args.learners or []:
        make_learner(name)  # an unknown learner is an error naming them
        if not any(name in learners for _, learners in selection):
            raise ConfigError(
                f"learner {name!r} is in no chosen task's entry; "
                + "; ".join(f"{e.task}: {', '.join(e.learners)}" for e, _ in selection)
            )
    return selection


def _task_name(name: str, tasks: Sequence[str]) -> str:
    """The core's task ``name`` names, in any case (``Nav``: ``nav``).

    Raises:
        ConfigError: No task of that name; the message suggests the nearest and lists them.
    """
    if name.lower() in tasks:
        return name.lower()
    raise ConfigError(f"unknown task {name!r}; {arguments.did_you_mean(name, tasks)}")


def _version(task: str, version: int | None) -> int:
    versions = registry.task_versions(task)
    if version is None:
        return versions[-1]
    if version not in versions:
        raise ConfigError(f"{task} has no behaviour version {version}; it has {versions}")
    return version


def reproduce(task: str, row: Mapping[str, Any]) -> str:
    """The command that runs one row of a task's table (:func:`task_rows`) again: its learner,
    seeds and version, and whatever its command changed (``--hp``, ``--timesteps``, held-out
    and evaluation episodes). The version is always written: without it the command would run
    the latest version of the day it is run, not the row's."""
    parts = ["khepera-gym benchmark", f"--tasks {task}", f"--learners {row['learner']}"]
    parts.append(f"--seed-list {' '.join(map(str, row['seeds']))}")
    parts.append(f"--version {row['version']}")
    settings = row.get("settings") or {}
    if settings.get("timesteps") is not None:
        parts.append(f"--timesteps {settings['timesteps']}")
    for flag, name, default in (
        ("--episodes", "episodes", DEFAULT_EPISODES),
        ("--heldout-seed", "heldout_seed", DEFAULT_HELDOUT_SEED),
        ("--eval-episodes", "eval_episodes", DEFAULT_EVAL_EPISODES),
    ):
        if settings.get(name) not in (None, default):
            parts.append(f"{flag} {settings[name]}")
    for key, value in (settings.get("overrides") or {}).items():
        parts.append("--hp " + shlex.quote(f"{key}={toml_value(value, '--hp')}"))
    return " ".join(parts)


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym benchmark`` from parsed arguments.

    Raises:
        ConfigError: Any bad argument or suite entry, before anything is trained.
        SystemExit: Ctrl-C, with status :data:`INTERRUPTED` after one line on stderr saying
            how many runs are done and that the same command resumes.
    """
    from tqdm import tqdm

    suite = load_suite(args.suite)
    if args.list:
        for entry in suite.values():
            print(
                f"{entry.task}: learners {', '.join(entry.learners)}; baselines "
                f"{', '.join(entry.baselines)}; solved when {entry.describe_criterion()}"
            )
        missing = [name for name in registry.task_names() if name not in suite]
        if missing:
            print(f"tasks without an entry: {', '.join(missing)}")
        return 0
    selection = _selection(args, suite)
    seeds = args.seed_list or list(range(args.seeds or DEFAULT_SEEDS))
    arguments.at_least(min(seeds), 0, "--seed-list")
    arguments.at_least(args.episodes, 1, "--episodes")
    arguments.at_least(args.eval_episodes, 1, "--eval-episodes")
    arguments.at_least(args.timesteps, 1, "--timesteps")
    settings = Settings(
        out=args.out,
        episodes=args.episodes,
        heldout_seed=args.heldout_seed,
        eval_episodes=args.eval_episodes,
        timesteps=args.timesteps,
        overrides=parse_key_values(args.hp, "--hp"),
        device=check_device(args.device, here=args.ray is None),
        num_threads=args.num_threads,
        progress=not args.no_progress,
        command=portable_command(current_command(), args.out),
    )
    plan = []
    for entry, learners in selection:
        version = _version(entry.task, args.version)
        for name in learners:
            learner = make_learner(name)
            learner.recipe(entry.task, version, settings.overrides)  # a missing recipe: now
            plan += [(entry, learner, version, seed) for seed in seeds]
    done = [
        finished(entry, learner, version, seed, settings, args.restart) is not None
        for entry, learner, version, seed in plan
    ]
    cluster = None
    if args.ray is not None:
        from khepera_gym.learning.benchmark.cluster import start

        cluster = start(args.ray or None, settings)  # a bad address fails here, before any work
    if any(done):
        print(_skipped(args.out, [run for run, skip in zip(plan, done, strict=True) if skip]))
    baselines: dict[tuple[str, int], Any] = {}
    bar = tqdm(total=len(plan), desc="benchmark", unit="run", disable=args.no_progress)
    gone_through: set[int] = set()  # runs of the plan whose file is on disk (or was there)
    failed: list[str] = []  # runs lost on the cluster, and why

    def baselines_of(entry: Any, version: int) -> Any:
        key = (entry.task, version)
        if key not in baselines:
            bar.set_postfix_str(f"{entry.task} baselines")
            baselines[key] = run_baselines(entry, version, settings, args.restart)
        return baselines[key]

    def show(index: int, record: dict[str, Any]) -> None:
        entry, learner, _, seed = plan[index]
        gone_through.add(index)
        bar.update(1)
        line = _line(entry, learner.name, seed, record)
        skip = done[index]
        bar.write(line + (" (done before: read from its file, not run again)" if skip else ""))

    try:
        with bar:
            if cluster is None:
                for index, (entry, learner, version, seed) in enumerate(plan):
                    base = baselines_of(entry, version)
                    bar.set_postfix_str(f"{entry.task} {learner.name} seed {seed}")
                    show(
                        index,
                        run_one(entry, learner, version, seed, settings, base, args.restart),
                    )
            else:
                with cluster:
                    for index, (entry, learner, version, seed) in enumerate(plan):
                        base = baselines_of(entry, version)
                        if done[index]:
                            show(index, run_one(entry, learner, version, seed, settings, base))
                        else:
                            cluster.submit(index, plan[index], base)
                    bar.set_postfix_str(f"{cluster.running} runs on Ray")
                    for index, record, why in cluster.ended():
                        if record is None:
                            entry, learner, _, seed = plan[index]
                            failed.append(f"{entry.task} {learner.name} seed {seed} ({why})")
                            bar.write(f"{failed[-1]}: failed on the cluster, nothing written")
                            bar.update(1)
                        else:
                            show(index, record)
                        bar.set_postfix_str(f"{cluster.running} runs on Ray")
        _write_summary(args.out, [e.task for e, _ in selection], settings.command)
    except KeyboardInterrupt:
        # Ctrl-C: what is done is on disk (each file is written whole as its run ends), and
        # so are the runs further on that were done before.
        print(
            f"khepera-gym benchmark: interrupted with "
            f"{len(gone_through | {i for i, skip in enumerate(done) if skip})} of {len(plan)} "
            f"runs done in {args.out}; the same command resumes (the runs done there are "
            "skipped)",
            file=sys.stderr,
        )
        raise SystemExit(INTERRUPTED) from None
    if failed:
        raise SystemExit(
            f"khepera-gym benchmark: {len(failed)} of {len(plan)} runs failed on the cluster "
            f"and are not in {args.out}: {'; '.join(failed)}; the same command runs them again"
        )
    return 0


def _skipped(out: Path, runs: Sequence[tuple[Any, Any, int, int]]) -> str:
    """The line saying which runs a resumed benchmark finds done (``nav ppo v2 seeds 0, 1``)."""
    seeds: dict[str, list[int]] = {}
    for entry, learner, version, seed in runs:
        seeds.setdefault(f"{entry.task} {learner.name} v{version}", []).append(seed)
    listed = "; ".join(
        f"{what} seed{'s' if len(s) > 1 else ''} {', '.join(map(str, s))}"
        for what, s in seeds.items()
    )
    return (
        f"resuming in {out}: {len(runs)} run{'s' if len(runs) > 1 else ''} done already, "
        f"not run again: {listed}"
    )


def _value(value: float | None) -> str:
    """A held-out mean on a run's line: a number, or that no episode gave one (never nan)."""
    number = math.nan if value is None else float(value)  # JSON: NaN is None, inf "inf"
    if math.isnan(number):
        return "none (no held-out episode gave a value)"
    return f"{number:.4g}"


def _line(entry: Any, learner: str, seed: int, record: dict[str, Any]) -> str:
    values = ", ".join(
        f"{c.metric} {_value(record['final'][c.metric]['value'])}" for c in entry.criterion
    )
    reached = record["reached"]
    when = "never" if reached is None else f"at {reached['steps']:,} steps"
    return (
        f"{entry.task} {learner} seed {seed}: {values} (held-out, mean actions); solved "
        f"{'yes' if record['solved'] else 'no'}; criterion first met {when}; trained "
        f"{record['train_seconds']:.0f} s"
    )


def _write_summary(out: Path, tasks: Sequence[str], command: str | None) -> None:
    baselines, runs = load_records(out)
    tables = []
    for task in tasks:
        table = task_rows(task, baselines, runs)
        for row in table["learners"]:
            row["reproduce"] = reproduce(task, row)
        tables.append(table)
        print("\n" + markdown(table))
        for row in table["learners"]:
            print(f"  reproduce {row['learner']}: {row['reproduce']}")
    summary = {"meta": provenance(command), "tables": tables}
    (out / "benchmark.json").write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    print(f"\nwrote {out / 'benchmark.json'}")


__all__ = [
    "DEFAULT_OUT",
    "INTERRUPTED",
    "add_arguments",
    "check_device",
    "reproduce",
    "run_from_args",
]
