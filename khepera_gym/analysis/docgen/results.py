"""Results tables from data: the JSON files that ``khepera-gym compare``, ``train`` and
``bench`` write (each with its ``meta``: date, commit, machine, command), kept in docs/results/,
rendered into the results pages at docs build time.

A file's kind is read from its content (:func:`khepera_gym.analysis.docgen.results_files.kind`):
a comparison, the consensus sweep, a training run, a learned formation, a benchmark (its tables
in :mod:`khepera_gym.analysis.docgen.throughput`) or a hostile-input campaign; this module
renders each kind into its fragment and names the files it copies in (:func:`import_results`).
The tables are the tools' own (a comparison's columns come from
:func:`khepera_gym.analysis.compare.report.table_rows`), so a page shows what the tool printed. A
comparison of fewer than :data:`FULL_EPISODES` episodes per policy is marked as a short run.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shlex
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Any

from khepera_gym import registry
from khepera_gym.analysis.compare.report import table_notes, table_rows
from khepera_gym.analysis.compare.run import Comparison
from khepera_gym.analysis.docgen.markdown import code, escape_cell, missing_results, table
from khepera_gym.analysis.docgen.results_files import kind, load, provenance_line
from khepera_gym.analysis.docgen.throughput import bench_fragment, swarm_fragment
from khepera_gym.analysis.docgen.width import split_table
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import SAMPLED_SUFFIX, SB3_PREFIX
from khepera_gym.learning.recipes import load_hyperparams
from khepera_gym.tooling.stats import Estimate

#: Episodes per policy of a full comparison (the project's published tables).
FULL_EPISODES = 200


def _version(env_id: str) -> int:
    return int(env_id.rsplit("-v", 1)[1])


#: A policy label naming a file by its absolute path (``sb3:/work/runs/s0/model.zip``).
_PATH_LABEL = re.compile(r"^(?P<prefix>[\w.-]+:)(?P<path>/\S+?)(?P<rest>(?: \(.*\))?)$")


def portable_labels(labels: list[str]) -> list[str]:
    """Policy labels without the absolute paths of the machine that ran them: each path from
    the folder that holds all of the table's paths (``sb3:/work/runs/nav/s0/model.zip`` and
    ``.../s1/model.zip`` are ``sb3:nav/s0/model.zip`` and ``sb3:nav/s1/model.zip``), so the rows
    stay apart."""
    matches = [_PATH_LABEL.match(label) for label in labels]
    paths = [PurePosixPath(m["path"]) for m in matches if m is not None]
    if not paths:
        return labels
    common = PurePosixPath(os.path.commonpath([str(p.parent) for p in paths]))
    base = common.parent
    return [
        label
        if m is None
        else f"{m['prefix']}{PurePosixPath(m['path']).relative_to(base)}{m['rest']}"
        for label, m in zip(labels, matches, strict=True)
    ]


def _compare_section(document: dict[str, Any]) -> str:
    comparison = Comparison.from_json(document)
    rows = table_rows(comparison)
    labels = portable_labels([row[0] for row in rows[1:]])
    rows = [rows[0], *([label, *row[1:]] for label, row in zip(labels, rows[1:], strict=True))]
    cells = [[escape_cell(cell) for cell in row] for row in rows]
    title = f"`{comparison.env_id}`" + escape_cell(comparison.scenario)
    note = ""
    if comparison.episodes < FULL_EPISODES:
        note = (
            f"\n\n```{{note}}\nShort run: {comparison.episodes} episodes per policy (seeds "
            f"{comparison.seed}–{comparison.seed + comparison.episodes - 1}). The full table "
            f"({FULL_EPISODES} episodes) still needs a run.\n```"
        )
    notes = escape_cell(table_notes(comparison).replace("\n", "; "))
    return (
        f"#### {title}\n\n{provenance_line(document.get('meta'))}{note}\n\n"
        # Track's 12 statistics do not fit the page's column in one table.
        + "\n\n".join(split_table(cells[0], cells[1:]))
        + f"\n\n{notes}."
    )


def compare_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """Every comparison, by version (newest first), then task (the core's order)."""
    documents = [d for _, d in files if kind(d) == "compare"]
    if not documents:
        return missing_results("khepera-gym compare --task avoid --episodes 200 --out compare_out")
    order = {task: index for index, task in enumerate(registry.task_names())}

    def key(document: dict[str, Any]) -> tuple[int, int, str]:
        task = Comparison.from_json(document).task or ""
        scene = f"{document.get('config') or ''}{sorted((document.get('overrides') or {}).items())}"
        return (-_version(document["env_id"]), order.get(task, len(order)), scene)

    parts = []
    version = None
    for document in sorted(documents, key=key):
        if _version(document["env_id"]) != version:
            version = _version(document["env_id"])
            parts.append(f"### Version {version}")
        parts.append(_compare_section(document))
    return "\n\n".join(parts)


def _estimate(record: dict[str, Any], scale: float, digits: int) -> str:
    return Estimate.from_json(record).format(scale, digits)


def consensus_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """The consensus sweeps: error, convergence and messages per trigger setting."""
    documents = [d for _, d in files if kind(d) == "consensus"]
    if not documents:
        return missing_results("khepera-gym compare --task consensus --episodes 200")
    parts = []
    for document in documents:
        rows = []
        for row in document["rows"]:
            unit = "s" if row["trigger"] == "periodic" else "m"
            rows.append(
                [
                    f"{row['trigger']} {row['value']:g} {unit}",
                    _estimate(row["error_final"], 1000, 1),
                    _estimate(row["converged"], 100, 1),
                    _estimate(row["converge_time"], 1, 2),
                    _estimate(row["messages"], 1, 2),
                ]
            )
        episodes = document["rows"][0]["error_final"]["n"] if document["rows"] else 0
        note = ""
        if episodes < FULL_EPISODES:
            note = (
                f"\n\n```{{note}}\nShort run: {episodes} episodes per setting. The full table "
                f"({FULL_EPISODES} episodes) still needs a run.\n```"
            )
        header = ["trigger", "final error mm", "converged %", "converge time s", "messages/robot/s"]
        # A file without "env" is from before the sweep took --version: it always ran v1.
        env = document.get("env", "consensus_v1")
        parts.append(
            f"**{env}**. "
            + provenance_line(document.get("meta"))
            + note
            + "\n\n"
            + table(header, rows)
            + "\n\nEach cell: the estimate over the episodes [95 % interval]: mean final error "
            "and messages (bootstrap), share converged (Wilson), median converge time."
        )
    return "\n\n".join(parts)


def table_changes(document: dict[str, Any]) -> dict[str, Any]:
    """The hyperparameters of a training run that differ from today's shipped table of its env
    and algorithm (``frame_stack`` and the step count aside, shown on their own); empty when
    there is no such table."""
    try:
        shipped = load_hyperparams(document["algo"], document["env_id"])
    except (ConfigError, KeyError):
        return {}
    used = document.get("hyperparams") or {}
    return {
        key: value
        for key, value in sorted(used.items())
        if key not in ("frame_stack", "n_timesteps") and key in shipped and shipped[key] != value
    }


def train_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """The training runs, one table an env and algorithm: steps, observations stacked
    (``frame_stack``), what differs from the shipped table, seed, final success on the mean
    action and sampling actions (runs that recorded it), wall time, steps/s. Each row's number
    refers to the list of runs under the table: where and how it was measured (the command is
    too long for a cell of a table that fits the page)."""
    documents = [d for _, d in files if kind(d) == "train"]
    if not documents:
        return missing_results(
            "khepera-gym train --env KheperaIV-Nav --algo ppo --seed 0 --out runs/ppo-nav",
            "run.json",
        )
    header = ["run", "steps", "frames", "changed from the shipped table", "seed"]
    header += ["success %", "sampled %", "wall time", "steps/s"]
    parts = []
    number = 0

    def algorithm(document: dict[str, Any]) -> str:
        return document.get("backend", "sb3") + " " + document["algo"].upper()

    documents = sorted(documents, key=lambda d: (d["env_id"], algorithm(d), d["seed"]))
    for (env_id, learner), group in itertools.groupby(
        documents, key=lambda d: (d["env_id"], algorithm(d))
    ):
        rows, runs = [], []
        for document in group:
            number += 1
            final = document["final"]
            sampled = document.get("final_sampled")
            rows.append(
                [
                    str(number),
                    f"{document['timesteps']:,}",
                    str((document.get("hyperparams") or {}).get("frame_stack", 1)),
                    escape_cell(
                        ", ".join(f"{k} {v}" for k, v in table_changes(document).items()) or "–"
                    ),
                    str(document["seed"]),
                    f"{100 * final['success_rate']:.0f} of {final['episodes']}",
                    "–" if sampled is None else f"{100 * sampled['success_rate']:.0f}",
                    f"{document['wall_time']:.0f} s",
                    f"{document['steps_per_second']:,.0f}",
                ]
            )
            runs.append(f"{number}. {provenance_line(document.get('meta'))}")
        parts.append(
            f"**{code(env_id)}, {learner}**: success on the final model's evaluation episodes "
            "(mean actions; sampled: sampling them):\n\n"
            + table(header, rows)
            + "\n\nThe runs:\n\n"
            + "\n".join(runs)
        )
    return "\n\n".join(parts)


def learning_seed(document: dict[str, Any]) -> int | None:
    """The training seed of a learned formation: its ``train_seed``, or for a file written
    before it was recorded, the ``--seed`` of its command line (None if neither says)."""
    seed = document["formation_learning"].get("train_seed")
    if seed is not None:
        return int(seed)
    words = shlex.split(str((document.get("meta") or {}).get("command", "")))
    for flag, value in itertools.pairwise(words):
        if flag == "--seed" and value.isdigit():
            return int(value)
    return None


def learning_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """Learned formations against the baseline: formation error, per results file."""
    documents = [d for _, d in files if kind(d) == "learning"]
    if not documents:
        return missing_results("python examples/formation_shared_ppo.py --json shared_ppo.json")
    parts = []
    for document in documents:
        run = document["formation_learning"]
        rows = [
            [
                escape_cell(row["policy"]),
                f"{100 * row['formation_error_mean']:.1f} cm",
                f"{100 * row['formation_error_max']:.1f} cm",
                "–" if row.get("success_rate") is None else f"{100 * row['success_rate']:.0f}",
                f"{row['contact_steps']:.1f}",
            ]
            for row in run["rows"]
        ]
        header = ["policy", "formation error mean", "max per episode", "leader arrived %"]
        header.append("steps in contact")
        # A file without its version is from before v3, when "formation (latest)" meant v2.
        env = run["env"] if run.get("version") else run["env"].replace("(latest)", "v2")
        note = (
            f" {escape_cell(env)}; {run['steps']:,} training steps in "
            f"{run['train_seconds']:.0f} s"
            + ("" if (seed := learning_seed(document)) is None else f", training seed {seed}")
            + f"; {run['episodes']} episodes from seed {run['eval_seed']}."
        )
        parts.append(provenance_line(document.get("meta")) + note + "\n\n" + table(header, rows))
    return "\n\n".join(parts)


def hostile_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """The hostile-input campaigns: cases by kind and outcome, failures, per results file."""
    documents = [d for _, d in files if kind(d) == "hostile"]
    if not documents:
        return missing_results(
            "python tests/hostile_campaign.py --cases 100000 --json hostile.json", "hostile.json"
        )
    parts = []
    for document in sorted(documents, key=lambda d: (d.get("meta") or {}).get("date", "")):
        rows = [
            [
                code(case_kind),
                ", ".join(f"{outcome} {n:,}" for outcome, n in sorted(outcomes.items())),
                f"{sum(outcomes.values()):,}",
            ]
            for case_kind, outcomes in sorted(document["by_kind"].items())
        ]
        summary = (
            f"**{document['cases']:,} cases, {document['failures']} failures**: "
            f"{document['accepted']:,} accepted, {document['refused']:,} refused with their "
            f"typed error, in {document['seconds']:,.0f} s."
        )
        failures = [
            f"`{f['replay']}` {escape_cell(f['kind'])}: {escape_cell(f['outcome'])}"
            for f in document.get("failure_list", [])
        ]
        listed = (
            ("\n\nFailures (replay with `--replay SEED:INDEX`): " + "; ".join(failures))
            if failures
            else ""
        )
        parts.append(
            provenance_line(document.get("meta"))
            + "\n\n"
            + summary
            + listed
            + "\n\n"
            + table(["kind of case", "outcomes", "cases"], rows)
        )
    return "\n\n".join(parts)


#: The fragments and what renders each.
FRAGMENTS: dict[str, Callable[[list[tuple[Path, dict[str, Any]]]], str]] = {
    "baselines": compare_fragment,
    "consensus": consensus_fragment,
    "training": train_fragment,
    "learning": learning_fragment,
    "bench": bench_fragment,
    "swarm": swarm_fragment,
    "hostile": hostile_fragment,
}


def fragments(results_dir: Path) -> dict[str, str]:
    """Every results fragment (``results-<name>.md``) from the folder's files.

    Raises:
        ValueError: A file of no known kind (so a mistyped file fails the build).
    """
    files = load(results_dir)
    for path, document in files:
        if kind(document) == "unknown":
            raise ValueError(f"{path}: not a results file of compare, train, bench or a campaign")
    rendered = {name: render(files) + "\n" for name, render in FRAGMENTS.items()}
    from khepera_gym.analysis.docgen.benchmark_results import (
        BENCHMARK_DIR,
        RECIPE_BEFORE_DIR,
        benchmark_fragment,
        recipe_speed_fragment,
    )

    rendered["benchmark"] = benchmark_fragment(results_dir / BENCHMARK_DIR) + "\n"
    rendered["recipe-speed"] = (
        recipe_speed_fragment(results_dir / RECIPE_BEFORE_DIR, results_dir / BENCHMARK_DIR) + "\n"
    )
    return rendered


def target_name(document: dict[str, Any]) -> str:
    """The file name a results file gets in docs/results/: its kind, what it measured and its
    date, so that a later run of another version or day does not replace it
    (``compare_KheperaIV-Avoid-v1_paper_fig6_2026-11-27.json``)."""
    date = (document.get("meta") or {}).get("date", "undated")[:10]
    policies = [str(summary.get("policy", "")) for summary in document.get("summaries", [])]
    trained = any(policy.startswith(SB3_PREFIX) for policy in policies)
    # Sampled actions (compare --sample-actions) are other figures of the same models.
    sampled = any(
        policy.startswith(SB3_PREFIX) and policy.endswith(SAMPLED_SUFFIX) for policy in policies
    )
    stack = (document.get("hyperparams") or {}).get("frame_stack", 1)
    what = {
        # A comparison with trained models next to the baselines does not replace their table.
        "compare": lambda: (
            f"{document['env_id']}_{document.get('label') or 'scene'}"
            + ("_trained" if trained else "")
            + ("_sampled" if sampled else "")
        ),
        "train": lambda: (
            f"{document['env_id']}_{document['algo']}_seed{document['seed']}"
            + (f"_stack{stack}" if stack != 1 else "")
            + "".join(
                "_" + "".join(c if c.isalnum() or c in ".-" else "_" for c in f"{k}{v}")
                for k, v in table_changes(document).items()
            )
        ),
        "consensus": lambda: "sweep",
        "learning": lambda: (
            "formation_"
            # Files since v3 name their version (earlier ones were all v2's, the latest then).
            + (f"v{version}_" if (version := document["formation_learning"].get("version")) else "")
            + "".join(
                c if c.isascii() and c.isalnum() else "_"
                for c in document["formation_learning"]["method"]
            )
            + (f"_seed{seed}" if (seed := learning_seed(document)) else "")
        ),
        "bench": lambda: f"v{document['version']}",
        "hostile": lambda: f"{document['cases']}cases_seed{document['seed']}",
    }[kind(document)]()
    return f"{kind(document)}_{what}_{date}.json"


def import_results(paths: list[Path], results_dir: Path) -> list[Path]:
    """Copies results files into the results folder (named by :func:`target_name`), without a
    comparison's per-episode rows (the tables need only the summaries).

    Raises:
        ValueError: A file that is not a results file of compare, train, bench or a campaign.
    """
    written = []
    results_dir.mkdir(parents=True, exist_ok=True)
    for path in paths:
        document = json.loads(path.read_text(encoding="utf-8"))
        if kind(document) == "unknown":
            raise ValueError(f"{path}: not a results file of compare, train, bench or a campaign")
        document.pop("episodes", None)
        target = results_dir / target_name(document)
        target.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
        written.append(target)
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m khepera_gym.analysis.docgen.results FILE... [--to docs/results]``."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m khepera_gym.analysis.docgen.results",
        description="copy results JSON files into the docs' results folder",
    )
    parser.add_argument("files", nargs="+", type=Path)
    parser.add_argument("--to", type=Path, default=Path("docs/results"))
    args = parser.parse_args(argv)
    for path in import_results(args.files, args.to):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = [
    "FRAGMENTS",
    "FULL_EPISODES",
    "fragments",
    "import_results",
]
