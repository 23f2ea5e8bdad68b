"""The env names khepera_gym registers with Ray Tune, and the creators RLlib calls per EnvRunner.

Names (``config.environment(NAME, env_config={...})``; ``env_config`` takes the keyword
arguments of the env, e.g. ``{"max_steps": 300, "config": "paper_fig6"}``):

* ``khepera_gym/<id>`` for every registered Gymnasium id (:func:`khepera_gym.registration.
  registered_ids`: ``KheperaIV-Nav-v3``, ``KheperaIV-Avoid-v3``, ..., every
  version): each EnvRunner gets
  ONE native vector env of its task (``khepera_gym.vector.VECTOR_ENV_CLASSES``, through the id's
  ``vector_entry_point``) of ``num_envs_per_env_runner`` worlds, a single Rust batch, in RLlib's
  ``VECTOR_ENTRY_POINT`` mode (no N Python env copies);
* :data:`FOLLOWERS_ENVS` (``formation_followers_v0`` to ``_v3``, one a version): the followers of
  ``num_envs_per_env_runner / K`` Formation worlds as the rows of one
  :class:`~khepera_gym.learning.rllib.FormationFollowersVectorEnv`;
* :data:`MULTI_AGENT_ENVS`: one :class:`~khepera_gym.learning.rllib.KheperaMultiAgentEnv` (one
world)
  per env copy, run by RLlib's ``MultiAgentEnvRunner``.

Every creator applies the seed mapping of :mod:`khepera_gym.learning.rllib.seeding`, and a vector
env's batch gets as many threads as the CPUs Ray assigned to its EnvRunner (``env_config={
"num_threads": k}`` changes it). :func:`register_envs` runs when :mod:`khepera_gym.learning.rllib`
is
imported. Creating envs is the only work here (no threads of its own).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import ModuleType
from typing import Any

import gymnasium as gym
from ray.rllib.env.env_context import EnvContext
from ray.tune.registry import register_env

from khepera_gym import pettingzoo, registry
from khepera_gym.errors import ConfigError
from khepera_gym.learning.rllib.followers import FormationFollowersVectorEnv
from khepera_gym.learning.rllib.multi_agent import KheperaMultiAgentEnv
from khepera_gym.learning.rllib.seeding import SeedPerRunner, runner_cpus
from khepera_gym.pettingzoo import modules as pettingzoo_modules
from khepera_gym.registration import registered_ids, resolve_env_id

#: Prefix of every env name this package registers with Ray Tune.
ENV_PREFIX = "khepera_gym/"
#: Names of the formation-followers vector env (one row per follower, one shared policy) →
#: the behaviour version each runs (as the PettingZoo ``formation_vN``): every version of the
#: formation task the core knows.
FOLLOWERS_ENVS: dict[str, int] = {
    f"{ENV_PREFIX}formation_followers_v{v}": v for v in registry.task_versions("formation")
}
#: The formation-followers env of the latest behaviour version.
FOLLOWERS_ENV = max(FOLLOWERS_ENVS, key=FOLLOWERS_ENVS.__getitem__)
#: PettingZoo families not offered as RLlib multi-agent envs: those whose agents are not alike
#: (:attr:`khepera_gym.registry.TaskInfo.alike_agents`; DroneFollow's quadcopter and, with
#: driver="agent", a Khepera have different spaces): none of this package's RLlib
#: configurations is made for them.
NOT_MULTI_AGENT = frozenset(
    module.family
    for module in pettingzoo.module_infos()
    if not registry.task(module.task).alike_agents
)
#: Multi-agent env names → the PettingZoo module whose ``parallel_env`` they wrap: every
#: versioned module of :mod:`khepera_gym.pettingzoo` but :data:`NOT_MULTI_AGENT`.
MULTI_AGENT_ENVS: dict[str, ModuleType] = {
    ENV_PREFIX + name: module
    for name, module in pettingzoo_modules().items()
    if name.rpartition("_v")[0] not in NOT_MULTI_AGENT
}


# --- names -----------------------------------------------------------------------------------


def env_names() -> list[str]:
    """Every env name this package registers with Ray Tune."""
    gym_ids = sorted(env_id for ids in registered_ids().values() for env_id in ids)
    return [ENV_PREFIX + env_id for env_id in gym_ids] + [*FOLLOWERS_ENVS, *MULTI_AGENT_ENVS]


def env_name(env_id: str) -> str:
    """The RLlib env name of a khepera_gym Gymnasium id: ``"KheperaIV-Nav"`` →
    ``"khepera_gym/KheperaIV-Nav-v3"`` (the latest version); names of this package are returned
    unchanged.

    Raises:
        ConfigError: Neither a khepera_gym id nor a name of this package.
    """
    if env_id in env_names():
        return env_id
    return ENV_PREFIX + resolve_env_id(env_id.removeprefix(ENV_PREFIX))


def is_multi_agent(name: str) -> bool:
    """Whether the registered env ``name`` is a :class:`KheperaMultiAgentEnv`."""
    return name in MULTI_AGENT_ENVS


# --- creators --------------------------------------------------------------------------------


class VectorEnvCreator:
    """The ``register_env`` creator of a khepera_gym vector env (one per EnvRunner).

    RLlib calls it with ``env_config | {"num_envs": num_envs_per_env_runner}`` in the
    ``VECTOR_ENTRY_POINT`` mode. It builds ONE vector env of that many rows (for
    :data:`FOLLOWERS_ENV`: ``num_envs / K`` worlds of K followers) whose batch has
    ``num_threads`` threads (default: the runner's CPUs), wrapped in :class:`SeedPerRunner`.

    Args:
        name: The registered name (``"khepera_gym/KheperaIV-Nav-v3"`` or a key of
            :data:`FOLLOWERS_ENVS`).
    """

    def __init__(self, name: str) -> None:
        self.name = name

    def __call__(self, env_config: Mapping[str, Any]) -> gym.vector.VectorEnv:
        """Builds the env; see the class docstring.

        Raises:
            ConfigError: No ``num_envs`` (RLlib is not in the vector entry point mode), a row
                count that is not a multiple of the followers per world, or a scenario error.
        """
        kwargs = dict(env_config)
        if "num_envs" not in kwargs:
            raise ConfigError(
                f"{self.name} is a native vector env: set config.env_runners("
                "gym_env_vectorize_mode='vector_entry_point') (RLlib built it as a single env)"
            )
        num_envs = int(kwargs.pop("num_envs"))
        if kwargs.get("num_threads") is None:
            kwargs["num_threads"] = runner_cpus()
        if self.name in FOLLOWERS_ENVS:
            kwargs.setdefault("version", FOLLOWERS_ENVS[self.name])
            followers = followers_per_world(kwargs)
            if num_envs % followers:
                raise ConfigError(
                    f"{FOLLOWERS_ENV}: num_envs_per_env_runner ({num_envs}) must be a multiple "
                    f"of the {followers} followers per world (one row per follower)"
                )
            env: gym.vector.VectorEnv = FormationFollowersVectorEnv(num_envs // followers, **kwargs)
        else:
            env = make_vector_env(self.name, num_envs, **kwargs)
        return SeedPerRunner(env)


def make_vector_env(name: str, num_envs: int, **kwargs: Any) -> gym.vector.VectorEnv:
    """The native vector env (``VECTOR_ENV_CLASSES[task]``) of the Gymnasium id under ``name``,
    made as ``gym.make_vec`` makes it (with the version's scenario keywords)."""
    return gym.make_vec(
        name.removeprefix(ENV_PREFIX),
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        **kwargs,
    )


def followers_per_world(env_config: Mapping[str, Any]) -> int:
    """K, the followers per Formation world of ``env_config`` (builds a 1-world env to ask)."""
    probe = FormationFollowersVectorEnv(1, **{**env_config, "num_threads": 1})
    followers = probe.followers_per_world
    probe.close()
    return followers


class MultiAgentEnvCreator:
    """The ``register_env`` creator of a :class:`KheperaMultiAgentEnv` (one world per copy).

    Args:
        name: A key of :data:`MULTI_AGENT_ENVS`.
    """

    def __init__(self, name: str) -> None:
        self.name = name

    def __call__(self, env_config: Mapping[str, Any]) -> KheperaMultiAgentEnv:
        """Builds the env from ``env_config`` (an ``EnvContext`` under RLlib, whose
        ``worker_index`` drives the seed mapping)."""
        worker_index = env_config.worker_index if isinstance(env_config, EnvContext) else None
        return make_multi_agent_env(self.name, env_config, worker_index=worker_index)


def make_multi_agent_env(
    name: str, env_config: Mapping[str, Any], worker_index: int | None = None
) -> KheperaMultiAgentEnv:
    """The multi-agent env ``name`` built with ``env_config``.

    Raises:
        ConfigError: ``name`` is not a multi-agent env, or a scenario error.
    """
    if name not in MULTI_AGENT_ENVS:
        raise ConfigError(
            f"{name!r} is not a multi-agent env; those are {sorted(MULTI_AGENT_ENVS)}"
        )
    module = MULTI_AGENT_ENVS[name]
    return KheperaMultiAgentEnv(module.parallel_env(**dict(env_config)), worker_index)


def register_envs() -> list[str]:
    """Registers every env of this package with Ray Tune (done on import); returns the names.

    Registering again replaces the creators with equal ones, so calling it twice is harmless.
    """
    names = env_names()
    for name in names:
        if is_multi_agent(name):
            register_env(name, MultiAgentEnvCreator(name))
        else:
            register_env(name, VectorEnvCreator(name))
    return names


__all__ = [
    "ENV_PREFIX",
    "FOLLOWERS_ENV",
    "FOLLOWERS_ENVS",
    "MULTI_AGENT_ENVS",
    "MultiAgentEnvCreator",
    "VectorEnvCreator",
    "env_name",
    "env_names",
    "followers_per_world",
    "is_multi_agent",
    "make_multi_agent_env",
    "make_vector_env",
    "register_envs",
]
