"""The learning benchmark's aggregate results page fragment (``results-benchmark-reliable.md``)
and figures, from the files ``khepera-gym benchmark`` wrote in ``docs/results/benchmark/``: per
task the IQM and mean of the runs' scores with 95 % stratified-bootstrap intervals and the ratio
to the best classical baseline; the normalised scores aggregated across tasks; the probability of
improvement between the learners of a task; performance profiles; one sample-efficiency figure a
task (:mod:`khepera_gym.learning.benchmark.aggregate` computes them).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import EngFormatter

from khepera_gym import registry
from khepera_gym.analysis.docgen.markdown import code, missing_results, table
from khepera_gym.analysis.docgen.width import split_table
from khepera_gym.learning.benchmark import aggregate
from khepera_gym.learning.benchmark.random_rows import RANDOM_DIR
from khepera_gym.learning.benchmark.suite import load_suite
from khepera_gym.learning.benchmark.tables import load_records

#: Resolution of the figures (dots per inch).
DPI = 100
#: Figures' width in inches: they fit the page's content column (about 740 px at 100 dpi).
WIDTH = 7.2


def _random_summaries(folder: Path, baselines: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Each task's random row: from its baselines file, else from ``random/``."""
    found = {}
    for record in baselines:
        if aggregate.RANDOM in record["summaries"]:
            found[record["key"]["task"]] = record["summaries"][aggregate.RANDOM]
    for path in sorted((folder / RANDOM_DIR).glob("*.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        found.setdefault(record["key"]["task"], record["summaries"][aggregate.RANDOM])
    return found


def _format(value: float, low: float, high: float, scale: float = 1.0, digits: int = 2) -> str:
    if not math.isfinite(value):
        return "–"
    return f"{value * scale:.{digits}f} [{low * scale:.{digits}f}, {high * scale:.{digits}f}]"


def _scale(metric: str) -> tuple[float, str]:
    """Errors in mm, shares in %."""
    if "error" in metric:
        return 1000.0, " mm"
    if metric == "success":
        return 100.0, " %"
    return 1.0, ""


def reliable_fragment(folder: Path, images: Path, image_prefix: str) -> str:
    """The fragment's Markdown; writes its figures into ``images`` (linked as
    ``image_prefix/<name>.png``)."""
    baselines, runs = load_records(folder)
    if not runs:
        return missing_results("khepera-gym benchmark --out docs/results/benchmark")
    suite = load_suite()
    randoms = _random_summaries(folder, baselines)
    base = {r["key"]["task"]: r["summaries"] for r in baselines}
    images.mkdir(parents=True, exist_ok=True)

    per_task_rows = []
    normalised: dict[str, dict[str, np.ndarray]] = {}  # learner -> task -> scores
    improvement_rows = []
    curve_links = []
    for task in registry.task_names():
        entry = suite.get(task)
        mine = [r for r in runs if r["key"]["task"] == task]
        if entry is None or not mine:
            continue
        metric = aggregate.task_metric(entry)
        scale, unit = _scale(metric.metric)
        best = aggregate.best_baseline(base.get(task, {}), metric)
        random = randoms.get(task, {}).get(metric.metric, {}).get("value")
        scores: dict[str, list[float]] = {}
        for run in mine:
            value = run["final"].get(metric.metric, {}).get("value")
            if value is not None:
                scores.setdefault(run["key"]["learner"], []).append(float(value))
        for learner, values in sorted(scores.items()):
            x = np.asarray(values, dtype=float)
            iqm = aggregate.stratified_bootstrap([x], aggregate.iqm)
            mean = aggregate.stratified_bootstrap([x], aggregate.mean)
            ratio = "–"
            if best is not None and best[1] != 0:
                ratio = f"{mean[0] / best[1]:.2g}×"
            norm_text = "–"
            if best is not None and random is not None:
                norm = np.array([aggregate.normalise(v, float(random), best[1], metric) for v in x])
                if np.all(np.isfinite(norm)):
                    normalised.setdefault(learner, {})[task] = norm
                    norm_text = _format(*aggregate.stratified_bootstrap([norm], aggregate.iqm))
            per_task_rows.append(
                [
                    task,
                    learner,
                    str(len(x)),
                    _format(*iqm, scale=scale) + unit,
                    _format(*mean, scale=scale) + unit,
                    f"{best[0]} {best[1] * scale:.2f}{unit}" if best else "–",
                    ratio,
                    norm_text,
                ]
            )
        learners = sorted(scores)
        for i, a in enumerate(learners):
            for b in learners[i + 1 :]:
                xa, xb = np.asarray(scores[a]), np.asarray(scores[b])
                poi = aggregate.improvement_interval(xa, xb, metric.higher_is_better)
                improvement_rows.append(
                    [task, f"{a} > {b}", f"{len(xa)} vs {len(xb)}", _format(*poi)]
                )
        figure = curves_figure(aggregate.curves(mine, metric), metric, scale, unit)
        if figure is not None:
            name = f"{task}_curves.png"
            figure.savefig(images / name, dpi=DPI)
            curve_links.append(f"![{task}: learning curves]({image_prefix}/{name})")

    aggregate_rows = []
    for learner, by_task in sorted(normalised.items()):
        strata = list(by_task.values())
        iqm = aggregate.stratified_bootstrap(strata, aggregate.iqm)
        mean = aggregate.stratified_bootstrap(strata, aggregate.mean)
        aggregate_rows.append(
            [
                learner,
                ", ".join(by_task),
                str(sum(len(s) for s in strata)),
                _format(*iqm),
                _format(*mean),
            ]
        )
    profile = profile_figure(normalised)
    profile_link = ""
    if profile is not None:
        profile.savefig(images / "profiles.png", dpi=DPI)
        profile_link = f"![performance profiles]({image_prefix}/profiles.png)"

    metrics = "; ".join(
        f"{task}: {aggregate.task_metric(entry).describe()}"
        for task, entry in suite.items()
        if any(r["key"]["task"] == task for r in runs)
    )
    parts = [
        "Estimators: rliable's IQM, mean and probability of improvement; 95 % intervals from "
        f"{aggregate.RESAMPLES:,} stratified-bootstrap resamples of the seeds (seed "
        f"{aggregate.SEED}). A run's score is its mean over the held-out episodes of the task's "
        f"metric: {metrics}. The normalised score is 0 for the random policy and 1 for the best "
        "classical baseline, on a log scale for lower-is-better metrics; the ratio is the "
        "learned mean over the best baseline's (below 1 is better for a lower-is-better metric).",
        # Task and learner, then the statistics: in two tables if one is wider than the page.
        *split_table(
            [
                "task",
                "learner",
                "seeds",
                "IQM [95 % CI]",
                "mean [95 % CI]",
                "best baseline",
                "ratio",
                "normalised IQM",
            ],
            per_task_rows,
            keep=2,
        ),
        "Normalised scores aggregated across tasks (each task's seeds resampled apart):",
        table(["learner", "tasks", "runs", "IQM [95 % CI]", "mean [95 % CI]"], aggregate_rows)
        if aggregate_rows
        else "No task has both a random row and a baseline yet.",
        "Probability of improvement (P(A beats B) on the task's metric, a run against a run):",
        table(["task", "A > B", "seeds", "P [95 % CI]"], improvement_rows)
        if improvement_rows
        else "No task has two learners yet.",
        profile_link,
        "Sample efficiency: the metric of each seed's evaluations during training (on seeds "
        "apart from the held-out ones), median and interquartile band over the seeds, against "
        "environment steps and training seconds. Rows again: "
        + code("khepera-gym benchmark --out docs/results/benchmark")
        + ".",
        *curve_links,
        "How each learner's recipe was chosen (``searched`` in configs/benchmark.toml; "
        + code("khepera-gym tune")
        + " reruns a search):",
        table(
            ["task", "learner", "recipe"],
            [
                [task, name, entry.search_of(name)]
                for task, entry in suite.items()
                for name in entry.learners
            ],
        ),
    ]
    return "\n\n".join(p for p in parts if p)


def tune_fragment(folder: Path) -> str:
    """The recipe searches (``khepera-gym tune``'s files in ``folder``): what was searched, the
    best configuration against the shipped table, and every trial's last evaluation."""
    from khepera_gym.analysis.docgen.results_files import provenance_line
    from khepera_gym.tooling.provenance import portable_command

    files = sorted(folder.glob("*.json")) if folder.is_dir() else []
    if not files:
        return missing_results("khepera-gym tune --task TASK --learner LEARNER --space ... --out")
    parts = []
    for path in files:
        document = json.loads(path.read_text(encoding="utf-8"))
        keys = sorted({k for trial in document["trials"] for k in trial["config"]})
        rows = []
        for trial in document["trials"]:
            scores = [p["score"] for p in trial["evaluations"]]
            rows.append(
                [
                    *(
                        f"{trial['config'].get(k, ''):.3g}"
                        if isinstance(trial["config"].get(k), float)
                        else str(trial["config"].get(k, ""))
                        for k in keys
                    ),
                    str(len(scores)),
                    f"{scores[-1]:.3g}" if scores else "–",
                    f"{sum(scores) / len(scores):.3g}" if scores else "–",
                ]
            )
        shipped = {k: document["shipped_table"].get(k) for k in keys}
        meta = dict(document.get("meta") or {})
        meta["command"] = portable_command(str(meta.get("command", "?")), str(folder))
        parts.append(
            f"**{document['task']}-v{document['version']}, {document['learner']}**: "
            f"{len(document['trials'])} trials scored by {document['metric']} on the training's "
            f"evaluation seeds ({document['evaluation_seeds']}); best "
            f"{code(json.dumps(document['best']['config']))}, shipped {code(json.dumps(shipped))}. "
            + provenance_line(meta)
            + "\n\n"
            + table([*keys, "evaluations", "last score", "mean score"], rows)
        )
    return "\n\n".join(parts)


def curves_figure(
    found: Sequence[aggregate.Curve], metric: aggregate.TaskMetric, scale: float, unit: str
) -> Figure | None:
    """One task's curves: the metric against steps (left) and seconds (right)."""
    if not found:
        return None
    figure = Figure(figsize=(WIDTH, 2.8), layout="constrained")
    left, right = figure.subplots(1, 2, sharey=True)
    for curve in found:
        values = curve.values * scale
        with np.errstate(all="ignore"):
            middle = np.nanmedian(values, axis=0)
            low, high = np.nanpercentile(values, [25, 75], axis=0)
            steps = np.nanmedian(curve.steps, axis=0)
            seconds = np.nanmedian(curve.seconds, axis=0)
        for ax, x in ((left, steps), (right, seconds)):
            (line,) = ax.plot(x, middle, label=f"{curve.learner} ({len(values)} seeds)")
            # An explicit `where`: matplotlib 3.6.0 (the floor) fails without one on arrays
            # with no NaN.
            where = np.isfinite(x) & np.isfinite(low) & np.isfinite(high)
            ax.fill_between(
                x, low, high, where=where, color=line.get_color(), alpha=0.25, linewidth=0
            )
    left.xaxis.set_major_formatter(EngFormatter())
    if metric.log_scale:
        left.set_yscale("log")
    left.set_xlabel("environment steps")
    right.set_xlabel("training seconds")
    left.set_ylabel(f"{metric.metric}{unit and f' ({unit.strip()})'}")
    left.set_title(f"{metric.task}: {metric.describe()}", fontsize=9, loc="left")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    left.legend(fontsize=8)
    return figure


def profile_figure(normalised: Mapping[str, Mapping[str, np.ndarray]]) -> Figure | None:
    """Performance profiles: the share of runs above each normalised score, per learner."""
    if not normalised:
        return None
    figure = Figure(figsize=(WIDTH, 3.2), layout="constrained")
    ax = figure.add_subplot()
    for learner, by_task in sorted(normalised.items()):
        profile = aggregate.performance_profile(list(by_task.values()))
        ax.plot(aggregate.PROFILE_TAUS, profile, label=f"{learner} ({len(by_task)} tasks)")
    ax.set_xlabel("normalised score τ (0: random, 1: best classical baseline)")
    ax.set_ylabel("share of runs with score > τ")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return figure


__all__ = ["curves_figure", "profile_figure", "reliable_fragment", "tune_fragment"]
