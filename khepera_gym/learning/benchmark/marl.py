"""BenchMARL's MAPPO and IPPO as learners of the benchmark (the ``benchmarl`` extra).

The task's agents form one group (``followers``, ``robots``) sharing one actor; MAPPO's critic
reads the joint observation (``state``), IPPO's each agent's own. The recipe is the family's
table in ``configs/hyperparams/mappo.toml`` (or ``ippo.toml``): ``n_timesteps`` (env steps),
``n_envs`` (worlds collecting), ``frames_per_batch``, ``minibatch_size``, ``n_epochs``,
``hidden``, ``learning_rate``, ``gamma``, ``gae_lambda``, ``max_grad_norm``,
``normalize_advantage`` (each minibatch's advantages standardised, as SB3's PPO does),
``entropy_coef``, ``tanh`` (BenchMARL's tanh-squashed Gaussian, or a Gaussian clipped to the
bounds), ``sigma_min`` (a floor under the actor's σ, before the tanh: BenchMARL maps half of the
actor's outputs to σ by a softplus whose floor is 0.01; this raises it, so σ cannot collapse) and
``env_kwargs``. The trained actor plays the held-out episodes agent by agent, as the
rows of :func:`khepera_gym.learning.sb3.make_vec_env` of the task's PettingZoo module.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np

from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark.jobs import (
    Job,
    Means,
    Trained,
    agents_of,
    module_of,
    shares_rows,
)
from khepera_gym.learning.recipes import EVAL_SEED, load_hyperparams
from khepera_gym.tooling.arguments import did_you_mean

#: Recipe keys this learner reads (any other is an error naming them).
RECIPE_KEYS = (
    "n_timesteps",
    "n_envs",
    "frames_per_batch",
    "minibatch_size",
    "n_epochs",
    "hidden",
    "learning_rate",
    "gamma",
    "gae_lambda",
    "max_grad_norm",
    "normalize_advantage",
    "entropy_coef",
    "tanh",
    "sigma_min",
    "env_kwargs",
)

#: BenchMARL's own floor under σ (its ``biased_softplus_1.0`` mapping: σ = 1 at a zero output).
SIGMA_MIN = 0.01


def scale_mapping(sigma_min: float) -> str:
    """BenchMARL's σ mapping (tensordict's ``biased_softplus_<σ at 0>_<floor>``) with a floor.

    Raises:
        ConfigError: A floor that is not a number in [0.01, 1) (1 is σ at a zero output).
    """
    if isinstance(sigma_min, bool) or not isinstance(sigma_min, int | float):
        raise ConfigError(f"sigma_min must be a number, got {sigma_min!r}")
    if not SIGMA_MIN <= sigma_min < 1.0:
        raise ConfigError(f"sigma_min must be in [{SIGMA_MIN}, 1), got {sigma_min!r}")
    return f"biased_softplus_1.0_{float(sigma_min)!r}"


def return_description(mean_return: float, last: float) -> str:
    """What the progress bar says of a batch's mean episode return: the batch's, else (no
    episode ended in it) the last known one, else that no episode has ended yet; never ``nan``,
    which BenchMARL's own bar shows for a batch without an ended episode."""
    if math.isfinite(mean_return):
        return f"mean return = {mean_return:.4g}"
    if math.isfinite(last):
        return f"mean return = {last:.4g} (no episode ended in the last batch)"
    return "mean return: no episode ended yet"


@contextlib.contextmanager
def _learner_output(experiment: Any, shown: bool) -> Iterator[None]:
    """What BenchMARL and torchrl show while ``experiment`` runs.

    ``shown``: BenchMARL's progress bar, described by :func:`return_description`. Not shown: no
    bar, and torchrl's INFO lines (its ``torchrl`` logger, on stdout) held back. BenchMARL 1.5
    has no option for its bar (its experiment module calls ``tqdm`` itself), so that name is
    bound to a bar of ours for the run. Either way BenchMARL's lines on stdout as the run stops
    (``Experiment was closed gracefully`` after Ctrl-C) are dropped: the benchmark says what
    happened in one line.
    """
    from benchmarl.experiment import experiment as module
    from tqdm import tqdm

    known = [math.nan]

    class Bar(tqdm):
        def set_description(self, desc: str | None = None, refresh: bool | None = True) -> None:
            value = float(experiment.mean_return)
            if math.isfinite(value):
                known[0] = value
            super().set_description(return_description(value, known[0]), refresh)

    def bar(*args: Any, **kwargs: Any) -> Any:
        return Bar(*args, **{**kwargs, "disable": not shown})

    torchrl_log = logging.getLogger("torchrl")
    level, original = torchrl_log.level, module.tqdm
    module.tqdm = bar
    if not shown:
        torchrl_log.setLevel(max(level, logging.WARNING))
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        module.tqdm = original
        torchrl_log.setLevel(level)


class _ActorOnRows:
    """A BenchMARL actor as a predictor on rows (world-major agent blocks, K agents a world)."""

    def __init__(self, policy: Any, group: str, agents: int, random: bool = False) -> None:
        self.policy, self.group, self.agents, self.random = policy, group, agents, random

    def predict(self, rows: Any, *args: Any, deterministic: bool = True) -> tuple[Any, None]:
        import torch
        from tensordict import TensorDict
        from torchrl.envs.utils import ExplorationType, set_exploration_type

        rows = np.asarray(rows, dtype=np.float32)
        worlds = rows.shape[0] // self.agents
        observation = torch.from_numpy(rows.reshape(worlds, self.agents, -1))
        data = TensorDict({self.group: {"observation": observation}}, batch_size=[worlds])
        kind = ExplorationType.RANDOM if self.random else ExplorationType.DETERMINISTIC
        with torch.no_grad(), set_exploration_type(kind):
            actions = self.policy(data)[self.group, "action"]
        return actions.reshape(rows.shape[0], -1).numpy(), None


class BenchMARLLearner:
    """MAPPO (``name="mappo"``) or IPPO (``"ippo"``) through BenchMARL."""

    def __init__(self, name: str) -> None:
        self.name = name

    def env_name(self, task: str, version: int) -> str:
        module = module_of(task, version)
        if module is None or not shares_rows(task):
            raise ConfigError(
                f"learner {self.name!r} trains the agents of a multi-agent task sharing one "
                f"actor; {task!r} is not one (agents: {agents_of(task)})"
            )
        return module

    def check_overrides(self, overrides: Mapping[str, Any]) -> None:
        """Checks the keys of ``overrides`` (``--hp``) against :data:`RECIPE_KEYS`.

        Raises:
            ConfigError: A key the learner does not read; the message suggests the nearest.
        """
        for key in overrides:
            if key not in RECIPE_KEYS:
                raise ConfigError(
                    f"--hp {key}: learner {self.name!r} has no recipe key {key!r}; "
                    f"{did_you_mean(key, RECIPE_KEYS)}"
                )

    def recipe(self, task: str, version: int, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """The recipe table with ``overrides``.

        Raises:
            ConfigError: The learner does not apply to the task, its table is missing, or a key
                (of the table or an override) is not one it reads, or ``sigma_min`` is wrong.
        """
        self.check_overrides(overrides)
        recipe = load_hyperparams(self.name, self.env_name(task, version))
        recipe.update(overrides)
        unknown = sorted(set(recipe) - set(RECIPE_KEYS))
        if unknown:
            raise ConfigError(
                f"{self.name} recipe: unknown key {unknown[0]!r}; "
                f"{did_you_mean(unknown[0], RECIPE_KEYS)}"
            )
        scale_mapping(recipe.get("sigma_min", SIGMA_MIN))  # a wrong floor: now, not after training
        return recipe

    def train(self, job: Job, report: Callable[[int, int], None] | None = None) -> Trained:
        import torch

        from khepera_gym.learning.sb3 import make_vec_env
        from khepera_gym.learning.sb3.evaluate import first_episode_stats
        from khepera_gym.learning.torchrl import torchrl_import_warnings_ignored
        from khepera_gym.learning.torchrl.benchmarl import KheperaTask

        with torchrl_import_warnings_ignored():
            from benchmarl.algorithms import IppoConfig, MappoConfig
            from benchmarl.experiment import Experiment, ExperimentConfig
            from benchmarl.experiment.callback import Callback
            from benchmarl.models import MlpConfig

        name = self.env_name(job.task, job.version)
        recipe = self.recipe(job.task, job.version, job.overrides)
        total = int(job.timesteps if job.timesteps is not None else recipe["n_timesteps"])
        config = ExperimentConfig.get_from_yaml()
        config.sampling_device = config.train_device = config.buffer_device = job.device
        per_batch = int(recipe.get("frames_per_batch", 4096))
        config.max_n_frames = max(total, per_batch)
        config.on_policy_collected_frames_per_batch = per_batch
        config.on_policy_n_envs_per_worker = int(recipe.get("n_envs", 16))
        config.on_policy_minibatch_size = int(recipe.get("minibatch_size", 1024))
        config.on_policy_n_minibatch_iters = int(recipe.get("n_epochs", 5))
        config.lr = float(recipe.get("learning_rate", 3e-4))
        config.gamma = float(recipe.get("gamma", 0.99))
        config.clip_grad_val = float(recipe.get("max_grad_norm", 0.5))
        config.evaluation = False
        config.render = False
        config.loggers = []
        config.create_json = False
        config.checkpoint_at_end = False
        config.save_folder = tempfile.mkdtemp(prefix=f"khepera_{self.name}_")
        algorithm = (MappoConfig if self.name == "mappo" else IppoConfig).get_from_yaml()
        algorithm.lmbda = float(recipe.get("gae_lambda", 0.95))
        algorithm.use_tanh_normal = bool(recipe.get("tanh", True))
        algorithm.entropy_coef = float(recipe.get("entropy_coef", 0.0))
        algorithm.scale_mapping = scale_mapping(recipe.get("sigma_min", SIGMA_MIN))
        model = MlpConfig.get_from_yaml()
        model.num_cells = list(recipe.get("hidden", [64, 64]))
        task_config = {**recipe.get("env_kwargs", {}), "version": job.version}
        if job.num_threads is not None:
            task_config["num_threads"] = job.num_threads
        member = getattr(KheperaTask, job.task.upper())
        history: list[tuple[int, float, Means]] = []
        clock = {"eval": 0.0, "start": 0.0}
        eval_env = make_vec_env(name, job.eval_episodes, num_threads=job.num_threads)
        agents = len(agents_of(job.task))
        every = max(per_batch, total // max(1, job.eval_points))

        def evaluate(experiment: Any) -> None:
            start = time.perf_counter()
            group = next(iter(experiment.group_map))
            actor = _ActorOnRows(experiment.policy, group, agents)
            stats = first_episode_stats(actor, eval_env, EVAL_SEED)
            seconds = time.perf_counter() - start
            trained = start - clock["start"] - clock["eval"]
            clock["eval"] += seconds
            steps = int(experiment.total_frames)
            history.append((steps, trained, {k: float(np.mean(v)) for k, v in stats.items()}))
            if job.on_evaluation is not None:
                job.on_evaluation(*history[-1])
            if report is not None:
                report(steps, total)

        class Evaluations(Callback):
            def on_train_end(self, training_td: Any, group: str) -> None:
                if self.experiment.total_frames // every > len(history):
                    evaluate(self.experiment)

        previous = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            with warnings.catch_warnings():
                # The advantages are standardised over every agent of the minibatch together, as
                # SB3's PPO does for a policy shared by its rows: on purpose, so torchrl's advice
                # to keep the agents' dimension apart is not taken.
                warnings.filterwarnings("ignore", "You requested advantage normalization")
                # BenchMARL's note that a batch in which no episode ended has a NaN mean return
                # (the progress line says so in words: return_description), and torchrl's, made
                # with the collector, that the last batch overshoots the steps (the record's
                # timesteps say how many ran): printed by Python on stderr, they reached the user
                # whatever --no-progress said.
                warnings.filterwarnings("ignore", "No episode terminated this iteration")
                warnings.filterwarnings("ignore", r"total_frames \(\d+\) is not exactly divisible")
                experiment = Experiment(
                    task=member.get_task(config=task_config),
                    algorithm_config=algorithm,
                    model_config=model,
                    critic_model_config=model,
                    seed=job.seed,
                    config=config,
                )
                # Added after construction: BenchMARL pickles the callbacks it is given.
                evaluations = Evaluations()
                evaluations.experiment = experiment
                experiment.callbacks.append(evaluations)
                if recipe.get("normalize_advantage", True):
                    for loss in experiment.losses.values():
                        loss.normalize_advantage = True  # torchrl's ClipPPOLoss option
                clock["start"] = time.perf_counter()
                with _learner_output(experiment, job.progress):
                    experiment.run()
            if not history or history[-1][0] != experiment.total_frames:
                evaluate(experiment)
            wall = time.perf_counter() - clock["start"]
        finally:
            torch.set_num_threads(previous)
        job.out_dir.mkdir(parents=True, exist_ok=True)
        files = {"policy": str(job.out_dir / "policy.pt")}
        torch.save(experiment.policy.state_dict(), files["policy"])
        group = next(iter(experiment.group_map))
        recipe["n_timesteps"] = total
        eval_env.close()

        def sample(seed: int) -> Any:
            torch.manual_seed(seed)
            return _ActorOnRows(experiment.policy, group, agents, random=True)

        return Trained(
            policy=_ActorOnRows(experiment.policy, group, agents),
            timesteps=int(experiment.total_frames),
            train_seconds=wall - clock["eval"],
            eval_seconds=clock["eval"],
            history=history,
            recipe=recipe,
            files=files,
            sample=sample,
        )


__all__ = [
    "RECIPE_KEYS",
    "SIGMA_MIN",
    "BenchMARLLearner",
    "return_description",
    "scale_mapping",
]
