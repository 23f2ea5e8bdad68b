"""MAPPO on Formation with BenchMARL, on the CPU in a few minutes; formation error before/after.

    python examples/benchmarl_mappo.py [--frames 150000] [--worlds 8] [--episodes 50]
    python examples/benchmarl_mappo.py --version 0     # the v0 dynamics (the paper's V-REP)
    python examples/benchmarl_mappo.py --algorithm ippo  # each follower's critic on its own block
    python examples/benchmarl_mappo.py --set wheel_accel_limit=inf  # a scenario key (TOML value)
    python examples/benchmarl_mappo.py --fixed-sigma 0.6 --frames 600000  # learns v1 (README)
    python examples/benchmarl_mappo.py --no-tanh --entropy-coef 0.001  # other noise settings
    python examples/benchmarl_mappo.py --no-normalize-advantage --max-grad-norm 5  # BenchMARL's
    python examples/benchmarl_mappo.py --shared-sigma  # one learned σ per action, as SB3's PPO
    python examples/benchmarl_mappo.py --json mappo.json  # also the results page's file

BenchMARL trains MAPPO (one actor shared by the followers, a centralised critic on the ``state``,
the joint observation) on ``khepera_gym.learning.torchrl.benchmarl.KheperaTask.FORMATION``: a
``KheperaTorchEnv`` of ``--worlds`` worlds, each follower an agent of the ``"followers"`` group with
its own 23-value observation and its own reward (minus its distance to its eq. 12 target, minus
contacts); the scripted leader drives to its goal. Before and after training the policy
(deterministic actions) plays the same ``--episodes`` seeded episodes (seeds 10000 + i), as does the
LeaderFollower baseline for reference, and the mean formation error is printed.
Hyperparameters mirror the ``formation-followers`` table of configs/hyperparams/ppo.toml (1,024 env
steps per batch, 10 epochs of minibatches of 128, γ = λ = 0.95, 64 × 64 MLPs) and SB3's PPO: each
minibatch's advantages standardised, the gradients' norm clipped at 0.5 (BenchMARL's MAPPO does not
standardise them and clips at 5: with its settings MAPPO ends 600k env steps at 1.0, 8.0 and 4.1 cm
over three training seeds, with these at 0.3, 0.8 and 0.9 cm; LeaderFollower 0.4 cm;
docs/history.md). BenchMARL's default of 45 epochs per batch is far slower on a CPU. Every
``--report-every`` iterations the script prints the policy's mean action noise (the σ of its
Gaussian before the tanh) over the batch just collected: on v1 it shows why MAPPO fails there
(README), and ``--fixed-sigma`` holds σ constant (a scale mapping registered with tensordict's
``add_custom_mapping``), with which MAPPO learns v1. ``--no-tanh`` samples actions from a plain
Gaussian clipped to the bounds (as SB3's PPO does) instead of BenchMARL's tanh-squashed one, and
``--entropy-coef`` rewards the policy's entropy (BenchMARL's default: 0), which pushes against a
collapsing σ. ``--no-normalize-advantage`` and ``--max-grad-norm 5`` go back to BenchMARL's own
settings. ``--shared-sigma`` learns σ as SB3's PPO does, one number per action whatever the state
(its log starts at 0, σ = 1), instead of from the actor's output. A results file names the
settings that differ from BenchMARL's defaults.
Needs the ``benchmarl`` extra (``pip install 'khepera-gym[benchmarl]'``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from khepera_gym import registry
from khepera_gym.analysis.compare import parse_overrides
from khepera_gym.analysis.compare.report import write_formation_learning
from khepera_gym.baselines import LeaderFollower
from khepera_gym.errors import ConfigError
from khepera_gym.learning.torchrl import KheperaTorchEnv, torchrl_import_warnings_ignored
from khepera_gym.learning.torchrl.benchmarl import KheperaTask

with torchrl_import_warnings_ignored():
    from benchmarl.algorithms import IppoConfig, MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.experiment.callback import Callback
    from benchmarl.models import MlpConfig
    from tensordict import TensorDictBase
    from tensordict.nn import add_custom_mapping
    from torchrl.envs.utils import ExplorationType, set_exploration_type

#: Evaluation episodes are seeded EVAL_SEED + i, away from the training worlds' seeds.
EVAL_SEED = 10_000
#: The gradient clip of SB3's PPO (its ``max_grad_norm``), this example's default, and of
#: BenchMARL's experiment config (``clip_grad_val``).
SB3_MAX_GRAD_NORM = 0.5
BENCHMARL_MAX_GRAD_NORM = 5.0
#: The task's scenario: Formation's defaults (4 followers in a cross, scripted leader).
TASK_CONFIG: dict[str, Any] = {"n_followers": 4, "shape": "cross"}


def formation_errors(
    policy: Callable[[TensorDictBase], TensorDictBase], episodes: int, task_config: dict[str, Any]
) -> dict[str, float]:
    """Mean formation error (m) and contacts of one episode in each of ``episodes`` worlds."""
    env = KheperaTorchEnv("formation", episodes, seed=EVAL_SEED, **task_config)
    error_mean = np.full(episodes, np.nan)
    error_max = np.full(episodes, np.nan)
    collisions = np.full(episodes, np.nan)
    tensordict = env.reset()
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(env.max_episode_steps):
            tensordict, next_tensordict = env.step_and_maybe_reset(policy(tensordict))
            ended = tensordict["next", "done"].squeeze(-1).numpy() & np.isnan(error_mean)
            if ended.any():
                stats = env.episode_stats()
                error_mean[ended] = stats["formation_error_mean"][ended]
                error_max[ended] = stats["formation_error_max"][ended]
                collisions[ended] = stats["collisions"][ended]
            if not np.isnan(error_mean).any():
                break
            tensordict = next_tensordict
    return {
        "error_mean": float(error_mean.mean()),
        "error_max": float(error_max.mean()),
        "collisions": float(collisions.mean()),
    }


def leader_follower_policy() -> Callable[[TensorDictBase], TensorDictBase]:
    """The LeaderFollower baseline (eq. 12 on each follower's observed target) as a policy."""
    controller = LeaderFollower(shape=None)

    def act(tensordict: TensorDictBase) -> TensorDictBase:
        observation = tensordict["followers", "observation"]
        actions, _ = controller.predict(observation.reshape(-1, observation.shape[-1]).numpy())
        tensordict["followers", "action"] = torch.from_numpy(actions).reshape(
            *observation.shape[:-1], 2
        )
        return tensordict

    return act


class NoiseReport(Callback):
    """Prints the policy's mean action noise σ and mean |location| every ``every`` batches."""

    def __init__(self, every: int) -> None:
        super().__init__()
        self.every = every

    def on_batch_collected(self, batch: TensorDictBase) -> None:
        iteration = self.experiment.n_iters_performed
        if self.every > 0 and iteration % self.every == 0:
            followers = batch["followers"]
            print(
                f"\niteration {iteration}: action noise sigma {followers['scale'].mean():.2f}, "
                f"|loc| {followers['loc'].abs().mean():.2f}, "
                f"reward per step {batch['next', 'followers', 'reward'].mean():.3f}"
            )


class SharedSigma:
    """σ learned as SB3's PPO learns it: one parameter per action (its log, from 0: σ = 1),
    whatever the state, instead of from the actor's output (BenchMARL's ``NormalParamExtractor``
    maps half of the actor's outputs to σ; with this mapping those outputs get no gradient)."""

    #: The name of the scale mapping registered with tensordict.
    MAPPING = "khepera_shared_sigma"

    def __init__(self, algorithm: MappoConfig | IppoConfig, actions: int = 2) -> None:
        """Sets ``algorithm``'s scale mapping to σ = exp(``log_sigma``), one per action (a
        follower commands two wheels)."""
        self.log_sigma = torch.nn.Parameter(torch.zeros(actions))
        algorithm.scale_mapping = self.MAPPING
        add_custom_mapping(self.MAPPING, lambda x: self.log_sigma.exp().expand_as(x))

    def train_with(self, experiment: Experiment) -> None:
        """Adds ``log_sigma`` to the optimizer of every group's actor loss (and so to its
        gradient clip), as SB3 trains its ``log_std`` with the policy."""
        for optimizers in experiment.optimizers.values():
            optimizers["loss_objective"].add_param_group({"params": [self.log_sigma]})

    @property
    def sigma(self) -> torch.Tensor:
        """The current σ, one per action."""
        return self.log_sigma.detach().exp()


def result_row(policy: str, errors: dict[str, float]) -> dict[str, Any]:
    """A policy's row of the results file (the leader's arrival is not measured here)."""
    return {
        "policy": policy,
        "formation_error_mean": errors["error_mean"],
        "formation_error_max": errors["error_max"],
        "success_rate": None,
        "contact_steps": errors["collisions"],
    }


def report(name: str, errors: dict[str, float]) -> None:
    print(
        f"{name:<24} formation error mean {100 * errors['error_mean']:6.1f} cm, "
        f"max {100 * errors['error_max']:6.1f} cm, steps in contact {errors['collisions']:5.1f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=150_000, help="env steps to train on")
    parser.add_argument("--worlds", type=int, default=8, help="worlds collecting in parallel")
    parser.add_argument("--frames-per-batch", type=int, default=1_024, help="env steps")
    parser.add_argument("--minibatch-size", type=int, default=128, help="env steps")
    parser.add_argument("--epochs", type=int, default=10, help="passes over each batch")
    parser.add_argument("--hidden", type=int, nargs="+", default=[64, 64], help="MLP layers")
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--gamma", type=float, default=0.95)
    parser.add_argument("--episodes", type=int, default=50, help="evaluation episodes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--version", type=int, help="behaviour version (default: the latest)")
    parser.add_argument(
        "--algorithm",
        choices=("mappo", "ippo"),
        default="mappo",
        help="mappo: critic on the joint observation; ippo: each follower's critic on its own",
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario key for training and evaluation, e.g. wheel_accel_limit=inf",
    )
    parser.add_argument(
        "--fixed-sigma",
        type=float,
        metavar="SIGMA",
        help="hold the policy's action noise (σ before the tanh) at SIGMA instead of learning it",
    )
    parser.add_argument(
        "--shared-sigma",
        action="store_true",
        help="learn one σ per action whatever the state (SB3's PPO), not σ from the actor's output",
    )
    parser.add_argument(
        "--no-tanh",
        action="store_true",
        help="a Gaussian clipped to the action bounds instead of BenchMARL's tanh-squashed one",
    )
    parser.add_argument(
        "--entropy-coef",
        type=float,
        default=0.0,
        metavar="C",
        help="weight of the policy's entropy in the loss (BenchMARL's default: 0)",
    )
    parser.add_argument(
        "--normalize-advantage",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="standardise each minibatch's advantages, as SB3's PPO does (default; BenchMARL's "
        "MAPPO does not)",
    )
    parser.add_argument(
        "--max-grad-norm",
        type=float,
        default=SB3_MAX_GRAD_NORM,
        metavar="N",
        help=f"clip the gradients' norm to N ({SB3_MAX_GRAD_NORM:g}, SB3's PPO's; BenchMARL's: "
        f"{BENCHMARL_MAX_GRAD_NORM:g})",
    )
    parser.add_argument(
        "--report-every", type=int, default=20, help="iterations between noise reports (0: none)"
    )
    parser.add_argument("--json", help="also write the figures to this results file")
    args = parser.parse_args()
    if args.fixed_sigma is not None and args.shared_sigma:
        parser.error("--fixed-sigma and --shared-sigma are two ways to set σ: choose one")
    if args.fixed_sigma is not None and not 0.0 < args.fixed_sigma < float("inf"):
        parser.error(f"--fixed-sigma must be a finite number > 0, got {args.fixed_sigma}")
    if not 0.0 < args.max_grad_norm < float("inf"):
        parser.error(f"--max-grad-norm must be a finite number > 0, got {args.max_grad_norm}")
    if not 0.0 <= args.entropy_coef < float("inf"):
        parser.error(f"--entropy-coef must be a finite number >= 0, got {args.entropy_coef}")
    task_config = dict(TASK_CONFIG)
    try:
        task_config.update(parse_overrides(args.set))
    except ConfigError as error:
        parser.error(str(error))
    if args.version is not None:
        task_config["version"] = args.version
    # One torch thread: on these small MLPs more threads only add synchronisation (2 cores).
    torch.set_num_threads(1)

    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = config.buffer_device = "cpu"
    config.max_n_frames = args.frames
    config.on_policy_collected_frames_per_batch = args.frames_per_batch
    config.on_policy_n_envs_per_worker = args.worlds
    config.on_policy_minibatch_size = args.minibatch_size
    # BenchMARL's n_minibatch_iters counts passes over the batch (its default, 45, is slow on
    # a CPU: 675 gradient steps per batch).
    config.on_policy_n_minibatch_iters = args.epochs
    config.lr = args.lr
    config.gamma = args.gamma
    config.clip_grad_val = args.max_grad_norm
    config.evaluation = False
    config.render = False
    config.loggers = []
    config.create_json = False
    config.checkpoint_at_end = False
    config.save_folder = tempfile.mkdtemp(prefix="benchmarl_mappo_")
    algorithm = (MappoConfig if args.algorithm == "mappo" else IppoConfig).get_from_yaml()
    algorithm.lmbda = 0.95
    algorithm.use_tanh_normal = not args.no_tanh
    algorithm.entropy_coef = args.entropy_coef
    if args.fixed_sigma is not None:
        # BenchMARL maps the second half of the actor's output to σ through a named mapping: a
        # constant one holds σ where it is (those outputs then get no gradient).
        sigma = args.fixed_sigma
        algorithm.scale_mapping = f"khepera_fixed_sigma_{sigma}"
        add_custom_mapping(algorithm.scale_mapping, lambda x: torch.full_like(x, sigma))
    shared_sigma = SharedSigma(algorithm) if args.shared_sigma else None
    model = MlpConfig.get_from_yaml()
    model.num_cells = list(args.hidden)
    experiment = Experiment(
        task=KheperaTask.FORMATION.get_task(config=dict(task_config)),
        algorithm_config=algorithm,
        model_config=model,
        critic_model_config=model,
        seed=args.seed,
        config=config,
        callbacks=[NoiseReport(args.report_every)],
    )
    if shared_sigma is not None:
        shared_sigma.train_with(experiment)
    if args.normalize_advantage:
        for loss in experiment.losses.values():
            loss.normalize_advantage = True  # torchrl's ClipPPOLoss option
    print(f"{args.episodes} seeded Formation episodes (4 followers, cross), deterministic actions")
    baseline = formation_errors(leader_follower_policy(), args.episodes, task_config)
    report("LeaderFollower", baseline)
    name = args.algorithm.upper()
    report(
        f"{name} before training", formation_errors(experiment.policy, args.episodes, task_config)
    )
    start = time.perf_counter()
    experiment.run()
    elapsed = time.perf_counter() - start
    print(
        f"trained on {experiment.total_frames:,} env steps ({experiment.n_iters_performed} "
        f"iterations) in {elapsed:.0f} s: {experiment.total_frames / elapsed:,.0f} env steps/s"
    )
    learned = formation_errors(experiment.policy, args.episodes, task_config)
    report(f"{name} after training", learned)
    if args.json:
        # A run with other settings is another method: its name lists those that differ from
        # BenchMARL's defaults, so that its file does not replace another's.
        settings = []
        if args.fixed_sigma is not None:
            settings.append(f"sigma fixed at {args.fixed_sigma:g}")
        if args.shared_sigma:
            settings.append("one σ per action")
        if args.no_tanh:
            settings.append("Gaussian without tanh")
        if args.entropy_coef:
            settings.append(f"entropy coefficient {args.entropy_coef:g}")
        if args.normalize_advantage:
            settings.append("normalised advantages")
        if args.max_grad_norm != BENCHMARL_MAX_GRAD_NORM:
            settings.append(f"gradient norm clipped at {args.max_grad_norm:g}")
        method = f"{name} (BenchMARL{''.join(', ' + part for part in settings)})"
        rows = [result_row(method, learned), result_row("LeaderFollower", baseline)]
        frames = experiment.total_frames
        write_formation_learning(
            args.json,
            method,
            frames,
            elapsed,
            args.episodes,
            EVAL_SEED,
            rows,
            args.seed,
            version=registry.LATEST_VERSION if args.version is None else args.version,
        )
        print(f"saved {args.json}")


if __name__ == "__main__":
    main()
