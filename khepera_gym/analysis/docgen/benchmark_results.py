"""The learning benchmark's results pages: the tables of ``docs/results/benchmark/`` (what
``khepera-gym benchmark`` writes) and the shipped recipes' speed against the recipes before
them (``docs/results/benchmark_recipe_before/``). The other results fragments are
:mod:`khepera_gym.analysis.docgen.results`'s.
"""

from __future__ import annotations

import shlex
import statistics
from pathlib import Path
from typing import Any

from khepera_gym import registry
from khepera_gym.analysis.docgen.markdown import code, missing_results, table
from khepera_gym.tooling.provenance import portable_command

#: The learning benchmark's folder under docs/results/ (``khepera-gym benchmark --out``).
BENCHMARK_DIR = "benchmark"


def benchmark_fragment(folder: Path) -> str:
    """The learning benchmark's tables (:mod:`khepera_gym.learning.benchmark.tables`), one a task,
    from
    ``docs/results/benchmark/``, with where each was measured and how to run it again."""
    from khepera_gym.learning.benchmark.command import reproduce
    from khepera_gym.learning.benchmark.suite import load_suite
    from khepera_gym.learning.benchmark.tables import load_records, markdown, task_rows

    baselines, runs = load_records(folder)
    if not runs:
        return missing_results(f"khepera-gym benchmark --out docs/results/{BENCHMARK_DIR}")
    suite = load_suite()
    tasks = registry.task_names()
    parts = []
    for task in tasks:
        table = task_rows(task, baselines, runs)
        # A learner of the suite without a recorded run is named, never left out silently.
        recorded = {row["learner"] for row in table["learners"]}
        entry = suite.get(task)
        unrun = [name for name in (entry.learners if entry else ()) if name not in recorded]
        not_run = (
            "Not run yet: "
            + "; ".join(
                f"{name} ({code(f'khepera-gym benchmark --tasks {task} --learners {name}')})"
                for name in unrun
            )
            + "."
            if unrun
            else ""
        )
        if not table["learners"]:
            parts.append(f"**{task}**: no learned run recorded yet. {not_run}".rstrip())
            continue
        mine = [r for r in runs if r["key"]["task"] == task]
        dates = sorted({r["meta"]["date"][:10] for r in mine})
        commits = sorted(
            {
                (r["meta"].get("commit") or {}).get("id", "?")[:10]
                + (" with local changes" if (r["meta"].get("commit") or {}).get("dirty") else "")
                for r in mine
            }
        )
        commands = "\n".join(reproduce(task, row) for row in table["learners"])
        parts.append(
            markdown(table)
            + f"\n\nMeasured {', '.join(dates)} at commit {', '.join(f'`{c}`' for c in commits)}"
            + f" on {mine[0]['meta']['machine'].get('cpu', '?')} "
            + f"({mine[0]['meta']['machine'].get('cpus', '?')} CPUs)."
            + (f" {not_run}" if not_run else "")
            + " The rows again:"
            + f"\n\n```bash\n{commands}\n```"
            + (f"\n\nTried: {entry.tried}" if entry and entry.tried else "")
        )
    seconds = sum(r["train_seconds"] + (r.get("eval_seconds") or 0.0) for r in runs)
    parts.append(
        f"The {len(runs)} run{'s' if len(runs) != 1 else ''} above took {seconds / 3600:.1f} h "
        "of training and evaluation "
        "(the baselines aside), one after another on the machines named, which were shared: "
        "the suite's wall-clock on one machine. `--ray` spreads the runs over a cluster's CPUs."
    )
    return "\n\n".join(parts)


#: Runs of an earlier recipe, interleaved seed by seed with the shipped recipe's in one session
#: (``khepera-gym benchmark --hp ...`` into another folder): what the recipe's speed is measured
#: against.
RECIPE_BEFORE_DIR = "benchmark_recipe_before"


def recipe_speed_fragment(before_dir: Path, after_dir: Path) -> str:
    """The shipped recipe's training time against an earlier recipe's, seed by seed, from the
    runs of both in one session: per seed, each one's training time (evaluations excluded), the
    ratio, and each one's held-out success (one statistic a column)."""
    from khepera_gym.learning.benchmark.runner import means
    from khepera_gym.learning.benchmark.tables import load_records

    _, before = load_records(before_dir)
    if not before:
        return missing_results(
            f"khepera-gym benchmark --out docs/results/{RECIPE_BEFORE_DIR} --hp ..."
        )
    _, after = load_records(after_dir)

    def key(run: dict[str, Any]) -> tuple[Any, ...]:
        k = run["key"]
        return (k["task"], k["learner"], k["version"], k["seed"])

    shipped = {key(run): run for run in after}
    rows, ratios, totals = [], [], [0.0, 0.0]
    for run in sorted(before, key=key):
        other = shipped.get(key(run))
        if other is None:
            continue
        ratio = run["train_seconds"] / other["train_seconds"]
        ratios.append(ratio)
        totals[0] += run["train_seconds"]
        totals[1] += other["train_seconds"]
        task, learner, version, seed = key(run)
        rows.append(
            [
                f"{task} {learner} v{version}",
                str(seed),
                f"{run['train_seconds']:.0f}",
                f"{other['train_seconds']:.0f}",
                f"{ratio:.1f}",
                f"{100 * means(run['final']).get('success', 0):.1f}",
                f"{100 * means(other['final']).get('success', 0):.1f}",
            ]
        )
    if not rows:
        return "No run of the earlier recipe has a run of the shipped recipe of the same seed."
    meta = before[0]["meta"]
    words = shlex.split(meta.get("command", ""))
    # The folder is the measuring machine's; the recipe is what a reader needs.
    for flag in ("--out", "--seed-list"):
        while flag in words:
            i = words.index(flag)
            end = i + 1
            while end < len(words) and not words[end].startswith("--"):
                end += 1
            del words[i:end]
    # And no other path of the machine (a --suite file): its name is what a reader can use.
    words = shlex.split(portable_command(shlex.join(words), before_dir))
    median = statistics.median(ratios)
    return (
        table(
            [
                "task",
                "seed",
                "training s, earlier recipe",
                "training s, shipped",
                "ratio",
                "success %, earlier",
                "success %, shipped",
            ],
            rows,
        )
        + f"\n\nIn all, {totals[0]:.0f} s against {totals[1]:.0f} s of training "
        + f"({totals[0] / totals[1]:.1f}x; median ratio {median:.1f}); success is on the 200 "
        + "held-out episodes with mean actions. Run interleaved, seed by seed, on "
        + f"{meta['date'][:10]} at commit `{(meta.get('commit') or {}).get('id', '?')[:10]}` on "
        + f"{meta['machine'].get('cpu', '?')} ({meta['machine'].get('cpus', '?')} CPUs). "
        + "The earlier recipe's runs:"
        + f"\n\n```bash\n{shlex.join(words)} --seed-list S\n```"
    )
