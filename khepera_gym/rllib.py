"""Ray RLlib (new API stack, Ray >= 2.52) environments and PPO training over the Rust batch.

Importing this module registers these names with ``ray.tune.registry.register_env`` (use them as
``config.environment(NAME, env_config={...})``; ``env_config`` takes the keyword arguments of the
env, e.g. ``{"max_steps": 300, "config": "paper_fig6"}``):

* ``khepera_gym/KheperaIV-Nav-v0``, ``.../KheperaIV-Avoid-v0``, ``.../KheperaIV-Formation-v0``:
  each EnvRunner gets ONE native vector env (``khepera_gym.vector.NavVectorEnv``, ...) of
  ``num_envs_per_env_runner`` worlds, a single Rust batch, through RLlib's ``VECTOR_ENTRY_POINT``
  mode (no N Python env copies);
* ``khepera_gym/formation_followers_v0``: the followers of ``num_envs_per_env_runner / K``
  Formation worlds as the rows of one vector env (:class:`FormationFollowersVectorEnv`), for one
  policy shared by every follower;
* ``khepera_gym/formation_v0``, ``khepera_gym/multinav_v0``: one :class:`KheperaMultiAgentEnv`
  (one world) per env copy, run by RLlib's ``MultiAgentEnvRunner``, with the agents of
  :mod:`khepera_gym.pettingzoo` (shared or separate policies: :func:`policy_mapping`).

The single-agent names need ``config.env_runners(gym_env_vectorize_mode="vector_entry_point")``
(:func:`ppo_config` sets it; :func:`check_config` says so when it is missing).

Seeds. RLlib resets EnvRunner w once with ``s = config.seed + w`` (+ 10**6 for evaluation
runners; the local runner is w = 0, remote ones 1, 2, ...) and khepera_gym's batch seeds world i
with ``seed + i``, so plain use would give world i + 1 of runner w the seed of world i of runner
w + 1. Here every env is built with a seed adapter:

* vector envs: world i of runner w is seeded ``(config.seed + w) · N + i`` with N the runner's
  number of worlds (:func:`runner_world_seed`), so runners get disjoint seed ranges;
* multi-agent envs (one world each, ``num_envs_per_env_runner`` copies J per runner, which RLlib
  seeds ``s + j``): copy j of runner w is seeded ``(config.seed + j) · 2**16 + w``
  (:func:`multi_agent_world_seed`), disjoint for up to 2**16 runners.

Later episodes continue each world's own random stream, as everywhere in khepera_gym.

Threads: each vector env's rayon pool has ``num_threads`` threads, by default the CPUs Ray
assigned to the EnvRunner (``num_cpus_per_env_runner``, 1), so runners do not oversubscribe the
machine; set ``env_config={"num_threads": k}`` to change it. RLlib still loops in Python over the
rows of a vector env each step to fill its episodes, so one runner's throughput is bounded by
RLlib's bookkeeping rather than by the Rust core: scale with more EnvRunners.

Tools: :func:`policy_mapping` (shared or per-agent policies for the multi-agent envs),
:func:`check_config` and :func:`build_algo` (clear errors for a config the env cannot serve),
:func:`ppo_config` (PPO from ``configs/hyperparams/rllib_ppo.toml``), :func:`evaluate_policy`
(the seeded evaluation episodes of ``khepera-gym train``), :func:`train` (``khepera-gym train
--backend rllib``) and :func:`sampling_throughput` (env-steps/s of RLlib's sampling alone).
"""

from __future__ import annotations

import dataclasses
import json
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import gymnasium as gym
import numpy as np
import numpy.typing as npt

try:
    import ray
    from ray.rllib.algorithms.algorithm import Algorithm
    from ray.rllib.algorithms.algorithm_config import AlgorithmConfig
    from ray.rllib.core import DEFAULT_MODULE_ID
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.env.env_context import EnvContext
    from ray.rllib.env.multi_agent_env import MultiAgentEnv
    from ray.tune.registry import register_env
except ImportError as error:  # pragma: no cover - exercised only without the extra
    raise ImportError(
        f"khepera_gym.rllib needs Ray RLlib (>= 2.52) and torch ({error}): "
        "pip install 'khepera-gym[rllib]'"
    ) from error

import khepera_gym
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.layout import layout_dict
from khepera_gym.pettingzoo import formation_v0, multinav_v0
from khepera_gym.render import DEFAULT_FRAME_SIZE, Renderer

if TYPE_CHECKING:
    from khepera_gym.pettingzoo._parallel import KheperaParallelEnv

#: Prefix of every env name this module registers with Ray Tune.
ENV_PREFIX = "khepera_gym/"
#: Name of the formation-followers vector env (one row per follower, one shared policy).
FOLLOWERS_ENV = f"{ENV_PREFIX}formation_followers_v0"
#: Multi-agent env names → the PettingZoo module whose ``parallel_env`` they wrap.
MULTI_AGENT_ENVS = {
    f"{ENV_PREFIX}formation_v0": formation_v0,
    f"{ENV_PREFIX}multinav_v0": multinav_v0,
}
#: Multi-agent world seeds are strided by this many runners (see :func:`multi_agent_world_seed`).
MAX_ENV_RUNNERS = 2**16
#: Seed of the first evaluation episode, as ``khepera-gym train`` (world i: EVAL_SEED + i).
EVAL_SEED = 10_000
#: The hyperparameter file of :func:`train` in ``configs/hyperparams``.
HYPERPARAMS_NAME = "rllib_ppo"
#: Keys of a hyperparameter table that configure the run, not ``PPOConfig.training``.
_RUN_KEYS = ("n_timesteps", "num_env_runners", "num_envs_per_env_runner", "model", "env_kwargs")


# --- names and ids ---------------------------------------------------------------------------


def _vector_env_ids() -> list[str]:
    """The registered Gymnasium ids whose vector entry point is a khepera_gym vector env."""
    return sorted(
        spec.id
        for spec in gym.registry.values()
        if str(spec.vector_entry_point or "").startswith("khepera_gym.")
    )


def resolve_env_id(env_id: str) -> str:
    """The registered id of a khepera_gym env: ``"KheperaIV-Nav"`` → ``"KheperaIV-Nav-v0"``.

    Raises:
        ConfigError: ``env_id`` is not a khepera_gym environment (the message lists them).
    """
    ours = _vector_env_ids()
    if env_id in ours:
        return env_id
    versions = [known for known in ours if known.rsplit("-v", 1)[0] == env_id.rstrip("-")]
    if not versions:
        raise ConfigError(f"unknown environment {env_id!r}; khepera_gym registers {ours}")
    return max(versions, key=lambda known: int(known.rsplit("-v", 1)[1]))


def env_name(env_id: str) -> str:
    """The RLlib env name of a khepera_gym Gymnasium id: ``"KheperaIV-Nav"`` →
    ``"khepera_gym/KheperaIV-Nav-v0"``; names of this module are returned unchanged.

    Raises:
        ConfigError: Neither a khepera_gym id nor a name of this module.
    """
    if env_id in env_names():
        return env_id
    return ENV_PREFIX + resolve_env_id(env_id.removeprefix(ENV_PREFIX))


def env_names() -> list[str]:
    """Every env name this module registers with Ray Tune."""
    return [ENV_PREFIX + env_id for env_id in _vector_env_ids()] + [
        FOLLOWERS_ENV,
        *MULTI_AGENT_ENVS,
    ]


def is_multi_agent(name: str) -> bool:
    """Whether the registered env ``name`` is a :class:`KheperaMultiAgentEnv`."""
    return name in MULTI_AGENT_ENVS


# --- seeds -----------------------------------------------------------------------------------


def runner_world_seed(seed: int, worker_index: int, num_worlds: int, world: int) -> int:
    """The seed of world ``world`` of EnvRunner ``worker_index`` (vector envs of this module).

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
        """Resets every world; an int ``seed`` is multiplied by ``num_worlds`` first."""
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            if seed < 0:
                raise ConfigError(f"seed must be >= 0, got {seed}")
            seed = int(seed) * self.num_worlds
        return self.env.reset(seed=seed, options=options)


def _runner_cpus() -> int:
    """CPUs Ray assigned to this process's actor (an EnvRunner), or 1 outside an actor."""
    if not ray.is_initialized():
        return 1
    context = ray.get_runtime_context()
    if context.get_actor_id() is None:
        return 1  # the driver (local EnvRunner): Ray reserves no CPU for it
    return max(1, round(context.get_assigned_resources().get("CPU", 1.0)))


# --- formation followers as rows of a gymnasium VectorEnv ------------------------------------


class FormationFollowersVectorEnv(gym.vector.VectorEnv):
    """The followers of N Formation worlds as the rows of one Gymnasium ``VectorEnv``.

    Row ``w · K + k`` is follower k of world w: it observes its own 23-value block (IR,
    ultrasonic, ``target_offset``, ``leader_offset``, ``leader_heading``, ``leader_velocity``,
    ``wheel_speeds``; see :class:`khepera_gym.envs.FormationEnv`), acts with its (left, right)
    wheel pair and earns its own reward, so one policy trained on these rows drives every
    follower (parameter sharing). The leader is scripted. All rows of a world end together.

    Semantics as :class:`khepera_gym.vector.KheperaVectorEnv`: NEXT_STEP autoreset (the step
    after a world ended resets it: first observations, reward 0, flags False, its actions
    ignored), ``reset(seed=s)`` seeds world w with ``s + w`` (``None`` continues the streams),
    and at a step where a world ended ``info["episode_stats"]`` holds that world's statistics on
    each of its rows (arrays of shape (N · K,) with boolean masks ``"_return"``, ...). The
    Rust batch steps the worlds on its pool of ``num_threads`` threads with the GIL released;
    returned arrays are fresh.

    Args:
        num_worlds: Number of worlds N; the env has ``num_envs = N · K`` rows.
        config: None, a built-in scenario name (e.g. "paper_fig7") or a TOML path.
        action_type: "wheels" or "unicycle".
        num_threads: Threads of the batch's pool; None uses every core.
        max_episode_steps: If given, overrides the scenario's ``max_steps``.
        render_mode: None, "rgb_array" or "human" (a mosaic of the first ``render_worlds``).
        frame_size: (width, height) in pixels of one world's frame.
        render_worlds: Worlds tiled by ``render()``.
        **overrides: Scenario keys (``n_followers=3``, ``shape="wedge"``, ...).

    Raises:
        ConfigError: An agent leader (``leader="agent"``), or any scenario error.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array", "human"],
        "render_fps": 20,
        "autoreset_mode": gym.vector.AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_worlds: int = 1,
        *,
        config: ConfigArg = None,
        action_type: str = "wheels",
        num_threads: int | None = None,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        frame_size: tuple[int, int] = DEFAULT_FRAME_SIZE,
        render_worlds: int = 4,
        **overrides: Any,
    ) -> None:
        if "task" in overrides:
            raise ConfigError("FormationFollowersVectorEnv runs the task 'formation'")
        self._batch = make_batch(
            "formation",
            num_worlds,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=True,
            episode_steps=("max_episode_steps", max_episode_steps),
        )
        agents = self._batch.agents()
        names = [name for name, *_ in agents]
        if any(not name.startswith("follower_") for name in names):
            raise ConfigError(
                "the formation-followers env needs the scripted leader (formation.leader = "
                f"'scripted'); the agents here are {names}: use khepera_gym/formation_v0 for "
                "an agent leader"
            )
        block = agents[0][3] - agents[0][2]
        if [(start, stop) for _, _, start, stop, _ in agents] != [
            (k * block, (k + 1) * block) for k in range(len(agents))
        ] or agents[-1][3] != self._batch.obs_dim:
            raise KheperaError(f"unexpected follower blocks in the joint observation: {agents}")
        #: Worlds in the batch.
        self.num_worlds: int = self._batch.num_worlds
        #: Followers per world (rows per world), K.
        self.followers_per_world: int = len(agents)
        #: Agent names of the rows of one world, in order.
        self.follower_names: list[str] = names
        #: Layout of one follower's block, name → slice.
        self.follower_layout: dict[str, slice] = layout_dict(agents[0][4])
        self.num_envs = self.num_worlds * self.followers_per_world
        self.render_mode = render_mode
        low, high = self._batch.obs_bounds()
        self.single_observation_space = gym.spaces.Box(
            low[:block].astype(np.float32), high[:block].astype(np.float32), dtype=np.float32
        )
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = gym.vector.utils.batch_space(
            self.single_observation_space, self.num_envs
        )
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._block = block
        self._ended = np.zeros(self.num_worlds, dtype=bool)
        self._render_worlds = max(1, int(render_worlds))
        self._renderer = Renderer(
            self._batch, render_mode, frame_size, fps=20, title="khepera_gym formation followers"
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Resets every world (world w seeded ``seed + w``; None continues each stream, the
        very first reset drawing a base seed from ``self.np_random``).

        Returns:
            Observations (num_envs, 23) and an empty info dict.
        """
        super().reset(seed=seed)
        if seed is None and not hasattr(self, "_has_reset"):
            seed = int(self.np_random.integers(2**62))
        self._has_reset = True
        self._ended = np.zeros(self.num_worlds, dtype=bool)
        joint = self._batch.reset(None if seed is None else int(seed))
        return joint.reshape(self.num_envs, self._block), {}

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.bool_],
        npt.NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Steps every world once with the followers' actions, shape (num_envs, 2).

        Raises:
            ActionError: Wrong shape, non-numeric or NaN/inf actions.
        """
        action_array = np.asarray(actions, dtype=np.float32)
        if action_array.shape != (self.num_envs, 2):
            raise ActionError(
                f"actions must have shape ({self.num_envs}, 2), got {action_array.shape}"
            )
        joint_actions = np.ascontiguousarray(action_array.reshape(self.num_worlds, -1))
        joint, _, terminated, truncated = self._batch.step(joint_actions)
        rows = self.followers_per_world
        rewards = self._batch.agent_rewards().reshape(-1).astype(np.float32)
        # Worlds that ended on the previous step were reset by this one (reward 0, as the
        # batch's own reward); the core's per-agent rewards still hold their last step's.
        rewards[np.repeat(self._ended, rows)] = 0.0
        ended = terminated | truncated
        self._ended = ended
        infos: dict[str, Any] = {}
        if np.count_nonzero(ended):
            ended_rows = np.repeat(ended, rows)
            episode: dict[str, Any] = {}
            for name, values in self._batch.episode_stats().items():
                values = np.repeat(values, rows)
                values[~ended_rows] = 0
                episode[name] = values
                episode[f"_{name}"] = ended_rows.copy()
            infos = {"episode_stats": episode, "_episode_stats": ended_rows}
        return (
            joint.reshape(self.num_envs, self._block),
            rewards,
            np.repeat(terminated, rows),
            np.repeat(truncated, rows),
            infos,
        )

    @property
    def num_threads(self) -> int:
        """Threads of the batch's rayon pool."""
        return self._batch.num_threads

    def render(self) -> npt.NDArray[np.uint8] | None:
        """A mosaic of the first ``render_worlds`` worlds (rgb_array), or shown in a window."""
        return self._renderer.render(self._render_worlds)

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12) of every world, shape (num_worlds, K, 2)."""
        return self._batch.formation_targets()

    def poses(self) -> npt.NDArray[np.float64]:
        """Ground-truth poses, shape (num_worlds, K + 1, 3), the leader first."""
        return self._batch.poses()

    def close_extras(self, **kwargs: Any) -> None:
        """Closes the render window, if any (also after a constructor that raised)."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()


# --- multi-agent ------------------------------------------------------------------------------


class KheperaMultiAgentEnv(MultiAgentEnv):
    """A khepera_gym PettingZoo parallel env (one world) as a native RLlib ``MultiAgentEnv``.

    Semantics are those of :mod:`khepera_gym.pettingzoo` (``formation_v0``, ``multinav_v0``):
    each agent observes its own block and acts with ``Box(-1, 1, (2,))``; an agent that
    terminates (a multinav robot on its goal) gets its last observation with
    ``terminateds[agent] = True`` and then leaves ``agents``; ``"__all__"`` is set in
    ``terminateds`` (every robot arrived, or the formation's leader did) or in ``truncateds``
    (time limit) when no agent is left. ``agents`` and ``possible_agents`` keep the env's fixed
    order (unlike RLlib's ``ParallelPettingZooEnv``, which builds them from a set), and
    ``render()`` takes no argument.

    Args:
        parallel_env: The PettingZoo env, e.g. ``formation_v0.parallel_env(n_followers=3)``.
        worker_index: The EnvRunner's index when RLlib builds the env: an int reset seed s is
            then mapped to :func:`multi_agent_world_seed` so that no two runners share worlds;
            None (direct use) seeds the world with s itself.
    """

    def __init__(self, parallel_env: KheperaParallelEnv, worker_index: int | None = None) -> None:
        super().__init__()
        self.parallel_env = parallel_env
        self.worker_index = worker_index
        self.possible_agents = list(parallel_env.possible_agents)
        self.agents = []
        self.observation_spaces = {
            agent: parallel_env.observation_space(agent) for agent in self.possible_agents
        }
        self.action_spaces = {
            agent: parallel_env.action_space(agent) for agent in self.possible_agents
        }
        self.render_mode = parallel_env.render_mode
        self.metadata = dict(parallel_env.metadata)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Resets the world; returns observations and infos of every agent."""
        if seed is not None and self.worker_index is not None:
            seed = multi_agent_world_seed(seed, self.worker_index)
        observations, infos = self.parallel_env.reset(seed=seed, options=options)
        self.agents = list(self.parallel_env.agents)
        return observations, infos

    def step(
        self, action_dict: dict[str, Any]
    ) -> tuple[dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, Any]]:
        """Steps the world with one action per live agent (see the class docstring).

        Raises:
            ActionError: A live agent has no action, or an action is malformed (PettingZoo
                env's checks).
        """
        observations, rewards, terminated, truncated, infos = self.parallel_env.step(action_dict)
        self.agents = list(self.parallel_env.agents)
        over = not self.agents
        time_limit = any(truncated.values())
        terminateds = {**terminated, "__all__": over and not time_limit}
        truncateds = {**truncated, "__all__": over and time_limit}
        return observations, rewards, terminateds, truncateds, infos

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The world's frame (rgb_array), or shown in a window (human); None without a mode."""
        return self.parallel_env.render()

    def close(self) -> None:
        """Closes the render window, if any."""
        self.parallel_env.close()

    def state(self) -> npt.NDArray[np.float32]:
        """The joint observation of every possible agent (for centralised critics)."""
        return self.parallel_env.state()


class SharedPolicy:
    """A ``policy_mapping_fn`` mapping every agent to one module (parameter sharing)."""

    def __init__(self, module_id: str) -> None:
        self.module_id = module_id

    def __call__(self, agent_id: str, episode: Any = None, **kwargs: Any) -> str:
        """The shared module's id, whatever the agent."""
        return self.module_id


def policy_per_agent(agent_id: str, episode: Any = None, **kwargs: Any) -> str:
    """A ``policy_mapping_fn`` giving each agent a module of its own, named after it."""
    return agent_id


def policy_mapping(
    name: str,
    env_config: Mapping[str, Any] | None = None,
    *,
    shared: bool = True,
    module_id: str = "shared_policy",
) -> dict[str, Any]:
    """``policies`` and ``policy_mapping_fn`` for ``config.multi_agent(**policy_mapping(...))``.

    Args:
        name: A multi-agent env name (``"khepera_gym/formation_v0"``, ``".../multinav_v0"``).
        env_config: The env's ``env_config`` (the agents depend on it: ``n_followers``,
            ``n_robots``, ``leader``).
        shared: One module for every agent (parameter sharing), else one module per agent
            (named after the agent).
        module_id: The shared module's id.

    Raises:
        ConfigError: ``name`` is not a multi-agent env, or ``shared`` with agents whose spaces
            differ (an agent leader observes 18 values, a follower 23).
    """
    env = _multi_agent_env(name, env_config or {}, worker_index=None)
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


# --- env creators ----------------------------------------------------------------------------


class VectorEnvCreator:
    """The ``register_env`` creator of a khepera_gym vector env (one per EnvRunner).

    RLlib calls it with ``env_config | {"num_envs": num_envs_per_env_runner}`` in the
    ``VECTOR_ENTRY_POINT`` mode. It builds ONE vector env of that many rows (for
    :data:`FOLLOWERS_ENV`: ``num_envs / K`` worlds of K followers) whose batch has
    ``num_threads`` threads (default: the runner's CPUs), wrapped in :class:`SeedPerRunner`.

    Args:
        name: The registered name (``"khepera_gym/KheperaIV-Nav-v0"`` or :data:`FOLLOWERS_ENV`).
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
            kwargs["num_threads"] = _runner_cpus()
        if self.name == FOLLOWERS_ENV:
            followers = followers_per_world(kwargs)
            if num_envs % followers:
                raise ConfigError(
                    f"{FOLLOWERS_ENV}: num_envs_per_env_runner ({num_envs}) must be a multiple "
                    f"of the {followers} followers per world (one row per follower)"
                )
            env: gym.vector.VectorEnv = FormationFollowersVectorEnv(num_envs // followers, **kwargs)
        else:
            env = gym.make_vec(
                self.name.removeprefix(ENV_PREFIX),
                num_envs=num_envs,
                vectorization_mode="vector_entry_point",
                **kwargs,
            )
        return SeedPerRunner(env)


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
        return _multi_agent_env(self.name, env_config, worker_index=worker_index)


def _multi_agent_env(
    name: str, env_config: Mapping[str, Any], worker_index: int | None
) -> KheperaMultiAgentEnv:
    if name not in MULTI_AGENT_ENVS:
        raise ConfigError(
            f"{name!r} is not a multi-agent env; those are {sorted(MULTI_AGENT_ENVS)}"
        )
    module = MULTI_AGENT_ENVS[name]
    return KheperaMultiAgentEnv(module.parallel_env(**dict(env_config)), worker_index)


def register_envs() -> list[str]:
    """Registers every env of this module with Ray Tune (done on import); returns the names.

    Registering again replaces the creators with equal ones, so calling it twice is harmless.
    """
    names = env_names()
    for name in names:
        if is_multi_agent(name):
            register_env(name, MultiAgentEnvCreator(name))
        else:
            register_env(name, VectorEnvCreator(name))
    return names


register_envs()


# --- config checks ---------------------------------------------------------------------------


#: Keyword arguments of the vector envs that a single env does not take.
_VECTOR_ONLY_KWARGS = ("num_threads", "render_worlds", "max_episode_steps")


def _spaces_of(name: str, env_config: Mapping[str, Any]) -> dict[str, tuple[gym.Space, gym.Space]]:
    """Observation and action space of every agent (single-agent: ``DEFAULT_MODULE_ID``), from
    a one-world probe env built with ``env_config`` (which raises on a bad scenario)."""
    if "task" in env_config and not is_multi_agent(name):
        raise ConfigError(
            f"env_config asks for task={env_config['task']!r}, but {name} runs its own task; "
            f"choose the env name of the task instead, one of {env_names()}"
        )
    if is_multi_agent(name):
        env = _multi_agent_env(name, env_config, worker_index=None)
        return {
            agent: (env.observation_spaces[agent], env.action_spaces[agent])
            for agent in env.possible_agents
        }
    config = {key: value for key, value in env_config.items() if key not in _VECTOR_ONLY_KWARGS}
    if name == FOLLOWERS_ENV:
        followers = FormationFollowersVectorEnv(1, num_threads=1, **config)
        followers.close()
        return {
            DEFAULT_MODULE_ID: (followers.single_observation_space, followers.single_action_space)
        }
    # A single env of the same task has the vector env's single spaces.
    single = gym.make(name.removeprefix(ENV_PREFIX), disable_env_checker=True, **config)
    spaces = (single.observation_space, single.action_space)
    single.close()
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
                f"{sorted(config.policies)}); use khepera_gym/formation_v0 or multinav_v0"
            )
        if name == FOLLOWERS_ENV:
            followers = followers_per_world(env_config)
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
                f"**khepera_gym.rllib.policy_mapping({name!r}, env_config, shared=True))"
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
                f"not among the policies {sorted(policies)} (see khepera_gym.rllib."
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
    """:func:`check_config`, then ``config.build_algo()``.

    Raises:
        ConfigError: See :func:`check_config`.
    """
    check_config(config)
    return config.build_algo()


# --- PPO from the hyperparameter file --------------------------------------------------------


def load_hyperparams(env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The table of ``env_id`` in ``configs/hyperparams/rllib_ppo.toml`` (or ``path``).

    Raises:
        ConfigError: Missing file or table.
    """
    from khepera_gym.train import load_hyperparams as load_table

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


# --- evaluation on seeded episodes ------------------------------------------------------------


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
    Worlds that end early are reset and ignored until every world has finished once.
    """
    start = time.perf_counter()
    envs = gym.make_vec(
        resolve_env_id(env_id.removeprefix(ENV_PREFIX)),
        num_envs=episodes,
        vectorization_mode="vector_entry_point",
        num_threads=num_threads,
        **dict(env_kwargs or {}),
    )
    layout = envs.unwrapped.obs_layout()
    distance = layout.get("goal_distance")
    observations, _ = envs.reset(seed=seed)
    first_distance = observations[:, distance].ravel() if distance is not None else None
    finished = np.zeros(episodes, dtype=bool)
    stats: dict[str, npt.NDArray[Any]] = {}
    progress = np.full(episodes, np.nan)
    while not finished.all():
        observations, _, terminated, truncated, infos = envs.step(policy(observations))
        newly = (terminated | truncated) & ~finished
        if not newly.any():
            continue
        for key, values in infos["episode_stats"].items():
            if not key.startswith("_"):
                stats.setdefault(key, np.zeros(episodes, dtype=values.dtype))[newly] = values[newly]
        if first_distance is not None:
            progress[newly] = first_distance[newly] - observations[newly, distance].ravel()
        finished |= newly
    envs.close()
    return Evaluation(
        timesteps=timesteps,
        episodes=episodes,
        success_rate=float(np.mean(stats["success"])),
        mean_return=float(np.mean(stats["return"])),
        mean_length=float(np.mean(stats["length"])),
        mean_collisions=float(np.mean(stats["collisions"])),
        mean_progress=float(np.mean(progress)),
        seconds=time.perf_counter() - start,
    )


# --- training (khepera-gym train --backend rllib) ---------------------------------------------


@dataclasses.dataclass
class TrainResult:
    """What :func:`train` did; also written to ``run.json``."""

    env_id: str
    backend: str
    algo: str
    seed: int
    timesteps: int
    #: Worlds per EnvRunner.
    n_envs: int
    num_env_runners: int
    iterations: int
    hyperparams: dict[str, Any]
    #: Wall time of the training loop (``algo.train()`` calls and evaluations), s.
    wall_time: float
    #: Wall time of the evaluations inside it, s.
    eval_time: float
    #: Environment steps per second of the training loop (evaluations included, as SB3's).
    steps_per_second: float
    #: CPU time of the training loop (s): this process (learner, evaluations, a local runner)
    #: plus the remote EnvRunner processes; Ray's own daemons are not counted. Unlike the wall
    #: time it hardly depends on other work on the machine.
    cpu_time: float
    final: Evaluation
    history: list[Evaluation]
    checkpoint: str
    out_dir: str

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict of the run."""
        record = dataclasses.asdict(self)
        record["hyperparams"] = json.loads(json.dumps(self.hyperparams, default=str))
        return record


def _sampled_steps(result: Mapping[str, Any]) -> int:
    return int(result["env_runners"]["num_env_steps_sampled_lifetime"])


def _cpu_seconds(algo: Algorithm) -> float:
    """CPU time so far of this process and of the algorithm's remote EnvRunner processes."""
    remote = 0.0
    if algo.config.num_env_runners > 0:
        remote = sum(
            algo.env_runner_group.foreach_env_runner(
                lambda runner: time.process_time(), local_env_runner=False
            )
        )
    return time.process_time() + remote


def train(
    env_id: str,
    *,
    timesteps: int | None = None,
    n_envs: int | None = None,
    num_env_runners: int | None = None,
    seed: int = 0,
    out_dir: str | Path | None = None,
    hyperparams_path: str | Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    eval_freq: int | None = None,
    eval_episodes: int = 100,
    eval_seed: int = EVAL_SEED,
    address: str | None = None,
    verbose: int = 1,
    torch_threads: int | None = 1,
) -> TrainResult:
    """Trains RLlib PPO on a khepera_gym env over the Rust batch, evaluates and saves it.

    Args:
        env_id: "KheperaIV-Nav" etc. (the table of ``configs/hyperparams/rllib_ppo.toml``).
        timesteps: Environment steps (all runners); None takes the table's ``n_timesteps``.
        n_envs: Worlds per EnvRunner; None takes the table's ``num_envs_per_env_runner``.
        num_env_runners: Remote EnvRunners (0: sample in this process); None: the table's.
        seed: ``config.seed``: torch and the worlds (runner w's world i: (seed + w)·N + i).
        out_dir: Run directory; None makes ``runs/rllib-ppo-<env>-s<seed>``.
        hyperparams_path: Another TOML file.
        overrides: Keys replacing the table's (``--hp KEY=VALUE``).
        eval_freq: Steps between evaluations; None a tenth of the run; 0 only the final one.
        eval_episodes: Seeded episodes per evaluation.
        eval_seed: Seed of the first evaluation episode.
        address: Ray cluster address for ``ray.init`` ("auto", "ray://host:10001"); None
            starts or joins a local instance. Ray is left running if it already was.
        verbose: 1 prints each evaluation and a summary.
        torch_threads: Torch threads of the learner in this process (restored afterwards);
            1 is fastest for these small networks (as for SB3).

    Returns:
        A :class:`TrainResult`, also saved as ``run.json`` beside ``checkpoint/``.
    """
    import torch

    env_id = resolve_env_id(env_id)
    hyperparams = load_hyperparams(env_id, hyperparams_path)
    hyperparams.update(overrides or {})
    if timesteps is not None:
        hyperparams["n_timesteps"] = timesteps
    if n_envs is not None:
        hyperparams["num_envs_per_env_runner"] = n_envs
    if num_env_runners is not None:
        hyperparams["num_env_runners"] = num_env_runners
    total = int(hyperparams.get("n_timesteps", 100_000))
    if total < 1:
        raise ConfigError(f"timesteps must be >= 1, got {total}")
    env_kwargs = dict(hyperparams.get("env_kwargs", {}))
    short_name = env_id.removeprefix("KheperaIV-").lower()
    out = Path(out_dir) if out_dir is not None else Path("runs") / f"rllib-ppo-{short_name}-s{seed}"
    out = out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    config = ppo_config(env_id, hyperparams, seed=seed)
    check_config(config)

    started_ray = not ray.is_initialized()
    if started_ray:
        ray.init(address=address, include_dashboard=False, log_to_driver=verbose >= 2)
    previous_threads = torch.get_num_threads()
    if torch_threads is not None:
        torch.set_num_threads(torch_threads)
    try:
        algo = config.build_algo()
        every = max(total // 10, 1) if eval_freq is None else eval_freq
        if verbose:
            print(
                f"training RLlib PPO on {env_id}: {total:,} steps, {config.num_env_runners} "
                f"EnvRunner(s) x {config.num_envs_per_env_runner} worlds, seed {seed}, "
                f"run directory {out}"
            )
        history: list[Evaluation] = []
        steps = iterations = last_eval = 0
        cpu_start = _cpu_seconds(algo)
        start = time.perf_counter()
        while steps < total:
            steps = _sampled_steps(algo.train())
            iterations += 1
            if (every > 0 and steps - last_eval >= every) or steps >= total:
                last_eval = steps
                evaluation = evaluate_policy(
                    module_policy(algo.get_module()),
                    env_id,
                    eval_episodes,
                    eval_seed,
                    env_kwargs,
                    timesteps=steps,
                )
                history.append(evaluation)
                if verbose:
                    print(
                        f"step {steps:>9,}: success {100 * evaluation.success_rate:5.1f} % of "
                        f"{evaluation.episodes}, return {evaluation.mean_return:7.2f}, "
                        f"length {evaluation.mean_length:5.1f}"
                    )
        wall_time = time.perf_counter() - start
        cpu_time = _cpu_seconds(algo) - cpu_start
        checkpoint = algo.save_to_path(str(out / "checkpoint"))
        algo.stop()
    finally:
        torch.set_num_threads(previous_threads)
        if started_ray:
            ray.shutdown()
    result = TrainResult(
        env_id=env_id,
        backend="rllib",
        algo="ppo",
        seed=seed,
        timesteps=steps,
        n_envs=int(config.num_envs_per_env_runner),
        num_env_runners=int(config.num_env_runners),
        iterations=iterations,
        hyperparams=hyperparams,
        wall_time=wall_time,
        eval_time=sum(evaluation.seconds for evaluation in history),
        steps_per_second=steps / wall_time,
        cpu_time=cpu_time,
        final=history[-1],
        history=history,
        checkpoint=str(checkpoint),
        out_dir=str(out),
    )
    record = result.to_json()
    record["versions"] = {
        "khepera_gym": khepera_gym.__version__,
        "ray": ray.__version__,
        "torch": torch.__version__,
        "python": platform.python_version(),
    }
    (out / "run.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    if verbose:
        final = result.final
        print(
            f"done in {wall_time:.0f} s ({result.steps_per_second:,.0f} steps/s, evaluations "
            f"{result.eval_time:.0f} s); final policy: success {100 * final.success_rate:.1f} % "
            f"of {final.episodes} episodes (seeds {eval_seed}..{eval_seed + final.episodes - 1}),"
            f" mean return {final.mean_return:.2f}"
        )
        print(f"saved {checkpoint}")
    return result


def sampling_throughput(
    config: AlgorithmConfig, steps_per_runner: int = 8192, repeats: int = 3
) -> float:
    """Env-steps/s of RLlib's sampling alone (no learning) with the EnvRunners of ``config``.

    Builds the algorithm (Ray must be initialised), lets every EnvRunner (remote ones in
    parallel, else the local one) sample ``steps_per_runner`` env steps with the initial policy
    once untimed, then ``repeats`` times timed, and stops it. Counts the steps the episodes hold.

    Raises:
        ConfigError: ``steps_per_runner`` or ``repeats`` < 1, or see :func:`check_config`.
    """
    if steps_per_runner < 1 or repeats < 1:
        raise ConfigError(
            f"steps_per_runner and repeats must be >= 1, got {steps_per_runner}, {repeats}"
        )
    algo = build_algo(config)

    def sample(runner: Any) -> int:
        episodes = runner.sample(num_timesteps=steps_per_runner)
        return sum(len(episode) for episode in episodes)

    local = config.num_env_runners == 0
    try:
        algo.env_runner_group.foreach_env_runner(sample, local_env_runner=local)
        start = time.perf_counter()
        steps = 0
        for _ in range(repeats):
            steps += sum(algo.env_runner_group.foreach_env_runner(sample, local_env_runner=local))
        elapsed = time.perf_counter() - start
    finally:
        algo.stop()
    return steps / elapsed


__all__ = [
    "ENV_PREFIX",
    "EVAL_SEED",
    "FOLLOWERS_ENV",
    "MAX_ENV_RUNNERS",
    "MULTI_AGENT_ENVS",
    "Evaluation",
    "FormationFollowersVectorEnv",
    "KheperaMultiAgentEnv",
    "MultiAgentEnvCreator",
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
