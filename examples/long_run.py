"""Long-run check: steps a native vector env for many env-steps (10^8 by default) with random
actions and autoresets, and prints, every tenth of the run, the throughput of that tenth and the
process's resident memory, so that a leak (memory growing) or a slowdown (later tenths slower than
the first) shows.

Usage::

    python examples/long_run.py                       # 10^8 Nav env-steps, 1024 worlds
    python examples/long_run.py --env KheperaIV-Avoid --steps 2e7

The actions are a fixed cycle of 64 seeded random batches, drawn once, so the loop measures the
simulator and not NumPy's random generator.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import khepera_gym  # noqa: F401  (registers the envs)
from khepera_gym.analysis.throughput import _resident_bytes
from khepera_gym.registration import resolve_env_id


def _mib(value: int | None) -> str:
    return "n/a" if value is None else f"{value / 2**20:.1f} MiB"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="KheperaIV-Nav")
    parser.add_argument("--steps", type=float, default=1e8, help="total env-steps")
    parser.add_argument("--num-envs", type=int, default=1024)
    parser.add_argument("--num-threads", type=int, default=None)
    parser.add_argument("--segments", type=int, default=10)
    args = parser.parse_args()

    env_id = resolve_env_id(args.env)  # an id without its version: the latest
    envs = gym.make_vec(env_id, num_envs=args.num_envs, num_threads=args.num_threads)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    shape = envs.action_space.shape
    actions = [rng.uniform(-1, 1, shape).astype(np.float32) for _ in range(64)]
    steps_per_segment = max(1, int(args.steps) // (args.num_envs * args.segments))
    total_steps = steps_per_segment * args.num_envs * args.segments
    rss_start = _resident_bytes()
    print(
        f"{args.env}: {args.num_envs} worlds, {total_steps:.3g} env-steps in {args.segments} "
        f"segments; RSS at start {_mib(rss_start)}"
    )
    print(f"{'segment':>7} {'env-steps':>12} {'env-steps/s':>12} {'RSS':>12} {'episodes':>9}")
    rates = []
    episodes = 0
    started = time.perf_counter()
    for segment in range(args.segments):
        begin = time.perf_counter()
        for step in range(steps_per_segment):
            _, _, terminations, truncations, _ = envs.step(actions[step % len(actions)])
            episodes += int(np.count_nonzero(terminations | truncations))
        rate = steps_per_segment * args.num_envs / (time.perf_counter() - begin)
        rates.append(rate)
        done = (segment + 1) * steps_per_segment * args.num_envs
        print(
            f"{segment + 1:>7} {done:>12.3g} {rate:>12,.0f} {_mib(_resident_bytes()):>12} "
            f"{episodes:>9}"
        )
    rss_end = _resident_bytes()
    elapsed = time.perf_counter() - started
    print(
        f"done in {elapsed:.0f} s: RSS {_mib(rss_start)} at start, {_mib(rss_end)} at the end; "
        f"first segment {rates[0]:,.0f} env-steps/s, last {rates[-1]:,.0f} "
        f"({rates[-1] / rates[0]:.2f}x), {episodes} episodes ended"
    )
    envs.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
