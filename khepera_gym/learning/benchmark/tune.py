"""``khepera-gym tune``: a recipe search anyone can rerun. It searches some keys of a learner's
recipe for a task with Ray Tune's asynchronous successive halving (ASHA: a trial whose
evaluations fall behind the others' at the same number of steps is stopped early), on this
machine or on a Ray cluster (``--ray ADDRESS``), and writes the best table and every trial to a
results file.

Ray Tune rather than Optuna: Ray is already the ``rllib`` extra, so the search needs no new
dependency, and the same cluster that runs the benchmark's runs runs its trials; ASHA prunes on
the evaluations the learners already make while they train. (Optuna would need a storage that
every machine shares to search across machines.)

A trial trains the benchmark's learner (:mod:`khepera_gym.learning.benchmark.learners`) with the
recipe's table and the trial's values of the searched keys, and is scored by its evaluations
while training: the mean of the task's metric (:mod:`khepera_gym.learning.benchmark.aggregate`)
on the training's evaluation episodes (seeds 10000 and up). It never plays the held-out episodes
(seeds 0-199) that the benchmark's results are measured on, so a searched recipe is judged on
episodes it was not chosen on.

Search space: ``--space KEY=LOW:HIGH`` (uniform), ``KEY=LOW:HIGH:log`` (log-uniform),
``KEY=LOW:HIGH:int`` (integers) or ``KEY=A,B,C`` (choices, TOML values). The configurations are
drawn from a generator seeded with ``--seed``.
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from khepera_gym import registry
from khepera_gym.config import parse_key_values
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.learning.benchmark.aggregate import TaskMetric, task_metric
from khepera_gym.learning.benchmark.jobs import Job, Means
from khepera_gym.learning.benchmark.learners import LEARNERS, learner
from khepera_gym.learning.benchmark.suite import load_suite
from khepera_gym.tooling import arguments
from khepera_gym.tooling.provenance import provenance

#: The results file's format.
FORMAT = 1
#: What the scheduler ranks trials by (the task's metric, signed so that higher is better).
SCORE = "score"


def parse_space(items: Sequence[str]) -> dict[str, Any]:
    """``--space`` items as Ray Tune search domains.

    Raises:
        ConfigError: An item that is not ``KEY=LOW:HIGH[:log|:int]`` or ``KEY=A,B,...``, or a
            key given twice.
    """
    from ray import tune

    space: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key or not text:
            raise ConfigError(f"--space {item!r}: write KEY=LOW:HIGH[:log|:int] or KEY=A,B,C")
        if key in space:
            raise ConfigError(f"--space: {key!r} given twice")
        if ":" in text:
            parts = text.split(":")
            kind = parts[2] if len(parts) == 3 else "uniform"
            if len(parts) not in (2, 3) or kind not in ("uniform", "log", "int"):
                raise ConfigError(f"--space {item!r}: write KEY=LOW:HIGH[:log|:int]")
            try:
                low, high = float(parts[0]), float(parts[1])
            except ValueError as error:
                raise ConfigError(f"--space {item!r}: {error}") from error
            if not low < high or (kind == "log" and low <= 0):
                raise ConfigError(f"--space {item!r}: needs 0 < LOW < HIGH (log) or LOW < HIGH")
            if kind == "int":
                space[key] = tune.randint(int(low), int(high) + 1)
            elif kind == "log":
                space[key] = tune.loguniform(low, high)
            else:
                space[key] = tune.uniform(low, high)
        else:
            choices = [parse_key_values([f"v={v}"], "--space")["v"] for v in text.split(",")]
            space[key] = tune.choice(choices)
    if not space:
        raise ConfigError("--space: give at least one KEY=... to search")
    return space


def check_keys(name: str, task: str, version: int, keys: Sequence[str]) -> None:
    """The searched keys exist in the learner's recipe for the task.

    Raises:
        ConfigError: A key that is not in the recipe (with the nearest one).
    """
    recipe = learner(name).recipe(task, version, {})
    for key in keys:
        if key not in recipe:
            near = difflib.get_close_matches(key, list(recipe), n=1)
            hint = f"did you mean {near[0]!r}? " if near else ""
            raise ConfigError(
                f"--space {key!r} is not a key of {name}'s recipe for {task}-v{version}; {hint}"
                f"its keys: {', '.join(sorted(recipe))}"
            )


def score(metric: TaskMetric, means: Mapping[str, float]) -> float:
    """An evaluation's score: the task's metric, negated where lower is better (NaN → -inf)."""
    value = float(means.get(metric.metric, math.nan))
    if math.isnan(value):
        return -math.inf
    return value if metric.higher_is_better else -value


def _rank(row: Mapping[str, Any]) -> tuple[float, float]:
    scores = [point[SCORE] for point in row["evaluations"]]
    return scores[-1], sum(scores) / len(scores)


def _trial(config: Mapping[str, Any], settings: Mapping[str, Any]) -> None:
    """One trial (runs on a Ray worker): trains with the config's keys, reporting every
    evaluation; the scheduler may stop it after any."""
    from ray import tune

    metric = TaskMetric(**settings["metric"])

    def on_evaluation(steps: int, seconds: float, means: Means) -> None:
        tune.report(
            {
                SCORE: score(metric, means),
                "steps": steps,
                "train_seconds": seconds,
                **{f"mean/{k}": v for k, v in means.items() if math.isfinite(v)},
            }
        )

    with tempfile.TemporaryDirectory() as folder:
        job = Job(
            task=settings["task"],
            version=settings["version"],
            seed=settings["seed"],
            out_dir=Path(folder),
            timesteps=settings["timesteps"],
            overrides={**settings["fixed"], **config},
            eval_episodes=settings["eval_episodes"],
            num_threads=1,
            on_evaluation=on_evaluation,
        )
        learner(settings["learner"]).train(job)


def tune_recipe(
    task: str,
    learner_name: str,
    space_items: Sequence[str],
    trials: int,
    timesteps: int | None,
    version: int | None = None,
    seed: int = 0,
    eval_episodes: int = 50,
    address: str | None = None,
    out: Path | None = None,
    grace_evaluations: int = 3,
    fixed: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Searches ``space_items`` of ``learner_name``'s recipe for ``task``; returns the results
    document (and writes it to ``out`` if given).

    Raises:
        ConfigError: An unknown task or learner, a bad space, or a key not in the recipe, before
            any work.
    """
    suite = load_suite()
    if task not in suite:
        raise ConfigError(f"unknown task {task!r}; known: {', '.join(suite)}")
    if learner_name not in LEARNERS:
        raise ConfigError(f"unknown learner {learner_name!r}; known: {', '.join(LEARNERS)}")
    version = registry.latest_version(task) if version is None else version
    if version not in registry.task_versions(task):
        raise ConfigError(f"{task} has no behaviour version {version}")
    arguments.at_least(trials, 1, "--trials")
    space = parse_space(space_items)
    fixed = dict(fixed or {})
    check_keys(learner_name, task, version, [*space, *fixed])
    metric = task_metric(suite[task])

    import ray
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler
    from ray.tune.search.basic_variant import BasicVariantGenerator

    settings = {
        "task": task,
        "version": version,
        "learner": learner_name,
        "seed": seed,
        "timesteps": timesteps,
        "eval_episodes": eval_episodes,
        "fixed": fixed,
        "metric": {
            "task": task,
            "metric": metric.metric,
            "higher_is_better": metric.higher_is_better,
        },
    }
    started = not ray.is_initialized()
    if started:
        # Without an address, a Ray of its own: ray.init() would join any cluster it finds.
        ray.init(address=address or "local", include_dashboard=False, log_to_driver=False)
    try:
        with tempfile.TemporaryDirectory() as storage:
            tuner = tune.Tuner(
                tune.with_resources(tune.with_parameters(_trial, settings=settings), {"cpu": 1}),
                param_space=space,
                tune_config=tune.TuneConfig(
                    metric=SCORE,
                    mode="max",
                    num_samples=trials,
                    scheduler=ASHAScheduler(
                        time_attr="training_iteration", grace_period=grace_evaluations
                    ),
                    search_alg=BasicVariantGenerator(random_state=seed),
                ),
                run_config=tune.RunConfig(storage_path=storage, name="tune", verbose=0),
            )
            grid = tuner.fit()
            rows = []
            for result in grid:
                history = result.metrics_dataframe
                points = [] if history is None else history.to_dict("records")
                rows.append(
                    {
                        "config": dict(result.config or {}),
                        "error": None if result.error is None else str(result.error),
                        "evaluations": [
                            {
                                "steps": int(p["steps"]),
                                "train_seconds": float(p["train_seconds"]),
                                SCORE: float(p[SCORE]),
                            }
                            for p in points
                            if SCORE in p
                        ],
                    }
                )
    finally:
        if started:
            ray.shutdown()
    finished = [r for r in rows if r["evaluations"]]
    if not finished:
        raise KheperaError("no trial of the search reported an evaluation")
    # The best last evaluation; among equals, the best mean over the evaluations (the one that
    # got there sooner: the area under its learning curve).
    best = max(finished, key=_rank)
    table = learner(learner_name).recipe(task, version, {**fixed, **best["config"]})
    document = {
        "format": FORMAT,
        "kind": "tune",
        "meta": provenance(),
        "task": task,
        "version": version,
        "learner": learner_name,
        "metric": metric.describe(),
        "evaluation_seeds": "10000 and up (the training's own; never the held-out 0-199)",
        "space": list(space_items),
        "fixed": fixed,
        "timesteps": timesteps,
        "command": provenance().get("command"),
        "trials": rows,
        "best": {"config": best["config"], "score": best["evaluations"][-1][SCORE]},
        "best_table": table,
        "shipped_table": learner(learner_name).recipe(task, version, {}),
    }
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(document, indent=1, default=str) + "\n", encoding="utf-8")
    return document


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``khepera-gym tune``."""
    parser.add_argument("--task", required=True, help="a task of the benchmark's suite")
    parser.add_argument("--learner", required=True, help=f"one of {', '.join(LEARNERS)}")
    parser.add_argument(
        "--space",
        nargs="+",
        required=True,
        metavar="KEY=RANGE",
        help="recipe keys to search: KEY=LOW:HIGH[:log|:int] or KEY=A,B,C",
    )
    parser.add_argument(
        "--hp",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a recipe key every trial takes (repeatable), under the searched ones",
    )
    parser.add_argument("--trials", type=int, default=8, help="configurations tried (8)")
    parser.add_argument("--timesteps", type=int, default=None, help="steps a trial (the recipe's)")
    parser.add_argument("--version", type=int, default=None, help="behaviour version (latest)")
    parser.add_argument("--seed", type=int, default=0, help="training seed and the search's (0)")
    parser.add_argument("--eval-episodes", type=int, default=50, help="episodes an evaluation")
    parser.add_argument("--ray", metavar="ADDRESS", default=None, help="a Ray cluster's address")
    parser.add_argument("--out", type=Path, required=True, help="the results file (JSON)")


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym tune``; prints the best configuration."""
    try:
        document = tune_recipe(
            args.task,
            args.learner,
            args.space,
            args.trials,
            args.timesteps,
            args.version,
            args.seed,
            args.eval_episodes,
            args.ray,
            args.out,
            fixed=parse_key_values(args.hp, "--hp"),
        )
    except (KheperaError, ValueError, OSError) as error:
        raise SystemExit(f"khepera-gym tune: {arguments.one_line(error)}") from error
    best = document["best"]
    print(f"best of {len(document['trials'])} trials: {best['config']} (score {best[SCORE]:.4g})")
    print(f"saved {args.out}")
    return 0


__all__ = [
    "FORMAT",
    "SCORE",
    "add_arguments",
    "parse_space",
    "run_from_args",
    "score",
    "tune_recipe",
]
