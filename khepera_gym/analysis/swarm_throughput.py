"""Swarm scale: world-steps/s and robot-steps/s of multinav worlds of 4 to 10,000
robots with IR, sonar and contacts, through the array env
(:class:`~khepera_gym.pettingzoo.arrays.MultiAgentArrayEnv` of multinav, the benchmark's behaviour
version), uniform random actions.

Arenas grow with √robots to keep multinav's density (4 robots in 2 m × 2 m); a batch holds 1,024
robots' worth of worlds. The last row is the built-in ``swarm`` scene (1,000 robots in a 20 m
arena, 2.5 times as dense). Every size runs twice: with ``physics.split = "world"`` (the
default: one robot that can touch something sends every robot through rapier) and ``"robot"``
(only those that can), small worlds too, so that a swarm's per-robot cost can be set beside
small worlds' on either split. "× real time" is one world's simulated seconds per second
(control step 0.05 s). Called by :func:`khepera_gym.analysis.throughput.run`;
prints, asserts nothing.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv
from khepera_gym.pettingzoo.multinav import MultiNavParallelEnv
from khepera_gym.registry import LATEST_VERSION

#: Control step of the scenes (s), for "× real time".
_DT = 0.05


def bench_swarm(
    robots: int,
    threads: int,
    duration: float,
    scene: bool = False,
    split: str = "world",
    version: int | None = None,
) -> float:
    """World-steps/s of worlds of ``robots`` robots on ``threads`` threads over ``duration`` s
    (``scene``: the built-in ``swarm`` scene instead of an arena scaled to multinav's density;
    ``split``: the ``physics.split`` key; ``version``: the behaviour version, the latest when
    None)."""
    worlds = max(1, 1024 // robots)
    side = 2.0 * (robots / 4.0) ** 0.5
    # The built-in scene, or multinav's density in an arena scaled to the robots.
    world: dict[str, Any] = (
        {"config": "swarm"} if scene else {"n_robots": robots, "width": side, "height": side}
    )
    env = MultiAgentArrayEnv(
        MultiNavParallelEnv.TASK,
        worlds,
        version=version,
        num_threads=threads,
        max_steps=100000,
        physics={"split": split},
        **world,
    )
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = [rng.uniform(-1, 1, (worlds, robots, 2)).astype(np.float32) for _ in range(16)]
    for action in actions[:5]:
        env.step(action)
    steps = 0
    start = time.perf_counter()
    while time.perf_counter() - start < duration:
        env.step(actions[steps % len(actions)])
        steps += 1
    return steps * worlds / (time.perf_counter() - start)


def swarm_rows(
    robot_counts: Sequence[int] = (4, 32, 100, 300, 1000),
    num_threads: Sequence[int] = (1, 2),
    duration: float = 1.5,
    version: int | None = None,
) -> list[dict[str, Any]]:
    """Prints the scaling table: one row per robot count, split and thread count, then the
    scene, of behaviour version ``version`` (the latest when None); returns the rows (robots,
    scene, split, threads, world-steps/s, robot-steps/s, × real time, version)."""
    header = (
        f"{'robots per world':<22} {'split':>5} {'threads':>7} {'world-steps/s':>13} "
        f"{'robot-steps/s':>13} {'× real time':>11}"
    )
    print("\nswarm scale (multinav through the array env, uniform random actions)")
    print(header)
    print("-" * len(header))
    cases = [(n, False) for n in robot_counts] + [(1000, True)]
    rows = []
    for robots, scene in cases:
        for split in ("world", "robot"):
            for threads in num_threads:
                rows.append(_row(robots, scene, split, threads, duration, version))
    return rows


def _row(
    robots: int, scene: bool, split: str, threads: int, duration: float, version: int | None
) -> dict[str, Any]:
    rate = bench_swarm(robots, threads, duration, scene, split, version)
    label = f"{robots} (swarm scene)" if scene else f"{robots}"
    worlds = max(1, 1024 // robots)
    real_time = rate / worlds * _DT
    print(
        f"{label:<22} {split:>5} {threads:>7} {rate:>13,.0f} {rate * robots:>13,.0f} "
        f"{real_time:>11.1f}",
        flush=True,
    )
    return {
        "robots": robots,
        "worlds": worlds,
        "scene": "swarm" if scene else None,
        "split": split,
        "threads": threads,
        "world_steps_per_second": rate,
        "robot_steps_per_second": rate * robots,
        "real_time_factor": real_time,
        "version": LATEST_VERSION if version is None else version,
    }


__all__ = ["bench_swarm", "swarm_rows"]
