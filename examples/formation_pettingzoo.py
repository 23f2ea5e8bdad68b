"""Formation control with PettingZoo: one agent per follower, all sharing one policy.

Usage: ``python examples/formation_pettingzoo.py [--episodes N]``. Runs the paper's Fig. 7
scene (``config="paper_fig7"``) with :func:`khepera_gym.envs.formation_follower_heuristic` as the
shared follower policy (parameter sharing: every follower has the same observation space) and
prints each episode's formation error.
"""

from __future__ import annotations

import argparse

import numpy as np

from khepera_gym.envs import formation_follower_heuristic
from khepera_gym.pettingzoo import formation_v3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3, help="episodes to run (3)")
    args = parser.parse_args()

    env = formation_v3.parallel_env(config="paper_fig7")
    shape = env.observation_space("follower_0").shape
    print(f"agents: {env.possible_agents}, observation shape {shape} each")
    for seed in range(args.episodes):
        observations, infos = env.reset(seed=seed)
        returns = dict.fromkeys(env.agents, 0.0)
        while env.agents:
            # One batched call of the shared policy for every live follower.
            agents = list(env.agents)
            actions = formation_follower_heuristic(np.stack([observations[a] for a in agents]))
            observations, rewards, _, _, infos = env.step(dict(zip(agents, actions, strict=True)))
            for agent, reward in rewards.items():
                returns[agent] += reward
        stats = infos["follower_0"]["world_episode_stats"]
        print(
            f"seed {seed}: {'leader reached the goal' if stats['success'] else 'timeout'} in "
            f"{stats['length']} steps, formation error mean {stats['formation_error_mean']:.3f} m "
            f"max {stats['formation_error_max']:.3f} m, returns "
            + ", ".join(f"{agent} {value:.1f}" for agent, value in returns.items())
        )
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
