"""``khepera-gym train``: stable-baselines3 agents trained on the Rust batch, end to end.

:func:`train` builds an SB3 ``VecEnv`` straight over ``_core.Batch``
(:func:`khepera_gym.learning.sb3.make_vec_env`, no subprocesses), creates the algorithm from the
hyperparameter file of the algorithm (``configs/hyperparams/ppo.toml``, ``sac.toml``: one table
per env id, as rl-zoo3's files), trains with a progress bar and a periodic seeded evaluation
(:class:`khepera_gym.learning.sb3.SuccessEvalCallback`: success rate over the same N episodes each
time), then evaluates the final model on ``eval_episodes`` seeded episodes. A run directory gets:

* ``model.zip``: the final model (SB3 ``model.save``); ``best_model.zip``: the best evaluated one;
* ``vecnormalize.pkl``: the ``VecNormalize`` statistics, only when the hyperparameters set
  ``normalize = true`` (:func:`khepera_gym.learning.sb3.load_policy` applies them); with
  ``frame_stack = n`` (n > 1) the policy sees the last n observations (SB3's ``VecFrameStack``,
  outside ``VecNormalize``), and ``load_policy`` stacks them the same way from ``run.json``;
* ``run.json``: env, algorithm, seed, resolved hyperparameters, wall time, steps/s, every
  evaluation, and ``meta``: the date, commit, machine and command
  (:mod:`khepera_gym.tooling.provenance`); ``progress.csv``: SB3's training log; TensorBoard event
  files when the ``tensorboard`` package is installed (``tensorboard --logdir runs``).

SB3 and torch are imported only when training starts, so ``khepera-gym demo`` stays light.

``--backend rllib`` trains Ray RLlib's PPO instead (:func:`khepera_gym.learning.rllib.train`, the
``rllib`` extra), from ``configs/hyperparams/rllib_ppo.toml``, evaluated on the same seeded
episodes; the run directory then holds ``checkpoint/`` (RLlib's) and ``run.json``. Both backends
read their tables with :mod:`khepera_gym.learning.recipes`.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import json
import platform
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import khepera_gym
from khepera_gym.config import parse_key_values
from khepera_gym.errors import ConfigError
from khepera_gym.learning.recipes import (
    EVAL_SEED,
    HYPERPARAMS_DIR,
    check_rollout_shape,
    load_hyperparams,
    parse_override,
)
from khepera_gym.tooling import arguments
from khepera_gym.tooling.provenance import provenance

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

    from khepera_gym.learning.sb3 import Evaluation

#: Algorithms ``train`` knows: command-line name → class name (stable-baselines3's, or
#: sb3-contrib's RecurrentPPO: PPO with an LSTM policy, ``MlpLstmPolicy``).
ALGORITHMS = {"ppo": "PPO", "sac": "SAC", "recurrent_ppo": "RecurrentPPO"}
#: Training libraries of ``--backend``: stable-baselines3 (default) or Ray RLlib (PPO only).
BACKENDS = ("sb3", "rllib")
#: Keys of a hyperparameter table that configure the run rather than the SB3 algorithm.
_RUN_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "frame_stack", "env_kwargs")
#: Keywords :func:`build_model` gives the algorithm itself, which a table therefore cannot set.
_SET_BY_BUILD = ("env", "seed", "device", "verbose", "_init_setup_model")
#: Activation functions by name, for ``policy_kwargs.activation_fn``.
_ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu")


class LinearDecay:
    """Learning-rate schedule decaying linearly from ``start`` to 0 over training ("lin_X")."""

    def __init__(self, start: float) -> None:
        self.start = start

    def __call__(self, progress_remaining: float) -> float:
        """SB3 passes the fraction of training left, 1 → 0."""
        return progress_remaining * self.start

    def __repr__(self) -> str:
        return f"lin_{self.start}"


def _learning_rate(value: Any) -> Any:
    if isinstance(value, str):
        if value.startswith("lin_"):
            try:
                return LinearDecay(float(value.removeprefix("lin_")))
            except ValueError:
                pass
        raise ConfigError(f"learning_rate must be a number or 'lin_<number>', got {value!r}")
    return float(value)


def _policy_kwargs(kwargs: Mapping[str, Any]) -> dict[str, Any]:
    import torch

    result = dict(kwargs)
    activation = result.get("activation_fn")
    if activation is not None:
        if activation not in _ACTIVATIONS:
            raise ConfigError(
                f"policy_kwargs.activation_fn must be one of {_ACTIVATIONS}, got {activation!r}"
            )
        names = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU"}
        result["activation_fn"] = getattr(torch.nn, names[activation])
    return result


def hyperparameter_keys(algo: str) -> tuple[str, ...]:
    """The keys a hyperparameter table of ``algo`` may hold: the run's (``n_envs``,
    ``n_timesteps``, ``policy``, ``normalize``, ``frame_stack``, ``env_kwargs``), then the
    keywords of the algorithm's constructor (``inspect.signature`` of SB3's class) but those
    :func:`build_model` sets.

    Raises:
        ConfigError: Unknown algorithm.
        ImportError: Its library is not installed.
    """
    import inspect

    from khepera_gym.learning.sb3 import algorithm_class

    if algo not in ALGORITHMS:
        raise ConfigError(f"unknown algorithm {algo!r}; known: {sorted(ALGORITHMS)}")
    parameters = inspect.signature(algorithm_class(ALGORITHMS[algo])).parameters
    keywords = [name for name in parameters if name not in (*_RUN_KEYS, *_SET_BY_BUILD)]
    return (*_RUN_KEYS, *keywords)


def build_model(
    algo: str,
    env: Any,
    hyperparams: Mapping[str, Any],
    seed: int | None,
    device: str = "cpu",
) -> BaseAlgorithm:
    """The SB3 algorithm ``algo`` on ``env`` from a hyperparameter table (run keys ignored).

    Raises:
        ConfigError: Unknown algorithm, or a key the algorithm does not take.
    """
    from khepera_gym.learning.sb3 import algorithm_class

    if algo not in ALGORITHMS:
        raise ConfigError(f"unknown algorithm {algo!r}; known: {sorted(ALGORITHMS)}")
    algorithm = algorithm_class(ALGORITHMS[algo])
    kwargs = {key: value for key, value in hyperparams.items() if key not in _RUN_KEYS}
    if "learning_rate" in kwargs:
        kwargs["learning_rate"] = _learning_rate(kwargs["learning_rate"])
    if "policy_kwargs" in kwargs:
        kwargs["policy_kwargs"] = _policy_kwargs(kwargs["policy_kwargs"])
    if "train_freq" in kwargs and isinstance(kwargs["train_freq"], list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    policy = hyperparams.get("policy", "MlpPolicy")
    try:
        return algorithm(policy, env, seed=seed, device=device, verbose=0, **kwargs)
    except TypeError as error:
        raise ConfigError(f"{ALGORITHMS[algo]} hyperparameters: {error}") from error


@dataclasses.dataclass
class TrainResult:
    """What :func:`train` did; also written to ``run.json`` in the run directory."""

    env_id: str
    algo: str
    seed: int
    timesteps: int
    n_envs: int
    hyperparams: dict[str, Any]
    #: Wall time of ``model.learn`` (s), evaluations included.
    wall_time: float
    #: Wall time of the periodic evaluations inside it (s).
    eval_time: float
    #: Environment steps per second of ``model.learn`` (evaluations included).
    steps_per_second: float
    #: The final model on ``eval_episodes`` seeded episodes.
    final: Evaluation
    #: The periodic evaluations.
    history: list[Evaluation]
    out_dir: Path
    #: The final model on the same episodes, sampling its actions from its distribution as it
    #: did while it trained (torch seeded with the evaluation seed).
    final_sampled: Evaluation | None = None

    @property
    def model_path(self) -> Path:
        """The final model's zip."""
        return self.out_dir / "model.zip"

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict of the run."""
        record = dataclasses.asdict(self)
        record["out_dir"] = str(self.out_dir)
        record["hyperparams"] = json.loads(json.dumps(self.hyperparams, default=str))
        return record


def train(
    env_id: str,
    algo: str = "ppo",
    *,
    timesteps: int | None = None,
    n_envs: int | None = None,
    seed: int = 0,
    out_dir: str | Path | None = None,
    hyperparams_path: str | Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    eval_freq: int | None = None,
    eval_episodes: int = 100,
    eval_seed: int = EVAL_SEED,
    num_threads: int | None = None,
    progress_bar: bool = True,
    verbose: int = 1,
    device: str = "cpu",
    torch_threads: int | None = 1,
) -> TrainResult:
    """Trains ``algo`` on ``env_id`` over the Rust batch, evaluates it and saves the run.

    Args:
        env_id: A khepera_gym id ("KheperaIV-Nav" picks the latest version).
        algo: "ppo", "sac" or "recurrent_ppo" (sb3-contrib's RecurrentPPO).
        timesteps: Environment steps in total; None takes the table's ``n_timesteps``.
        n_envs: Worlds trained in parallel; None takes the table's ``n_envs``.
        seed: Seeds the algorithm (torch) and the training worlds (world i: seed + i).
        out_dir: The run directory; None makes ``runs/<algo>-<env>-s<seed>``.
        hyperparams_path: Another hyperparameter file than ``configs/hyperparams/<algo>.toml``.
        overrides: Hyperparameters replacing the table's (``--hp KEY=VALUE``).
        eval_freq: Environment steps between evaluations; None: a tenth of the run; 0: none
            (the final evaluation still runs).
        eval_episodes: Seeded episodes per evaluation (worlds of the evaluation env).
        eval_seed: Seed of the first evaluation episode (the others: + 1, + 2, ...).
        num_threads: Threads of the Rust batches; None uses all cores.
        progress_bar: Show SB3's progress bar (needs tqdm and rich).
        verbose: 1 prints the evaluations and a summary; 2 also SB3's training tables.
        device: Torch device ("cpu": these small MLPs gain nothing on a GPU).
        torch_threads: Torch's intra-op threads while training (restored afterwards); None
            keeps torch's setting. 1 by default: on small MLPs more threads only add
            synchronisation (measured on 2 cores, PPO on Nav: 8,300 steps/s with 1 torch
            thread, 1,050 with 2).

    Returns:
        A :class:`TrainResult` (also saved as ``run.json``).
    """
    import torch

    previous_threads = torch.get_num_threads()
    if torch_threads is not None:
        torch.set_num_threads(torch_threads)
    try:
        return _train(
            env_id,
            algo,
            timesteps=timesteps,
            n_envs=n_envs,
            seed=seed,
            out_dir=out_dir,
            hyperparams_path=hyperparams_path,
            overrides=overrides,
            eval_freq=eval_freq,
            eval_episodes=eval_episodes,
            eval_seed=eval_seed,
            num_threads=num_threads,
            progress_bar=progress_bar,
            verbose=verbose,
            device=device,
        )
    finally:
        torch.set_num_threads(previous_threads)


def _train(
    env_id: str,
    algo: str,
    *,
    timesteps: int | None,
    n_envs: int | None,
    seed: int,
    out_dir: str | Path | None,
    hyperparams_path: str | Path | None,
    overrides: Mapping[str, Any] | None,
    eval_freq: int | None,
    eval_episodes: int,
    eval_seed: int,
    num_threads: int | None,
    progress_bar: bool,
    verbose: int,
    device: str,
) -> TrainResult:
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor, VecNormalize

    from khepera_gym.learning.sb3 import (
        VECNORMALIZE_FILE,
        SuccessEvalCallback,
        as_predictor,
        evaluate_episodes,
        make_vec_env,
        resolve_env_id,
    )

    env_id = resolve_env_id(env_id)
    hyperparams = load_hyperparams(algo, env_id, hyperparams_path)
    hyperparams.update(overrides or {})
    if timesteps is not None:
        hyperparams["n_timesteps"] = timesteps
    table_worlds = hyperparams.get("n_envs")
    if n_envs is not None:
        hyperparams["n_envs"] = n_envs
    total = int(hyperparams.get("n_timesteps", 100_000))
    worlds = int(hyperparams.get("n_envs", 1))
    if total < 1 or worlds < 1:
        raise ConfigError(f"timesteps and n_envs must be >= 1, got {total} and {worlds}")
    check_rollout_shape(env_id, worlds, hyperparams, table_worlds)
    frame_stack = hyperparams.get("frame_stack", 1)
    if isinstance(frame_stack, bool) or not isinstance(frame_stack, int) or frame_stack < 1:
        raise ConfigError(f"frame_stack must be an integer >= 1, got {frame_stack!r}")
    if frame_stack > 1 and ALGORITHMS.get(algo) == "RecurrentPPO":
        raise ConfigError(
            "a RecurrentPPO model keeps its memory in its LSTM: train it without frame_stack"
        )
    env_kwargs = dict(hyperparams.get("env_kwargs", {}))
    short_name = env_id.removeprefix("KheperaIV-").lower()
    out = Path(out_dir) if out_dir is not None else Path("runs") / f"{algo}-{short_name}-s{seed}"
    out.mkdir(parents=True, exist_ok=True)

    env = VecMonitor(make_vec_env(env_id, worlds, seed=seed, num_threads=num_threads, **env_kwargs))
    if hyperparams.get("normalize", False):
        env = VecNormalize(env, gamma=float(hyperparams.get("gamma", 0.99)))
    if frame_stack > 1:
        env = VecFrameStack(env, frame_stack)
    model = build_model(algo, env, hyperparams, seed, device)
    formats = ["csv"] + (["stdout"] if verbose >= 2 else [])
    if importlib.util.find_spec("tensorboard") is not None:
        formats.append("tensorboard")
    model.set_logger(configure(str(out), formats))

    eval_env = make_vec_env(env_id, eval_episodes, num_threads=num_threads, **env_kwargs)
    every = max(total // 10, 1) if eval_freq is None else eval_freq
    callback = None
    if every > 0:
        callback = SuccessEvalCallback(
            eval_env,
            every,
            eval_seed,
            best_model_path=out / "best_model.zip",
            verbose=verbose,
            frame_stack=frame_stack,
        )
    if progress_bar and importlib.util.find_spec("rich") is None:
        print("progress bar off: it needs the rich package (pip install 'khepera-gym[sb3]')")
        progress_bar = False
    if verbose:
        print(
            f"training {ALGORITHMS[algo]} on {env_id}: {total:,} steps, {worlds} worlds, "
            f"seed {seed}, run directory {out}"
        )
    start = time.perf_counter()
    try:
        model.learn(total_timesteps=total, callback=callback, progress_bar=progress_bar)
    finally:
        model.logger.close()
    wall_time = time.perf_counter() - start
    model.save(out / "model.zip")
    normalizer = model.get_vec_normalize_env()
    if normalizer is not None:
        normalizer.save(str(out / VECNORMALIZE_FILE))
    history = callback.history if callback is not None else []
    policy = as_predictor(model, normalizer, frame_stack)
    if history and history[-1].timesteps == model.num_timesteps:
        final = history[-1]  # the callback evaluated the final model at the end of training
    else:
        final = evaluate_episodes(policy, eval_env, eval_seed, model.num_timesteps)
    # A policy's mean can stall where the policy it learnt does not (Avoid-v2, docs/history.md).
    final_sampled = evaluate_episodes(
        policy, eval_env, eval_seed, model.num_timesteps, sample_seed=eval_seed
    )
    result = TrainResult(
        env_id=env_id,
        algo=algo,
        seed=seed,
        timesteps=int(model.num_timesteps),
        n_envs=worlds,
        hyperparams=hyperparams,
        wall_time=wall_time,
        eval_time=sum(evaluation.seconds for evaluation in history),
        steps_per_second=model.num_timesteps / wall_time,
        final=final,
        history=history,
        out_dir=out,
        final_sampled=final_sampled,
    )
    record = result.to_json()
    record["versions"] = _versions()
    record["meta"] = provenance()
    (out / "run.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    env.close()
    eval_env.close()
    if verbose:
        print(
            f"done in {wall_time:.0f} s ({result.steps_per_second:,.0f} steps/s, evaluations "
            f"{result.eval_time:.0f} s); final model: success {100 * final.success_rate:.1f} % "
            f"of {final.episodes} episodes (seeds {eval_seed}..{eval_seed + final.episodes - 1}),"
            f" mean return {final.mean_return:.2f}, mean length {final.mean_length:.1f}"
        )
        print(
            f"sampling its actions (compare/export --sample-actions): success "
            f"{100 * final_sampled.success_rate:.1f} %, mean length {final_sampled.mean_length:.1f}"
        )
        print(f"saved {out / 'model.zip'}")
    return result


def _versions() -> dict[str, str]:
    import stable_baselines3
    import torch

    return {
        "khepera_gym": khepera_gym.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "python": platform.python_version(),
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of ``khepera-gym train``."""
    parser.add_argument("--env", required=True, help="env id, e.g. KheperaIV-Nav (latest version)")
    parser.add_argument("--algo", choices=sorted(ALGORITHMS), default="ppo", help="(ppo)")
    parser.add_argument("--timesteps", type=int, help="environment steps (the table's n_timesteps)")
    parser.add_argument("--n-envs", type=int, help="worlds trained in parallel (the table's)")
    parser.add_argument("--seed", type=int, default=0, help="training seed (0)")
    parser.add_argument("--out", type=Path, help="run directory (runs/<algo>-<env>-s<seed>)")
    parser.add_argument(
        "--hyperparams", type=Path, help="hyperparameter TOML (configs/hyperparams/<algo>.toml)"
    )
    parser.add_argument(
        "--hp",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a hyperparameter, VALUE in TOML syntax (repeatable)",
    )
    parser.add_argument(
        "--eval-freq", type=int, help="steps between evaluations (a tenth of the run; 0: none)"
    )
    parser.add_argument(
        "--eval-episodes", type=int, default=100, help="seeded episodes per evaluation (100)"
    )
    parser.add_argument(
        "--eval-seed", type=int, default=EVAL_SEED, help=f"first evaluation seed ({EVAL_SEED})"
    )
    parser.add_argument("--num-threads", type=int, help="threads of the Rust batch (all cores)")
    parser.add_argument("--device", default="cpu", help="torch device (cpu)")
    parser.add_argument(
        "--torch-threads", type=int, default=1, help="torch intra-op threads (1: fastest here)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--verbose", type=int, default=1, help="0 quiet, 1 evaluations (default), 2 SB3 tables"
    )
    parser.add_argument(
        "--backend",
        choices=BACKENDS,
        default="sb3",
        help="sb3 (stable-baselines3, default) or rllib (Ray RLlib PPO: the rllib extra; "
        "--n-envs is then worlds per EnvRunner)",
    )
    parser.add_argument(
        "--num-env-runners",
        type=int,
        help="rllib: remote EnvRunners, 1 CPU each (the table's; 0 samples in this process)",
    )
    parser.add_argument(
        "--address", help="rllib: address of a Ray cluster (ray.init(address=...)); default local"
    )


def check_arguments(args: argparse.Namespace) -> None:
    """Checks ``khepera-gym train``'s arguments before anything is built or trained: the env
    id (the nearest khepera_gym id is suggested), counts, seeds, the hyperparameter file, and
    the run directory (created if given, and writable).

    Raises:
        SystemExit: One line naming the first bad argument.
    """
    try:
        arguments.env_id(args.env)
        arguments.at_least(args.timesteps, 1, "--timesteps")
        arguments.at_least(args.n_envs, 1, "--n-envs")
        arguments.seed(args.seed)
        arguments.seed(args.eval_seed, "--eval-seed")
        arguments.at_least(args.eval_freq, 0, "--eval-freq")
        arguments.at_least(args.eval_episodes, 1, "--eval-episodes")
        arguments.at_least(args.num_threads, 1, "--num-threads")
        arguments.at_least(args.torch_threads, 1, "--torch-threads")
        arguments.at_least(getattr(args, "num_env_runners", None), 0, "--num-env-runners")
        arguments.input_file(args.hyperparams, "--hyperparams")
        if args.out is not None:
            arguments.output_folder(args.out, "--out")
    except ConfigError as error:
        raise SystemExit(f"khepera-gym train: {arguments.one_line(error)}") from None


def _run_rllib(args: argparse.Namespace) -> int:
    """``khepera-gym train --backend rllib``: :func:`khepera_gym.learning.rllib.train`."""
    if importlib.util.find_spec("ray") is None or importlib.util.find_spec("torch") is None:
        raise SystemExit(
            "khepera-gym train --backend rllib needs Ray RLlib and torch: "
            "pip install 'khepera-gym[rllib]'"
        )
    if args.algo != "ppo":
        raise SystemExit(f"khepera-gym train --backend rllib trains ppo only, not {args.algo}")
    check_arguments(args)
    from khepera_gym.learning import rllib

    try:
        rllib.train(
            args.env,
            timesteps=args.timesteps,
            n_envs=args.n_envs,
            num_env_runners=args.num_env_runners,
            seed=args.seed,
            out_dir=args.out,
            hyperparams_path=args.hyperparams,
            overrides=parse_key_values(args.hp, "--hp"),
            eval_freq=args.eval_freq,
            eval_episodes=args.eval_episodes,
            eval_seed=args.eval_seed,
            address=args.address,
            verbose=args.verbose,
            torch_threads=args.torch_threads,
        )
    except ConfigError as error:
        raise SystemExit(f"khepera-gym train: {error}") from None
    return 0


def run_from_args(args: argparse.Namespace) -> int:
    """Runs ``khepera-gym train`` from parsed arguments; returns the exit code."""
    if getattr(args, "backend", "sb3") == "rllib":
        return _run_rllib(args)
    if importlib.util.find_spec("stable_baselines3") is None:
        raise SystemExit(
            "khepera-gym train needs stable-baselines3: pip install 'khepera-gym[sb3]'"
        )
    check_arguments(args)
    try:
        train(
            args.env,
            args.algo,
            timesteps=args.timesteps,
            n_envs=args.n_envs,
            seed=args.seed,
            out_dir=args.out,
            hyperparams_path=args.hyperparams,
            overrides=parse_key_values(args.hp, "--hp"),
            eval_freq=args.eval_freq,
            eval_episodes=args.eval_episodes,
            eval_seed=args.eval_seed,
            num_threads=args.num_threads,
            progress_bar=not args.no_progress,
            verbose=args.verbose,
            device=args.device,
            torch_threads=args.torch_threads,
        )
    except ConfigError as error:
        raise SystemExit(f"khepera-gym train: {error}") from None
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m khepera_gym.learning.train ...``: the same as ``khepera-gym train ...``."""
    parser = argparse.ArgumentParser(prog="khepera-gym train", description=__doc__.split("\n")[0])
    add_arguments(parser)
    return run_from_args(parser.parse_args(argv))


__all__ = [
    "ALGORITHMS",
    "BACKENDS",
    "EVAL_SEED",
    "HYPERPARAMS_DIR",
    "LinearDecay",
    "TrainResult",
    "add_arguments",
    "build_model",
    "hyperparameter_keys",
    "load_hyperparams",
    "parse_override",
    "run_from_args",
    "train",
]


if __name__ == "__main__":
    raise SystemExit(main())
