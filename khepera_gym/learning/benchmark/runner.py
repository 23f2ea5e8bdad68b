"""Running the benchmark: the baselines and every (task, learner, seed) run, each written to a
results file as it ends, so an interrupted benchmark resumes where it stopped.

Held-out evaluation: ``episodes`` episodes seeded ``heldout_seed + i`` (0..199 by default: the
seeds ``khepera-gym compare`` uses; training evaluates on 10000 + i), one per world, the
learned policy on its mean actions and sampling them, the baselines on the same episodes. Each
statistic is reported as its mean with a 95 % bootstrap interval over the episodes (success:
Wilson), and the task's criterion is judged on those means.

Files, under the output folder: ``baselines/<task>-v<N>.json`` and
``runs/<task>-v<N>_<learner>_seed<S>.json``, each with its provenance (date, commit, machine,
command); a run's model files (``models/<stem>/``) are named relative to the folder, and the
command without the machine's absolute paths, so the folder reads the same on another machine.
A run whose file exists is not run again when the file comes from the same commit, version,
held-out episodes and recipe; a file from another commit is refused (the message says to use
another folder or ``--restart``), so results of different code are never mixed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark.jobs import Job, Means, gym_id, module_of, shares_rows
from khepera_gym.learning.benchmark.marl_eval import write_marl_eval
from khepera_gym.learning.benchmark.suite import TaskEntry
from khepera_gym.tooling.provenance import provenance
from khepera_gym.tooling.stats import bootstrap_interval, json_number, wilson_interval

#: Results file format, in every file (a reader refuses another).
FORMAT = 1
#: Torch's intra-op threads during a run, its training and its held-out evaluation alike. One
#: count everywhere, because a float sum's order follows the thread count: with it, a run gives
#: the same bits on any machine and in a Ray worker (which starts with ``OMP_NUM_THREADS=1``);
#: and the networks are small, so more threads would only synchronise.
TORCH_THREADS = 1


@dataclasses.dataclass(frozen=True)
class Settings:
    """What every run of one benchmark shares."""

    out: Path
    episodes: int = 200
    heldout_seed: int = 0
    eval_episodes: int = 50
    timesteps: int | None = None
    overrides: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    device: str = "cpu"
    num_threads: int | None = None
    #: Whether the learners may show their own progress (``--no-progress``: they print nothing).
    progress: bool = True
    #: The command the results files record (None: the one running, as typed); the benchmark
    #: gives it without the machine's absolute paths.
    command: str | None = None


def baseline_env_name(task: str, version: int) -> str:
    """The env the baselines play the held-out episodes on: the task's Gymnasium id (rows are
    worlds, as ``khepera-gym compare`` plays them), else its PettingZoo module (rows are agents,
    each driven by the baseline)."""
    env_id = gym_id(task, version)
    if env_id is not None:
        return env_id
    module = module_of(task, version)
    if module is None or not shares_rows(task):
        raise ConfigError(f"{task!r} has neither a Gymnasium id nor agents sharing one policy")
    return module


def summarize(stats: Mapping[str, Any]) -> dict[str, Any]:
    """Each statistic's mean over the episodes with its 95 % interval (JSON-ready)."""
    summary = {}
    for name, values in stats.items():
        values = np.asarray(values, dtype=float)
        if name == "success":
            estimate = wilson_interval(int(values.sum()), len(values))
        else:
            finite = values[np.isfinite(values)]
            estimate = bootstrap_interval(finite, "mean")
        summary[name] = estimate.to_json()
    return summary


def means(summary: Mapping[str, Any]) -> Means:
    """The means of a :func:`summarize` record (NaN where there was no data)."""
    return {name: _number(record["value"]) for name, record in summary.items()}


def _number(value: Any) -> float:
    if value is None:
        return math.nan
    return float(value)


def play(policy: Any, env_name: str, settings: Settings, sampled: bool = False) -> Any:
    """One held-out episode per world of ``env_name`` (a Gymnasium id: rows are worlds; a
    PettingZoo module: rows are agents) with ``policy`` on its rows; the statistics per
    episode."""
    from khepera_gym.learning.sb3 import make_vec_env
    from khepera_gym.learning.sb3.evaluate import first_episode_stats

    env = make_vec_env(env_name, settings.episodes, num_threads=settings.num_threads)
    try:
        return first_episode_stats(policy, env, settings.heldout_seed, deterministic=not sampled)
    finally:
        env.close()


#: The random policy's row, played beside every task's baselines: the 0 of the normalised
#: scores (:mod:`khepera_gym.learning.benchmark.aggregate`), uniform actions in [-1, 1].
RANDOM = "random"
#: Seed of the random policy's generator.
RANDOM_SEED = 0


def baseline_names(entry: TaskEntry) -> tuple[str, ...]:
    """The rows of a task's baselines file: its suite's baselines, then :data:`RANDOM`."""
    return tuple(dict.fromkeys((*entry.baselines, RANDOM)))


def baseline_policy(name: str, env_name: str) -> Any:
    """A baseline acting on the rows of ``env_name`` (one world, or one agent's block), or the
    random policy (:data:`RANDOM`)."""
    from khepera_gym.learning.benchmark.suite import all_baselines
    from khepera_gym.learning.policies import VARIANTS, RandomPolicy
    from khepera_gym.learning.sb3 import make_vec_env

    if name == RANDOM:
        env = make_vec_env(env_name, 1, num_threads=1)
        try:
            return RandomPolicy(env.action_space.shape[-1], RANDOM_SEED)
        finally:
            env.close()

    controller, params = VARIANTS.get(name, (name, {}))
    cls = all_baselines()[controller]
    env = make_vec_env(env_name, 1, num_threads=1)
    try:
        if "for_env" in vars(cls):  # it reads its settings from the scenario (a formation)
            return cls.for_env(env, **params)
        layout = getattr(env, "agent_layout", None) or env
        return cls(layout=layout, **params)
    finally:
        env.close()


def _fingerprint(record: Mapping[str, Any]) -> str:
    text = json.dumps(record, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def write_record(path: Path, record: dict[str, Any]) -> None:
    """Writes a results file whole (a run interrupted while writing leaves no half file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(record, indent=1, default=json_number) + "\n", encoding="utf-8")
    tmp.replace(path)


def load_records(out: Path) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The baseline records and run records of a benchmark folder."""

    def read(folder: str) -> list[dict[str, Any]]:
        records = []
        for path in sorted((out / folder).glob("*.json")):
            record = json.loads(path.read_text(encoding="utf-8"))
            if record.get("format") == FORMAT:
                records.append(record)
        return records

    return read("baselines"), read("runs")


def _reusable(path: Path, key: Mapping[str, Any], restart: bool) -> dict[str, Any] | None:
    """The results file at ``path`` if it holds the same work as ``key`` from this commit."""
    if restart or not path.is_file():
        return None
    record = json.loads(path.read_text(encoding="utf-8"))
    if record.get("format") != FORMAT:
        raise ConfigError(f"{path}: not a results file of this benchmark (format)")
    here = provenance().get("commit")
    there = record.get("meta", {}).get("commit")
    if here != there:
        raise ConfigError(
            f"{path} comes from commit {(there or {}).get('id', '?')[:12]}"
            f"{' (dirty)' if (there or {}).get('dirty') else ''}, this is "
            f"{(here or {}).get('id', '?')[:12]}{' (dirty)' if (here or {}).get('dirty') else ''}"
            ": results of different code are not mixed; use another --out, or --restart to "
            "discard them"
        )
    if record.get("key") != dict(key):
        return None  # other work (recipe, episodes, version): done again, the file replaced
    return record


def run_baselines(entry: TaskEntry, version: int, settings: Settings, restart: bool) -> dict:
    """The baselines of a task on the held-out episodes (from their file when done already)."""
    key = {
        "task": entry.task,
        "version": version,
        "baselines": list(baseline_names(entry)),
        "episodes": settings.episodes,
        "heldout_seed": settings.heldout_seed,
    }
    path = settings.out / "baselines" / f"{entry.task}-v{version}.json"
    done = _reusable(path, key, restart)
    if done is not None:
        return done
    rows = baseline_env_name(entry.task, version)
    summaries = {
        name: summarize(play(baseline_policy(name, rows), rows, settings))
        for name in baseline_names(entry)
    }
    meta = provenance(settings.command)
    record = {"format": FORMAT, "key": key, "meta": meta, "summaries": summaries}
    write_record(path, record)
    return record


def judge(entry: TaskEntry, values: Mapping[str, float], baselines: Mapping[str, Any]) -> bool:
    """Whether means ``values`` meet the task's criterion."""
    base = {name: means(summary) for name, summary in baselines["summaries"].items()}
    return all(c.holds(values.get(c.metric, math.nan), c.threshold(base)) for c in entry.criterion)


@contextlib.contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Within the block, torch computes on ``count`` threads (the former count restored)."""
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def run_path(settings: Settings, task: str, version: int, learner: str, seed: int) -> Path:
    """The results file of one (task, learner, seed)."""
    return settings.out / "runs" / f"{_stem(task, version, learner, seed)}.json"


def _stem(task: str, version: int, learner: str, seed: int) -> str:
    return f"{task}-v{version}_{learner}_seed{seed}"


def _run_key(
    entry: TaskEntry, learner: Any, version: int, seed: int, settings: Settings
) -> dict[str, Any]:
    """What a run's file must hold for the run to be done already: its work but for the code."""
    name = learner.env_name(entry.task, version)
    recipe = learner.recipe(entry.task, version, settings.overrides)
    if settings.timesteps is not None:
        recipe["n_timesteps"] = settings.timesteps
    return {
        "task": entry.task,
        "version": version,
        "learner": learner.name,
        "env": name,
        "seed": seed,
        "recipe": _fingerprint(recipe),
        "episodes": settings.episodes,
        "heldout_seed": settings.heldout_seed,
        "criterion": [c.to_json() for c in entry.criterion],
    }


def finished(
    entry: TaskEntry, learner: Any, version: int, seed: int, settings: Settings, restart: bool
) -> dict[str, Any] | None:
    """The record of one (task, learner, seed) if its file holds this very work from this code
    (:func:`run_one` then returns it without training), else None.

    Raises:
        ConfigError: As :func:`run_one`.
    """
    key = _run_key(entry, learner, version, seed, settings)
    return _reusable(run_path(settings, entry.task, version, learner.name, seed), key, restart)


def run_one(
    entry: TaskEntry,
    learner: Any,
    version: int,
    seed: int,
    settings: Settings,
    baselines: Mapping[str, Any],
    restart: bool = False,
    report: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Trains and evaluates one (task, learner, seed); returns its record (written to its file).

    Raises:
        ConfigError: The learner does not apply to the task, a recipe is missing or wrong, or
            the run's file comes from other code.
    """
    name = learner.env_name(entry.task, version)
    key = _run_key(entry, learner, version, seed, settings)
    stem = _stem(entry.task, version, learner.name, seed)
    path = run_path(settings, entry.task, version, learner.name, seed)
    done = _reusable(path, key, restart)
    if done is not None:
        return done
    job = Job(
        task=entry.task,
        version=version,
        seed=seed,
        out_dir=settings.out / "models" / stem,
        timesteps=settings.timesteps,
        overrides=dict(settings.overrides),
        eval_episodes=settings.eval_episodes,
        device=settings.device,
        num_threads=settings.num_threads,
        progress=settings.progress,
    )
    with torch_threads(TORCH_THREADS):
        trained = learner.train(job, report)
        final = summarize(play(trained.policy, name, settings))
        sampled = None
        if trained.sample is not None:
            policy = trained.sample(settings.heldout_seed)
            sampled = summarize(play(policy, name, settings, sampled=True))
    base = {n: means(s) for n, s in baselines["summaries"].items()}
    thresholds = [c.threshold(base) for c in entry.criterion]
    reached = next(
        (
            {"steps": steps, "train_seconds": seconds}
            for steps, seconds, values in trained.history
            if all(
                c.holds(values.get(c.metric, math.nan), t)
                for c, t in zip(entry.criterion, thresholds, strict=True)
            )
        ),
        None,
    )
    record = {
        "format": FORMAT,
        "key": key,
        "meta": provenance(settings.command),
        "recipe": trained.recipe,
        # What the command changed from the recipe, so its row prints the command again.
        "settings": {
            "timesteps": settings.timesteps,
            "overrides": dict(settings.overrides),
            "eval_episodes": settings.eval_episodes,
        },
        "timesteps": trained.timesteps,
        "train_seconds": trained.train_seconds,
        "eval_seconds": trained.eval_seconds,
        "steps_per_second": trained.timesteps / max(trained.train_seconds, 1e-9),
        "thresholds": thresholds,
        "history": [
            {"steps": steps, "train_seconds": seconds, "means": values}
            for steps, seconds, values in trained.history
        ],
        "reached": reached,
        "final": final,
        "final_sampled": sampled,
        "solved": judge(entry, means(final), baselines),
        "solved_sampled": None if sampled is None else judge(entry, means(sampled), baselines),
        # Relative to the results folder, which can move to another machine (docs/results/).
        "files": {
            name: Path(os.path.relpath(path, settings.out)).as_posix()
            for name, path in trained.files.items()
        },
    }
    write_record(path, record)
    # The folder's runs in marl-eval's format as well, for the field's plotting tools.
    write_marl_eval(settings.out, load_records(settings.out)[1])
    return record


__all__ = [
    "FORMAT",
    "TORCH_THREADS",
    "Settings",
    "baseline_env_name",
    "baseline_policy",
    "finished",
    "judge",
    "load_records",
    "means",
    "play",
    "run_baselines",
    "run_one",
    "run_path",
    "summarize",
    "torch_threads",
    "write_record",
]
