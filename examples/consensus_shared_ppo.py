"""PPO with one policy shared by every robot of the latest ``consensus_vN`` (parameter
sharing), against the consensus law: trains on
:class:`khepera_gym.learning.sb3.SharedAgentsVecEnv` (each row one robot of one world, with its
own observation and the shared reward −error), then plays the same seeded episodes with both
policies and prints the final error, the share of episodes that converged (below 3 cm for good),
the messages per robot per second and the steps in contact.

Usage: ``python examples/consensus_shared_ppo.py [--timesteps 1000000] [--episodes 200]``
(timesteps count robot-steps, summed over the rows).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from stable_baselines3 import PPO

from khepera_gym.baselines import ConsensusLaw
from khepera_gym.learning.sb3 import SharedAgentsVecEnv
from khepera_gym.learning.sb3.evaluate import first_episode_stats


def summary(name: str, stats: dict) -> str:
    """One table row: final error (mm), converged (%), messages per robot per s, contact steps."""
    converged = np.isfinite(stats["consensus_converge_time"])
    return (
        f"| {name} | {1000 * np.mean(stats['consensus_error_final']):.1f} | "
        f"{100 * np.mean(converged):.1f} | {np.mean(stats['messages_per_robot_s']):.2f} | "
        f"{np.mean(stats['collisions']):.1f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=1_000_000)
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    train = SharedAgentsVecEnv("consensus", 16, seed=args.seed, num_threads=1)
    model = PPO(
        "MlpPolicy",
        train,
        n_steps=256,
        batch_size=256,
        learning_rate=3e-4,
        policy_kwargs={"net_arch": [64, 64], "log_std_init": -0.5},
        seed=args.seed,
        device="cpu",
    )
    start = time.perf_counter()
    model.learn(args.timesteps)
    print(f"trained {args.timesteps} robot-steps in {time.perf_counter() - start:.0f} s")

    evaluation = SharedAgentsVecEnv("consensus", args.episodes, num_threads=1)
    law = ConsensusLaw(layout=evaluation.agent_layout)
    print("| policy | final error (mm) | converged (%) | messages/robot/s | contact steps |")
    print("|---|---|---|---|---|")
    for name, policy in (("ConsensusLaw", law), ("shared PPO", model)):
        stats = first_episode_stats(policy, evaluation, seed=10_000)
        print(summary(name, stats))


if __name__ == "__main__":
    main()
