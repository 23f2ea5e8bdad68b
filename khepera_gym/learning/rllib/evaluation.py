"""Seeded evaluation of RLlib policies on the khepera_gym Gymnasium envs (single-agent).

:func:`evaluate_policy` plays one episode in every world of a native vector env (world i seeded
``seed + i``; by default the episodes 10000 .. 10099 that ``khepera-gym train`` evaluates SB3
models on) with the shared episode loop :func:`khepera_gym.rollout.run_episodes`, and returns
an :class:`Evaluation`. :func:`module_policy` turns an RLlib ``RLModule`` into a batched policy
(observations (N, D) → actions (N, 2)); :func:`random_policy` is the seeded random baseline.

Threading: the batch steps its worlds on ``num_threads`` threads (None: every core) with the GIL
released; the policy runs in the caller's thread (torch with its own thread setting).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym.learning.recipes import EVAL_SEED
from khepera_gym.learning.rllib.creators import ENV_PREFIX, make_vector_env
from khepera_gym.registration import resolve_env_id
from khepera_gym.rollout import run_episodes

#: A batched policy: observations (N, D) float32 → actions (N, 2) in [-1, 1].
Policy = Callable[[npt.NDArray[np.float32]], npt.NDArray[np.float32]]


@dataclasses.dataclass
class Evaluation:
    """Statistics over one seeded episode per world (``khepera-gym train``'s evaluation)."""

    #: Environment steps of training done when it ran.
    timesteps: int
    #: Episodes (world i seeded ``seed + i``).
    episodes: int
    success_rate: float
    mean_return: float
    mean_length: float
    #: Mean steps in contact per episode.
    mean_collisions: float
    #: Mean decrease of the goal distance over an episode (m); NaN for tasks without a goal
    #: distance in the observation (Formation).
    mean_progress: float
    #: Wall time (s).
    seconds: float


def module_policy(module: Any, deterministic: bool = True) -> Policy:
    """A batched policy (obs (N, D) → actions (N, 2) in [-1, 1]) from an RLlib RLModule.

    ``deterministic`` takes the action distribution's mode (the Gaussian's mean), as RLlib's
    ``explore=False``; else a sample. Actions are clipped to [-1, 1], as RLlib does.
    """
    import torch

    distribution = module.get_inference_action_dist_cls()

    def act(observations: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        with torch.no_grad():
            batch = {"obs": torch.from_numpy(np.ascontiguousarray(observations, np.float32))}
            outputs = module.forward_inference(batch)
            action_distribution = distribution.from_logits(outputs["action_dist_inputs"])
            if deterministic:
                action_distribution = action_distribution.to_deterministic()
            actions = action_distribution.sample().numpy()
        return np.clip(actions, -1.0, 1.0).astype(np.float32)

    return act


def random_policy(action_dim: int = 2, seed: int = 0) -> Policy:
    """Uniform random actions in [-1, 1] of ``action_dim`` values per row, seeded."""
    generator = np.random.default_rng(seed)

    def act(observations: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        return generator.uniform(-1.0, 1.0, (len(observations), action_dim)).astype(np.float32)

    return act


def evaluate_policy(
    policy: Policy,
    env_id: str,
    episodes: int = 100,
    seed: int = EVAL_SEED,
    env_kwargs: Mapping[str, Any] | None = None,
    num_threads: int | None = None,
    timesteps: int = 0,
) -> Evaluation:
    """Plays one episode per world of ``env_id`` (world i seeded ``seed + i``) with ``policy``.

    The same episodes as ``khepera-gym train``'s SB3 evaluation (seeds 10000 + i by default).
    Worlds that end early go on (their later episodes are ignored) until every world has
    finished once (:func:`khepera_gym.rollout.run_episodes`).

    Args:
        policy: Observations (N, D) → actions (N, 2).
        env_id: A khepera_gym Gymnasium id or its RLlib name ("khepera_gym/KheperaIV-Nav-v3").
        episodes: Worlds, one episode each.
        seed: Seed of world 0's episode.
        env_kwargs: Keyword arguments of the env (``max_steps``, ``config``, ...).
        num_threads: Threads of the batch; None uses every core.
        timesteps: Stored in :attr:`Evaluation.timesteps`.

    Raises:
        ConfigError: ``env_id`` is not a khepera_gym Gymnasium id, or a scenario error.
    """
    start = time.perf_counter()
    env_id = resolve_env_id(env_id.removeprefix(ENV_PREFIX))
    envs = make_vector_env(
        env_id, episodes, num_threads=num_threads, **dict(env_kwargs or {})
    ).unwrapped
    distance = envs.obs_layout().get("goal_distance")
    first_distance = np.full(episodes, np.nan)
    progress = np.full(episodes, np.nan)

    def on_reset(observations: npt.NDArray[np.float32]) -> None:
        if distance is not None:
            first_distance[:] = observations[:, distance].ravel()

    def on_step(
        _step: int,
        observations: npt.NDArray[np.float32],
        _rewards: npt.NDArray[np.float32],
        ended: npt.NDArray[np.bool_],
        _done: npt.NDArray[np.bool_],
    ) -> None:
        if distance is not None and np.count_nonzero(ended):
            progress[ended] = first_distance[ended] - observations[ended, distance].ravel()

    try:
        stats = run_episodes(envs._batch, policy, seed, on_reset=on_reset, on_step=on_step)
    finally:
        envs.close()

    def mean(name: str) -> float:
        return float(np.mean([world[name] for world in stats if world is not None]))

    return Evaluation(
        timesteps=timesteps,
        episodes=episodes,
        success_rate=mean("success"),
        mean_return=mean("return"),
        mean_length=mean("length"),
        mean_collisions=mean("collisions"),
        mean_progress=float(np.mean(progress)),
        seconds=time.perf_counter() - start,
    )


__all__ = ["EVAL_SEED", "Evaluation", "Policy", "evaluate_policy", "module_policy", "random_policy"]
