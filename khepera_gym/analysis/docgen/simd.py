"""The results page's vector-path section: khepera_gym's throughput on each of the CPU's vector
paths (``portable``, ``avx2``, ``avx512``; :func:`khepera_gym.simd_path`), from the files
``python -m benchmarks.simd_paths --out docs/results/simd/simd_paths_DATE.json`` writes
(benchmarks/, outside the wheel).

Each file becomes its provenance line, the CPU's vector extensions and one table: per
configuration of ``khepera-gym bench``, each path's env-steps/s (robot-steps/s for the swarm's
worlds; the median over interleaved rounds) and its ratio to the first column (taken within each
round: the median and range). Every path gives the same results bit for bit, so the ratios are
all that differs.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from khepera_gym.analysis.docgen.markdown import escape_cell, missing_results, table
from khepera_gym.analysis.docgen.peers import rate_cell, vector_extensions
from khepera_gym.analysis.docgen.results_files import provenance_line

#: The vector paths' folder under docs/results/.
SIMD_DIR = "simd"
#: The command that writes a file of that folder.
SIMD_COMMAND = "python -m benchmarks.simd_paths --out docs/results/simd/simd_paths_DATE.json"


def simd_section(document: dict[str, Any]) -> str:
    """One results file as Markdown: provenance, extensions and the table of paths."""
    columns: list[str] = document["columns"]
    reference = document["reference"]
    others = [name for name in columns if name != reference]
    rows = []
    for row in document["rows"]:
        cells = [escape_cell(row["configuration"]), rate_cell(row["columns"][reference]["median"])]
        for name in others:
            ratio = row["ratios"].get(name)
            cells.append(
                "–"
                if ratio is None
                else f"{ratio['median']:.2f} ({ratio['min']:.2f}–{ratio['max']:.2f})"
            )
        rows.append(cells)
    settings = document["settings"]
    machine = (document.get("meta") or {}).get("machine") or {}
    flags = machine.get("cpu_flags") or {}
    before = document.get("before_commit")
    before_text = ""
    if before:
        before_text = f" `before` is the build at commit `{before[:10]}`, timed in the same rounds."
    return "\n\n".join(
        [
            provenance_line(document.get("meta")),
            f"Vector extensions: {vector_extensions(flags)}. {settings['rounds']} interleaved "
            f"rounds of `khepera-gym bench` ({settings['duration']:g} s a configuration, "
            f"{', '.join(map(str, settings['num_envs']))} worlds, "
            f"{', '.join(map(str, settings['threads']))} threads): {reference}'s steps/s (the "
            f"median over the rounds), and each other column's ratio to it, taken within each "
            f"round: the median (range).{before_text}",
            table(["configuration", reference, *[f"× {name}" for name in others]], rows),
        ]
    )


def simd_fragment(folder: Path) -> str:
    """Every ``simd_paths_*.json`` file of ``folder`` (oldest first), or a note saying how to
    make one."""
    paths = sorted(folder.glob("simd_paths_*.json")) if folder.is_dir() else []
    if not paths:
        return missing_results(SIMD_COMMAND)
    return "\n\n".join(simd_section(json.loads(path.read_text(encoding="utf-8"))) for path in paths)


__all__ = ["SIMD_COMMAND", "SIMD_DIR", "simd_fragment", "simd_section"]
