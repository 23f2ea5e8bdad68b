"""Throughput and memory benchmark of the Nav task (``khepera-gym bench``, examples/benchmark.py).

Measures env-steps per second of

* the native vector env, ``gym.make_vec("KheperaIV-Nav-v3", num_envs=n, num_threads=t)``, for
  n in 1, 64, 1024, 4096 and t in 1, 2; then every other task with a Gymnasium env (from the
  registry: :data:`OTHER_TASKS`) and Nav with the camera (4 rays a pixel, and 1) for n = 1024;
* the single env through ``gym.make`` with its wrappers (env checker, order enforcing);
* (v1) world-steps/s of swarms of 4 to 10,000 robots per world
(:mod:`khepera_gym.analysis.swarm_throughput`);

with uniform random actions generated beforehand, a warm-up, then a fixed wall time per
configuration; and the resident memory per world of a 4096-world batch (Linux ``/proc``).
Timing is wall-clock (``time.perf_counter``) and includes the Python layer. ``--json PATH``
writes the rows with the date, commit, machine and command (:mod:`khepera_gym.tooling.provenance`),
the data of the documentation's performance tables.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import json
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import khepera_gym
from khepera_gym import _core, registry
from khepera_gym.analysis.swarm_throughput import swarm_rows
from khepera_gym.errors import ConfigError
from khepera_gym.registration import registered_ids
from khepera_gym.tooling import arguments
from khepera_gym.tooling.provenance import provenance

NAV_ID = f"KheperaIV-Nav-v{registry.LATEST_VERSION}"
#: Distinct pregenerated action arrays cycled through while timing.
_ACTION_SETS = 8
#: The other tasks' native vector envs timed after Nav (with ``task_envs`` worlds), by id
#: without its version: every task with a Gymnasium env but Nav, in the registry's order (a new
#: task is timed without an edit here). A task whose version does not exist (most begin at v1)
#: is left out of ``--version 0``.
OTHER_TASKS = tuple(
    ids[-1].rsplit("-v", 1)[0] for task, ids in registered_ids().items() if task != "nav"
)
#: Nav with the camera observed (4 rays a pixel, then 1): what the sensor costs.
CAMERA_ROWS: tuple[tuple[str, dict[str, object]], ...] = (
    ("Nav+camera", {"carry": ["ir", "us", "gyro", "camera"], "observe": ["ir", "us", "camera"]}),
    (
        "Nav+camera 1 ray",
        {
            "carry": ["ir", "us", "gyro", "camera"],
            "observe": ["ir", "us", "camera"],
            "camera_rays_per_pixel": 1,
        },
    ),
)
#: Worlds of the batch whose memory is measured.
_MEMORY_WORLDS = 4096


@dataclass
class Measurement:
    """One benchmark configuration and its throughput."""

    label: str
    num_envs: int
    num_threads: int | None
    steps: int
    seconds: float

    @property
    def env_steps_per_second(self) -> float:
        """Env-steps (one world advanced by one control step) per second of wall time."""
        return self.num_envs * self.steps / self.seconds

    @property
    def microseconds_per_step(self) -> float:
        """Wall time of one call to ``step`` (all worlds), in µs."""
        return 1e6 * self.seconds / self.steps


def _random_actions(rng: np.random.Generator, shape: tuple[int, ...]) -> list[np.ndarray]:
    return [rng.uniform(-1.0, 1.0, size=shape).astype(np.float32) for _ in range(_ACTION_SETS)]


def bench_vector(
    num_envs: int,
    num_threads: int,
    duration: float,
    warmup: int = 20,
    env_id: str = NAV_ID,
    label: str | None = None,
    **overrides: object,
) -> Measurement:
    """Times ``step`` of the native vector env for about ``duration`` seconds (``overrides``:
    scenario keys, as ``gym.make_vec``'s; ``label`` names the row instead of the task)."""
    envs = gym.make_vec(env_id, num_envs=num_envs, num_threads=num_threads, **overrides)
    act_dim = envs.single_action_space.shape[0]
    actions = _random_actions(np.random.default_rng(0), (num_envs, act_dim))
    envs.reset(seed=0)
    for step in range(warmup):
        envs.step(actions[step % _ACTION_SETS])
    steps = 0
    start = time.perf_counter()
    deadline = start + duration
    now = start
    while now < deadline:
        for action in actions:
            envs.step(action)
        steps += _ACTION_SETS
        now = time.perf_counter()
    envs.close()
    task = env_id.removeprefix("KheperaIV-").rsplit("-v", 1)[0]
    name = label + " " if label else "" if task == "Nav" else task + " "
    return Measurement(f"{name}make_vec n={num_envs}", num_envs, num_threads, steps, now - start)


def bench_single(duration: float, warmup: int = 200, env_id: str = NAV_ID) -> Measurement:
    """Times ``step`` of one env made by ``gym.make`` (with its wrappers); resets on episode end."""
    env = gym.make(env_id)
    actions = _random_actions(np.random.default_rng(0), (2,))
    env.reset(seed=0)
    steps = 0

    def run(count: int) -> None:
        for index in range(count):
            _, _, terminated, truncated, _ = env.step(actions[index % _ACTION_SETS])
            if terminated or truncated:
                env.reset()

    run(warmup)
    start = time.perf_counter()
    deadline = start + duration
    now = start
    chunk = 256
    while now < deadline:
        run(chunk)
        steps += chunk
        now = time.perf_counter()
    env.close()
    return Measurement("gym.make (single)", 1, None, steps, now - start)


def _resident_bytes() -> int | None:
    """Resident set size of this process from /proc/self/statm, or None where unavailable."""
    try:
        with open("/proc/self/statm", encoding="ascii") as statm:
            resident_pages = int(statm.read().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return resident_pages * os.sysconf("SC_PAGE_SIZE")


def memory_per_world(num_worlds: int = _MEMORY_WORLDS) -> float | None:
    """Resident bytes per world added by creating, resetting and stepping a batch of Nav worlds,
    measured in a fresh Python process: in this one, memory that earlier measurements freed is
    reused and the growth reads as 0 (two benchmark runs of 2026-11-28 recorded 0.0 KiB). None
    where the resident set cannot be read or the child fails."""
    code = (
        "import sys; from khepera_gym.analysis.throughput import _memory_here; "
        "print(_memory_here(int(sys.argv[1])))"
    )
    try:
        child = subprocess.run(
            [sys.executable, "-c", code, str(num_worlds)],
            capture_output=True,
            text=True,
            timeout=600,
            check=True,
        )
        return float(child.stdout.split()[-1])
    except (OSError, subprocess.SubprocessError, ValueError, IndexError):
        return None


def _memory_here(num_worlds: int) -> float | None:
    """:func:`memory_per_world`, in this process (what its child runs)."""
    gc.collect()
    before = _resident_bytes()
    if before is None:
        return None
    batch = _core.Batch("nav", num_worlds, num_threads=1)
    batch.reset(0)
    batch.step(np.zeros((num_worlds, batch.act_dim), dtype=np.float32))
    after = _resident_bytes()
    del batch
    assert after is not None
    return (after - before) / num_worlds


def run(
    num_envs: Sequence[int] = (1, 64, 1024, 4096),
    num_threads: Sequence[int] = (1, 2),
    duration: float = 1.5,
    single: bool = True,
    memory: bool = True,
    task_envs: int = 1024,
    version: int = registry.LATEST_VERSION,
    swarm: Sequence[int] = (),
    json_path: str | Path | None = None,
) -> list[Measurement]:
    """Runs the benchmark of behaviour ``version``'s envs and prints a table; returns the
    measurements, and with ``json_path`` writes them, the memory per world, the swarm rows and
    the provenance (``meta``) there."""
    nav_id = f"KheperaIV-Nav-v{version}"
    print(f"khepera_gym {khepera_gym.__version__} benchmark: {nav_id}, uniform random actions,")
    print(f"{duration:.1f} s per configuration after warm-up; {os.cpu_count()} CPU(s) visible\n")
    header = (
        f"{'configuration':<22} {'threads':>7} {'env-steps/s':>13} {'µs/step':>10} {'×1 thread':>9}"
    )
    print(header)
    print("-" * len(header))
    measurements: list[Measurement] = []

    def thread_rows(
        count: int, env_id: str, label: str | None = None, overrides: dict | None = None
    ) -> None:
        """Times one batch size at every thread count and prints a row each."""
        single_thread_rate: float | None = None
        for threads in num_threads:
            result = bench_vector(
                count, threads, duration, env_id=env_id, label=label, **(overrides or {})
            )
            measurements.append(result)
            rate = result.env_steps_per_second
            if threads == 1:
                single_thread_rate = rate
            speedup = f"{rate / single_thread_rate:.2f}" if single_thread_rate else ""
            print(
                f"{result.label:<22} {threads:>7} {rate:>13,.0f} "
                f"{result.microseconds_per_step:>10.1f} {speedup:>9}",
                flush=True,
            )

    for count in num_envs:
        thread_rows(count, nav_id)
    for env_id in OTHER_TASKS if task_envs else ():
        if f"{env_id}-v{version}" in gym.registry:
            thread_rows(task_envs, f"{env_id}-v{version}")
    for label, overrides in CAMERA_ROWS if task_envs and version >= 1 else ():
        thread_rows(task_envs, nav_id, label, overrides)
    if single:
        result = bench_single(duration, env_id=nav_id)
        measurements.append(result)
        print(
            f"{result.label:<22} {'-':>7} {result.env_steps_per_second:>13,.0f} "
            f"{result.microseconds_per_step:>10.1f} {'':>9}",
            flush=True,
        )
    per_world = None
    if memory:
        per_world = memory_per_world()
        print()
        if per_world is None:
            print("memory per world: n/a (needs /proc/self/statm)")
        else:
            print(
                f"memory per world: {per_world / 1024:.1f} KiB "
                f"(resident-set growth of a {_MEMORY_WORLDS}-world Nav batch)"
            )
    swarm_table = (
        swarm_rows(swarm, num_threads, duration, version) if swarm and version >= 1 else []
    )
    if json_path is not None:
        document = {
            "meta": provenance(),
            "version": version,
            "duration": duration,
            "rows": [
                dataclasses.asdict(m) | {"env_steps_per_second": m.env_steps_per_second}
                for m in measurements
            ],
            "memory_per_world_bytes": per_world,
            # How it was measured: the results page shows only a fresh process's figure.
            "memory_process": "fresh" if per_world is not None else None,
            "swarm": swarm_table,
        }
        _write_json(Path(json_path), document)
    return measurements


def _write_json(path: Path, document: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    print(f"\nsaved {path}")


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; ``--quick`` runs smaller batches for a shorter time."""
    parser = argparse.ArgumentParser(
        prog="khepera-gym bench",
        description="Env-steps/s of the vector and single envs; memory per world.",
    )
    add_arguments(parser)
    return run_from_args(parser.parse_args(argv))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's options to ``parser`` (shared with the ``khepera-gym`` CLI)."""
    parser.add_argument(
        "--quick", action="store_true", help="n in 1, 64, 1024 for 0.3 s each (a smoke run)"
    )
    parser.add_argument(
        "--duration", type=float, default=None, help="seconds per configuration (default 1.5)"
    )
    parser.add_argument(
        "--num-envs", type=int, nargs="+", default=None, help="batch sizes (default 1 64 1024 4096)"
    )
    parser.add_argument(
        "--threads", type=int, nargs="+", default=[1, 2], help="thread counts (default 1 2)"
    )
    parser.add_argument("--no-single", action="store_true", help="skip the gym.make single env")
    parser.add_argument("--no-memory", action="store_true", help="skip the memory measurement")
    parser.add_argument(
        "--version",
        type=int,
        choices=range(registry.LATEST_VERSION + 1),
        default=registry.LATEST_VERSION,
        help=f"behaviour version of the envs (default {registry.LATEST_VERSION}, the latest)",
    )
    parser.add_argument(
        "--json",
        type=Path,
        default=None,
        metavar="PATH",
        help="also write the rows, with date, commit, machine and command, to this JSON file",
    )


def run_from_args(args: argparse.Namespace) -> int:
    """Runs the benchmark as configured by :func:`add_arguments`'s options, once they are
    checked (counts, duration, the JSON file's folder, created if needed).

    Raises:
        ConfigError: A bad option, before anything is measured.
    """
    arguments.all_at_least(args.num_envs, 1, "--num-envs")
    arguments.all_at_least(args.threads, 1, "--threads")
    if args.duration is not None and not args.duration > 0:
        raise ConfigError(f"--duration must be > 0 s, got {args.duration}")
    if args.json is not None:
        arguments.output_file(args.json, (".json",), "--json")
    quick = args.quick
    num_envs = args.num_envs or ([1, 64, 1024] if quick else [1, 64, 1024, 4096])
    duration = args.duration if args.duration is not None else (0.3 if quick else 1.5)
    run(
        num_envs=num_envs,
        num_threads=args.threads,
        duration=duration,
        single=not args.no_single,
        memory=not args.no_memory,
        version=args.version,
        swarm=(4, 1000) if quick else (4, 32, 100, 300, 1000, 10000),
        json_path=args.json,
    )
    return 0


__all__ = ["Measurement", "bench_single", "bench_vector", "main", "memory_per_world", "run"]
