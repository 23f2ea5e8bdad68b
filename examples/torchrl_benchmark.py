"""Env-steps/s of the TorchRL env (khepera_gym.learning.torchrl) against the native vector env.

    python examples/torchrl_benchmark.py [--worlds 64 1024] [--threads N] [--repeats 3]
                                         [--clock wall|cpu]

For Nav and Formation and each number of worlds N, with uniform random actions drawn in advance
(64 batches, cycled) so that neither side pays for sampling:

* native: ``gym.make_vec(id, num_envs=N)`` stepped in a loop (NEXT_STEP autoreset in Rust);
* TorchRL: ``KheperaTorchEnv(task, N)`` stepped with ``step_and_maybe_reset``, the inner loop of
  TorchRL's collectors and of ``rollout`` (finished worlds reset through the ``"_reset"`` mask);
* TorchRL rollout: ``env.rollout(T, break_when_any_done=False)`` with TorchRL's random policy
  (sampling from the action spec and stacking the T steps included).

Runs alternate between the two sides and the best of ``--repeats`` runs is kept, so that other
programs on the machine disturb the ratio less; "overhead/step" is the time the TorchRL side
adds to one step of the whole batch (N / rate difference). A last table times resets: the
batch's parallel reset of every world against the per-world ``reset_world`` loop that a partial
reset runs. ``--clock cpu`` times the process's CPU time instead of the wall clock: with
``--threads 1`` (the batch then steps on the calling thread) it measures the work done whatever
else runs on the machine, where wall-clock figures swing with the load.
Needs the ``torchrl`` extra.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import torch

from khepera_gym.learning.torchrl import KheperaTorchEnv
from khepera_gym.registration import latest_ids

#: Tasks measured (their Gymnasium ids come from the registration).
TASKS = ("nav", "formation")
#: Distinct random action batches, cycled.
ACTION_BATCHES = 64
#: A clock in seconds: time.perf_counter (wall) or time.process_time (CPU).
Clock = Callable[[], float]


def best_rate(run: Callable[[], float], repeats: int) -> float:
    """The highest of ``repeats`` rates returned by ``run``."""
    return max(run() for _ in range(repeats))


def native_rate(
    env_id: str, worlds: int, steps: int, threads: int | None, clock: Clock
) -> Callable[[], float]:
    envs = gym.make_vec(env_id, num_envs=worlds, num_threads=threads)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    shape = (ACTION_BATCHES, worlds, envs.single_action_space.shape[0])
    actions = rng.uniform(-1, 1, shape).astype(np.float32)

    def run() -> float:
        start = clock()
        for step in range(steps):
            envs.step(actions[step % ACTION_BATCHES])
        return worlds * steps / (clock() - start)

    return run


def torchrl_rate(
    task: str, worlds: int, steps: int, threads: int | None, clock: Clock
) -> Callable[[], float]:
    env = KheperaTorchEnv(task, worlds, num_threads=threads, seed=0)
    key = "action" if not env.group_map else (next(iter(env.group_map)), "action")
    shape = (ACTION_BATCHES, *env.full_action_spec[key].shape)
    actions = torch.from_numpy(np.random.default_rng(0).uniform(-1, 1, shape).astype(np.float32))
    state = {"tensordict": env.reset()}

    def run() -> float:
        tensordict = state["tensordict"]
        start = clock()
        for step in range(steps):
            tensordict.set(key, actions[step % ACTION_BATCHES])  # as a policy module writes
            _, tensordict = env.step_and_maybe_reset(tensordict)
        rate = worlds * steps / (clock() - start)
        state["tensordict"] = tensordict
        return rate

    return run


def rollout_rate(
    task: str, worlds: int, steps: int, threads: int | None, clock: Clock
) -> Callable[[], float]:
    env = KheperaTorchEnv(task, worlds, num_threads=threads, seed=0)

    def run() -> float:
        start = clock()
        env.rollout(steps, break_when_any_done=False)
        return worlds * steps / (clock() - start)

    return run


def reset_costs(task: str, worlds: int, threads: int | None, clock: Clock) -> tuple[float, float]:
    """Microseconds per world: the batch's reset of every world, and the reset_world loop."""
    env = KheperaTorchEnv(task, worlds, num_threads=threads, seed=0)
    tensordict = env.reset()
    repeats = max(1, 4096 // worlds)
    start = clock()
    for _ in range(repeats):
        tensordict = env.reset()
    full = (clock() - start) / (repeats * worlds) * 1e6
    mask = torch.ones(worlds, 1, dtype=torch.bool)
    mask[0] = False  # one world left alone: the per-world loop runs for the others
    start = clock()
    for _ in range(repeats):
        tensordict["_reset"] = mask
        tensordict = env.reset(tensordict)
    partial = (clock() - start) / (repeats * (worlds - 1)) * 1e6
    return full, partial


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, nargs="+", default=[64, 1024])
    parser.add_argument("--threads", type=int, default=None, help="rayon threads (all cores)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--env-steps", type=int, default=400_000, help="per run and side")
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall")
    args = parser.parse_args()
    torch.set_num_threads(1)
    clock: Clock = time.process_time if args.clock == "cpu" else time.perf_counter

    print(
        f"env-steps/s ({args.clock} clock, threads: {args.threads or 'all cores'}), best of "
        f"{args.repeats} runs of {args.env_steps:,} env steps each"
    )
    header = (
        f"{'task':<10} {'N':>5} {'native':>11} {'TorchRL':>11} {'ratio':>6} "
        f"{'overhead/step':>14} {'rollout':>11}"
    )
    print(header)
    for task in TASKS:
        env_id = latest_ids()[task]
        for worlds in args.worlds:
            steps = max(50, args.env_steps // worlds)
            native = native_rate(env_id, worlds, steps, args.threads, clock)
            torchrl = torchrl_rate(task, worlds, steps, args.threads, clock)
            rates: dict[str, list[float]] = {"native": [], "torchrl": []}
            for _ in range(args.repeats):  # alternate the two sides
                rates["native"].append(native())
                rates["torchrl"].append(torchrl())
            native_best, torchrl_best = max(rates["native"]), max(rates["torchrl"])
            rollout = best_rate(
                rollout_rate(task, worlds, steps, args.threads, clock), args.repeats
            )
            # Time TorchRL adds to one step of the whole batch, in microseconds.
            overhead = (worlds / torchrl_best - worlds / native_best) * 1e6
            print(
                f"{task:<10} {worlds:>5} {native_best:>11,.0f} {torchrl_best:>11,.0f} "
                f"{native_best / torchrl_best:>5.2f}x {overhead:>11.0f} µs {rollout:>11,.0f}"
            )
    print("\nreset cost, µs per world")
    print(f"{'task':<10} {'N':>5} {'all (batch)':>12} {'masked (loop)':>14}")
    for task in TASKS:
        for worlds in args.worlds:
            full, partial = reset_costs(task, worlds, args.threads, clock)
            print(f"{task:<10} {worlds:>5} {full:>12.1f} {partial:>14.1f}")


if __name__ == "__main__":
    main()
