"""The quadcopter of the KH4VREP paper's Fig. 8 following a Khepera IV (KheperaIV-DroneFollow):
PD pursuit against a random command, over seeded episodes, with 95 % intervals; saves a frame.

Usage: ``python examples/drone_follow.py [--episodes 200]
[--frame dronefollow.png]``.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import khepera_gym  # noqa: F401  (registers the envs)
from khepera_gym.envs import dronefollow_heuristic
from khepera_gym.registration import latest_ids
from khepera_gym.tooling.stats import bootstrap_interval, wilson_interval

ENV_ID = latest_ids()["dronefollow"]  # the latest version, as gym.make("KheperaIV-DroneFollow")


def run(policy_name: str, episodes: int) -> list[dict]:
    """Episode statistics of ``episodes`` seeded episodes (seeds 0..episodes-1)."""
    envs = gym.make_vec(ENV_ID, num_envs=episodes, num_threads=None)
    obs, _ = envs.reset(seed=0)
    rng = np.random.default_rng(0)
    stats: list[dict | None] = [None] * episodes
    while any(s is None for s in stats):
        if policy_name == "pd_pursuit":
            actions = dronefollow_heuristic(obs)
        else:
            actions = rng.uniform(-1, 1, (episodes, 2)).astype(np.float32)
        obs, _, terminated, truncated, info = envs.step(actions)
        for i in np.flatnonzero(terminated | truncated):
            if stats[i] is None:
                stats[i] = {k: float(v[i]) for k, v in info["episode_stats"].items() if k[0] != "_"}
                stats[i]["lost"] = bool(terminated[i])
    return stats  # type: ignore[return-value]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--frame", default=None, help="save a frame of PD pursuit to this PNG")
    args = parser.parse_args()
    print(f"{ENV_ID}, {args.episodes} seeded episodes per policy (estimate [95% interval])")
    print(f"{'policy':<12} {'in view (%)':>22} {'horizontal RMS (cm)':>22} {'lost (%)':>20} steps")
    for name in ("pd_pursuit", "random"):
        stats = run(name, args.episodes)
        view = bootstrap_interval([s["in_view_share"] for s in stats])
        error = bootstrap_interval([s["horizontal_error_rms"] for s in stats])
        lost = wilson_interval(sum(s["lost"] for s in stats), len(stats))
        steps = np.mean([s["length"] for s in stats])
        print(
            f"{name:<12} {view.format(100, 1):>22} {error.format(100, 2):>22} "
            f"{lost.format(100, 1):>20} {steps:5.0f}"
        )
    if args.frame:
        from PIL import Image

        env = gym.make(ENV_ID, render_mode="rgb_array", frame_size=(600, 600))
        obs, _ = env.reset(seed=1)
        for _ in range(300):
            obs, *_ = env.step(dronefollow_heuristic(obs))
        Image.fromarray(env.render()).save(args.frame)
        print(f"frame saved to {args.frame}")


if __name__ == "__main__":
    main()
