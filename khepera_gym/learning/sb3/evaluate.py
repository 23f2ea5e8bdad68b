"""Evaluating SB3 policies on seeded episodes: one episode per world of an SB3 VecEnv (world w
seeded ``seed + w``), run by the shared episode loop :func:`khepera_gym.rollout.run_episodes`,
and the training callback that does it every so many steps.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from stable_baselines3.common.callbacks import BaseCallback

from khepera_gym.errors import ConfigError
from khepera_gym.learning.sb3.policy import Predictor, as_predictor
from khepera_gym.learning.sb3.vec_env import KheperaSB3VecEnv
from khepera_gym.rollout import run_episodes


def first_episode_stats(
    policy: Predictor,
    env: KheperaSB3VecEnv,
    seed: int,
    deterministic: bool = True,
) -> dict[str, npt.NDArray[Any]]:
    """Runs one seeded episode in every world of ``env`` with ``policy``; returns its statistics.

    World w starts from seed ``seed + w``, so ``env`` with N worlds evaluates the N episodes
    seeded ``seed .. seed + N - 1`` (the same ones as single envs reset with those seeds).
    Worlds that finish early keep running (their later episodes are ignored) until all are done.

    Returns:
        ``episode_stats`` keys ("return", "length", "success", ...) → arrays of one value per
        world; for :class:`FormationFollowersVecEnv` one value per world as well.
    """

    def act(joint: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        actions, _ = policy.predict(env.row_observations(joint), deterministic=deterministic)
        return env.joint_actions(np.asarray(actions, dtype=np.float32))

    reset = getattr(policy, "reset", None)
    if callable(reset):  # a stateful policy (frame stacking): every world starts an episode
        reset()
    stats = run_episodes(env._batch, act, seed)
    results: dict[str, list[Any]] = {}
    for world_stats in stats:
        assert world_stats is not None  # no max_steps: every episode ends
        for name, value in world_stats.items():
            results.setdefault(name, []).append(value)
    return {name: np.asarray(values) for name, values in results.items()}


@dataclass
class Evaluation:
    """One evaluation of :class:`SuccessEvalCallback` (or ``khepera-gym train``'s final one)."""

    #: Environment steps of training done when it ran.
    timesteps: int
    #: Episodes evaluated (one per seeded world).
    episodes: int
    #: Fraction of them that reached the goal.
    success_rate: float
    #: Mean undiscounted return.
    mean_return: float
    #: Mean episode length (steps).
    mean_length: float
    #: Mean number of steps in contact per episode.
    mean_collisions: float
    #: Wall time of the evaluation (s).
    seconds: float


def evaluate_episodes(
    policy: Predictor,
    env: KheperaSB3VecEnv,
    seed: int,
    timesteps: int = 0,
    sample_seed: int | None = None,
) -> Evaluation:
    """Success rate and means over one seeded episode per world of ``env``: on the policy's
    deterministic actions, or with ``sample_seed`` on actions sampled from its distribution
    (torch's generator seeded with ``sample_seed`` first, so the figures repeat).

    World w plays the episode seeded ``seed + w``; see :func:`first_episode_stats`.
    """
    start = time.perf_counter()
    if sample_seed is not None:
        import torch  # stable-baselines3 samples with torch's global generator

        torch.manual_seed(sample_seed)
    stats = first_episode_stats(policy, env, seed, deterministic=sample_seed is None)
    return Evaluation(
        timesteps=timesteps,
        episodes=len(stats["success"]),
        success_rate=float(np.mean(stats["success"])),
        mean_return=float(np.mean(stats["return"])),
        mean_length=float(np.mean(stats["length"])),
        mean_collisions=float(np.mean(stats["collisions"])),
        seconds=time.perf_counter() - start,
    )


class SuccessEvalCallback(BaseCallback):
    """Evaluates the model every ``eval_freq`` environment steps on the same seeded episodes.

    Like SB3's ``EvalCallback`` but batched and reproducible: each evaluation plays one episode
    in every world of ``eval_env`` (world w seeded ``seed + w``), deterministically, and logs
    ``eval/success_rate``, ``eval/mean_return``, ``eval/mean_length`` and
    ``eval/mean_collisions`` (then dumps the logger, so TensorBoard and progress.csv get a
    point per evaluation). When the training env is under ``VecNormalize``, observations are
    normalised with its current statistics; with ``frame_stack`` > 1 they are stacked as
    ``VecFrameStack`` stacks the training env's. The best model (by success rate, then return) is
    saved to ``best_model_path`` when given.

    Args:
        eval_env: The evaluation env; its number of worlds is the number of episodes.
        eval_freq: Environment steps (summed over worlds) between evaluations; also evaluates
            at the end of training.
        seed: Seed of world 0's episode.
        best_model_path: Where to save the best model (a ``.zip`` path), or None.
        verbose: 1 prints one line per evaluation.
        frame_stack: Observations per stack of the model (1: no stacking).
    """

    def __init__(
        self,
        eval_env: KheperaSB3VecEnv,
        eval_freq: int,
        seed: int,
        best_model_path: str | Path | None = None,
        verbose: int = 1,
        frame_stack: int = 1,
    ) -> None:
        super().__init__(verbose)
        self.frame_stack = frame_stack
        if eval_freq < 1:
            raise ConfigError(f"eval_freq must be >= 1 environment steps, got {eval_freq}")
        self.eval_env = eval_env
        self.eval_freq = eval_freq
        self.seed = seed
        self.best_model_path = None if best_model_path is None else Path(best_model_path)
        #: Every evaluation so far, in order.
        self.history: list[Evaluation] = []
        self._last_eval_timesteps = 0
        self._best: tuple[float, float] | None = None

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last_eval_timesteps >= self.eval_freq:
            self.evaluate()
        return True

    def _on_training_end(self) -> None:
        if not self.history or self.history[-1].timesteps != self.num_timesteps:
            self.evaluate()

    def evaluate(self) -> Evaluation:
        """Runs one evaluation now, logs it and keeps the best model."""
        self._last_eval_timesteps = self.num_timesteps
        normalizer = self.model.get_vec_normalize_env()
        policy: Predictor = as_predictor(self.model, normalizer, self.frame_stack)
        result = evaluate_episodes(policy, self.eval_env, self.seed, self.num_timesteps)
        self.history.append(result)
        for name in ("success_rate", "mean_return", "mean_length", "mean_collisions"):
            self.logger.record(f"eval/{name}", getattr(result, name))
        self.logger.dump(self.num_timesteps)
        if self.verbose:
            print(
                f"step {self.num_timesteps:>9,}: success {100 * result.success_rate:5.1f} % of "
                f"{result.episodes}, return {result.mean_return:7.2f}, "
                f"length {result.mean_length:5.1f}, collisions {result.mean_collisions:5.1f}"
            )
        score = (result.success_rate, result.mean_return)
        if self.best_model_path is not None and (self._best is None or score > self._best):
            self._best = score
            self.model.save(self.best_model_path)
        return result


__all__ = ["Evaluation", "SuccessEvalCallback", "evaluate_episodes", "first_episode_stats"]
