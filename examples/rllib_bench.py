"""Env-steps/s of RLlib PPO with 1 and 2 EnvRunners on KheperaIV-Nav, against SB3 PPO, here.

    python examples/rllib_bench.py [--timesteps 100000] [--n-envs 16] [--runners 1 2]

Prints two tables, measured on this machine:

* training: ``khepera-gym train --env KheperaIV-Nav --algo ppo --timesteps T --n-envs 16`` (SB3)
  and ``khepera-gym train --backend rllib ... --num-env-runners R`` for each R (RLlib; 16 worlds
  per runner), with the hyperparameters of configs/hyperparams/ppo.toml and rllib_ppo.toml (both
  4096 env steps per update, minibatches of 256, 10 epochs, 64-64 tanh networks): env-steps/s of
  the whole run as its run.json reports it (sampling, learning and the ten evaluations on 100
  seeded episodes), env-steps per CPU-second (this process, plus RLlib's EnvRunner processes;
  not Ray's daemons), which other load on the machine hardly changes, and the final success rate;
* sampling alone: env-steps/s of RLlib's EnvRunners stepping the Rust batch with the initial
  policy, no learning (``khepera_gym.learning.rllib.sampling_throughput``).

Ray runs locally with one CPU per core; each remote EnvRunner takes one. The learner runs in
this process on one torch thread. Needs the ``sb3`` and ``rllib`` extras. About 3 minutes on 2
cores. The load average is printed: other work on the machine lowers every figure.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import ray
import torch

from khepera_gym.learning import rllib
from khepera_gym.learning.train import train as train_sb3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--timesteps", type=int, default=100_000, help="per training run")
    parser.add_argument("--n-envs", type=int, default=16, help="worlds (SB3) / per runner (RLlib)")
    parser.add_argument("--runners", type=int, nargs="+", default=[1, 2], help="EnvRunners")
    parser.add_argument("--skip-sb3", action="store_true", help="RLlib only")
    args = parser.parse_args()

    cores = os.cpu_count() or 1
    print(f"{cores} cores, load average {os.getloadavg()[0]:.2f} at the start")
    torch.set_num_threads(1)
    rows: list[tuple[str, float, float, float]] = []
    with tempfile.TemporaryDirectory() as scratch:
        if not args.skip_sb3:
            cpu_start = time.process_time()  # SB3 runs in this process (rayon threads included)
            result = train_sb3(
                "KheperaIV-Nav",
                "ppo",
                timesteps=args.timesteps,
                n_envs=args.n_envs,
                out_dir=Path(scratch) / "sb3",
                progress_bar=False,
                verbose=0,
            )
            cpu_steps = result.timesteps / (time.process_time() - cpu_start)
            label = f"SB3 PPO, {args.n_envs} worlds"
            rows.append((label, result.steps_per_second, cpu_steps, result.final.success_rate))
        ray.init(address="local", num_cpus=cores, include_dashboard=False, log_to_driver=False)
        for runners in args.runners:
            run = rllib.train(
                "KheperaIV-Nav",
                timesteps=args.timesteps,
                n_envs=args.n_envs,
                num_env_runners=runners,
                out_dir=Path(scratch) / f"rllib-{runners}",
                verbose=0,
            )
            label = f"RLlib PPO, {runners} EnvRunner(s) x {args.n_envs} worlds"
            cpu_steps = run.timesteps / run.cpu_time
            rows.append((label, run.steps_per_second, cpu_steps, run.final.success_rate))
        hyperparams = rllib.load_hyperparams("KheperaIV-Nav")
        sampling = []
        for runners in args.runners:
            config = rllib.ppo_config(
                "KheperaIV-Nav",
                hyperparams,
                num_env_runners=runners,
                num_envs_per_env_runner=args.n_envs,
            )
            sampling.append((runners, rllib.sampling_throughput(config)))
        ray.shutdown()

    print(f"\ntraining, {args.timesteps:,} env steps per run (evaluations included)")
    print(f"{'run':<44} {'env-steps/s':>12} {'per CPU-s':>10} {'success':>8}")
    for label, steps_per_second, cpu_steps, success in rows:
        print(f"{label:<44} {steps_per_second:>12,.0f} {cpu_steps:>10,.0f} {100 * success:>7.0f}%")
    print("\nRLlib sampling alone (no learning)")
    print(f"{'EnvRunners':<44} {'env-steps/s':>12}")
    for runners, steps_per_second in sampling:
        print(f"{f'{runners} x {args.n_envs} worlds':<44} {steps_per_second:>12,.0f}")
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
