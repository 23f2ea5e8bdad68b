"""The random policy's rows of a results folder whose baselines were played before the benchmark
played it beside them (``runner.RANDOM``): ``python -m khepera_gym.learning.benchmark.random_rows
--out docs/results/benchmark`` plays it on each suite task's held-out episodes (the same episodes,
seeds and env as the baselines file beside it) and writes ``<out>/random/<task>-v<version>.json``,
a baselines file of one row with its own provenance. The aggregate statistics
(:mod:`khepera_gym.learning.benchmark.aggregate`) read it where the baselines file has no random
row.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark.runner import (
    FORMAT,
    RANDOM,
    Settings,
    baseline_env_name,
    baseline_policy,
    play,
    summarize,
    write_record,
)
from khepera_gym.learning.benchmark.suite import load_suite
from khepera_gym.tooling.provenance import provenance

#: The folder of the random rows, under a results folder.
RANDOM_DIR = "random"


def write_random_rows(out: Path, tasks: Sequence[str] | None = None) -> list[Path]:
    """For each baselines file of ``out`` (of ``tasks``, or all) without a random row, plays
    the random policy on its episodes and writes ``out/random/<task>-v<version>.json``.

    Raises:
        ConfigError: ``out`` has no baselines files.
    """
    files = sorted((out / "baselines").glob("*.json"))
    if not files:
        raise ConfigError(f"{out}: no baselines/ files to add random rows to")
    suite = load_suite()
    written = []
    for path in files:
        record = json.loads(path.read_text(encoding="utf-8"))
        key = record["key"]
        task = key["task"]
        if (tasks and task not in tasks) or task not in suite or RANDOM in record["summaries"]:
            continue
        settings = Settings(out=out, episodes=key["episodes"], heldout_seed=key["heldout_seed"])
        rows = baseline_env_name(task, key["version"])
        summary = summarize(play(baseline_policy(RANDOM, rows), rows, settings))
        row_key = {**key, "baselines": [RANDOM]}
        target = out / RANDOM_DIR / path.name
        write_record(
            target,
            {
                "format": FORMAT,
                "key": row_key,
                "meta": provenance(),
                "summaries": {RANDOM: summary},
            },
        )
        print(f"{task}: random {summary.get('success', {}).get('value', '')} -> {target}")
        written.append(target)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m khepera_gym.learning.benchmark.random_rows", description=__doc__
    )
    parser.add_argument("--out", type=Path, required=True, help="the benchmark's results folder")
    parser.add_argument("--tasks", nargs="*", default=None, help="only these tasks")
    args = parser.parse_args(argv)
    write_random_rows(args.out, args.tasks)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
