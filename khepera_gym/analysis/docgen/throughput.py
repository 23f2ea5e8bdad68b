"""The results page's throughput sections, from the files ``khepera-gym bench --json`` writes
(:mod:`khepera_gym.analysis.throughput`): env-steps/s per configuration and thread count with
the memory per world (:func:`bench_fragment`), and the swarm table, worlds of 4 to 10,000
robots (:func:`swarm_fragment`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from khepera_gym.analysis.docgen.markdown import escape_cell, missing_results, table
from khepera_gym.analysis.docgen.results_files import kind, provenance_line


def bench_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """The benchmark runs: env-steps/s per configuration and thread count, memory per world."""
    documents = [d for _, d in files if kind(d) == "bench"]
    if not documents:
        return missing_results("khepera-gym bench --json bench.json")
    parts = []
    for document in documents:
        rows = [
            [
                escape_cell(row["label"]),
                str(row["num_threads"] or "–"),
                f"{row['env_steps_per_second']:,.0f}",
                f"{1e6 * row['seconds'] / row['steps']:.1f}",
            ]
            for row in document["rows"]
        ]
        memory = document.get("memory_per_world_bytes")
        if memory is None:
            memory_text = ""
        elif document.get("memory_process") == "fresh":
            memory_text = f"\n\nMemory per Nav world: {memory / 1024:.1f} KiB."
        else:
            memory_text = (
                "\n\nMemory per Nav world: not valid in this run (measured in the benchmark's "
                "own process, where memory the earlier measurements freed was reused; "
                "`khepera-gym bench` now measures it in a fresh process)."
            )
        parts.append(
            f"Version {document['version']}, {document['duration']:g} s per configuration. "
            + provenance_line(document.get("meta"))
            + "\n\n"
            + table(["configuration", "threads", "env-steps/s", "µs per step"], rows)
            + memory_text
        )
    return "\n\n".join(parts)


#: The behaviour version of the swarm rows in results files written before rows named theirs:
#: ``khepera-gym bench`` then timed ``multinav_v1`` whatever its ``--version``.
SWARM_VERSION_BEFORE = 1


def _robot_step_cost(rows: list[dict[str, Any]]) -> list[str]:
    """Each row's time of a robot-step against 4-robot worlds split by world (the default) on
    as many threads, as a cell ("–" where the run has no such row)."""
    small = {
        row["threads"]: row["robot_steps_per_second"]
        for row in rows
        if row["robots"] == 4 and row["split"] == "world" and not row.get("scene")
    }
    return [
        f"{small[row['threads']] / row['robot_steps_per_second']:.2f}×"
        if row["threads"] in small
        else "–"
        for row in rows
    ]


def swarm_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """The swarm rows of the benchmark runs: world- and robot-steps/s by robots per world, and
    each row's cost of a robot-step against 4-robot worlds split by world on as many threads."""
    documents = [d for _, d in files if kind(d) == "bench" and d.get("swarm")]
    if not documents:
        return missing_results("khepera-gym bench --json bench.json")
    parts = []
    for document in documents:
        swarm = document["swarm"]
        rows = [
            [
                f"{row['robots']:,}" + (" (`swarm` scene)" if row.get("scene") else ""),
                str(row["worlds"]),
                row["split"],
                str(row["threads"]),
                f"{row['world_steps_per_second']:,.0f}",
                f"{row['robot_steps_per_second']:,.0f}",
                cost,
                f"{row['real_time_factor']:.1f}",
            ]
            for row, cost in zip(swarm, _robot_step_cost(swarm), strict=True)
        ]
        header = ["robots per world", "worlds", "split", "threads", "world-steps/s"]
        header += ["robot-steps/s", "cost of a robot-step", "× real time"]
        if "version" in swarm[0]:
            note = "Multinav " + ", ".join(f"v{v}" for v in sorted({r["version"] for r in swarm}))
            note += "."
        else:
            note = (
                f"Multinav v{SWARM_VERSION_BEFORE} (until 2026-12-07 the swarm rows ran version "
                f"{SWARM_VERSION_BEFORE} whatever the bench's `--version`)."
            )
        parts.append(
            provenance_line(document.get("meta")) + " " + note + "\n\n" + table(header, rows)
        )
    return "\n\n".join(parts)


__all__ = ["SWARM_VERSION_BEFORE", "bench_fragment", "swarm_fragment"]
