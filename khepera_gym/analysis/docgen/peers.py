"""The results page's side-by-side section: khepera_gym beside VMAS and a hand-vectorised NumPy
env, from the files ``python -m benchmarks.peers.compare_peers --out
docs/results/peers`` writes (benchmarks/peers/, outside the wheel).

Each file becomes its provenance line, the CPU's vector extensions and what the peers' libraries
dispatch to, a table of env-steps/s (median and range over interleaved rounds) and a table of
khepera_gym's ratios over VMAS' and NumPy's fastest rows (taken within each round). Speeds from a
busy machine are only meaningful as these ratios; the load average is shown with them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from khepera_gym.analysis.docgen.markdown import escape_cell, missing_results, table
from khepera_gym.analysis.docgen.results_files import provenance_line

#: The peers' folder under docs/results/.
PEERS_DIR = "peers"
#: The command that writes a file of that folder.
PEERS_COMMAND = "python -m benchmarks.peers.compare_peers --out docs/results/peers"
#: The design goals for khepera_gym's lead over each peer.
GOALS = {"vmas": 20.0, "numpy": 8.0}
#: Display names of the peers.
PEER_NAMES = {"khepera_gym": "khepera_gym", "vmas": "VMAS", "numpy": "NumPy"}
#: CPU flags by the name a reader knows them by, in the order shown.
_FLAG_NAMES = {
    "avx2": "AVX2",
    "fma": "FMA",
    "avx512f": "AVX-512F",
    "avx512dq": "DQ",
    "avx512cd": "CD",
    "avx512bw": "BW",
    "avx512vl": "VL",
    "avx512_vnni": "VNNI",
    "avx512_bf16": "BF16",
    "avx512_fp16": "FP16",
}


def rate_cell(value: float) -> str:
    """Env-steps/s in a short cell: 1.05M, 45.3k."""
    if value >= 1e6:
        return f"{value / 1e6:.2f}M"
    if value >= 1e3:
        return f"{value / 1e3:.1f}k"
    return f"{value:.0f}"


def vector_extensions(flags: dict[str, bool]) -> str:
    """The CPU's vector extensions in one phrase: those present, then the absent ones."""
    present = [name for flag, name in _FLAG_NAMES.items() if flags.get(flag)]
    absent = [name for flag, name in _FLAG_NAMES.items() if flag in flags and not flags[flag]]
    text = ", ".join(present) if present else "none of AVX2, FMA, AVX-512"
    return text + (f" (not {', '.join(absent)})" if absent else "")


def _libraries(software: dict[str, Any]) -> str:
    """What torch and NumPy dispatch to and their versions, from the VMAS interpreter's record
    (the khepera_gym one's without VMAS)."""
    info = software.get("vmas") or software.get("khepera_gym") or {}
    versions = info.get("versions", {})
    parts = []
    if versions.get("vmas"):
        parts.append(f"VMAS {versions['vmas']}")
    if versions.get("torch"):
        parts.append(
            f"torch {versions['torch']} ({info.get('torch_cpu_capability', '?')} kernels, "
            f"{info.get('torch_default_threads', '?')} threads by default)"
        )
    if versions.get("numpy"):
        dispatch = info.get("numpy_simd_dispatch") or []
        parts.append(
            f"NumPy {versions['numpy']}" + (f" (kernels up to {dispatch[-1]})" if dispatch else "")
        )
    return "; ".join(parts)


def _task(row: dict[str, Any]) -> str:
    """A row's task: khepera_gym's env ("Nav-v3", "Nav-v3 + 5 circles"), else the peers'
    scene."""
    if row["peer"] != "khepera_gym":
        return "scene"
    return escape_cell(row["label"].removeprefix("khepera_gym "))


def peers_section(document: dict[str, Any]) -> str:
    """One results file as Markdown: provenance, extensions, throughput and ratio tables."""
    rows = sorted(
        document["rows"],
        key=lambda row: (
            list(PEER_NAMES).index(row["peer"]),
            row["label"],
            -row["num_envs"],
            -row["threads"],
        ),
    )
    speed_rows = [
        [
            PEER_NAMES[row["peer"]],
            _task(row),
            f"{row['num_envs']:,}",
            str(row["threads"]),
            rate_cell(row["env_steps_per_second"]["median"]),
            f"{rate_cell(row['env_steps_per_second']['min'])}–"
            f"{rate_cell(row['env_steps_per_second']['max'])}",
        ]
        for row in rows
    ]
    by_key = {row["key"]: row for row in rows}
    ratio_cells: dict[str, dict[str, str]] = {}
    references: dict[str, str] = {}
    for ratio in document.get("ratios", []):
        cell = f"{ratio['median']:.1f}× ({ratio['min']:.1f}–{ratio['max']:.1f})"
        ratio_cells.setdefault(ratio["row"], {})[ratio["peer"]] = cell
        over = by_key[ratio["over"]]
        threads = "1 thread" if over["threads"] == 1 else f"{over['threads']} threads"
        references[ratio["peer"]] = f"{over['num_envs']:,} worlds, {threads}"
    peers = [peer for peer in ("vmas", "numpy") if peer in references]
    ratio_rows = [
        [_task(by_key[key]), str(by_key[key]["threads"])] + [cells.get(peer, "–") for peer in peers]
        for key, cells in ratio_cells.items()
    ]
    settings = document.get("settings", {})
    load_after = document.get("load_average_after")
    goals = ", ".join(f"{GOALS[p]:g}× {PEER_NAMES[p]}" for p in peers)
    against = "; ".join(f"{PEER_NAMES[p]}'s fastest row: {references[p]}" for p in peers)
    return "\n\n".join(
        [
            provenance_line(document.get("meta"))
            + (f" Load average at the end: {load_after[0]}." if load_after else ""),
            f"CPU vector extensions: {vector_extensions(document.get('cpu_flags', {}))}. "
            + _libraries(document.get("software", {}))
            + ".",
            f"{settings.get('repetitions', '?')} interleaved rounds of "
            f"{settings.get('duration_seconds', '?'):g} s a configuration; median and range "
            'over the rounds, with random actions. "scene": the peers\' Khepera IV among five '
            'obstacles (benchmarks/peers/); "+ 5 circles": Nav-v3 with five such obstacles.',
            table(["simulator", "task", "worlds", "threads", "env-steps/s", "range"], speed_rows),
            f"khepera_gym's lead, within each round ({against}); the design goal: {goals}.",
            table(["khepera_gym", "threads"] + [f"× {PEER_NAMES[p]}" for p in peers], ratio_rows),
        ]
    )


def peers_fragment(folder: Path) -> str:
    """Every ``peers_*.json`` file of ``folder`` (oldest first), or a note saying how to make
    one."""
    paths = sorted(folder.glob("peers_*.json")) if folder.is_dir() else []
    if not paths:
        return missing_results(PEERS_COMMAND)
    return "\n\n".join(
        peers_section(json.loads(path.read_text(encoding="utf-8"))) for path in paths
    )


__all__ = [
    "PEERS_COMMAND",
    "PEERS_DIR",
    "peers_fragment",
    "peers_section",
    "rate_cell",
    "vector_extensions",
]
