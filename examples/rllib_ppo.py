"""Train Ray RLlib's PPO on KheperaIV-Nav over the Rust batch, on a laptop or on a Ray cluster.

    python examples/rllib_ppo.py                          # a local Ray (ray.init())
    python examples/rllib_ppo.py --address auto           # on a node of a running cluster
    python examples/rllib_ppo.py --address auto --num-env-runners 8

The same script runs in both places; only ``--address`` changes (and the number of EnvRunners
you can afford). Each EnvRunner (a Ray actor with 1 CPU) steps ONE Rust batch of
``--envs-per-runner`` worlds through RLlib's vector entry point, world i of runner w seeded
``(seed + w) · N + i`` (``khepera_gym.learning.rllib``); the learner runs in this process. After
training the policy is evaluated on the same 100 seeded episodes as ``khepera-gym train`` (seeds
10000..10099) and the algorithm is saved as an RLlib checkpoint.

Every node must be able to import khepera_gym, a compiled extension: install the abi3 wheel of
``make wheel`` with pip into the Python environment of Ray on every node (README, "Training on a
cluster"). Needs the ``rllib`` extra: ``pip install 'khepera-gym[rllib]'``. About 20 s of
training on 2 cores for the default 100k steps.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import ray
import torch
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

from khepera_gym.learning import rllib  # registers "khepera_gym/<id>" names with Ray Tune
from khepera_gym.registration import latest_ids

NAV_ID = latest_ids()["nav"]  # the latest version, as gym.make("KheperaIV-Nav")
ENV = f"khepera_gym/{NAV_ID}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--address", help="Ray cluster address ('auto' on a cluster node); default: a local Ray"
    )
    parser.add_argument("--num-env-runners", type=int, default=1, help="EnvRunner actors (1)")
    parser.add_argument("--envs-per-runner", type=int, default=16, help="worlds per runner (16)")
    parser.add_argument("--timesteps", type=int, default=100_000, help="env steps (100k)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("runs/rllib-ppo-nav-example"))
    args = parser.parse_args()

    ray.init(address=args.address, include_dashboard=False)
    # The learner runs here: one torch thread is fastest for these small networks.
    torch.set_num_threads(1)
    config = (
        PPOConfig()
        .environment(ENV, env_config={})  # scenario overrides go here, e.g. {"max_steps": 300}
        .env_runners(
            num_env_runners=args.num_env_runners,
            num_envs_per_env_runner=args.envs_per_runner,
            gym_env_vectorize_mode="vector_entry_point",  # one Rust batch per runner
        )
        .training(  # configs/hyperparams/rllib_ppo.toml, table KheperaIV-Nav
            train_batch_size_per_learner=4096,
            minibatch_size=256,
            num_epochs=10,
            lr=3e-4,
            gamma=0.99,
            lambda_=0.95,
            clip_param=0.2,
            vf_clip_param=1000.0,
            vf_loss_coeff=0.5,
            entropy_coeff=0.0,
            use_kl_loss=False,
            grad_clip=0.5,
        )
        .rl_module(
            model_config=DefaultModelConfig(
                fcnet_hiddens=[64, 64], fcnet_activation="tanh", vf_share_layers=False
            )
        )
        .debugging(seed=args.seed)
    )
    algo = rllib.build_algo(config)  # checks the config against the env, then builds it
    if args.num_env_runners > 0:
        nodes = algo.env_runner_group.foreach_env_runner(
            lambda runner: ray.get_runtime_context().get_node_id()[:8], local_env_runner=False
        )
        print(f"{len(nodes)} EnvRunners on {len(set(nodes))} Ray node(s): {sorted(nodes)}")
    steps, start = 0, time.perf_counter()
    while steps < args.timesteps:
        result = algo.train()
        steps = int(result["env_runners"]["num_env_steps_sampled_lifetime"])
        print(
            f"iteration {result['training_iteration']:3d}: {steps:>7,} steps, "
            f"mean return {result['env_runners'].get('episode_return_mean', float('nan')):6.2f}"
        )
    elapsed = time.perf_counter() - start
    print(f"{steps:,} steps in {elapsed:.1f} s: {steps / elapsed:,.0f} env-steps/s")

    evaluation = rllib.evaluate_policy(rllib.module_policy(algo.get_module()), NAV_ID, episodes=100)
    print(
        f"evaluation on seeds 10000..10099: success {100 * evaluation.success_rate:.0f} %, "
        f"mean return {evaluation.mean_return:.2f}, mean length {evaluation.mean_length:.1f}"
    )
    checkpoint = algo.save_to_path(str(args.out.resolve() / "checkpoint"))
    print(f"saved {checkpoint}")
    algo.stop()
    ray.shutdown()


if __name__ == "__main__":
    main()
