"""Kanayama's tracking controller on every agent of the PettingZoo platoon: per-robot tracking
errors over seeded episodes, the figures of the manual of
:class:`khepera_gym.pettingzoo.platoon_v3.PlatoonParallelEnv`.

Each robot's error is the distance from its centre to its own reference point after every step
(``env.poses()`` against ``env.goals()``, m); its RMS and maximum are taken after the transient
(``platoon.transient``, 5 s), as the task's statistics are. Usage::

    python examples/platoon_kanayama.py [--episodes 20] [--robots 3] [--reference circle]
"""

from __future__ import annotations

import argparse

import numpy as np

from khepera_gym.baselines import Kanayama
from khepera_gym.pettingzoo import platoon_v3

#: Seconds excluded from the RMS and maximum (the scenario's ``platoon.transient``).
TRANSIENT = 5.0
#: Control step (s), the scenario's ``physics.dt``.
DT = 0.05


def run(episodes: int, robots: int, reference: str) -> None:
    """Runs ``episodes`` episodes seeded 0.. and prints per-robot and platoon figures."""
    env = platoon_v3.parallel_env(robots=robots, reference=reference)
    policy = Kanayama()
    skip = round(TRANSIENT / DT) - 1  # errors[i] is after step i + 1: from t = TRANSIENT on
    rms = np.zeros((episodes, robots))
    peak = np.zeros((episodes, robots))
    stats = []
    lost = 0
    for seed in range(episodes):
        observations, _ = env.reset(seed=seed)
        errors = []
        infos: dict = {}
        while env.agents:
            observations, _, terminations, _, infos = env.step(policy(observations))
            lost += sum(terminations.values())
            distance = np.linalg.norm(env.poses()[:, :2] - env.goals(), axis=1)
            errors.append(distance)
        after = np.array(errors)[skip:]
        rms[seed] = np.sqrt((after**2).mean(axis=0))
        peak[seed] = after.max(axis=0)
        stats.append(next(iter(infos.values()))["world_episode_stats"])
    print(
        f"platoon_v3, {robots} robots on the {reference}, Kanayama on every agent, "
        f"{episodes} episodes seeded 0..{episodes - 1}; {lost} agents lost"
    )
    for k in range(robots):
        print(
            f"  robot_{k}: RMS error after {TRANSIENT:.0f} s mean {rms[:, k].mean() * 1000:.1f} mm "
            f"(worst episode {rms[:, k].max() * 1000:.1f} mm), max error worst "
            f"{peak[:, k].max() * 1000:.1f} mm"
        )
    for key in ("track_error_rms", "track_error_max", "track_iae", "track_converge_time"):
        values = np.array([s[key] for s in stats])
        print(f"  {key}: mean {values.mean():.4f}, worst {values.max():.4f}")
    collisions = np.array([s["collisions"] for s in stats])
    print(f"  steps with a robot in contact: mean {collisions.mean():.1f}, max {collisions.max()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--robots", type=int, default=3)
    parser.add_argument("--reference", default="circle")
    args = parser.parse_args()
    run(args.episodes, args.robots, args.reference)


if __name__ == "__main__":
    main()
