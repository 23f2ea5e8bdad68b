"""The learners of the benchmark: how a task is trained, evaluated while it trains, and turned
into a policy the held-out episodes are played with.

Every learner trains on the Rust batch and acts on *rows*: one world of a single-agent task
(``ppo``, ``sac``: stable-baselines3 on ``khepera_gym.learning.sb3.make_vec_env(<Gymnasium id>)``),
or one agent of a multi-agent task sharing one policy (``shared_ppo``: SB3's PPO on the rows of
``make_vec_env(<PettingZoo module>)``, parameter sharing; ``mappo``/``ippo``: BenchMARL's, in
:mod:`khepera_gym.learning.benchmark.marl`). Its recipe is the table of the task in
``configs/hyperparams/<algo>.toml`` (by the Gymnasium id, or by the PettingZoo module with
``-shared`` appended), as for ``khepera-gym train``.

While it trains, a learner evaluates its policy every tenth of the run on the training's own
evaluation episodes (seeds 10000 + i, never the held-out ones) and reports each evaluation's
statistics, so the runner can tell when the criterion was first met. Evaluation time is kept
apart from training time.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark.jobs import (
    Job,
    Means,
    Trained,
    agents_of,
    gym_id,
    module_of,
    shares_rows,
)
from khepera_gym.learning.recipes import EVAL_SEED, load_hyperparams
from khepera_gym.tooling.arguments import did_you_mean


class SB3Learner:
    """stable-baselines3 (``algo``: PPO, SAC or sb3-contrib's RecurrentPPO) on rows of worlds,
    or with ``shared`` on rows of agents of a multi-agent task (parameter sharing)."""

    def __init__(self, name: str, algo: str, shared: bool) -> None:
        self.name = name
        self.algo = algo
        self.shared = shared

    def env_name(self, task: str, version: int) -> str:
        """The Gymnasium id (or PettingZoo module) it trains on.

        Raises:
            ConfigError: The learner does not apply to the task, and why.
        """
        if self.shared:
            module = module_of(task, version)
            if module is None or not shares_rows(task):
                raise ConfigError(
                    f"learner {self.name!r} shares one policy between the agents of a multi-agent "
                    f"task whose agents observe blocks of one length; {task!r} is not one "
                    f"(agents: {agents_of(task)})"
                )
            return module
        env_id = gym_id(task, version)
        if env_id is None:
            raise ConfigError(
                f"learner {self.name!r} trains a Gymnasium env; {task!r} is a PettingZoo task "
                "(use shared_ppo, mappo or ippo)"
            )
        return env_id

    def table(self, task: str, version: int) -> str:
        """The recipe's table name."""
        name = self.env_name(task, version)
        return f"{name}-shared" if self.shared else name

    def check_overrides(self, overrides: Mapping[str, Any]) -> None:
        """Checks the keys of ``overrides`` (``--hp``) against those a table of the algorithm may
        hold (:func:`khepera_gym.learning.train.hyperparameter_keys`: the run's keys and the
        keywords of the SB3 class), so a misspelt key fails before anything runs.

        Raises:
            ConfigError: A key the algorithm does not take; the message suggests the nearest.
        """
        from khepera_gym.learning.train import ALGORITHMS, hyperparameter_keys

        if not overrides:
            return
        keys = hyperparameter_keys(self.algo)
        for key in overrides:
            if key not in keys:
                raise ConfigError(
                    f"--hp {key}: learner {self.name!r} ({ALGORITHMS[self.algo]}) has no "
                    f"hyperparameter {key!r}; {did_you_mean(key, keys)}"
                )

    def recipe(self, task: str, version: int, overrides: Mapping[str, Any]) -> dict[str, Any]:
        """The hyperparameter table with ``overrides``.

        Raises:
            ConfigError: The learner does not apply to the task, its table is missing, or an
                override's key is not one of the algorithm's (:meth:`check_overrides`).
        """
        self.check_overrides(overrides)
        recipe = load_hyperparams(self.algo, self.table(task, version))
        recipe.update(overrides)
        return recipe

    def train(self, job: Job, report: Callable[[int, int], None] | None = None) -> Trained:
        """Trains, evaluating ``job.eval_points`` times on the evaluation seeds."""
        import torch
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.vec_env import VecFrameStack, VecNormalize

        from khepera_gym.learning.sb3 import as_predictor, make_vec_env
        from khepera_gym.learning.sb3.evaluate import first_episode_stats
        from khepera_gym.learning.sb3.policy import RUN_FILE, VECNORMALIZE_FILE
        from khepera_gym.learning.train import build_model

        name = self.env_name(job.task, job.version)
        recipe = self.recipe(job.task, job.version, job.overrides)
        total = int(job.timesteps if job.timesteps is not None else recipe["n_timesteps"])
        worlds = int(recipe.get("n_envs", 1))
        frame_stack = int(recipe.get("frame_stack", 1))
        env_kwargs = dict(recipe.get("env_kwargs", {}))
        env: Any = make_vec_env(
            name, worlds, seed=job.seed, num_threads=job.num_threads, **env_kwargs
        )
        if recipe.get("normalize", False):
            env = VecNormalize(env, gamma=float(recipe.get("gamma", 0.99)))
        if frame_stack > 1:
            env = VecFrameStack(env, frame_stack)
        # The evaluations run the task's default scenario (a recipe's env_kwargs shape training).
        eval_env = make_vec_env(name, job.eval_episodes, num_threads=job.num_threads)
        model = build_model(self.algo, env, recipe, job.seed, job.device)
        history: list[tuple[int, float, Means]] = []
        clock = {"eval": 0.0, "start": 0.0}

        def predictor() -> Any:
            return as_predictor(model, model.get_vec_normalize_env(), frame_stack)

        def evaluate(steps: int) -> None:
            start = time.perf_counter()
            stats = first_episode_stats(predictor(), eval_env, EVAL_SEED)
            seconds = time.perf_counter() - start
            trained = start - clock["start"] - clock["eval"]
            clock["eval"] += seconds
            history.append((steps, trained, {k: float(np.mean(v)) for k, v in stats.items()}))
            if job.on_evaluation is not None:
                job.on_evaluation(*history[-1])
            if report is not None:
                report(steps, total)

        every = max(1, total // max(1, job.eval_points))

        class Evaluations(BaseCallback):
            def _on_step(self) -> bool:
                if self.num_timesteps // every > len(history):
                    evaluate(self.num_timesteps)
                return True

        previous = torch.get_num_threads()
        torch.set_num_threads(1)  # small networks: more threads only synchronise (train.py)
        try:
            clock["start"] = time.perf_counter()
            model.learn(total, callback=Evaluations())
            if not history or history[-1][0] != model.num_timesteps:
                evaluate(model.num_timesteps)
            wall = time.perf_counter() - clock["start"]
        finally:
            torch.set_num_threads(previous)
        job.out_dir.mkdir(parents=True, exist_ok=True)
        files = {"model": str(job.out_dir / "model.zip")}
        model.save(files["model"])
        normalizer = model.get_vec_normalize_env()
        if normalizer is not None:
            files["vecnormalize"] = str(job.out_dir / VECNORMALIZE_FILE)
            normalizer.save(files["vecnormalize"])
        recipe["n_timesteps"] = total
        # As `khepera-gym train` leaves it beside its model: load_policy (compare, render)
        # stacks frames from it and export reads the env and scenario the policy trained on.
        files["run"] = str(job.out_dir / RUN_FILE)
        run = {"env_id": name, "algo": self.algo, "seed": job.seed, "hyperparams": recipe}
        Path(files["run"]).write_text(
            json.dumps(run, indent=2, default=str) + "\n", encoding="utf-8"
        )
        eval_env.close()

        def sample(seed: int) -> Any:
            torch.manual_seed(seed)  # SB3 samples with torch's global generator
            return _Sampling(predictor())

        return Trained(
            policy=predictor(),
            timesteps=int(model.num_timesteps),
            train_seconds=wall - clock["eval"],
            eval_seconds=clock["eval"],
            history=history,
            recipe=recipe,
            files=files,
            sample=sample,
        )


class _Sampling:
    """A predictor that samples its actions (``deterministic=False`` whatever it is asked)."""

    def __init__(self, policy: Any) -> None:
        self._policy = policy

    def predict(self, observation: Any, *args: Any, deterministic: bool = True) -> Any:
        return self._policy.predict(observation, *args[:2], deterministic=False)

    def reset(self) -> None:
        reset = getattr(self._policy, "reset", None)
        if callable(reset):
            reset()


def _marl(name: str) -> Any:
    from khepera_gym.learning.benchmark.marl import BenchMARLLearner

    return BenchMARLLearner(name)


#: The learners by name: how each is made (lazily: BenchMARL is an optional extra).
LEARNERS: dict[str, Callable[[], Any]] = {
    "ppo": lambda: SB3Learner("ppo", "ppo", shared=False),
    "sac": lambda: SB3Learner("sac", "sac", shared=False),
    # sb3-contrib's PPO with an LSTM policy: the memory is its state, not a frame stack.
    "recurrent_ppo": lambda: SB3Learner("recurrent_ppo", "recurrent_ppo", shared=False),
    "shared_ppo": lambda: SB3Learner("shared_ppo", "ppo", shared=True),
    "mappo": lambda: _marl("mappo"),
    "ippo": lambda: _marl("ippo"),
}


def learner(name: str) -> Any:
    """The learner of a name.

    Raises:
        ConfigError: An unknown name (the message suggests the nearest and lists the learners).
    """
    if name not in LEARNERS:
        raise ConfigError(f"unknown learner {name!r}; {did_you_mean(name, list(LEARNERS))}")
    return LEARNERS[name]()


__all__ = [
    "LEARNERS",
    "Job",
    "SB3Learner",
    "Trained",
    "agents_of",
    "gym_id",
    "learner",
    "module_of",
    "shares_rows",
]
