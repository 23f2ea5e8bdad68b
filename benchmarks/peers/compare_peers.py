"""khepera_gym beside VMAS and a hand-vectorised NumPy env: env-steps/s, interleaved (issue 54).

Run from the checkout's root, with an interpreter that has khepera_gym (built) and, for the
VMAS rows, ``vmas`` (``pip install vmas==1.5.2``; see README.md beside this file)::

    python -m benchmarks.peers.compare_peers --out docs/results/peers

Each measurement runs in a fresh child process (so no peer's thread pool or memory is left
behind for the next one): it builds the env, resets it with seed 0, steps it with uniform
random actions (8 arrays drawn beforehand, cycled) for a warm-up that is not timed, then for at
least ``--duration`` seconds of wall time (``time.perf_counter``), and reports env-steps/s (one
world advanced by one 50 ms control step). Every configuration is measured once in each of
``--repetitions`` rounds, in the same order (A B C ... A B C ...), so a change in the machine's
load touches all of them alike; ratios are taken within a round, and the median and range over
the rounds are reported.

The configurations (:data:`RUNS`):

* khepera_gym: ``gym.make_vec("KheperaIV-Nav-v3", num_envs=1024, num_threads=t)``, t = 2 and 1
  (its rayon pool), as issue 54 states it; and Nav-v3 with five random circular obstacles
  (``count=5, kinds=["circle"]``), the peers' scene.
* VMAS 1.5.2 on CPU, :mod:`benchmarks.peers.vmas_khepera`, 4,096 and 1,024 worlds, with torch's
  intra-op pool at 2 and at 1 thread (on a busy machine torch's spinning pool can lose most of
  its speed at 2 threads; both are measured and the ratios use VMAS' faster row). Worlds that
  finish are reset as VMAS' TorchRL wrapper does it: ``reset()`` when all are done, else
  ``reset_at(i)`` for each.
* NumPy, :mod:`benchmarks.peers.numpy_khepera`, 4,096 and 1,024 worlds (one thread: NumPy's
  element-wise kernels do not use more).

The JSON file holds the rows (each round's figure, median, min, max), the ratios, the date,
commit, machine and command (:func:`khepera_gym.tooling.provenance.provenance`), the CPU's
vector extensions (/proc/cpuinfo flags), which instruction sets NumPy and torch dispatch to,
and the versions and thread counts of torch and NumPy. The results page renders it
(:mod:`khepera_gym.analysis.docgen.peers`).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import shlex
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Distinct random action arrays cycled through while timing (as khepera-gym bench).
ACTION_SETS = 8
#: Seconds of untimed stepping before the timed window (and at least MIN_STEPS steps).
WARMUP_SECONDS = 1.0
#: Fewest steps in the warm-up and in the timed window.
MIN_STEPS = 3
#: The scene overrides of Nav-v3 that give it the peers' five circular obstacles.
FIVE_CIRCLES: dict[str, Any] = {"count": 5, "kinds": ["circle"]}


@dataclass(frozen=True)
class Run:
    """One configuration: which simulator, how many worlds, how many threads."""

    peer: str  # "khepera_gym", "vmas" or "numpy"
    label: str
    num_envs: int
    threads: int
    overrides: dict[str, Any] = field(default_factory=dict)

    @property
    def key(self) -> str:
        """A short unique name of the row."""
        return f"{self.label} n={self.num_envs} t={self.threads}"


#: Every configuration, in the order of a round.
RUNS: tuple[Run, ...] = (
    Run("khepera_gym", "khepera_gym Nav-v3", 1024, 2),
    Run("vmas", "VMAS", 4096, 2),
    Run("numpy", "NumPy", 4096, 1),
    Run("khepera_gym", "khepera_gym Nav-v3", 1024, 1),
    Run("vmas", "VMAS", 4096, 1),
    Run("numpy", "NumPy", 1024, 1),
    Run("khepera_gym", "khepera_gym Nav-v3 + 5 circles", 1024, 2, FIVE_CIRCLES),
    Run("vmas", "VMAS", 1024, 2),
    Run("khepera_gym", "khepera_gym Nav-v3 + 5 circles", 1024, 1, FIVE_CIRCLES),
    Run("vmas", "VMAS", 1024, 1),
)


# --- child: one measurement --------------------------------------------------------------------
def _actions(num_envs: int) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.uniform(-1.0, 1.0, (num_envs, 2)).astype(np.float32) for _ in range(ACTION_SETS)]


def _time_loop(step: Any, duration: float) -> tuple[int, float]:
    """Steps for the warm-up, then for at least ``duration`` s; returns (steps, seconds)."""
    start = time.perf_counter()
    count = 0
    while count < MIN_STEPS or time.perf_counter() - start < WARMUP_SECONDS:
        step(count)
        count += 1
    steps = 0
    start = time.perf_counter()
    now = start
    while steps < MIN_STEPS or now - start < duration:
        step(steps)
        steps += 1
        now = time.perf_counter()
    return steps, now - start


def _measure_khepera(run: Run, duration: float) -> dict[str, Any]:
    import gymnasium as gym

    import khepera_gym  # noqa: F401  (registers the envs)

    envs = gym.make_vec(
        "KheperaIV-Nav-v3", num_envs=run.num_envs, num_threads=run.threads, **run.overrides
    )
    actions = _actions(run.num_envs)
    envs.reset(seed=0)
    steps, seconds = _time_loop(lambda i: envs.step(actions[i % ACTION_SETS]), duration)
    envs.close()
    return {"steps": steps, "seconds": seconds}


def _measure_numpy(run: Run, duration: float) -> dict[str, Any]:
    from benchmarks.peers.numpy_khepera import NumpyKheperaNav

    env = NumpyKheperaNav(run.num_envs, seed=0)
    actions = _actions(run.num_envs)
    env.reset(seed=0)
    steps, seconds = _time_loop(lambda i: env.step(actions[i % ACTION_SETS]), duration)
    return {"steps": steps, "seconds": seconds}


def _measure_vmas(run: Run, duration: float) -> dict[str, Any]:
    import torch
    import vmas

    from benchmarks.peers import khepera_iv as k4
    from benchmarks.peers.vmas_khepera import Scenario

    torch.set_num_threads(run.threads)
    env = vmas.make_env(
        Scenario(),
        num_envs=run.num_envs,
        device="cpu",
        continuous_actions=True,
        max_steps=k4.MAX_STEPS,
        seed=0,
    )
    actions = [torch.from_numpy(a) for a in _actions(run.num_envs)]
    env.reset()
    resets = 0

    def step(index: int) -> None:
        nonlocal resets
        _, _, dones, _ = env.step([actions[index % ACTION_SETS]])
        if bool(dones.any()):
            finished = dones.nonzero().flatten().tolist()
            resets += len(finished)
            if len(finished) == run.num_envs:
                env.reset()
            else:
                for world in finished:
                    env.reset_at(world)

    steps, seconds = _time_loop(step, duration)
    return {
        "steps": steps,
        "seconds": seconds,
        "torch_threads": torch.get_num_threads(),
        "torch_cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "resets_during_run": resets,
    }


_MEASURE = {"khepera_gym": _measure_khepera, "numpy": _measure_numpy, "vmas": _measure_vmas}


def _child(index: int, duration: float) -> None:
    """Measures RUNS[index] and prints one JSON line."""
    run = RUNS[index]
    result = _MEASURE[run.peer](run, duration)
    result["load_average"] = [round(x, 2) for x in os.getloadavg()]
    print(json.dumps(result))


# --- parent: the interleaved rounds ------------------------------------------------------------


def software(python: str) -> dict[str, Any]:
    """Versions, thread counts and SIMD dispatch of the peers' libraries in ``python``."""
    code = (
        "import json, numpy, os\n"
        "info = {'numpy_threads_note': 'element-wise ufuncs run on the calling thread'}\n"
        "try:\n"
        "    from numpy._core import _multiarray_umath as m\n"
        "    info['numpy_simd_baseline'] = list(m.__cpu_baseline__)\n"
        "    info['numpy_simd_dispatch'] = list(m.__cpu_dispatch__)\n"
        "except ImportError:\n"
        "    pass\n"
        "try:\n"
        "    import torch\n"
        "    info['torch_default_threads'] = torch.get_num_threads()\n"
        "    info['torch_cpu_capability'] = torch.backends.cpu.get_cpu_capability()\n"
        "except ImportError:\n"
        "    pass\n"
        "print(json.dumps(info))\n"
    )
    child = subprocess.run([python, "-c", code], capture_output=True, text=True, check=True)
    info = json.loads(child.stdout)
    versions_code = (
        "import importlib.metadata as m, json\n"
        "def v(p):\n"
        "    try:\n"
        "        return m.version(p)\n"
        "    except m.PackageNotFoundError:\n"
        "        return None\n"
        "print(json.dumps({p: v(p) for p in ('numpy', 'torch', 'vmas', 'gymnasium')}))\n"
    )
    versions = subprocess.run(
        [python, "-c", versions_code], capture_output=True, text=True, check=True
    )
    info["versions"] = json.loads(versions.stdout)
    info["environment"] = {
        name: os.environ[name]
        for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "RAYON_NUM_THREADS")
        if name in os.environ
    }
    return info


def _measure_in_child(python: str, index: int, duration: float) -> dict[str, Any]:
    root = Path(__file__).resolve().parents[2]
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join(
        [str(root), *filter(None, [environment.get("PYTHONPATH")])]
    )
    child = subprocess.run(
        [
            python,
            "-m",
            "benchmarks.peers.compare_peers",
            *("--child", str(index)),
            *("--duration", str(duration)),
        ],
        capture_output=True,
        text=True,
        cwd=root,
        env=environment,
        check=False,
    )
    if child.returncode != 0:
        raise RuntimeError(f"{RUNS[index].key} failed:\n{child.stderr[-3000:]}")
    return json.loads(child.stdout.strip().splitlines()[-1])


def spread(values: Sequence[float]) -> dict[str, float]:
    """The median and range of interleaved rounds' figures (every benchmark here reports them)."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def ratios(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each khepera_gym row over VMAS' and NumPy's fastest rows (by median), within each round:
    the median and range over the rounds."""
    by_peer: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        by_peer.setdefault(row["peer"], []).append(row)
    best = {
        peer: max(peer_rows, key=lambda row: row["env_steps_per_second"]["median"])
        for peer, peer_rows in by_peer.items()
        if peer != "khepera_gym"
    }
    out = []
    for row in by_peer.get("khepera_gym", []):
        for peer, reference in best.items():
            per_round = [
                ours / theirs
                for ours, theirs in zip(row["rounds"], reference["rounds"], strict=True)
            ]
            out.append(
                {"row": row["key"], "over": reference["key"], "peer": peer, **spread(per_round)}
            )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the rounds, prints a table and writes the JSON file."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.peers.compare_peers", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--repetitions", type=int, default=5, help="rounds (default 5)")
    parser.add_argument(
        "--duration", type=float, default=4.0, help="timed seconds per measurement (4)"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder for peers_<date>.json (docs/results/peers for the results page)",
    )
    parser.add_argument(
        "--vmas-python",
        default=sys.executable,
        help="interpreter with vmas for the VMAS rows (default: this one)",
    )
    parser.add_argument("--skip-vmas", action="store_true", help="leave the VMAS rows out")
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        _child(args.child, args.duration)
        return 0

    from khepera_gym.tooling.provenance import provenance

    command = "python -m benchmarks.peers.compare_peers " + shlex.join(
        sys.argv[1:] if argv is None else list(argv)
    )
    runs = [run for run in RUNS if not (args.skip_vmas and run.peer == "vmas")]
    if not args.skip_vmas:
        probe = subprocess.run([args.vmas_python, "-c", "import vmas"], capture_output=True)
        if probe.returncode != 0:
            parser.error(
                f"{args.vmas_python} cannot import vmas: pip install vmas==1.5.2 there (see "
                "benchmarks/peers/README.md), pass --vmas-python, or --skip-vmas"
            )
    meta = provenance(command.strip())
    samples: dict[str, list[dict[str, Any]]] = {run.key: [] for run in runs}
    print(f"{len(runs)} configurations × {args.repetitions} rounds, {args.duration:g} s each")
    for round_index in range(args.repetitions):
        for run in runs:
            python = args.vmas_python if run.peer == "vmas" else sys.executable
            result = _measure_in_child(python, RUNS.index(run), args.duration)
            result["env_steps_per_second"] = run.num_envs * result["steps"] / result["seconds"]
            samples[run.key].append(result)
            print(
                f"round {round_index + 1}: {run.key:<48} "
                f"{result['env_steps_per_second']:>13,.0f} env-steps/s "
                f"(load {result['load_average'][0]})",
                flush=True,
            )
    rows = []
    for run in runs:
        figures = [s["env_steps_per_second"] for s in samples[run.key]]
        rows.append(
            {
                **asdict(run),
                "key": run.key,
                "rounds": figures,
                "env_steps_per_second": spread(figures),
                "samples": samples[run.key],
            }
        )
    from khepera_gym.tooling.provenance import cpu_flags  # the flags every results file records

    document = {
        "peers": 1,
        "meta": meta,
        "cpu_flags": cpu_flags(),
        "software": {
            "khepera_gym": software(sys.executable),
            "vmas": None if args.skip_vmas else software(args.vmas_python),
        },
        "settings": {
            "repetitions": args.repetitions,
            "duration_seconds": args.duration,
            "warmup_seconds": WARMUP_SECONDS,
            "action_sets": ACTION_SETS,
            "order": "interleaved: every configuration once per round, in the order of rows",
        },
        "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "rows": rows,
        "ratios": ratios(rows),
    }
    print()
    for ratio in document["ratios"]:
        print(
            f"{ratio['row']:<48} ÷ {ratio['over']:<24} {ratio['median']:6.2f}× "
            f"({ratio['min']:.2f}–{ratio['max']:.2f})"
        )
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        date = meta["date"][:10] if meta.get("date") else datetime.date.today().isoformat()
        path = args.out / f"peers_{date}.json"
        path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
        print(f"\nwrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
