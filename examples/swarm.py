"""A swarm of Khepera IVs: 1,000 robots drive to their own goals across a 20 m arena (the built-in
``swarm`` scene; ``--robots`` up to 10,000 widens the arena at the same density), each with the
KH4VREP paper's position control and Braitenberg avoidance
(:func:`khepera_gym.envs.avoid_heuristic`), through the array env that returns every agent's data
at once. Prints how many arrived, the contacts and the speed; saves the last frame.

Usage: ``python examples/swarm.py [--robots 1000] [--steps 600]
[--frame swarm.png] [--frame-size 900]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from khepera_gym.envs import avoid_heuristic
from khepera_gym.pettingzoo import multinav_v3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=600, help="control steps of 0.05 s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frame", default=None, help="save the last frame to this PNG")
    parser.add_argument("--frame-size", type=int, default=900, help="its side in pixels")
    args = parser.parse_args()
    side = 20.0 * (args.robots / 1000) ** 0.5  # the swarm scene's density, 2.5 robots per m²
    env = multinav_v3.array_env(
        config="swarm",
        n_robots=args.robots,
        width=side,
        height=side,
        render_mode="rgb_array" if args.frame else None,
        frame_size=(args.frame_size, args.frame_size),
    )
    obs, _ = env.reset(seed=args.seed)
    arrived = np.zeros(env.n_agents, bool)
    contacts = 0
    start = time.perf_counter()
    for _ in range(args.steps):
        actions = avoid_heuristic(obs.reshape(-1, env.agent_obs_dim)).reshape(1, env.n_agents, 2)
        obs, _, terminated, _, info = env.step(actions)
        arrived |= terminated[0]
        if "episode_stats" in info:
            break
        contacts += int(np.sum(env.sensor_readings()["ir_raw"][0].max(axis=1) > 900))
    elapsed = time.perf_counter() - start
    print(
        f"{env.n_agents} robots, {args.steps} steps ({args.steps * 0.05:.0f} s simulated) in "
        f"{elapsed:.1f} s: {args.steps / elapsed:.0f} steps/s with the controller in NumPy; "
        f"{arrived.mean():.0%} arrived; {contacts / args.steps:.1f} robots per step with an IR "
        "reading above 900 (within about 2 cm of something)"
    )
    if args.frame:
        from PIL import Image

        Image.fromarray(env.render()).save(args.frame)
        print(f"frame saved to {args.frame}")


if __name__ == "__main__":
    main()
