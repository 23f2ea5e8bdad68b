"""Seeds and threads of the RLlib envs: disjoint worlds for every EnvRunner.

RLlib resets EnvRunner w once with ``s = config.seed + w`` (+ 10**6 for evaluation runners; the
local runner is w = 0, remote ones 1, 2, ...) and khepera_gym's batch seeds world i with
``seed + i``, so plain use would give world i + 1 of runner w the seed of world i of runner
w + 1. The envs of :mod:`khepera_gym.learning.rllib` therefore map RLlib's seed:

* vector envs (:class:`SeedPerRunner`): world i of runner w is seeded ``(config.seed + w) · N + i``
  with N the runner's number of worlds (:func:`runner_world_seed`), so runners get disjoint seed
  ranges;
* multi-agent envs (one world each, ``num_envs_per_env_runner`` copies J per runner, which RLlib
  seeds ``s + j``): copy j of runner w is seeded ``(config.seed + j) · 2**16 + w``
  (:func:`multi_agent_world_seed`), disjoint for up to 2**16 runners.

Later episodes continue each world's own random stream, as everywhere in khepera_gym.

Threads: :func:`runner_cpus` is the number of CPUs Ray assigned to the calling EnvRunner actor,
the default thread count of a runner's batch, so that runners do not oversubscribe the machine.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import ray

from khepera_gym._inputs import check_seed
from khepera_gym.errors import ConfigError

#: Multi-agent world seeds are strided by this many runners (see :func:`multi_agent_world_seed`).
MAX_ENV_RUNNERS = 2**16


def runner_world_seed(seed: int, worker_index: int, num_worlds: int, world: int) -> int:
    """The seed of world ``world`` of EnvRunner ``worker_index`` (vector envs of this package).

    RLlib resets runner w with ``seed + w`` (``seed`` = ``config.seed``); the adapter turns it into
    ``(seed + w) · num_worlds``, and the batch seeds world i with that plus i.
    """
    return (seed + worker_index) * num_worlds + world


def multi_agent_world_seed(rllib_seed: int, worker_index: int) -> int:
    """The world seed of a multi-agent env that RLlib resets with ``rllib_seed``.

    RLlib seeds copy j of runner w with ``config.seed + w + j``; the env knows w (from its
    ``EnvContext``) and seeds its world with ``(rllib_seed - w) · MAX_ENV_RUNNERS + w`` =
    ``(config.seed + j) · 2**16 + w``: distinct for every (runner, copy) pair.

    Raises:
        ConfigError: ``worker_index`` is not in [0, MAX_ENV_RUNNERS), or the seed is negative.
    """
    if not 0 <= worker_index < MAX_ENV_RUNNERS:
        raise ConfigError(f"worker_index must be in [0, {MAX_ENV_RUNNERS}), got {worker_index}")
    base = int(rllib_seed) - worker_index
    if base < 0:
        raise ConfigError(f"seed must be >= 0, got {base} (RLlib's seed {rllib_seed} - runner)")
    return base * MAX_ENV_RUNNERS + worker_index


class SeedPerRunner(gym.vector.VectorWrapper):
    """Scales an int reset seed by the number of worlds, so EnvRunners get disjoint seeds.

    ``reset(seed=s)`` resets the wrapped env with ``s · num_worlds``: world i gets
    ``s · num_worlds + i``, and runner w (reset by RLlib with ``config.seed + w``) gets
    :func:`runner_world_seed`. ``seed=None`` and per-world seed sequences pass unchanged.

    Args:
        env: A khepera_gym vector env (its ``num_worlds`` attribute, else ``num_envs``).
    """

    def __init__(self, env: gym.vector.VectorEnv) -> None:
        super().__init__(env)
        #: Worlds of the wrapped env (a formation-followers env has K rows per world).
        self.num_worlds: int = int(getattr(env, "num_worlds", env.num_envs))

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        """Resets every world; an int ``seed`` is multiplied by ``num_worlds`` first.

        Raises:
            ConfigError: A negative or too large int seed.
        """
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            checked = check_seed(seed)
            assert checked is not None  # an int stays an int
            seed = checked * self.num_worlds
        return self.env.reset(seed=seed, options=options)


def runner_cpus() -> int:
    """CPUs Ray assigned to this process's actor (an EnvRunner), or 1 outside an actor."""
    if not ray.is_initialized():
        return 1
    context = ray.get_runtime_context()
    if context.get_actor_id() is None:
        return 1  # the driver (local EnvRunner): Ray reserves no CPU for it
    return max(1, round(context.get_assigned_resources().get("CPU", 1.0)))


__all__ = [
    "MAX_ENV_RUNNERS",
    "SeedPerRunner",
    "multi_agent_world_seed",
    "runner_cpus",
    "runner_world_seed",
]
