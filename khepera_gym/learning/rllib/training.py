"""RLlib PPO training for ``khepera-gym train --backend rllib``, and RLlib's sampling speed.

:func:`train` builds a ``PPOConfig`` from ``configs/hyperparams/rllib_ppo.toml``
(:func:`khepera_gym.learning.rllib.ppo_config`), checks it, trains on the Rust batch (one batch per
EnvRunner), evaluates on seeded episodes every so many steps
(:func:`khepera_gym.learning.rllib.evaluate_policy`, the episodes of the SB3 backend), saves RLlib's
checkpoint and writes ``run.json``. :func:`sampling_throughput` measures env-steps/s of RLlib's
sampling alone, for ``examples/rllib_bench.py``.

Threading: Ray runs remote EnvRunners as processes (``num_cpus_per_env_runner`` CPUs each, 1 by
default; their batches use as many threads); the learner runs in this process with
``torch_threads`` torch threads. Ray is started here when it is not running, and stopped again.
"""

from __future__ import annotations

import dataclasses
import json
import platform
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import ray
from ray.rllib.algorithms.algorithm import Algorithm
from ray.rllib.algorithms.algorithm_config import AlgorithmConfig

import khepera_gym
from khepera_gym.errors import ConfigError
from khepera_gym.learning.recipes import EVAL_SEED
from khepera_gym.learning.rllib.config import build_algo, check_config, load_hyperparams, ppo_config
from khepera_gym.learning.rllib.evaluation import Evaluation, evaluate_policy, module_policy
from khepera_gym.registration import resolve_env_id
from khepera_gym.tooling.provenance import provenance


@dataclasses.dataclass
class TrainResult:
    """What :func:`train` did; also written to ``run.json``."""

    env_id: str
    backend: str
    algo: str
    seed: int
    timesteps: int
    #: Worlds per EnvRunner.
    n_envs: int
    num_env_runners: int
    iterations: int
    hyperparams: dict[str, Any]
    #: Wall time of the training loop (``algo.train()`` calls and evaluations), s.
    wall_time: float
    #: Wall time of the evaluations inside it, s.
    eval_time: float
    #: Environment steps per second of the training loop (evaluations included, as SB3's).
    steps_per_second: float
    #: CPU time of the training loop (s): this process (learner, evaluations, a local runner)
    #: plus the remote EnvRunner processes; Ray's own daemons are not counted. Unlike the wall
    #: time it hardly depends on other work on the machine.
    cpu_time: float
    final: Evaluation
    history: list[Evaluation]
    checkpoint: str
    out_dir: str

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict of the run."""
        record = dataclasses.asdict(self)
        record["hyperparams"] = json.loads(json.dumps(self.hyperparams, default=str))
        return record


def _sampled_steps(result: Mapping[str, Any]) -> int:
    return int(result["env_runners"]["num_env_steps_sampled_lifetime"])


def _cpu_seconds(algo: Algorithm) -> float:
    """CPU time so far of this process and of the algorithm's remote EnvRunner processes."""
    remote = 0.0
    if algo.config.num_env_runners > 0:
        remote = sum(
            algo.env_runner_group.foreach_env_runner(
                lambda runner: time.process_time(), local_env_runner=False
            )
        )
    return time.process_time() + remote


def train(
    env_id: str,
    *,
    timesteps: int | None = None,
    n_envs: int | None = None,
    num_env_runners: int | None = None,
    seed: int = 0,
    out_dir: str | Path | None = None,
    hyperparams_path: str | Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    eval_freq: int | None = None,
    eval_episodes: int = 100,
    eval_seed: int = EVAL_SEED,
    address: str | None = None,
    verbose: int = 1,
    torch_threads: int | None = 1,
) -> TrainResult:
    """Trains RLlib PPO on a khepera_gym env over the Rust batch, evaluates and saves it.

    Args:
        env_id: "KheperaIV-Nav" etc. (the table of ``configs/hyperparams/rllib_ppo.toml``).
        timesteps: Environment steps (all runners); None takes the table's ``n_timesteps``.
        n_envs: Worlds per EnvRunner; None takes the table's ``num_envs_per_env_runner``.
        num_env_runners: Remote EnvRunners (0: sample in this process); None: the table's.
        seed: ``config.seed``: torch and the worlds (runner w's world i: (seed + w)·N + i).
        out_dir: Run directory; None makes ``runs/rllib-ppo-<env>-s<seed>``.
        hyperparams_path: Another TOML file.
        overrides: Keys replacing the table's (``--hp KEY=VALUE``).
        eval_freq: Steps between evaluations; None a tenth of the run; 0 only the final one.
        eval_episodes: Seeded episodes per evaluation.
        eval_seed: Seed of the first evaluation episode.
        address: Ray cluster address for ``ray.init`` ("auto", "ray://host:10001"); None
            starts or joins a local instance. Ray is left running if it already was.
        verbose: 1 prints each evaluation and a summary.
        torch_threads: Torch threads of the learner in this process (restored afterwards);
            1 is fastest for these small networks (as for SB3).

    Returns:
        A :class:`TrainResult`, also saved as ``run.json`` beside ``checkpoint/``.
    """
    import torch

    env_id = resolve_env_id(env_id)
    hyperparams = load_hyperparams(env_id, hyperparams_path)
    hyperparams.update(overrides or {})
    if timesteps is not None:
        hyperparams["n_timesteps"] = timesteps
    if n_envs is not None:
        hyperparams["num_envs_per_env_runner"] = n_envs
    if num_env_runners is not None:
        hyperparams["num_env_runners"] = num_env_runners
    total = int(hyperparams.get("n_timesteps", 100_000))
    if total < 1:
        raise ConfigError(f"timesteps must be >= 1, got {total}")
    env_kwargs = dict(hyperparams.get("env_kwargs", {}))
    short_name = env_id.removeprefix("KheperaIV-").lower()
    out = Path(out_dir) if out_dir is not None else Path("runs") / f"rllib-ppo-{short_name}-s{seed}"
    out = out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    config = ppo_config(env_id, hyperparams, seed=seed)
    check_config(config)

    started_ray = not ray.is_initialized()
    if started_ray:
        ray.init(address=address, include_dashboard=False, log_to_driver=verbose >= 2)
    previous_threads = torch.get_num_threads()
    if torch_threads is not None:
        torch.set_num_threads(torch_threads)
    try:
        algo = config.build_algo()
        every = max(total // 10, 1) if eval_freq is None else eval_freq
        if verbose:
            print(
                f"training RLlib PPO on {env_id}: {total:,} steps, {config.num_env_runners} "
                f"EnvRunner(s) x {config.num_envs_per_env_runner} worlds, seed {seed}, "
                f"run directory {out}"
            )
        history: list[Evaluation] = []
        steps = iterations = last_eval = 0
        cpu_start = _cpu_seconds(algo)
        start = time.perf_counter()
        while steps < total:
            steps = _sampled_steps(algo.train())
            iterations += 1
            if (every > 0 and steps - last_eval >= every) or steps >= total:
                last_eval = steps
                evaluation = evaluate_policy(
                    module_policy(algo.get_module()),
                    env_id,
                    eval_episodes,
                    eval_seed,
                    env_kwargs,
                    timesteps=steps,
                )
                history.append(evaluation)
                if verbose:
                    print(
                        f"step {steps:>9,}: success {100 * evaluation.success_rate:5.1f} % of "
                        f"{evaluation.episodes}, return {evaluation.mean_return:7.2f}, "
                        f"length {evaluation.mean_length:5.1f}"
                    )
        wall_time = time.perf_counter() - start
        cpu_time = _cpu_seconds(algo) - cpu_start
        checkpoint = algo.save_to_path(str(out / "checkpoint"))
        algo.stop()
    finally:
        torch.set_num_threads(previous_threads)
        if started_ray:
            ray.shutdown()
    result = TrainResult(
        env_id=env_id,
        backend="rllib",
        algo="ppo",
        seed=seed,
        timesteps=steps,
        n_envs=int(config.num_envs_per_env_runner),
        num_env_runners=int(config.num_env_runners),
        iterations=iterations,
        hyperparams=hyperparams,
        wall_time=wall_time,
        eval_time=sum(evaluation.seconds for evaluation in history),
        steps_per_second=steps / wall_time,
        cpu_time=cpu_time,
        final=history[-1],
        history=history,
        checkpoint=str(checkpoint),
        out_dir=str(out),
    )
    record = result.to_json()
    record["versions"] = {
        "khepera_gym": khepera_gym.__version__,
        "ray": ray.__version__,
        "torch": torch.__version__,
        "python": platform.python_version(),
    }
    record["meta"] = provenance()
    (out / "run.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    if verbose:
        final = result.final
        print(
            f"done in {wall_time:.0f} s ({result.steps_per_second:,.0f} steps/s, evaluations "
            f"{result.eval_time:.0f} s); final policy: success {100 * final.success_rate:.1f} % "
            f"of {final.episodes} episodes (seeds {eval_seed}..{eval_seed + final.episodes - 1}),"
            f" mean return {final.mean_return:.2f}"
        )
        print(f"saved {checkpoint}")
    return result


def sampling_throughput(
    config: AlgorithmConfig, steps_per_runner: int = 8192, repeats: int = 3
) -> float:
    """Env-steps/s of RLlib's sampling alone (no learning) with the EnvRunners of ``config``.

    Builds the algorithm (Ray must be initialised), lets every EnvRunner (remote ones in
    parallel, else the local one) sample ``steps_per_runner`` env steps with the initial policy
    once untimed, then ``repeats`` times timed, and stops it. Counts the steps the episodes hold.

    Raises:
        ConfigError: ``steps_per_runner`` or ``repeats`` < 1, or see :func:`check_config`.
    """
    if steps_per_runner < 1 or repeats < 1:
        raise ConfigError(
            f"steps_per_runner and repeats must be >= 1, got {steps_per_runner}, {repeats}"
        )
    algo = build_algo(config)

    def sample(runner: Any) -> int:
        episodes = runner.sample(num_timesteps=steps_per_runner)
        return sum(len(episode) for episode in episodes)

    local = config.num_env_runners == 0
    try:
        algo.env_runner_group.foreach_env_runner(sample, local_env_runner=local)
        start = time.perf_counter()
        steps = 0
        for _ in range(repeats):
            steps += sum(algo.env_runner_group.foreach_env_runner(sample, local_env_runner=local))
        elapsed = time.perf_counter() - start
    finally:
        algo.stop()
    return steps / elapsed


__all__ = ["TrainResult", "sampling_throughput", "train"]
