"""Formation followers driven by one shared PPO policy (parameter sharing), against LeaderFollower.

    python examples/formation_shared_ppo.py [--timesteps 200000] [--worlds 8] [--episodes 50]
    python examples/formation_shared_ppo.py --json shared_ppo.json   # also the results file

Every follower of every world is one row of an SB3 ``VecEnv`` over a Rust Formation batch
(``khepera_gym.learning.sb3.make_formation_vec_env``): row w·K + k observes follower k's own
23-value block of world w (IR, ultrasonic, its target in its own frame, the leader's offset, heading
and velocity, its wheel speeds), drives its own two wheels and earns its own reward (minus its
distance to its eq. 12 target, minus contacts). One PPO policy learns from all rows at once;
the scripted leader drives to its goal. After training, the policy and the LeaderFollower
baseline (``khepera_gym.baselines.LeaderFollower``, or the proportional follower heuristic when
the baselines module is not there) play the same seeded episodes, and their mean formation error
is printed (and, with ``--json``, written with the date, commit, machine and command: the results
page renders it); finally the policy drives the PettingZoo env ``formation_vN`` of the latest
behaviour version N, one agent per follower.
Hyperparameters: the ``formation-followers`` table of configs/hyperparams/ppo.toml. Needs the
``sb3`` extra.
"""

from __future__ import annotations

import argparse
import importlib
import time
from typing import Any

import numpy as np
import torch
from stable_baselines3.common.vec_env import VecMonitor

from khepera_gym import registry
from khepera_gym.analysis.compare.report import write_formation_learning
from khepera_gym.learning.sb3 import first_episode_stats, make_formation_vec_env
from khepera_gym.learning.train import build_model, load_hyperparams

#: Evaluation episodes are seeded EVAL_SEED + i, away from the training worlds' seeds.
EVAL_SEED = 10_000


def baseline_policy() -> tuple[str, Any]:
    """LeaderFollower following each follower's observed target, or the heuristic fallback."""
    try:
        from khepera_gym.baselines import LeaderFollower
    except ImportError:
        from khepera_gym.envs import formation_follower_heuristic

        class Heuristic:
            def predict(self, observation: Any, **_: Any) -> tuple[Any, None]:
                return formation_follower_heuristic(observation), None

        return "follower heuristic", Heuristic()
    return "LeaderFollower", LeaderFollower(shape=None)


def result_row(policy: str, stats: dict[str, np.ndarray]) -> dict[str, Any]:
    """A policy's row of the results file (means over the episodes)."""
    return {
        "policy": policy,
        "formation_error_mean": float(stats["formation_error_mean"].mean()),
        "formation_error_max": float(stats["formation_error_max"].mean()),
        "success_rate": float(stats["success"].mean()),
        "contact_steps": float(stats["collisions"].mean()),
    }


def summary(name: str, stats: dict[str, np.ndarray]) -> str:
    return (
        f"{name:<20} formation error mean {100 * stats['formation_error_mean'].mean():5.1f} cm, "
        f"max {100 * stats['formation_error_max'].mean():5.1f} cm, "
        f"leader arrived {100 * stats['success'].mean():3.0f} %, "
        f"steps in contact {stats['collisions'].mean():5.1f}"
    )


def main() -> None:
    # One torch thread: on these small MLPs more threads only add synchronisation (on 2 cores
    # PPO runs several times faster so).
    torch.set_num_threads(1)
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--timesteps", type=int, help="follower steps (the table's n_timesteps)")
    parser.add_argument("--worlds", type=int, help="training worlds (the table's n_envs)")
    parser.add_argument("--episodes", type=int, default=50, help="evaluation episodes (50)")
    parser.add_argument("--json", help="also write the figures to this results file")
    args = parser.parse_args()

    version = registry.LATEST_VERSION  # the Formation env's default, which the vec env makes
    hyperparams = load_hyperparams("ppo", f"formation_v{version}-followers")
    worlds = args.worlds or hyperparams["n_envs"]
    timesteps = args.timesteps or hyperparams["n_timesteps"]
    envs = VecMonitor(make_formation_vec_env(worlds, seed=0))
    print(f"{worlds} worlds x {envs.num_envs // worlds} followers = {envs.num_envs} PPO rows")
    model = build_model("ppo", envs, hyperparams, seed=0)
    start = time.perf_counter()
    model.learn(timesteps, progress_bar=True)
    train_seconds = time.perf_counter() - start

    eval_envs = make_formation_vec_env(args.episodes)
    learned = first_episode_stats(model, eval_envs, EVAL_SEED)
    name, baseline = baseline_policy()
    reference = first_episode_stats(baseline, eval_envs, EVAL_SEED)
    print(f"\n{args.episodes} seeded episodes (seeds {EVAL_SEED}..), cross of 4 followers:")
    print(summary("shared PPO", learned))
    print(summary(name, reference))
    if args.json:
        rows = [result_row("shared PPO (SB3)", learned), result_row(name, reference)]
        write_formation_learning(
            args.json,
            "shared PPO (SB3)",
            timesteps,
            train_seconds,
            args.episodes,
            EVAL_SEED,
            rows,
            version=version,
        )
        print(f"saved {args.json}")

    # The same policy drives each PettingZoo agent from its own observation.
    formation = importlib.import_module(f"khepera_gym.pettingzoo.formation_v{version}")
    env = formation.parallel_env()
    observations, _ = env.reset(seed=EVAL_SEED)
    while env.agents:
        actions = {a: model.predict(observations[a], deterministic=True)[0] for a in env.agents}
        observations, _, _, _, infos = env.step(actions)
    stats = next(iter(infos.values()))["world_episode_stats"]
    error = 100 * stats["formation_error_mean"]
    print(f"formation_v{version}, seed {EVAL_SEED}: error {error:.1f} cm")


if __name__ == "__main__":
    main()
