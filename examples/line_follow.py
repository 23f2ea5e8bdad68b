"""Line following with the ground sensors (KheperaIV-LineFollow): K-Team's threshold follower
laps a random spline track drawn on the floor; prints the lap and saves a frame.

Usage: ``python examples/line_follow.py [--track spline] [--seed 3] [--frame out.png] [--camera]``.
The 200-episode tables of the README come from ``khepera-gym compare --task linefollow``.
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import khepera_gym  # noqa: F401  (registers the envs)
from khepera_gym.envs import linefollow_heuristic
from khepera_gym.registration import latest_ids


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--track", default="spline")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--frame", default=None, help="save a frame half way round to this PNG")
    parser.add_argument(
        "--camera", action="store_true", help="carry the camera too (its field shows in frames)"
    )
    args = parser.parse_args()
    mode = "rgb_array" if args.frame else None
    carry = ["ir", "us", "gyro", "ground"] + (["camera"] if args.camera else [])
    env = gym.make(
        latest_ids()["linefollow"],  # the latest version, as gym.make("KheperaIV-LineFollow")
        track=args.track,
        carry=carry,
        render_mode=mode,
        frame_size=(600, 600),
    )
    obs, _ = env.reset(seed=args.seed)
    frame = None
    steps = 0
    while True:
        obs, _, terminated, truncated, info = env.step(linefollow_heuristic(obs))
        steps += 1
        if args.frame and steps == 500:
            frame = env.render()
        if terminated or truncated:
            break
    stats = info["episode_stats"]
    print(
        f"{args.track} (seed {args.seed}): lap {'done' if stats['success'] else 'not done'} in "
        f"{stats['length'] * 0.05:.1f} s, RMS offset {stats['line_offset_rms'] * 1000:.1f} mm, "
        f"a front sensor over the line {stats['on_line_share']:.0%} of the time"
    )
    if args.frame and frame is not None:
        from PIL import Image

        Image.fromarray(frame).save(args.frame)
        print(f"frame saved to {args.frame}")


if __name__ == "__main__":
    main()
