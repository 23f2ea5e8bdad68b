"""khepera_gym on each vector path this CPU has, interleaved: env-steps/s of ``khepera-gym
bench`` per path (issue 54).

Run from the checkout's root, with an interpreter that has khepera_gym (built)::

    python -m benchmarks.simd_paths --out docs/results/simd_paths_DATE.json
    python -m benchmarks.simd_paths --before ../v0.2.0 --out ...   # and another build beside

Each measurement is one ``khepera-gym bench --json`` in a fresh child process with
``KHEPERA_GYM_SIMD`` set to the path (``portable``, ``avx2``, ``avx512``: those the CPU has).
``--before DIR`` adds a column for another source tree with its own built extension (its
``khepera_gym`` imported from DIR, as ``PYTHONPATH=DIR``), run on its own default path. Every
column is measured once in each of ``--rounds`` rounds, in the same order, so a change in the
machine's load touches all of them alike; each configuration's ratio to the first column is
taken within a round, and the median and range over the rounds are reported.

The JSON file holds, per configuration (the bench's rows: every task's ``make_vec`` batch and
the swarm table's worlds), each column's figures per round and the ratios, with the date,
commit, machine (its vector extensions and the path that runs by default) and command
(:func:`khepera_gym.tooling.provenance.provenance`).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from benchmarks.peers.compare_peers import spread
from khepera_gym import _core
from khepera_gym.tooling.provenance import portable_command, provenance


def bench(env: dict[str, str], args: argparse.Namespace) -> dict[str, float]:
    """One ``khepera-gym bench`` in a child process: configuration label → env-steps/s."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "bench.json"
        command = [
            sys.executable,
            "-m",
            "khepera_gym.cli",
            "bench",
            "--num-envs",
            *map(str, args.num_envs),
            "--threads",
            *map(str, args.threads),
            "--duration",
            str(args.duration),
            "--no-single",
            "--no-memory",
            "--json",
            str(out),
        ]
        subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL)
        document = json.loads(out.read_text(encoding="utf-8"))
    figures = {
        f"{row['label']} t={row['num_threads']}": row["env_steps_per_second"]
        for row in document["rows"]
    }
    for row in document.get("swarm") or []:
        scene = f" ({row['scene']} scene)" if row.get("scene") else ""
        label = f"swarm {row['robots']} robots{scene} split={row['split']} t={row['threads']}"
        figures[label] = row["robot_steps_per_second"]
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--duration", type=float, default=1.0, help="seconds a configuration")
    parser.add_argument("--num-envs", type=int, nargs="+", default=[1024])
    parser.add_argument("--threads", type=int, nargs="+", default=[2])
    parser.add_argument("--before", type=Path, default=None, help="another built source tree")
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args(argv)
    # What a user types (as compare_peers records it), without this machine's paths.
    command = "python -m benchmarks.simd_paths " + shlex.join(
        sys.argv[1:] if argv is None else list(argv)
    )
    paths = [name for name, have in _core.simd_paths() if have]
    base = {k: v for k, v in os.environ.items() if k not in ("KHEPERA_GYM_SIMD", "PYTHONPATH")}
    columns: dict[str, dict[str, str]] = {}
    head = None
    if args.before is not None:
        before = args.before.resolve()
        head = subprocess.run(
            ["git", "-C", str(before), "rev-parse", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        columns["before"] = {**base, "PYTHONPATH": str(before)}
    here = str(Path(__file__).resolve().parents[1])
    for path in paths:
        columns[path] = {**base, "KHEPERA_GYM_SIMD": path, "PYTHONPATH": here}
    rounds: dict[str, list[dict[str, float]]] = {name: [] for name in columns}
    for number in range(args.rounds):
        for name, env in columns.items():
            rounds[name].append(bench(env, args))
            print(f"round {number + 1}/{args.rounds}: {name}", file=sys.stderr)
    first = next(iter(columns))
    rows = []
    for label in rounds[first][0]:
        row: dict[str, Any] = {"configuration": label, "columns": {}, "ratios": {}}
        for name in columns:
            figures = [r[label] for r in rounds[name] if label in r]
            row["columns"][name] = {"rounds": figures, **spread(figures)}
            if name != first and len(figures) == args.rounds:
                pairs = zip(rounds[name], rounds[first], strict=True)
                ratio = [r[label] / f[label] for r, f in pairs]
                row["ratios"][name] = {"rounds": ratio, **spread(ratio)}
        rows.append(row)
    document = {
        "simd_paths": 1,
        "meta": provenance(portable_command(command, args.out.parent)),
        "columns": list(columns),
        "reference": first,
        "before_commit": head,
        "settings": {
            "rounds": args.rounds,
            "duration": args.duration,
            "num_envs": args.num_envs,
            "threads": args.threads,
        },
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
