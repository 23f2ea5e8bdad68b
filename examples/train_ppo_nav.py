"""Train PPO on KheperaIV-Nav over the Rust batch, evaluate it on 100 seeded episodes, save it.

    python examples/train_ppo_nav.py [--timesteps 300000] [--out runs/ppo-nav-example]

This is ``khepera-gym train --env KheperaIV-Nav --algo ppo --timesteps 300000 --n-envs 16
--seed 0`` written out in code: 16 worlds of one Rust batch form the SB3 ``VecEnv`` (no
subprocesses, SB3's reset semantics, world i seeded 0 + i), PPO with the hyperparameters of
configs/hyperparams/ppo.toml, a progress bar, an evaluation of the success rate on the same 100
seeded episodes every 30k steps, TensorBoard logs when tensorboard is installed, and the model
saved as a zip that ``PPO.load`` (or ``khepera-gym compare --policy sb3:model.zip``) reads back.
Needs the ``sb3`` extra: ``pip install 'khepera-gym[sb3]'``. About 2 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor

import khepera_gym  # noqa: F401  (registers the environments)
from khepera_gym.learning.sb3 import SuccessEvalCallback, evaluate_episodes, make_vec_env
from khepera_gym.registration import latest_ids

ENV_ID = latest_ids()["nav"]  # the latest version, as gym.make("KheperaIV-Nav")
#: Evaluation episodes are seeded EVAL_SEED + i, away from the training worlds' seeds.
EVAL_SEED = 10_000


def main() -> None:
    # One torch thread: on these small MLPs more threads only add synchronisation (on 2 cores
    # PPO runs several times faster so).
    torch.set_num_threads(1)
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--timesteps", type=int, default=300_000)
    parser.add_argument("--out", type=Path, default=Path("runs/ppo-nav-example"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    # Training: 16 worlds, world i seeded 0 + i; VecMonitor adds SB3's episode statistics.
    envs = VecMonitor(make_vec_env(ENV_ID, n_envs=16, seed=0))
    # Evaluation: 100 worlds, one episode each, seeded EVAL_SEED + i at every evaluation.
    eval_envs = make_vec_env(ENV_ID, n_envs=100)
    tensorboard = importlib.util.find_spec("tensorboard") is not None
    model = PPO(
        "MlpPolicy",
        envs,
        n_steps=256,
        batch_size=256,
        n_epochs=10,
        gamma=0.99,
        gae_lambda=0.95,
        learning_rate=3e-4,
        clip_range=0.2,
        policy_kwargs={"net_arch": [64, 64], "activation_fn": torch.nn.Tanh, "log_std_init": -0.5},
        tensorboard_log=str(args.out / "tb") if tensorboard else None,
        seed=0,
        device="cpu",
    )
    callback = SuccessEvalCallback(eval_envs, eval_freq=30_000, seed=EVAL_SEED)
    model.learn(args.timesteps, callback=callback, progress_bar=True)
    model.save(args.out / "model.zip")

    result = evaluate_episodes(model, eval_envs, seed=EVAL_SEED)
    print(
        f"success {100 * result.success_rate:.0f} % of {result.episodes} episodes, "
        f"mean length {result.mean_length:.1f} steps; saved {args.out / 'model.zip'}"
    )

    # The saved policy acts on raw observations of the ordinary single env.
    policy = PPO.load(args.out / "model.zip", device="cpu")
    env = gym.make(ENV_ID)
    observation, _ = env.reset(seed=0)
    while True:
        action, _ = policy.predict(observation, deterministic=True)
        observation, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    print(f"seed 0 with the loaded model: {info['episode_stats']}")


if __name__ == "__main__":
    main()
