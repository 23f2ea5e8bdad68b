"""The comparison's outputs: the table, the CSV and JSON files, the figures (trajectories; on a
task with a moving reference, reference vs actual paths and the error over time).

Which columns the table has is the task's entry of
:data:`khepera_gym.analysis.compare.metrics.TASK_METRICS`.
"""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from khepera_gym.analysis.compare.reference_plots import plot_error_over_time, plot_reference_paths
from khepera_gym.analysis.compare.run import (
    TIME_PERCENTILE,
    Comparison,
    EpisodeResult,
    PolicySummary,
)
from khepera_gym.analysis.plots import panel_title, plot_rollouts
from khepera_gym.tooling.provenance import provenance
from khepera_gym.tooling.stats import CONFIDENCE, Estimate, json_number

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: Resolution of the saved plots (dots per inch).
PLOT_DPI = 100

Column = tuple[str, Callable[[PolicySummary], str]]


def _error_columns(comparison: Comparison) -> list[Column]:
    """The columns of a task scored by an error (mm, m·s, %, s) and of its terminations."""
    metrics = comparison.metrics
    columns: list[Column] = []

    def error(name: str, scale: float, digits: int) -> Callable[[PolicySummary], str]:
        return lambda s: s.errors[name].format(scale, digits) if name in s.errors else "–"

    if metrics.error_prefix is not None:
        columns += [
            ("RMS error mm", error("error_rms", 1000, 1)),
            ("max error mm", error("error_max", 1000, 1)),
            ("IAE m·s", error("iae", 1, 3)),
            ("converged %", error("converged", 100, 1)),
            ("converge s", error("converge_time", 1, 2)),
        ]
    for name, header, scale, digits in metrics.columns:
        columns.append((header, error(name, scale, digits)))
    if metrics.termination is not None:
        columns.append(
            (
                f"{metrics.termination} %",
                lambda s: _format(s.terminated_rate, 100, 1),
            )
        )
    return columns


def _format(estimate: Estimate | None, scale: float, digits: int) -> str:
    return "–" if estimate is None else estimate.format(scale, digits)


def table_rows(comparison: Comparison) -> list[list[str]]:
    """The summary table's cells: the header, then one row per policy (estimates with their 95%
    intervals). :func:`format_table` prints them; the documentation's results pages render them
    from the JSON files (:meth:`Comparison.from_json`)."""
    metrics = comparison.metrics
    columns: list[Column] = [("policy", lambda s: s.policy)]
    if metrics.success is not None:
        columns += [
            (f"{metrics.success} %", lambda s: s.success_rate.format(100, 1)),
            (f"{metrics.time} s", lambda s: s.time_to_goal_mean.format(1, 1)),
            (f"p{TIME_PERCENTILE:g} time s", lambda s: s.time_to_goal_p95.format(1, 1)),
            ("path m", lambda s: s.path_length_mean.format(1, 2)),
        ]
    columns += _error_columns(comparison)
    if metrics.speed:
        columns.append(("speed m/s", lambda s: _format(s.mean_speed, 1, 3)))
    columns.append(("contact steps", lambda s: s.contact_steps_mean.format(1, 1)))
    if metrics.error_prefix is None:
        columns.append(("contact %", lambda s: s.contact_rate.format(100, 0)))
    if comparison.is_formation:
        columns.append(
            (
                "formation err cm",
                lambda s: (
                    "–" if s.formation_error_mean is None else s.formation_error_mean.format(100, 1)
                ),
            )
        )
    rows = [[header for header, _ in columns]]
    rows += [[cell(summary) for _, cell in columns] for summary in comparison.summaries]
    return rows


def table_notes(comparison: Comparison) -> str:
    """What the table's columns mean (printed under it)."""
    metrics = comparison.metrics
    notes = "estimate [95% interval]: Wilson for rates, bootstrap for means and percentiles"
    if metrics.success is not None:
        notes += f"; {metrics.time}, path{' and speed' if metrics.speed else ''} over "
        notes += "successful episodes"
    elif metrics.speed:
        notes += "; speed = path / duration, over all episodes"
    if metrics.error_prefix is not None:
        notes += (
            f"\n{metrics.error}: RMS and max per episode after the task's transient (whole "
            "episode if it ended sooner), averaged over episodes; IAE = integral of the error; "
            "converged = error below the convergence radius (2 cm) until the end; converge s = "
            "median over all episodes, one that never converged counting as inf (inf: fewer "
            "than half converged)"
        )
    if metrics.termination is not None:
        notes += f"\n{metrics.termination} = ended by a termination that is not a success"
    if comparison.is_formation:
        notes += (
            "\nformation: success = the leader reached its goal, path summed over the robots, "
            "error = followers' mean distance to their eq. 12 targets"
        )
    return notes


def format_table(comparison: Comparison) -> str:
    """The summary table: one row per policy, estimates with their 95% intervals."""
    rows = table_rows(comparison)
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]

    def line(row: list[str]) -> str:
        return "  ".join(
            cell.ljust(width) if i == 0 else cell.rjust(width)
            for i, (cell, width) in enumerate(zip(row, widths, strict=True))
        )

    title = (
        f"{comparison.env_id}{comparison.scenario}: {comparison.episodes} episodes per policy, "
        f"seeds {comparison.seed}..{comparison.seed + comparison.episodes - 1}"
    )
    rule = "-" * len(line(rows[0]))
    notes = table_notes(comparison)
    return "\n".join([title, rule, line(rows[0]), rule, *map(line, rows[1:]), rule, notes])


def write_results(comparison: Comparison, out_dir: Path) -> list[Path]:
    """Writes ``<label>_episodes.csv`` (one row per episode) and ``<label>_results.json``
    (``meta``: date, commit, machine and command; settings, summaries with intervals, and every
    episode) into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = [r.row() for results in comparison.results.values() for r in results]
    csv_path = out_dir / f"{comparison.label}_episodes.csv"
    with csv_path.open("w", newline="") as file:
        # The fields, then every task statistic (a column each; inf written as "inf").
        fieldnames = list(dict.fromkeys(name for row in rows for name in row))
        writer = csv.DictWriter(file, fieldnames=fieldnames or _row_names())
        writer.writeheader()
        writer.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    json_path = out_dir / f"{comparison.label}_results.json"
    document = {
        "meta": provenance(),
        "env_id": comparison.env_id,
        "task": comparison.task,
        "label": comparison.label,
        "config": comparison.config,
        "overrides": comparison.overrides,
        "seed": comparison.seed,
        "episodes_per_policy": comparison.episodes,
        "dt": comparison.dt,
        "confidence": CONFIDENCE,
        "summaries": [s.to_json() for s in comparison.summaries],
        "episodes": [{k: json_number(v) for k, v in row.items()} for row in rows],
    }
    json_path.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n")
    return [csv_path, json_path]


def _row_names() -> list[str]:
    """The CSV header of a comparison without episodes: the fields of a result."""
    return [name for name in EpisodeResult.__dataclass_fields__ if name != "task_stats"]


def plot_comparison(comparison: Comparison, out_dir: Path) -> Path | None:
    """Draws the recorded worlds, one row per world and one panel per policy (so the panels
    of a row are the same episode), into ``<label>_trajectories.png``; None if none recorded.

    On a task with a moving reference it draws instead, one panel per policy, the reference
    and the robot's path of every recorded world overlaid (``<label>_references.png``).
    """
    names = list(comparison.rollouts)
    worlds = min((len(r) for r in comparison.rollouts.values()), default=0)
    if worlds == 0:
        return None
    suptitle = f"{comparison.env_id}{comparison.scenario}"
    out_dir.mkdir(parents=True, exist_ok=True)
    if comparison.metrics.moving_reference:
        figure = plot_reference_paths(
            comparison.rollouts,
            error_stat=comparison.metrics.stat_name("error_rms"),
            suptitle=suptitle,
        )
        path = out_dir / f"{comparison.label}_references.png"
        figure.savefig(path, dpi=PLOT_DPI)
        return path
    rollouts = [comparison.rollouts[name][world] for world in range(worlds) for name in names]
    titles = [panel_title(f"{r.label} (seed {r.seed})", r) for r in rollouts]
    figure = plot_rollouts(rollouts, titles, ncols=len(names), suptitle=suptitle)
    if comparison.metrics.path_trace:
        # The path's points closest to the robot, for rollouts whose scene has no path drawn.
        for ax, rollout in zip(figure.axes, rollouts, strict=False):
            if rollout.scene.get("paths"):
                continue
            if rollout.targets is not None and len(rollout.targets):
                closest = np.asarray(rollout.targets)[:, 0]
                ax.plot(*closest.T, "--", color="0.45", linewidth=1.0, zorder=1, label="path")
    path = out_dir / f"{comparison.label}_trajectories.png"
    figure.savefig(path, dpi=PLOT_DPI)
    return path


def plot_errors(comparison: Comparison, out_dir: Path) -> Path | None:
    """Draws each policy's error over time (median and quartiles over its episodes) into
    ``<label>_errors.png``; None for a task without a moving reference."""
    if not comparison.error_traces:
        return None
    metrics = comparison.metrics
    try:
        table = tomllib.loads(comparison.config_toml).get(metrics.error_prefix or "", {})
        radius = float(table["converge_radius"])
    except (tomllib.TOMLDecodeError, KeyError, TypeError, ValueError):
        radius = None
    figure = plot_error_over_time(
        comparison.error_traces,
        comparison.dt,
        error=metrics.error,
        radius=radius,
        title=f"{comparison.env_id}{comparison.scenario}: {comparison.episodes} episodes",
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{comparison.label}_errors.png"
    figure.savefig(path, dpi=PLOT_DPI)
    return path


def report(comparison: Comparison, out_dir: Path | None, plot: bool = True) -> list[Path]:
    """Prints the table, writes the files (with ``out_dir``) and says where they are."""
    print(format_table(comparison))
    paths: list[Path] = []
    if out_dir is not None:
        paths += write_results(comparison, out_dir)
        if plot:
            for figure_path in (
                plot_comparison(comparison, out_dir),
                plot_errors(comparison, out_dir),
            ):
                if figure_path is not None:
                    paths.append(figure_path)
        for path in paths:
            print(f"saved {path}")
    return paths


def write_formation_learning(
    path: str | Path,
    method: str,
    steps: int,
    seconds: float,
    episodes: int,
    eval_seed: int,
    rows: list[dict[str, float | str | None]],
    train_seed: int | None = None,
    *,
    version: int,
) -> Path:
    """Writes the results file of a learned formation against its baseline (the results page's
    "Learned formations"), with :func:`~khepera_gym.tooling.provenance.provenance` under ``meta``.

    Args:
        path: The JSON file to write.
        method: What learned ("shared PPO (SB3)", "MAPPO (BenchMARL)").
        steps: Training steps (follower steps or env steps, as the method counts them).
        seconds: Wall time of the training (s).
        episodes: Evaluation episodes, seeded ``eval_seed`` + i.
        eval_seed: Seed of the first.
        rows: One per policy: ``policy``, ``formation_error_mean`` and ``formation_error_max``
            (m, means over the episodes), ``success_rate`` (the leader arrived; None when not
            measured) and ``contact_steps``.
        train_seed: The training's seed, when it has one.
        version: The behaviour version of the Formation env it trained and was evaluated on.
    """
    record = {
        "meta": provenance(),
        "formation_learning": {
            "method": method,
            "env": f"formation_v{version}, cross of 4 followers",
            "version": int(version),
            "steps": int(steps),
            "train_seconds": float(seconds),
            "episodes": int(episodes),
            "eval_seed": int(eval_seed),
            "train_seed": None if train_seed is None else int(train_seed),
            "rows": rows,
        },
    }
    target = Path(path)
    target.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    return target


__all__ = [
    "PLOT_DPI",
    "format_table",
    "plot_comparison",
    "plot_errors",
    "report",
    "table_notes",
    "table_rows",
    "write_formation_learning",
    "write_results",
]
