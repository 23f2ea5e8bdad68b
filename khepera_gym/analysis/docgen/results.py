"""Results tables from data: the JSON files that ``khepera-gym compare``, ``train`` and
``bench`` write (each with its ``meta``: date, commit, machine, command), kept in docs/results/,
rendered into the results pages at docs build time.

A file's kind is read from its content: a comparison (``summaries``), the consensus sweep
(``rows`` of triggers), a training run (``algo`` and ``final``) or a benchmark (``rows`` of
labels). The tables are the tools' own (a comparison's columns come from
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
from khepera_gym.analysis.docgen.width import split_table
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import SAMPLED_SUFFIX, SB3_PREFIX
from khepera_gym.learning.recipes import load_hyperparams
from khepera_gym.tooling.provenance import portable_command
from khepera_gym.tooling.stats import Estimate

#: Episodes per policy of a full comparison (the project's published tables).
FULL_EPISODES = 200


def load(results_dir: Path) -> list[tuple[Path, dict[str, Any]]]:
    """Every results file of the folder, by name."""
    if not results_dir.is_dir():
        return []
    return [
        (path, json.loads(path.read_text(encoding="utf-8")))
        for path in sorted(results_dir.glob("*.json"))
    ]


def kind(document: Any) -> str:
    """``"compare"``, ``"consensus"``, ``"train"``, ``"learning"`` (a learned formation, from
    ``examples/formation_shared_ppo.py --json``), ``"bench"``, ``"hostile"`` (a hostile-input
    campaign, ``python tests/hostile_campaign.py --json``) or ``"unknown"``."""
    if not isinstance(document, dict):
        return "unknown"
    if "summaries" in document:
        return "compare"
    if "algo" in document and "final" in document:
        return "train"
    if isinstance(document.get("formation_learning"), dict):
        return "learning"
    rows = document.get("rows")
    if isinstance(rows, list) and rows and "trigger" in rows[0]:
        return "consensus"
    if isinstance(rows, list) and "swarm" in document:
        return "bench"
    if isinstance(document.get("by_kind"), dict) and "failures" in document:
        return "hostile"
    return "unknown"


#: The package's command line run from a source tree (``python <tree>/khepera_gym/cli.py``, or
#: ``python -m khepera_gym.cli``): a user types it ``khepera-gym``.
_CLI = re.compile(r"^python3? (?:\S*/)?khepera_gym/cli\.py\b|^python3? -m khepera_gym\.cli\b")
#: A script of the repository run by its absolute path: a user types it from the checkout.
_SCRIPT = re.compile(r"^(python3?) \S*/((?:examples|tests)/\S+\.py)\b")
#: The checkout the documentation is built from.
_CHECKOUT = Path(__file__).resolve().parents[3]
#: A module of the package run by its file's path: a user types ``python -m`` and its name.
_MODULE = re.compile(r"^(python3?) \S*/khepera_gym/(\S+)\.py\b")


def as_typed(command: str) -> str:
    """A recorded command as a user types it in a checkout: ``khepera-gym train ...`` for the
    package's command line however it was started, ``python examples/x.py ...`` for a script,
    ``python -m khepera_gym.<module>`` for a module of the package; paths of the machine that
    ran it are made relative to the checkout or cut to their names
    (:func:`khepera_gym.tooling.provenance.portable_command`)."""
    command = _CLI.sub("khepera-gym", command)
    command = _SCRIPT.sub(r"\1 \2", command)
    command = _MODULE.sub(lambda m: f"{m[1]} -m khepera_gym.{m[2].replace('/', '.')}", command)
    return portable_command(command, _CHECKOUT / "docs")


def provenance_line(meta: dict[str, Any] | None) -> str:
    """Where a table's figures come from, in one sentence."""
    if not meta:
        return "*Provenance not recorded.*"
    commit = meta.get("commit")
    if commit:
        where = f"commit `{commit['id'][:10]}`" + (" with local changes" if commit["dirty"] else "")
    else:
        where = f"khepera_gym {meta.get('khepera_gym', '?')}"
    machine = meta.get("machine") or {}
    load_average = machine.get("load_average")
    load_text = f", load average {load_average[0]}" if load_average else ""
    return (
        f"Measured {meta.get('date', '?')[:10]} at {where} on {machine.get('cpu', '?')} "
        f"({machine.get('cpus', '?')} CPUs{load_text}): {code(as_typed(meta.get('command', '?')))}."
    )


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


def swarm_fragment(files: list[tuple[Path, dict[str, Any]]]) -> str:
    """The swarm rows of the benchmark runs: world- and robot-steps/s by robots per world, and
    each row's cost of a robot-step against 4-robot worlds split by world on as many threads."""
    documents = [d for _, d in files if kind(d) == "bench" and d.get("swarm")]
    if not documents:
        return missing_results("khepera-gym bench --json bench.json")
    parts = []
    for document in documents:
        swarm = document["swarm"]
        small = {
            row["threads"]: row["robot_steps_per_second"]
            for row in swarm
            if row["robots"] == 4 and row["split"] == "world" and not row.get("scene")
        }

        def cost(row: dict[str, Any], small: dict[int, float] = small) -> str:
            reference = small.get(row["threads"])
            return f"{reference / row['robot_steps_per_second']:.2f}×" if reference else "–"

        rows = [
            [
                f"{row['robots']:,}" + (" (`swarm` scene)" if row.get("scene") else ""),
                str(row["worlds"]),
                row["split"],
                str(row["threads"]),
                f"{row['world_steps_per_second']:,.0f}",
                f"{row['robot_steps_per_second']:,.0f}",
                cost(row),
                f"{row['real_time_factor']:.1f}",
            ]
            for row in swarm
        ]
        header = ["robots per world", "worlds", "split", "threads", "world-steps/s"]
        header += ["robot-steps/s", "cost of a robot-step", "× real time"]
        versions = sorted({row.get("version", SWARM_VERSION_BEFORE) for row in swarm})
        named = ", ".join(f"v{v}" for v in versions)
        note = f"Multinav {named}" + (
            " (until 2026-12-07 the swarm rows ran version 1 whatever the bench's `--version`)."
            if "version" not in swarm[0]
            else "."
        )
        parts.append(
            provenance_line(document.get("meta")) + " " + note + "\n\n" + table(header, rows)
        )
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
    "kind",
    "load",
    "provenance_line",
]
