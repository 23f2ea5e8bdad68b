"""``khepera-gym compare --task consensus``: the consensus law under a range of message triggers,
error against messages.

Each setting runs ``episodes`` seeded worlds of ``consensus_vN`` (the latest behaviour version
unless ``version`` says another; world i seeded ``seed + i``, the same worlds for every setting)
with :class:`khepera_gym.baselines.ConsensusLaw` on every agent, all worlds in one batch: periodic
broadcasts every ``period`` s and event-triggered ones at each ``threshold`` m. The table gives,
per setting, the final and RMS disagreement (mean, 95% bootstrap interval), the share of episodes
converged (Wilson interval), the median time to converge and the messages per robot per second; the
figure draws final error against messages.

Units: metres, seconds; errors in the table in mm.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from tqdm import tqdm

from khepera_gym import registry
from khepera_gym.baselines.consensus import ConsensusLaw
from khepera_gym.batch_face import WORLD_STATS_KEY
from khepera_gym.config import ConfigArg
from khepera_gym.errors import ConfigError
from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv
from khepera_gym.tooling.provenance import provenance
from khepera_gym.tooling.stats import (
    Estimate,
    bootstrap_interval,
    event_time_median,
    json_number,
    wilson_interval,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: Periods (s) of the periodic settings: every step (50 ms) to once a second.
PERIODS = (0.05, 0.1, 0.2, 0.5, 1.0)
#: Thresholds (m) of the event-triggered settings.
THRESHOLDS = (0.005, 0.01, 0.02, 0.05, 0.1)
#: Resolution of the saved figure (dots per inch).
PLOT_DPI = 100
#: The core's task the sweep runs.
TASK = "consensus"


def check_version(version: int | None) -> int:
    """The behaviour version of consensus to run: ``version``, or the latest for None.

    Raises:
        ConfigError: A version consensus does not exist in (it was added with v1).
    """
    versions = registry.task_versions(TASK)
    if version is None:
        return versions[-1]
    if isinstance(version, bool) or not isinstance(version, int) or version not in versions:
        known = ", ".join(str(v) for v in versions)
        raise ConfigError(f"consensus has no behaviour version {version!r}; it has {known}")
    return version


@dataclasses.dataclass(frozen=True)
class SweepRow:
    """One trigger setting's results over the episodes.

    Attributes:
        trigger: "periodic" or "event".
        value: Its period (s) or threshold (m).
        error_final: Disagreement at the end (m).
        error_rms: RMS disagreement over the episode (m).
        converged: Share of the episodes that ended below the bound.
        converge_time: Median time to converge (s; inf when fewer than half did).
        messages: Broadcasts per robot per second.
        version: The behaviour version it ran (``consensus_v<version>``).
    """

    trigger: str
    value: float
    error_final: Estimate
    error_rms: Estimate
    converged: Estimate
    converge_time: Estimate
    messages: Estimate
    version: int

    @property
    def label(self) -> str:
        """``"periodic 0.05 s"`` or ``"event 0.02 m"``."""
        unit = "s" if self.trigger == "periodic" else "m"
        return f"{self.trigger} {self.value:g} {unit}"


def _policy_params(env: MultiAgentArrayEnv) -> dict[str, Any]:
    """No avoidance for a rendezvous: there the robots must come into contact."""
    table = tomllib.loads(env.config_toml()).get("consensus", {})
    return {"avoid": False} if table.get("objective") == "rendezvous" else {}


def run_setting(
    trigger: str,
    value: float,
    episodes: int,
    seed: int = 0,
    config: ConfigArg = None,
    overrides: dict[str, Any] | None = None,
    num_threads: int | None = None,
    version: int | None = None,
) -> SweepRow:
    """Runs ``episodes`` worlds of ``consensus_v<version>`` (None: the latest) with one trigger
    setting and summarises them.

    Raises:
        ConfigError: A bad scenario key, a trigger other than "periodic" or "event", or a
            version consensus does not exist in.
    """
    version = check_version(version)
    if trigger not in ("periodic", "event"):
        raise ConfigError(f"trigger must be 'periodic' or 'event', got {trigger!r}")
    setting = {"trigger": trigger, "period" if trigger == "periodic" else "threshold": value}
    keys = {**(overrides or {}), **setting}
    env = MultiAgentArrayEnv(
        TASK, episodes, version=version, config=config, num_threads=num_threads, **keys
    )
    policy = ConsensusLaw.for_env(env, **_policy_params(env))
    observations, _ = env.reset(seed=seed)
    stats: dict[str, Any] = {}
    while not stats:
        observations, _, _, _, info = env.step(policy(observations))
        stats = info.get(WORLD_STATS_KEY, {})  # each world's, with the consensus errors
    times = np.asarray(stats["consensus_converge_time"], dtype=float)
    return SweepRow(
        trigger=trigger,
        value=float(value),
        error_final=bootstrap_interval(stats["consensus_error_final"]),
        error_rms=bootstrap_interval(stats["consensus_error_rms"]),
        converged=wilson_interval(int(np.isfinite(times).sum()), len(times)),
        converge_time=event_time_median(times),
        messages=bootstrap_interval(stats["messages_per_robot_s"]),
        version=version,
    )


def sweep(
    episodes: int = 50,
    seed: int = 0,
    config: ConfigArg = None,
    overrides: dict[str, Any] | None = None,
    periods: Sequence[float] = PERIODS,
    thresholds: Sequence[float] = THRESHOLDS,
    num_threads: int | None = None,
    progress: bool = True,
    version: int | None = None,
) -> list[SweepRow]:
    """Every periodic and event-triggered setting on the same seeded worlds of
    ``consensus_v<version>`` (None: the latest).

    Raises:
        ConfigError: ``episodes`` < 1, a bad scenario key, a trigger key in ``overrides``
            (the sweep sets them), or a version consensus does not exist in.
    """
    version = check_version(version)
    if episodes < 1:
        raise ConfigError(f"episodes must be >= 1, got {episodes}")
    taken = {"trigger", "period", "threshold"} & set(overrides or {})
    if taken:
        raise ConfigError(f"the consensus sweep sets {sorted(taken)} itself; do not --set them")
    settings = [("periodic", p) for p in periods] + [("event", t) for t in thresholds]
    rows = []
    for trigger, value in tqdm(settings, desc="consensus", unit="setting", disable=not progress):
        rows.append(
            run_setting(trigger, value, episodes, seed, config, overrides, num_threads, version)
        )
    return rows


def title(rows: Sequence[SweepRow]) -> str:
    """What the sweep ran, for a table's or a figure's title: ``"consensus_v3: ..."``."""
    versions = sorted({r.version for r in rows})
    names = ", ".join(f"{TASK}_v{v}" for v in versions) or TASK
    return f"{names}: the consensus law, periodic vs event-triggered"


def format_table(rows: Sequence[SweepRow]) -> str:
    """The sweep as a Markdown table (errors in mm, 95% intervals), under a line naming the
    env and version it ran."""
    header = [
        "trigger",
        "final error mm",
        "RMS error mm",
        "converged %",
        "converge s (median)",
        "messages / robot / s",
    ]
    lines = [title(rows), "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        cells = [
            r.label,
            r.error_final.format(1000, 1),
            r.error_rms.format(1000, 1),
            r.converged.format(100, 1),
            r.converge_time.format(1, 2),
            r.messages.format(1, 2),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot_tradeoff(rows: Sequence[SweepRow], title: str = "") -> Figure:
    """Final error (mm) against messages per robot per second, one line per trigger."""
    figure = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = figure.add_subplot()
    for trigger, marker in (("periodic", "o"), ("event", "s")):
        mine = [r for r in rows if r.trigger == trigger]
        if not mine:
            continue
        x = np.array([r.messages.value for r in mine])
        y = np.array([r.error_final.value for r in mine]) * 1000
        low = y - np.array([r.error_final.low for r in mine]) * 1000
        high = np.array([r.error_final.high for r in mine]) * 1000 - y
        ax.errorbar(x, y, yerr=[low, high], marker=marker, capsize=3, label=trigger)
        for r, xi, yi in zip(mine, x, y, strict=True):
            unit = "s" if trigger == "periodic" else "m"
            ax.annotate(
                f"{r.value:g} {unit}",
                (xi, yi),
                textcoords="offset points",
                xytext=(4, 4),
                fontsize=8,
            )
    ax.set_xscale("log")
    ax.set_xlabel("messages per robot per second")
    ax.set_ylabel("final disagreement (mm)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(title="trigger")
    if title:
        ax.set_title(title, fontsize=10)
    return figure


def report(rows: Sequence[SweepRow], out_dir: Path | None, plot: bool = True) -> list[Path]:
    """Prints the table; with ``out_dir`` writes ``consensus_sweep.csv``, ``.json`` (``meta``:
    date, commit, machine and command; ``rows``: one per trigger setting) and (with ``plot``)
    ``consensus_tradeoff.png``, and says where they are."""
    print(format_table(rows))
    if out_dir is None:
        return []
    out_dir.mkdir(parents=True, exist_ok=True)
    fields = ["error_final", "error_rms", "converged", "converge_time", "messages"]
    csv_path = out_dir / "consensus_sweep.csv"
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            ["trigger", "value"] + [f"{f}{s}" for f in fields for s in ("", "_low", "_high")]
        )
        for r in rows:
            cells: list[Any] = [r.trigger, r.value]
            for f in fields:
                e = getattr(r, f)
                cells += [e.value, e.low, e.high]
            writer.writerow(cells)
    json_path = out_dir / "consensus_sweep.json"
    versions = sorted({r.version for r in rows})
    document = {
        "meta": provenance(),
        "task": TASK,
        "version": versions[0] if len(versions) == 1 else versions,
        "env": ", ".join(f"{TASK}_v{v}" for v in versions),
        "rows": [
            {"trigger": r.trigger, "value": json_number(r.value), "version": r.version}
            | {f: getattr(r, f).to_json() for f in fields}
            for r in rows
        ],
    }
    json_path.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n")
    paths = [csv_path, json_path]
    if plot:
        figure = plot_tradeoff(rows, title(rows))
        png = out_dir / "consensus_tradeoff.png"
        figure.savefig(png, dpi=PLOT_DPI)
        paths.append(png)
    for path in paths:
        print(f"saved {path}")
    return paths


__all__ = [
    "PERIODS",
    "TASK",
    "THRESHOLDS",
    "SweepRow",
    "check_version",
    "format_table",
    "plot_tradeoff",
    "report",
    "run_setting",
    "sweep",
    "title",
]
