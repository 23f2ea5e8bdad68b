"""The PettingZoo ``ParallelEnv`` shared by the multi-robot tasks: one agent per controlled robot.

A :class:`KheperaParallelEnv` owns a ``_core.Batch`` of one world without autoreset. The Rust core
defines the agents (``Batch.agents()``: name, robot, slice of the joint observation), their
rewards (``agent_rewards()``) and terminations (``agent_terminated()``); this layer splits the
joint observation into per-agent arrays, assembles per-agent actions into the joint action and
keeps PettingZoo's bookkeeping (``agents`` shrinks as agents terminate or are truncated).

Units are SI (m, s, rad); robot frame x forward, y left. Threading and copies: ``step`` and
``reset`` release the GIL inside the Rust core; every returned observation is a fresh array (each
agent's is a slice of that step's joint observation, never reused by a later step).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium
import numpy as np
import numpy.typing as npt
from pettingzoo import ParallelEnv

from khepera_gym import registry
from khepera_gym._inputs import as_action_array, check_options, check_seed
from khepera_gym.batch_face import WORLD_STATS_KEY, BatchFace, check_render_mode, first_seed
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.observations import layout_dict
from khepera_gym.registry import with_history
from khepera_gym.render import Renderer

#: Wheel actions per agent: normalised (left, right) wheel speeds, or (v, ω) with "unicycle";
#: with ``task.led_action`` each agent has 3 more, its LEDs' red, green, blue (5 in all).
ACTION_DIM = 2

#: The family classes by family name (``"formation"`` → ``FormationParallelEnv``), filled by the
#: classes that set ``FAMILY``.
FAMILIES: dict[str, type[KheperaParallelEnv]] = {}

AgentObs = npt.NDArray[np.float32]
AgentAction = npt.NDArray[np.float32]


def merge_table_keywords(kwargs: dict[str, Any], table: str, values: Mapping[str, Any]) -> None:
    """Puts the keyword arguments ``values`` that are not None (``n_followers=4``) into the
    scenario table ``table`` of ``kwargs`` (``formation={...}``, which may already hold some of
    its keys; the arguments win), in place: how a wrapper's own keywords set its task's keys.

    Raises:
        ConfigError: ``kwargs[table]`` is given and is not a dict of keys (``formation=5``,
            ``formation="cross"``): the table keyword takes a table.
    """
    given = kwargs.pop(table, None)
    if given is not None and not isinstance(given, Mapping):
        raise ConfigError(
            f"{table}= takes a dict of [{table}] keys, got {type(given).__name__}: {given!r}"
        )
    merged = dict(given or {})
    merged.update({key: value for key, value in values.items() if value is not None})
    if given is not None or merged:
        kwargs[table] = merged


class KheperaParallelEnv(BatchFace, ParallelEnv[str, AgentObs, AgentAction]):
    """Base of the multi-agent Khepera IV environments; subclasses set :attr:`TASK`.

    Args:
        config: None (the task's defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        max_cycles: Steps before every agent is truncated (the scenario's ``task.max_steps``);
            None keeps the scenario's. ``max_steps`` is accepted as a synonym.
        render_mode: None, "rgb_array" (``render()`` returns the frame) or "human" (a pygame
            window, refreshed after every step).
        frame_size: (width, height) of the frame in pixels;
            None: 480 x 480, more for an arena over 4 m
            (:func:`khepera_gym.render.default_frame_size`).
        **overrides: Scenario keys overriding the file, as for the Gymnasium envs.

    Raises:
        ConfigError: Unknown or impossible scenario keys, both ``max_cycles`` and ``max_steps``.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "khepera_v0",
        "render_modes": ["rgb_array", "human"],
        "render_fps": 20,
        "is_parallelizable": True,
    }
    #: Task name in the Rust core.
    TASK: ClassVar[str] = ""
    #: Behaviour version whose defaults apply (the module's ``_v<n>``); None: the latest.
    VERSION: ClassVar[int | None] = None
    #: The family's name, set by the class that defines a family (``"formation"``): the package
    #: makes its module ``<family>_v<n>`` for every version of :attr:`TASK`.
    FAMILY: ClassVar[str] = ""
    #: Whether the family's modules offer ``array_env`` (every agent's data in one array).
    ARRAY_ENV: ClassVar[bool] = False
    _WORLD: ClassVar[int | None] = 0

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "FAMILY" not in cls.__dict__ or FAMILIES.setdefault(cls.FAMILY, cls) is not cls:
            return
        latest = registry.latest_version(cls.TASK)
        cls.metadata = {**cls.metadata, "name": f"{cls.FAMILY}_v{latest}"}
        # The family's manual (its class docstring, or else its module's) gets its Version
        # History from the core's versions.
        if "## Description" in (cls.__doc__ or ""):
            cls.__doc__ = with_history(cls.__doc__, cls.TASK)
        else:
            module = sys.modules[cls.__module__]
            module.__doc__ = with_history(module.__doc__, cls.TASK, indent="")

    def __init__(
        self,
        *,
        config: ConfigArg = None,
        action_type: str = "wheels",
        max_cycles: int | None = None,
        render_mode: str | None = None,
        frame_size: tuple[int, int] | None = None,
        **overrides: Any,
    ) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.action_type = action_type
        self._batch = make_batch(
            self.TASK,
            1,
            config,
            overrides,
            action_type=action_type,
            num_threads=1,
            autoreset=False,
            episode_steps=("max_cycles", max_cycles),
            version=self.VERSION,
        )
        self._renderer = Renderer(
            self._batch,
            render_mode,
            frame_size,
            fps=self.metadata["render_fps"],
            title=f"khepera_gym {self.metadata['name']}",
        )
        joint_space = self._row_observation_space()
        low, high = joint_space.low, joint_space.high
        agent_specs = self._batch.agents()
        self.possible_agents: list[str] = [name for name, *_ in agent_specs]
        #: Each agent's column in agent_rewards()/agent_terminated() (its actions: columns
        #: A·i .. A·(i + 1), A = agent_act_dim).
        self._agent_index = {name: index for index, (name, *_) in enumerate(agent_specs)}
        self._obs_slices = {name: slice(start, stop) for name, _, start, stop, _ in agent_specs}
        self._agent_layouts = {name: layout_dict(layout) for name, *_, layout in agent_specs}
        self._agent_robots = {name: int(robot) for name, robot, *_ in agent_specs}
        # Spaces are built once: PettingZoo requires the same object on every call.
        self.observation_spaces: dict[str, gymnasium.spaces.Box] = {
            name: gymnasium.spaces.Box(low[block], high[block], dtype=np.float32)
            for name, block in self._obs_slices.items()
        }
        #: Action values per agent: 2, or 5 with ``task.led_action``.
        self._act_dim: int = self._batch.agent_act_dim
        self.action_spaces: dict[str, gymnasium.spaces.Box] = {
            name: gymnasium.spaces.Box(-1.0, 1.0, shape=(self._act_dim,), dtype=np.float32)
            for name in self.possible_agents
        }
        #: The joint observation's space (``state()``), for centralised critics.
        self.state_space = joint_space
        #: Steps after which every remaining agent is truncated. PettingZoo's tests assign it: a
        #: value above the scenario's ``max_steps`` changes nothing (the core truncates first); a
        #: lower one truncates earlier, but then the infos carry no statistics (the core's
        #: episode has not ended; prefer ``max_cycles=`` at construction).
        self.max_cycles: int = self._batch.max_episode_steps
        self.agents: list[str] = []
        self._joint_actions = np.zeros((1, self._batch.act_dim), dtype=np.float32)
        self._observation = np.zeros(self._batch.obs_dim, dtype=np.float32)
        self._steps = 0
        self._has_reset = False

    # --- spaces --------------------------------------------------------------------------------

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        """The observation space of ``agent`` (the same object on every call)."""
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> gymnasium.spaces.Box:
        """The action space of ``agent``: ``Box(-1, 1, (2,), float32)``, ``(5,)`` with
        ``task.led_action`` (the same object on every call)."""
        return self.action_spaces[agent]

    def agent_obs_layout(self, agent: str) -> dict[str, slice]:
        """Layout of ``agent``'s observation, name → slice (e.g. "target_offset")."""
        return dict(self._agent_layouts[agent])

    # --- episode -------------------------------------------------------------------------------

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, AgentObs], dict[str, dict[str, Any]]]:
        """Start a new episode with every possible agent.

        Args:
            seed: Seeds the world's random stream (an int in [0, 2**64)); None continues it (the
                very first reset without a seed draws one from the operating system's entropy).
            options: None or a dict; unused, accepted for API compatibility.

        Returns:
            Observations and (empty) infos, keyed by agent.

        Raises:
            ConfigError: A seed that is not an int in [0, 2**64), or options that are not a
                dict.
        """
        seed = check_seed(seed)
        check_options(options)
        if seed is None and not self._has_reset:
            seed = first_seed()
        self._observation = self._batch.reset(seed)[0]
        self._has_reset = True
        self._steps = 0
        self.agents = list(self.possible_agents)
        observations = {agent: self._observation[self._obs_slices[agent]] for agent in self.agents}
        return observations, {agent: {} for agent in self.agents}

    def step(
        self, actions: Mapping[str, npt.ArrayLike]
    ) -> tuple[
        dict[str, AgentObs],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """Step every live agent at once.

        Args:
            actions: One action of shape (2,) per agent in ``self.agents`` ((5,) with
                ``task.led_action``; normalised, finite values outside [-1, 1] are clipped).
                Agents that already finished get zero wheel commands (their LEDs keep their
                last colour).

        Returns:
            ``(observations, rewards, terminations, truncations, infos)``, each keyed by the agents
            that were live before the step. An agent that terminated or was truncated leaves
            ``self.agents``; at the episode's end every remaining agent does. The info of an
            agent that leaves holds ``"episode_stats"``, its own statistics (Python scalars: the
            sum of its rewards, the steps it took part in, its success as the task defines it
            for one agent, its robot's path length and steps in contact); at the episode's end
            every remaining agent's info also holds ``"world_episode_stats"``, the world's (all
            agents together, as the Gymnasium env's ``"episode_stats"``, with the task's own
            statistics). An agent truncated early by a lowered ``max_cycles`` gets neither.

        Raises:
            ActionError: ``actions`` is not a mapping, misses a live agent, names one that is not
                live, or holds a non-numeric, wrongly shaped or NaN/inf action.
            KheperaError: ``step`` with no live agents (call ``reset()``).
        """
        if not self._has_reset:
            raise KheperaError("step() before reset(): the world was never started; call reset()")
        if not self.agents:
            raise KheperaError("step() with no live agents: the episode has ended, call reset()")
        self._fill_joint_actions(actions)
        observations, _, terminations, truncations = self._batch.step(self._joint_actions)
        self._observation = observations[0]
        self._steps += 1
        episode_over = bool(terminations[0] or truncations[0])
        cut_short = not episode_over and self._steps >= self.max_cycles
        agent_rewards = self._batch.agent_rewards()[0]
        agent_terminated = self._batch.agent_terminated()[0]

        live = self.agents
        observation_dict: dict[str, AgentObs] = {}
        rewards: dict[str, float] = {}
        terminated: dict[str, bool] = {}
        truncated: dict[str, bool] = {}
        infos: dict[str, dict[str, Any]] = {}
        world_stats = self._world_episode_stats(0) if episode_over else None
        # Each agent's own statistics, for the agents that leave now (the core's figures are
        # final for an agent it terminated, and for every agent when the episode ended).
        own_stats = (
            self._agent_episode_stats(0)
            if episode_over or agent_terminated[[self._agent_index[a] for a in live]].any()
            else None
        )
        for agent in live:
            index = self._agent_index[agent]
            observation_dict[agent] = self._observation[self._obs_slices[agent]]
            rewards[agent] = float(agent_rewards[index])
            terminated[agent] = bool(agent_terminated[index])
            # When the episode ends every remaining agent leaves: terminated if the core says so
            # (it terminates them all when the episode terminates), else truncated.
            truncated[agent] = not terminated[agent] and (episode_over or cut_short)
            info: dict[str, Any] = {}
            if own_stats is not None and (terminated[agent] or episode_over):
                info["episode_stats"] = own_stats[index]
            if world_stats is not None:
                info[WORLD_STATS_KEY] = dict(world_stats)
            infos[agent] = info
        self.agents = [agent for agent in live if not (terminated[agent] or truncated[agent])]
        if self.render_mode == "human":
            self.render()
        return observation_dict, rewards, terminated, truncated, infos

    def _fill_joint_actions(self, actions: Mapping[str, npt.ArrayLike]) -> None:
        if not isinstance(actions, Mapping):
            raise ActionError(
                f"actions must be a dict agent -> action of shape ({self._act_dim},), "
                f"got {type(actions).__name__}"
            )
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise ActionError(f"no action for live agent(s) {missing}; live agents: {self.agents}")
        live = set(self.agents)
        for agent in actions:
            if agent not in live:
                why = "has finished" if agent in self._agent_index else "is not an agent"
                raise ActionError(
                    f"action for {agent!r}, which {why}; give actions for {self.agents} only"
                )
        joint = self._joint_actions
        # Finished agents (multinav: parked robots) get zero wheel commands; their LED values
        # stay the last they sent (every agent acts on an episode's first step), so their LEDs
        # keep its colour.
        joint.reshape(-1, self._act_dim)[:, :ACTION_DIM] = 0.0
        for agent, action in actions.items():
            action_array = as_action_array(action, (self._act_dim,), f"action of {agent!r}")
            if not np.all(np.isfinite(action_array)):
                raise ActionError(f"action of {agent!r} is not finite: {action_array}")
            column = self._act_dim * self._agent_index[agent]
            joint[0, column : column + self._act_dim] = action_array

    # --- ground truth and the rest of the API --------------------------------------------------

    def state(self) -> npt.NDArray[np.float32]:
        """The joint observation of every possible agent (a copy), in ``state_space``."""
        return self._observation.copy()

    def agent_robot(self, agent: str) -> int:
        """The index of ``agent``'s robot in ``poses()``."""
        return self._agent_robots[agent]

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The frame (height, width, 3) uint8 for ``render_mode="rgb_array"``; shown in a window
        for ``"human"`` (returns None); None without a render mode."""
        return self._renderer.render()

    def close(self) -> None:
        """Closes the render window, if any (the Rust world is freed with the env); safe to call
        twice, and on an env whose construction failed."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()


__all__ = ["ACTION_DIM", "KheperaParallelEnv", "merge_table_keywords"]
