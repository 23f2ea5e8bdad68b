"""Seek a red pillar with the colour camera (KheperaIV-Seek): colour-blob servoing on one
seeded episode; prints the outcome and the scanline at the start, saves a frame.

Usage: ``python examples/seek.py [--seed 11] [--distractors 2] [--frame out.png]``.
The 200-episode tables of the README come from ``khepera-gym compare --task seek``.
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import khepera_gym  # noqa: F401  (registers the envs)
from khepera_gym.envs import seek_heuristic
from khepera_gym.registration import latest_ids


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--distractors", type=int, default=2)
    parser.add_argument("--frame-step", type=int, default=60, help="step of the saved frame")
    parser.add_argument("--frame", default=None, help="save a frame to this PNG")
    args = parser.parse_args()
    env = gym.make(
        latest_ids()["seek"],  # the latest version, as gym.make("KheperaIV-Seek")
        distractors=args.distractors,
        render_mode="rgb_array" if args.frame else None,
        frame_size=(600, 600),
    )
    obs, _ = env.reset(seed=args.seed)
    rgb = env.unwrapped.sensor_readings()["camera_rgb"][0].reshape(-1, 3)
    print("scanline at the start (r, g, b per pixel, left to right):")
    print(" ".join(f"{r:.1f}/{g:.1f}/{b:.1f}" for r, g, b in rgb))
    frame = None
    steps = 0
    while True:
        obs, _, terminated, truncated, info = env.step(seek_heuristic(obs))
        steps += 1
        if args.frame and steps == args.frame_step:
            frame = env.render()
        if terminated or truncated:
            break
    stats = info["episode_stats"]
    outcome = "reached" if stats["success"] else "not reached"
    print(f"seed {args.seed}: the pillar {outcome} after {stats['length'] * 0.05:.1f} s")
    if args.frame:
        from PIL import Image

        Image.fromarray(frame if frame is not None else env.render()).save(args.frame)
        print(f"frame saved to {args.frame}")


if __name__ == "__main__":
    main()
