"""RLlib ``AlgorithmConfig`` for khepera_gym envs: checks that name what the env cannot serve,
the policy mappings of the multi-agent envs, and PPO from ``configs/hyperparams/rllib_ppo.toml``.

:func:`check_config` compares a config with the env it names (probing a one-world env built from
its ``env_config``) before RLlib builds anything, so a mismatch is a
:class:`~khepera_gym.errors.ConfigError` naming it rather than an error deep inside an
EnvRunner; :func:`build_algo` checks then builds. :func:`policy_mapping` gives
``config.multi_agent(...)`` one shared policy or one per agent; :func:`ppo_config` builds the
``PPOConfig`` that ``khepera-gym train --backend rllib`` trains.

Seeds: ``ppo_config(seed=s)`` is ``config.debugging(seed=s)``, which RLlib passes on to the envs
(see :mod:`khepera_gym.learning.rllib.seeding`). No simulation runs here beyond the probes.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from ray.rllib.algorithms.algorithm import Algorithm
from ray.rllib.algorithms.algorithm_config import AlgorithmConfig
from ray.rllib.core import DEFAULT_MODULE_ID
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec

from khepera_gym.errors import ConfigError
from khepera_gym.learning.recipes import load_hyperparams as load_table
from khepera_gym.learning.rllib.creators import (
    ENV_PREFIX,
    FOLLOWERS_ENVS,
    env_name,
    env_names,
    followers_per_world,
    is_multi_agent,
    make_multi_agent_env,
    make_vector_env,
    register_envs,
)
from khepera_gym.learning.rllib.followers import FormationFollowersVectorEnv
from khepera_gym.learning.rllib.multi_agent import SharedPolicy, policy_per_agent

#: The hyperparameter file of :func:`ppo_config` in ``configs/hyperparams``.
HYPERPARAMS_NAME = "rllib_ppo"
#: Keys of a hyperparameter table that configure the run, not ``PPOConfig.training``.
_RUN_KEYS = ("n_timesteps", "num_env_runners", "num_envs_per_env_runner", "model", "env_kwargs")


# --- config checks ---------------------------------------------------------------------------


def _spaces_of(name: str, env_config: Mapping[str, Any]) -> dict[str, tuple[gym.Space, gym.Space]]:
    """Observation and action space of every agent (single-agent: ``DEFAULT_MODULE_ID``), from
    a one-world probe env built with ``env_config`` (which raises on a bad scenario)."""
    if "task" in env_config and not is_multi_agent(name):
        raise ConfigError(
            f"env_config asks for task={env_config['task']!r}, but {name} runs its own task; "
            f"choose the env name of the task instead, one of {env_names()}"
        )
    if is_multi_agent(name):
        env = make_multi_agent_env(name, env_config)
        env.close()
        return {
            agent: (env.observation_spaces[agent], env.action_spaces[agent])
            for agent in env.possible_agents
        }
    probe_config = {**env_config, "num_threads": 1}
    probe = (
        FormationFollowersVectorEnv(1, **{"version": FOLLOWERS_ENVS[name], **probe_config})
        if name in FOLLOWERS_ENVS
        else make_vector_env(name, 1, **probe_config)
    )
    spaces = (probe.single_observation_space, probe.single_action_space)
    probe.close()
    return {DEFAULT_MODULE_ID: spaces}


def describe_space(space: gym.Space) -> str:
    """A short description of a space for messages: ``Box(-1..1, (2,), float32)`` (the
    smallest low and largest high), other spaces as they print themselves."""
    if isinstance(space, gym.spaces.Box):
        return (
            f"Box({float(np.min(space.low)):g}..{float(np.max(space.high)):g}, {space.shape}, "
            f"{space.dtype})"
        )
    return str(space)


def _spaces_differ(given: gym.Space, expected: gym.Space) -> str:
    if (
        isinstance(given, gym.spaces.Box)
        and isinstance(expected, gym.spaces.Box)
        and given.shape == expected.shape
        and given.dtype == expected.dtype
    ):
        return " (same shape, other bounds)"
    return ""


def _check_space(where: str, kind: str, given: gym.Space | None, expected: gym.Space) -> None:
    if given is not None and given != expected:
        raise ConfigError(
            f"{where} asks for the {kind} space {describe_space(given)}, but the env has "
            f"{describe_space(expected)}{_spaces_differ(given, expected)}"
            + (
                " (khepera_gym actions are continuous normalised wheel speeds)"
                if kind == "action"
                else ""
            )
        )


def policy_mapping(
    name: str,
    env_config: Mapping[str, Any] | None = None,
    *,
    shared: bool = True,
    module_id: str = "shared_policy",
) -> dict[str, Any]:
    """``policies`` and ``policy_mapping_fn`` for ``config.multi_agent(**policy_mapping(...))``.

    Args:
        name: A multi-agent env name (``"khepera_gym/formation_v3"``, ``".../multinav_v3"``).
        env_config: The env's ``env_config`` (the agents depend on it: ``n_followers``,
            ``n_robots``, ``leader``).
        shared: One module for every agent (parameter sharing), else one module per agent
            (named after the agent).
        module_id: The shared module's id.

    Raises:
        ConfigError: ``name`` is not a multi-agent env, or ``shared`` with agents whose spaces
            differ (an agent leader observes 18 values, a follower 23).
    """
    env = make_multi_agent_env(name, env_config or {})
    env.close()
    agents = env.possible_agents
    if not shared:
        return {"policies": set(agents), "policy_mapping_fn": policy_per_agent}
    first = agents[0]
    for agent in agents[1:]:
        if (env.observation_spaces[agent], env.action_spaces[agent]) != (
            env.observation_spaces[first],
            env.action_spaces[first],
        ):
            raise ConfigError(
                f"{name}: agents {first!r} and {agent!r} have different spaces "
                f"({describe_space(env.observation_spaces[first])} vs "
                f"{describe_space(env.observation_spaces[agent])}), so they cannot share one "
                "policy; use shared=False"
            )
    return {"policies": {module_id}, "policy_mapping_fn": SharedPolicy(module_id)}


def check_config(config: AlgorithmConfig) -> None:
    """Checks that an RLlib config asks only for what its khepera_gym env has.

    Configs of other envs pass unchecked. For a name of this module (or one with its prefix) it
    checks: the name exists; ``env_config`` builds an env (scenario keys, task); a vector env
    runs in the ``VECTOR_ENTRY_POINT`` mode with a row count it can split into worlds; a
    single-agent env is not configured as multi-agent; every agent maps to a module listed in
    ``policies``; agents sharing a module have equal spaces; and the spaces set in the config
    (``config.environment(observation_space=..., action_space=...)``, ``RLModuleSpec`` or
    ``MultiRLModuleSpec``) equal the env's.

    Raises:
        ConfigError: The first mismatch, named (e.g. a ``Discrete`` action space).
    """
    name = config.env
    if not isinstance(name, str) or not name.startswith(ENV_PREFIX):
        return
    if name not in env_names():
        raise ConfigError(f"unknown khepera_gym RLlib env {name!r}; known: {env_names()}")
    env_config = dict(config.env_config)
    spaces = _spaces_of(name, env_config)
    if not is_multi_agent(name):
        mode = gym.VectorizeMode(config.gym_env_vectorize_mode)
        if mode != gym.VectorizeMode.VECTOR_ENTRY_POINT:
            raise ConfigError(
                f"{name} is a native vector env: set config.env_runners(gym_env_vectorize_mode="
                f"'vector_entry_point'), not {mode.value!r}"
            )
        if config.is_multi_agent:
            raise ConfigError(
                f"{name} is single-agent, but the config is multi-agent (policies "
                f"{sorted(config.policies)}); use khepera_gym/formation_v1 or multinav_v1"
            )
        if name in FOLLOWERS_ENVS:
            followers = followers_per_world({"version": FOLLOWERS_ENVS[name], **env_config})
            if config.num_envs_per_env_runner % followers:
                raise ConfigError(
                    f"{name}: num_envs_per_env_runner ({config.num_envs_per_env_runner}) must "
                    f"be a multiple of the {followers} followers per world"
                )
        observation_space, action_space = spaces[DEFAULT_MODULE_ID]
        _check_space(
            "config.environment(...)", "observation", config.observation_space, observation_space
        )
        _check_space("config.environment(...)", "action", config.action_space, action_space)
        module_spaces = {DEFAULT_MODULE_ID: spaces[DEFAULT_MODULE_ID]}
    else:
        if not config.is_multi_agent:
            raise ConfigError(
                f"{name} is multi-agent: configure its policies with config.multi_agent("
                f"**khepera_gym.learning.rllib.policy_mapping({name!r}, env_config, shared=True))"
            )
        module_spaces = _module_spaces(name, config, spaces)
    spec = config.rl_module_spec
    if spec is None:
        return
    specs = (
        spec.rl_module_specs if isinstance(spec, MultiRLModuleSpec) else {DEFAULT_MODULE_ID: spec}
    )
    for module_id, module_spec in specs.items():
        if module_id not in module_spaces:
            continue
        observation_space, action_space = module_spaces[module_id]
        where = f"the RLModuleSpec of {module_id!r}"
        _check_space(where, "observation", module_spec.observation_space, observation_space)
        _check_space(where, "action", module_spec.action_space, action_space)


def _module_spaces(
    name: str, config: AlgorithmConfig, spaces: Mapping[str, tuple[gym.Space, gym.Space]]
) -> dict[str, tuple[gym.Space, gym.Space]]:
    """The spaces of each module the agents of a multi-agent env map to (checked equal)."""
    policies = set(config.policies)
    module_spaces: dict[str, tuple[gym.Space, gym.Space]] = {}
    owners: dict[str, str] = {}
    for agent, agent_spaces in spaces.items():
        module_id = config.policy_mapping_fn(agent, None)
        if module_id not in policies:
            raise ConfigError(
                f"{name}: policy_mapping_fn maps agent {agent!r} to {module_id!r}, which is "
                f"not among the policies {sorted(policies)} (see khepera_gym.learning.rllib."
                "policy_mapping)"
            )
        if module_id in module_spaces and module_spaces[module_id] != agent_spaces:
            raise ConfigError(
                f"{name}: agents {owners[module_id]!r} and {agent!r} share module {module_id!r} "
                f"but their spaces differ ({describe_space(module_spaces[module_id][0])} vs "
                f"{describe_space(agent_spaces[0])})"
            )
        module_spaces.setdefault(module_id, agent_spaces)
        owners.setdefault(module_id, agent)
    return module_spaces


def build_algo(config: AlgorithmConfig) -> Algorithm:
    """:func:`check_config`, then ``config.build_algo()`` (with this package's env names
    registered again: see :func:`ppo_config`).

    Raises:
        ConfigError: See :func:`check_config`.
    """
    check_config(config)
    register_envs()
    return config.build_algo()


# --- PPO from the hyperparameter file --------------------------------------------------------


def load_hyperparams(env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The table of ``env_id`` in ``configs/hyperparams/rllib_ppo.toml`` (or ``path``).

    Raises:
        ConfigError: Missing file or table.
    """
    return load_table(HYPERPARAMS_NAME, env_id, path)


def ppo_config(
    name: str,
    hyperparams: Mapping[str, Any],
    *,
    seed: int | None = 0,
    num_env_runners: int | None = None,
    num_envs_per_env_runner: int | None = None,
    env_config: Mapping[str, Any] | None = None,
    shared: bool = True,
) -> Any:
    """A ``PPOConfig`` for the env ``name`` from a hyperparameter table.

    Args:
        name: An env name of this module (or a khepera_gym id, e.g. "KheperaIV-Nav").
        hyperparams: A table as in ``rllib_ppo.toml``: run keys (``num_env_runners``,
            ``num_envs_per_env_runner``, ``model`` for ``DefaultModelConfig``, ``env_kwargs``)
            and ``PPOConfig.training`` keywords (``lr``, ``gamma``, ``lambda_``, ...).
        seed: ``config.debugging(seed=...)``: seeds torch and the worlds (see module docstring).
        num_env_runners: Overrides the table's.
        num_envs_per_env_runner: Overrides the table's (rows per EnvRunner).
        env_config: Overrides the table's ``env_kwargs``.
        shared: Multi-agent envs: one policy for every agent, else one per agent (see
            :func:`policy_mapping`; call ``config.multi_agent(...)`` to change it).

    Raises:
        ConfigError: An unknown key for ``training`` or ``DefaultModelConfig``, or a shared
            policy over agents with different spaces.
    """
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    name = env_name(name)
    # Ray's registry hands what was registered before ray.init() to the first Ray session only:
    # after ray.shutdown() and a new ray.init() in this process, the names registered on import
    # are gone. Registering them again (harmless) makes them known to the session at hand.
    register_envs()
    table = dict(hyperparams)
    runners = int(table.get("num_env_runners", 0) if num_env_runners is None else num_env_runners)
    rows = int(
        table.get("num_envs_per_env_runner", 1)
        if num_envs_per_env_runner is None
        else num_envs_per_env_runner
    )
    if runners < 0 or rows < 1:
        raise ConfigError(
            f"num_env_runners must be >= 0 and num_envs_per_env_runner >= 1, got {runners}, {rows}"
        )
    training = {key: value for key, value in table.items() if key not in _RUN_KEYS}
    env_config = dict(table.get("env_kwargs", {}) if env_config is None else env_config)
    config = (
        PPOConfig()
        .environment(name, env_config=env_config)
        .env_runners(
            num_env_runners=runners,
            num_envs_per_env_runner=rows,
            gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT.value,
        )
        .debugging(seed=seed)
        .reporting(min_sample_timesteps_per_iteration=0)
    )
    if is_multi_agent(name):
        # RLlib vectorises multi-agent envs only synchronously (copies of one world each).
        config = config.env_runners(gym_env_vectorize_mode=gym.VectorizeMode.SYNC.value)
        config = config.multi_agent(**policy_mapping(name, env_config, shared=shared))
    try:
        config = config.training(**training)
        if "model" in table:
            config = config.rl_module(model_config=DefaultModelConfig(**table["model"]))
    except TypeError as error:
        raise ConfigError(f"RLlib PPO hyperparameters: {error}") from error
    return config


__all__ = [
    "HYPERPARAMS_NAME",
    "build_algo",
    "check_config",
    "describe_space",
    "load_hyperparams",
    "policy_mapping",
    "ppo_config",
]
