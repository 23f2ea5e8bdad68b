"""Ray RLlib (new API stack, Ray >= 2.52): khepera_gym's Rust batch as RLlib envs, and PPO.

Importing this package registers these names with ``ray.tune.registry.register_env`` (use them as
``config.environment(NAME, env_config={...})``; ``env_config`` takes the keyword arguments of the
env, e.g. ``{"max_steps": 300, "config": "paper_fig6"}``):

* ``khepera_gym/KheperaIV-Nav-v3``, ``.../KheperaIV-Avoid-v3``, ``.../KheperaIV-Formation-v3``
  (every registered id, the older versions too): each EnvRunner gets ONE native vector env of
  ``num_envs_per_env_runner`` worlds (``khepera_gym.vector.VECTOR_ENV_CLASSES``), a single Rust
  batch, through RLlib's ``VECTOR_ENTRY_POINT`` mode (no N Python env copies);
* ``khepera_gym/formation_followers_v3`` (and the older versions): the followers of
  ``num_envs_per_env_runner / K`` Formation worlds as the rows of one vector env
  (:class:`FormationFollowersVectorEnv`), for one policy shared by every follower;
* ``khepera_gym/formation_v3``, ``khepera_gym/multinav_v3``, ... (the PettingZoo modules of
  :data:`~khepera_gym.learning.rllib.creators.MULTI_AGENT_ENVS`, older versions too): one
  :class:`KheperaMultiAgentEnv` (one world) per env copy, run by RLlib's
  ``MultiAgentEnvRunner``, with the agents of :mod:`khepera_gym.pettingzoo` (shared or
  separate policies: :func:`policy_mapping`).

The single-agent names need ``config.env_runners(gym_env_vectorize_mode="vector_entry_point")``
(:func:`ppo_config` sets it; :func:`check_config` says so when it is missing). Every runner gets
worlds of its own (:mod:`khepera_gym.learning.rllib.seeding`); a runner's batch has as many threads
as Ray gave the runner CPUs. RLlib still loops in Python over the rows of a vector env each step to
fill its episodes, so one runner's throughput is bounded by RLlib's bookkeeping rather than by
the Rust core: scale with more EnvRunners.

The envs are faces over a ``_core.Batch`` (:class:`khepera_gym.batch_face.BatchFace`): ``poses()``,
``obs_layout()``, ``get_state()``, ... as on every khepera_gym env.

Modules, one job each:

* :mod:`~khepera_gym.learning.rllib.seeding`: seeds per EnvRunner and threads per runner;
* :mod:`~khepera_gym.learning.rllib.followers`: :class:`FormationFollowersVectorEnv`;
* :mod:`~khepera_gym.learning.rllib.multi_agent`: :class:`KheperaMultiAgentEnv` and the policy
mappings;
* :mod:`~khepera_gym.learning.rllib.creators`: the env names and the creators RLlib calls;
* :mod:`~khepera_gym.learning.rllib.config`: :func:`check_config`, :func:`build_algo`,
  :func:`policy_mapping`, :func:`ppo_config`;
* :mod:`~khepera_gym.learning.rllib.evaluation`: :func:`evaluate_policy` (the seeded evaluation
  episodes of ``khepera-gym train``), :func:`module_policy`, :func:`random_policy`;
* :mod:`~khepera_gym.learning.rllib.training`: :func:`train` (``khepera-gym train --backend rllib``)
and
  :func:`sampling_throughput` (env-steps/s of RLlib's sampling alone).

Needs the ``rllib`` extra: ``pip install 'khepera-gym[rllib]'``.
"""

from __future__ import annotations

try:
    import ray.rllib  # noqa: F401 - checked here so that every module of the package may use it
    import torch  # noqa: F401 - RLlib needs it but does not declare it
except ImportError as error:  # pragma: no cover - exercised only without the extra
    raise ImportError(
        f"khepera_gym.learning.rllib needs Ray RLlib (>= 2.52) and torch ({error}): "
        "pip install 'khepera-gym[rllib]'"
    ) from error

from khepera_gym.learning.rllib.config import (
    HYPERPARAMS_NAME,
    build_algo,
    check_config,
    describe_space,
    load_hyperparams,
    policy_mapping,
    ppo_config,
)
from khepera_gym.learning.rllib.creators import (
    ENV_PREFIX,
    FOLLOWERS_ENV,
    FOLLOWERS_ENVS,
    MULTI_AGENT_ENVS,
    MultiAgentEnvCreator,
    VectorEnvCreator,
    env_name,
    env_names,
    followers_per_world,
    is_multi_agent,
    make_multi_agent_env,
    register_envs,
)
from khepera_gym.learning.rllib.evaluation import (
    EVAL_SEED,
    Evaluation,
    Policy,
    evaluate_policy,
    module_policy,
    random_policy,
)
from khepera_gym.learning.rllib.followers import FormationFollowersVectorEnv
from khepera_gym.learning.rllib.multi_agent import (
    KheperaMultiAgentEnv,
    SharedPolicy,
    policy_per_agent,
)
from khepera_gym.learning.rllib.seeding import (
    MAX_ENV_RUNNERS,
    SeedPerRunner,
    multi_agent_world_seed,
    runner_world_seed,
)
from khepera_gym.learning.rllib.training import TrainResult, sampling_throughput, train
from khepera_gym.registration import resolve_env_id

register_envs()

__all__ = [
    "ENV_PREFIX",
    "EVAL_SEED",
    "FOLLOWERS_ENV",
    "FOLLOWERS_ENVS",
    "HYPERPARAMS_NAME",
    "MAX_ENV_RUNNERS",
    "MULTI_AGENT_ENVS",
    "Evaluation",
    "FormationFollowersVectorEnv",
    "KheperaMultiAgentEnv",
    "MultiAgentEnvCreator",
    "Policy",
    "SeedPerRunner",
    "SharedPolicy",
    "TrainResult",
    "VectorEnvCreator",
    "build_algo",
    "check_config",
    "describe_space",
    "env_name",
    "env_names",
    "evaluate_policy",
    "followers_per_world",
    "is_multi_agent",
    "load_hyperparams",
    "make_multi_agent_env",
    "module_policy",
    "multi_agent_world_seed",
    "policy_mapping",
    "policy_per_agent",
    "ppo_config",
    "random_policy",
    "register_envs",
    "resolve_env_id",
    "runner_world_seed",
    "sampling_throughput",
    "train",
]
