"""The comparison's outputs: the table, the CSV and JSON files, the trajectory figure."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

from khepera_gym.compare.run import TIME_PERCENTILE, Comparison, EpisodeResult
from khepera_gym.compare.stats import CONFIDENCE
from khepera_gym.plot import panel_title, plot_rollouts

#: Resolution of the saved plots (dots per inch).
PLOT_DPI = 100


def format_table(comparison: Comparison) -> str:
    """The summary table: one row per policy, estimates with their 95% intervals."""
    columns = [
        ("policy", lambda s: s.policy),
        ("success %", lambda s: s.success_rate.format(100, 1)),
        ("time to goal s", lambda s: s.time_to_goal_mean.format(1, 1)),
        (f"p{TIME_PERCENTILE:g} time s", lambda s: s.time_to_goal_p95.format(1, 1)),
        ("path m", lambda s: s.path_length_mean.format(1, 2)),
        ("contact steps", lambda s: s.contact_steps_mean.format(1, 1)),
        ("contact %", lambda s: s.contact_rate.format(100, 0)),
    ]
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
    widths = [max(len(row[i]) for row in rows) for i in range(len(columns))]

    def line(row: list[str]) -> str:
        return "  ".join(
            cell.ljust(width) if i == 0 else cell.rjust(width)
            for i, (cell, width) in enumerate(zip(row, widths, strict=True))
        )

    config = f', config="{comparison.config}"' if comparison.config else ""
    title = (
        f"{comparison.env_id}{config}: {comparison.episodes} episodes per policy, "
        f"seeds {comparison.seed}..{comparison.seed + comparison.episodes - 1}"
    )
    rule = "-" * len(line(rows[0]))
    notes = (
        "estimate [95% interval]: Wilson for rates, bootstrap for means and percentiles; "
        "time and path over successful episodes"
    )
    if comparison.is_formation:
        notes += (
            "\nformation: success = the leader reached its goal, path summed over the robots, "
            "error = followers' mean distance to their eq. 12 targets"
        )
    return "\n".join([title, rule, line(rows[0]), rule, *map(line, rows[1:]), rule, notes])


def write_results(comparison: Comparison, out_dir: Path) -> list[Path]:
    """Writes ``<label>_episodes.csv`` (one row per episode) and ``<label>_results.json``
    (settings, summaries with intervals, and every episode) into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = [dataclasses.asdict(r) for results in comparison.results.values() for r in results]
    csv_path = out_dir / f"{comparison.label}_episodes.csv"
    with csv_path.open("w", newline="") as file:
        writer = csv.DictWriter(
            file, fieldnames=[f.name for f in dataclasses.fields(EpisodeResult)]
        )
        writer.writeheader()
        writer.writerows({k: "" if v is None else v for k, v in row.items()} for row in rows)
    json_path = out_dir / f"{comparison.label}_results.json"
    document = {
        "env_id": comparison.env_id,
        "config": comparison.config,
        "seed": comparison.seed,
        "episodes_per_policy": comparison.episodes,
        "dt": comparison.dt,
        "confidence": CONFIDENCE,
        "summaries": [s.to_json() for s in comparison.summaries],
        "episodes": rows,
    }
    json_path.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n")
    return [csv_path, json_path]


def plot_comparison(comparison: Comparison, out_dir: Path) -> Path | None:
    """Draws the recorded worlds, one row per world and one panel per policy (so the panels
    of a row are the same episode), into ``<label>_trajectories.png``; None if none recorded."""
    names = list(comparison.rollouts)
    worlds = min((len(r) for r in comparison.rollouts.values()), default=0)
    if worlds == 0:
        return None
    rollouts = [comparison.rollouts[name][world] for world in range(worlds) for name in names]
    titles = [panel_title(f"{r.label} (seed {r.seed})", r) for r in rollouts]
    config = f', config="{comparison.config}"' if comparison.config else ""
    figure = plot_rollouts(
        rollouts, titles, ncols=len(names), suptitle=f"{comparison.env_id}{config}"
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{comparison.label}_trajectories.png"
    figure.savefig(path, dpi=PLOT_DPI)
    return path


def report(comparison: Comparison, out_dir: Path | None, plot: bool = True) -> list[Path]:
    """Prints the table, writes the files (with ``out_dir``) and says where they are."""
    print(format_table(comparison))
    paths: list[Path] = []
    if out_dir is not None:
        paths += write_results(comparison, out_dir)
        if plot:
            figure_path = plot_comparison(comparison, out_dir)
            if figure_path is not None:
                paths.append(figure_path)
        for path in paths:
            print(f"saved {path}")
    return paths


__all__ = ["PLOT_DPI", "format_table", "plot_comparison", "report", "write_results"]
