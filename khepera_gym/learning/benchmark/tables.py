"""The benchmark's tables: every run of a task and learner across seeds, beside the baselines.

For each task, one row per baseline (its held-out mean of each criterion statistic, with the
interval over episodes) and one per learner: over its seeds, the mean of each seed's held-out
mean with a 95 % bootstrap interval over the seeds, the seeds that met the criterion on mean
and on sampled actions, the median training time and steps to first meet it on the training's
evaluations, and the command that reproduces the row. Read from the results files only, so the
results page (``docs/results``) and ``khepera-gym benchmark`` print the same thing.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence
from typing import Any

from khepera_gym.learning.benchmark.runner import load_records, means
from khepera_gym.tooling.stats import bootstrap_interval


def _work(run: Mapping[str, Any]) -> tuple[Any, ...]:
    """What a run did, but for its seed: runs alike in it share a row."""
    key = run["key"]
    return (key["learner"], key["version"], key["recipe"], key["episodes"], key["heldout_seed"])


def _variant(work: tuple[Any, ...], twins: Sequence[tuple[Any, ...]]) -> str | None:
    """The label of ``work`` among the rows of its learner and version (``twins``)."""
    if len(twins) < 2:
        return None
    parts = []
    if len({w[2] for w in twins}) > 1:
        parts.append(f"recipe {work[2][:8]}")
    if len({w[3:] for w in twins}) > 1:
        parts.append(f"{work[3]} episodes from seed {work[4]}")
    return ", ".join(parts)


def _median(values: Sequence[float]) -> float:
    return statistics.median(values) if values else math.nan


def task_rows(
    task: str, baselines: Sequence[Mapping[str, Any]], runs: Sequence[Mapping[str, Any]]
) -> dict[str, Any]:
    """The table of one task: its criterion, baseline rows and learner rows (JSON-ready)."""
    runs = [r for r in runs if r["key"]["task"] == task]
    base = [b for b in baselines if b["key"]["task"] == task]
    if not runs and not base:
        return {"task": task, "baselines": [], "learners": []}
    criterion = runs[0]["key"]["criterion"] if runs else []
    metrics = list(dict.fromkeys(c["metric"] for c in criterion)) or ["success"]
    baseline_rows = [
        {
            "policy": name,
            "version": b["key"]["version"],
            "metrics": {m: summary.get(m) for m in metrics},
        }
        for b in base
        for name, summary in b["summaries"].items()
    ]
    learner_rows = []
    # One row per piece of work: runs of another recipe or other held-out episodes in the same
    # folder get their own row, never averaged in.
    works = list(dict.fromkeys(_work(r) for r in runs))
    for work in works:
        mine = [r for r in runs if _work(r) == work]
        learner, version = work[0], work[1]
        seeds = [r["key"]["seed"] for r in mine]
        twins = [w for w in works if w[:2] == work[:2]]
        row: dict[str, Any] = {
            "learner": learner,
            "version": version,
            "env": mine[0]["key"]["env"],
            # What tells the row from the learner's others in the folder: the recipe's
            # fingerprint and/or its held-out episodes (None when it is the only one).
            "variant": _variant(work, twins),
            "settings": {
                "timesteps": None,
                "overrides": {},
                "eval_episodes": None,
                **mine[0].get("settings", {}),  # files before it recorded none
                "episodes": mine[0]["key"]["episodes"],
                "heldout_seed": mine[0]["key"]["heldout_seed"],
            },
            "seeds": seeds,
            "metrics": {},
            "solved": sum(bool(r["solved"]) for r in mine),
            "solved_sampled": sum(bool(r.get("solved_sampled")) for r in mine),
            "median_train_seconds": _median([r["train_seconds"] for r in mine]),
            "median_steps": _median([r["timesteps"] for r in mine]),
            "reached": sum(r["reached"] is not None for r in mine),
            "median_seconds_to_criterion": _median(
                [r["reached"]["train_seconds"] for r in mine if r["reached"] is not None]
            ),
            "median_steps_to_criterion": _median(
                [r["reached"]["steps"] for r in mine if r["reached"] is not None]
            ),
            "recipe": mine[0]["recipe"],
            "reproduce": mine[0]["meta"].get("command", ""),
        }
        for metric in metrics:
            for kind in ("final", "final_sampled"):
                values = [
                    means(r[kind]).get(metric, math.nan) for r in mine if r.get(kind) is not None
                ]
                finite = [v for v in values if math.isfinite(v)]
                estimate = bootstrap_interval(finite, "mean").to_json()
                row["metrics"].setdefault(metric, {})[kind] = {"per_seed": values, **estimate}
        learner_rows.append(row)
    return {
        "task": task,
        "criterion": criterion,
        "thresholds": runs[0]["thresholds"] if runs else [],
        "baselines": baseline_rows,
        "learners": learner_rows,
    }


def _cell(record: Mapping[str, Any] | None, scale: float) -> str:
    if not record or record.get("value") is None:
        return "–"
    low, high = record.get("low"), record.get("high")
    value = float(record["value"]) * scale
    if low is None or high is None:
        return f"{value:.3g}"
    return f"{value:.3g} [{float(low) * scale:.3g}, {float(high) * scale:.3g}]"


def _scale(metric: str) -> tuple[float, str]:
    """How a statistic is shown: success and shares in %, errors in mm."""
    if metric == "success" or metric.endswith("_share"):
        return 100.0, " %"
    if "error" in metric or metric.endswith("_iae"):
        return 1000.0, " mm"
    return 1.0, ""


def _label(row: Mapping[str, Any]) -> str:
    """A learner row's name: learner, env and what tells it from the learner's other rows."""
    return f"{row['learner']} ({row['env']}" + (
        f", {row['variant']})" if row.get("variant") else ")"
    )


def markdown(table: Mapping[str, Any]) -> str:
    """One task's tables as Markdown: the held-out results (a row per baseline, and per learner
    one on its mean actions and one sampling them), then the learners' training (the criterion
    met during training, and how long it took). Every cell holds one statistic, named by its
    column, so that each table fits a page's content column."""
    criterion = " and ".join(
        f"{c['metric']} {'≥' if c['bound'] == 'at_least' else '≤'} {c['reference'] or c['value']}"
        for c in table.get("criterion", [])
    )
    metrics = list(dict.fromkeys(c["metric"] for c in table.get("criterion", []))) or ["success"]
    heads = [f"{m}{_scale(m)[1]}" for m in metrics]
    lines = [
        f"**{table['task']}**, solved when {criterion or '–'}: held-out mean [95 % interval]",
        "",
        "| policy | actions | seeds | " + " | ".join(heads) + " | solved |",
        "|---" * (4 + len(metrics)) + "|",
    ]
    for row in table["baselines"]:
        cells = [_cell(row["metrics"].get(m), _scale(m)[0]) for m in metrics]
        lines.append(f"| {row['policy']} (baseline) | – | – | " + " | ".join(cells) + " | – |")
    for row in table["learners"]:
        n = len(row["seeds"])
        for kind, actions, solved in (
            ("final", "mean", row["solved"]),
            ("final_sampled", "sampled", row["solved_sampled"]),
        ):
            cells = [_cell(row["metrics"][m].get(kind), _scale(m)[0]) for m in metrics]
            lines.append(
                f"| {_label(row)} | {actions} | {n} | " + " | ".join(cells) + f" | {solved}/{n} |"
            )
    if not table["learners"]:
        return "\n".join(lines)
    lines += [
        "",
        "Training, medians over the seeds (to the criterion: over the seeds that met it on the "
        "training's own evaluations):",
        "",
        "| learner | seeds that met it | time to it | steps to it | training time "
        "| training steps |",
        "|---" * 6 + "|",
    ]
    for row in table["learners"]:
        n = len(row["seeds"])
        time_to = row["median_seconds_to_criterion"]
        met = math.isfinite(time_to)
        lines.append(
            f"| {_label(row)} | {row['reached']}/{n} "
            + (
                f"| {time_to:.0f} s | {row['median_steps_to_criterion'] / 1e3:.0f}k "
                if met
                else "| never | – "
            )
            + f"| {row['median_train_seconds']:.0f} s | {row['median_steps'] / 1e3:.0f}k |"
        )
    return "\n".join(lines)


__all__ = ["load_records", "markdown", "task_rows"]
