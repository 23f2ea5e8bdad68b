"""The benchmark's reporting to the field's standard (issue 52): rliable's estimators under our
stratified bootstrap, normalised scores, probability of improvement, performance profiles,
learning curves, and the runs in marl-eval's JSON format checked against marl-eval's documented
structure."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rliable", reason="the report extra (make test installs it)")

from khepera_gym.learning.benchmark import aggregate
from khepera_gym.learning.benchmark.marl_eval import (
    MARL_EVAL_FILE,
    marl_eval_document,
)
from khepera_gym.learning.benchmark.suite import load_suite
from khepera_gym.learning.benchmark.tables import load_records

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results" / "benchmark"


def test_iqm_is_the_mean_of_the_middle_half_and_the_mean_is_the_mean() -> None:
    # 8 runs: the IQM averages the 4 in the middle (Agarwal et al. 2021, eq. of IQM).
    runs = np.array([9.0, 0.0, 3.0, 5.0, 1.0, 100.0, 4.0, 2.0])
    assert aggregate.iqm([runs]) == pytest.approx(np.mean([2.0, 3.0, 4.0, 5.0]))
    assert aggregate.mean([runs]) == pytest.approx(runs.mean())
    # Strata are pooled: two tasks of 4 runs are the same 8 runs.
    assert aggregate.iqm([runs[:4], runs[4:]]) == pytest.approx(aggregate.iqm([runs]))


def test_the_stratified_bootstrap_covers_the_true_mean_as_a_95_percent_interval_should() -> None:
    # The percentile bootstrap of a mean of 10 normal samples covers the true mean in about 91 %
    # of samples (it is known to undercover at small n); 200 samples put the share within about
    # +-0.04 of that with 95 % probability: 0.85 is a bound it misses only when broken.
    rng = np.random.default_rng(1)
    covered = 0
    for trial in range(200):
        sample = rng.normal(3.0, 2.0, 10)
        _, low, high = aggregate.stratified_bootstrap([sample], aggregate.mean, 500, seed=trial)
        covered += low <= 3.0 <= high
    assert covered / 200 >= 0.85
    # Each stratum is resampled on its own, keeping its size.
    sizes = aggregate.stratified_bootstrap(
        [np.zeros(3), np.ones(7)], lambda s: float(len(s[0]) * 10 + len(s[1])), 50
    )
    assert sizes == (37.0, 37.0, 37.0)
    # Seeded: the interval reproduces.
    a = aggregate.stratified_bootstrap([np.arange(10.0)], aggregate.iqm)
    assert a == aggregate.stratified_bootstrap([np.arange(10.0)], aggregate.iqm)


def test_normalised_scores_put_random_at_0_and_the_best_baseline_at_1() -> None:
    success = aggregate.TaskMetric("nav", "success", higher_is_better=True)
    assert aggregate.normalise(0.01, 0.01, 1.0, success) == 0.0
    assert aggregate.normalise(1.0, 0.01, 1.0, success) == 1.0
    assert aggregate.normalise(0.505, 0.01, 1.0, success) == pytest.approx(0.5)
    error = aggregate.TaskMetric("track", "track_error_rms", higher_is_better=False)
    assert error.log_scale
    random, best = 0.5, 0.0004  # m: Track's random policy and Kanayama
    assert aggregate.normalise(random, random, best, error) == 0.0
    assert aggregate.normalise(best, random, best, error) == pytest.approx(1.0)
    # The geometric middle scores 0.5; a learned 21 mm is far from Kanayama's 0.4 mm, not 0.97
    # (its linear score).
    assert aggregate.normalise(math.sqrt(random * best), random, best, error) == pytest.approx(0.5)
    learned = aggregate.normalise(0.021, random, best, error)
    assert learned == pytest.approx(math.log(0.5 / 0.021) / math.log(0.5 / 0.0004))
    assert learned < 0.5 < (random - 0.021) / (random - best)


@pytest.mark.parametrize("task", list(load_suite()))
def test_the_task_metric_is_the_criterions_error_else_its_first(task: str) -> None:
    entry = load_suite()[task]
    metric = aggregate.task_metric(entry)
    errors = [c for c in entry.criterion if "error" in c.metric]
    chosen = errors[0] if errors else entry.criterion[0]
    assert metric.metric == chosen.metric
    # Lower is better exactly where the criterion bounds the metric from above.
    assert metric.higher_is_better == (chosen.bound == "at_least")
    assert metric.log_scale == (not metric.higher_is_better)


def test_probability_of_improvement() -> None:
    low, high = np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0])
    assert aggregate.probability_of_improvement(high, low) == 1.0
    assert aggregate.probability_of_improvement(low, high) == 0.0
    assert aggregate.probability_of_improvement(low, low) == pytest.approx(0.5)  # ties: half
    # Lower is better: the lower runs improve.
    assert aggregate.probability_of_improvement(low, high, higher_is_better=False) == 1.0
    value, a, b = aggregate.improvement_interval(high, low)
    assert value == a == b == 1.0


def test_performance_profiles_are_shares_of_runs_above_each_threshold() -> None:
    taus = np.array([0.0, 0.5, 1.0])
    profile = aggregate.performance_profile([np.array([0.2, 0.7, 1.2, 1.4])], taus)
    assert profile.tolist() == [1.0, 0.75, 0.5]
    # Each task weighs the same, whatever its number of runs.
    two = aggregate.performance_profile([np.array([2.0]), np.array([0.0, 0.0, 0.0])], taus)
    assert two.tolist() == [0.5, 0.5, 0.5]


def test_curves_hold_each_seeds_evaluations() -> None:
    def run(seed: int, values: list[float]) -> dict[str, Any]:
        history = [
            {"steps": 100 * (i + 1), "train_seconds": float(i + seed), "means": {"success": v}}
            for i, v in enumerate(values)
        ]
        return {"key": {"task": "nav", "learner": "ppo", "seed": seed}, "history": history}

    metric = aggregate.TaskMetric("nav", "success", True)
    (curve,) = aggregate.curves([run(0, [0.1, 0.5]), run(1, [0.2, 0.6, 0.9])], metric)
    assert curve.learner == "ppo" and curve.values.shape == (2, 3)
    assert np.isnan(curve.values[0, 2]) and curve.values[1].tolist() == [0.2, 0.6, 0.9]
    assert curve.steps[1].tolist() == [100, 200, 300]


# --- marl-eval's format -----------------------------------------------------------------------


def marl_eval_problems(document: Any) -> list[str]:
    """What breaks marl-eval's documented structure (its README, "Data Structure for Raw
    Experiment data"): environment → task → algorithm → run → ``step_<k>`` entries (each with an
    int ``step_count`` and metric lists) and ``absolute_metrics`` (metric lists); each metric a
    non-empty list of numbers."""
    problems = []

    def metrics(where: str, values: Any, skip: str | None = None) -> None:
        if not isinstance(values, dict):
            problems.append(f"{where}: not an object")
            return
        for name, value in values.items():
            if name == skip:
                continue
            ok = (
                isinstance(value, list)
                and value
                and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                    for v in value
                )
            )
            if not ok:
                problems.append(f"{where}.{name}: not a non-empty list of numbers")

    if not isinstance(document, dict) or not document:
        return ["not an object of environments"]
    for env, tasks in document.items():
        for task, algorithms in tasks.items():
            for algorithm, runs in algorithms.items():
                if not runs:
                    problems.append(f"{env}.{task}.{algorithm}: no run")
                for run, steps in runs.items():
                    where = f"{env}.{task}.{algorithm}.{run}"
                    if "absolute_metrics" not in steps:
                        problems.append(f"{where}: no absolute_metrics")
                    for step, values in steps.items():
                        if step == "absolute_metrics":
                            metrics(f"{where}.{step}", values)
                            continue
                        if not step.startswith("step_") or not step[5:].isdigit():
                            problems.append(f"{where}.{step}: not step_<k>")
                            continue
                        count = values.get("step_count") if isinstance(values, dict) else None
                        if not isinstance(count, int) or isinstance(count, bool):
                            problems.append(f"{where}.{step}: no int step_count")
                        metrics(f"{where}.{step}", values, skip="step_count")
    return problems


def test_the_marl_eval_file_follows_marl_evals_structure_and_the_runs() -> None:
    _, runs = load_records(RESULTS)
    document = marl_eval_document(runs)
    assert marl_eval_problems(document) == []
    # The committed file is the document of the committed runs (rewritten after every run).
    assert json.loads((RESULTS / MARL_EVAL_FILE).read_text()) == document
    one = next(r for r in runs if r["key"]["task"] == "seek" and r["key"]["learner"] == "ppo")
    mine = document["khepera_gym"]["seek-v3"]["ppo"][f"seed_{one['key']['seed']}"]
    assert mine["step_1"]["step_count"] == one["history"][0]["steps"]
    assert mine["absolute_metrics"]["success"] == [one["final"]["success"]["value"]]


def test_the_structure_check_catches_what_marl_eval_would_refuse() -> None:
    good = {"e": {"t": {"a": {"seed_0": {"step_1": {"step_count": 5, "m": [1.0]},
                                         "absolute_metrics": {"m": [1.0]}}}}}}  # fmt: skip
    assert marl_eval_problems(good) == []
    broken = json.loads(json.dumps(good))
    run = broken["e"]["t"]["a"]["seed_0"]
    run["step_1"]["step_count"] = "5"
    run["step_2"] = {"step_count": 6, "m": []}
    del run["absolute_metrics"]
    problems = marl_eval_problems(broken)
    assert len(problems) == 3, problems


def test_the_results_page_fragment_names_every_statistic(tmp_path: Path) -> None:
    from khepera_gym.analysis.docgen.benchmark_reliable import reliable_fragment

    text = reliable_fragment(RESULTS, tmp_path, "generated/benchmark")
    for header in ("IQM [95 % CI]", "mean [95 % CI]", "normalised IQM", "P [95 % CI]"):
        assert header in text
    _, runs = load_records(RESULTS)
    for task in {r["key"]["task"] for r in runs}:
        assert (tmp_path / f"{task}_curves.png").stat().st_size > 0
        assert f"generated/benchmark/{task}_curves.png" in text
    assert (tmp_path / "profiles.png").is_file()
