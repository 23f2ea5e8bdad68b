"""Which tasks have agent groups, what the groups are, and the TorchRL specs of an env's keys.

Everything here comes from the Rust core: its task list (``registry.task_names()``), Gymnasium ids
(:mod:`khepera_gym.registration`), each batch's agents (``Batch.agents()``: names and
observation columns) and observation bounds. A task whose default scenario has one agent (nav,
avoid, track) gets flat keys, as TorchRL's Gym envs; the others (formation, multinav, platoon)
get agent groups, by default one per agent kind: ``follower_0``.. → ``"followers"``,
``robot_0``.. → ``"robots"``, ``leader`` → ``"leader"``.

Units: none (indices and shapes); observation bounds are those of the layout. Threading: pure
functions; the default agents of each task are computed once per process (a 1-world batch).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import torch
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs.utils import MarlGroupMapType

from khepera_gym import _core, registry
from khepera_gym.errors import ConfigError
from khepera_gym.registration import latest_ids, task_and_version

#: Wheel actions per agent: normalised (left, right) wheel speeds, or (v, ω) with "unicycle";
#: with ``task.led_action`` each agent has 3 more, its LEDs' red, green, blue (5 in all).
ACTION_DIM = 2
#: Tasks whose agents end separately (an agent's ``agent_terminated()`` may be True while the
#: episode goes on: a multinav robot parks at its goal, a lost platoon robot parks where it is);
#: their groups carry their own done flags. The core's task information says which
#: (:attr:`khepera_gym.registry.TaskInfo.agents_end_separately`).
AGENTS_END_SEPARATELY = frozenset(
    name for name, info in registry.tasks().items() if info.agents_end_separately
)
#: Root keys a group may not be named after.
RESERVED_KEYS = ("done", "terminated", "truncated", "state", "_reset", "observation", "action")

#: An agent as the env sees it: (name, first observation column, end column).
Agent = tuple[str, int, int]


def tasks() -> list[str]:
    """Every task of the Rust core, in registry order ("nav", "avoid", "formation", ...)."""
    return registry.task_names()


def resolve_task(task: Any) -> str:
    """The core's task name of ``task``: a task name, a khepera_gym Gymnasium id with or
    without its version ("KheperaIV-Nav-v3", "KheperaIV-Nav") or a PettingZoo module's name
    ("multinav_v3").

    Raises:
        ConfigError: ``task`` is none of these.
    """
    known = tasks()
    if isinstance(task, str):
        try:
            return task_and_version(task)[0]
        except ConfigError:
            pass
    raise ConfigError(
        f"unknown task {task!r} for KheperaTorchEnv; tasks: {known}, or the Gymnasium ids "
        f"{sorted(latest_ids().values())} (any version), or a PettingZoo module's name"
    )


def resolve_version(task: str) -> int | None:
    """The behaviour version a task argument asks for: a Gymnasium id's own
    ("KheperaIV-Nav-v0" → 0, "KheperaIV-Nav" → the latest), a PettingZoo module's
    ("multinav_v1" → 1), None (the latest) for a core task name."""
    return None if task in tasks() else task_and_version(task)[1]


@functools.cache
def default_agents(task: str) -> tuple[str, ...]:
    """The agents of ``task``'s default scenario (one world is built to ask the core)."""
    return tuple(name for name, *_ in _core.Batch(task, 1, num_threads=1).agents())


def has_agent_groups(task: str) -> bool:
    """True for multi-agent tasks (keys in agent groups), False for one-agent tasks (flat keys)."""
    return len(default_agents(task)) > 1


def multi_agent_tasks() -> list[str]:
    """The tasks with agent groups, in registry order."""
    return [task for task in tasks() if has_agent_groups(task)]


def default_group_map(names: Sequence[str]) -> dict[str, list[str]]:
    """One group per agent kind, in the agents' order: an indexed name ``kind_i`` goes to group
    ``kinds``, any other name is a group of its own."""
    groups: dict[str, list[str]] = {}
    for name in names:
        indexed = re.fullmatch(r"(.+)_\d+", name)
        groups.setdefault(f"{indexed.group(1)}s" if indexed else name, []).append(name)
    return groups


def resolve_group_map(task: str, group_map: Any, agents: Sequence[Agent]) -> dict[str, list[str]]:
    """The group map to use, checked against the env's agents.

    Args:
        task: The task's name (for messages).
        group_map: None (the default groups), a dict group → agent names, or a
            ``torchrl.envs.utils.MarlGroupMapType``.
        agents: The env's agents as (name, observation start, observation stop).

    Raises:
        ConfigError: ``group_map`` is not a dict or MarlGroupMapType, names an agent the env does
            not have, leaves one out or lists it twice, uses a reserved or empty group name, or
            mixes observation sizes in one group.
    """
    names = [name for name, _, _ in agents]
    if group_map is None:
        return default_group_map(names)
    if isinstance(group_map, MarlGroupMapType):
        group_map = group_map.get_group_map(names)
    if not isinstance(group_map, Mapping):
        raise ConfigError(
            "group_map must be a dict group name -> list of agent names or a "
            f"torchrl.envs.utils.MarlGroupMapType, got {type(group_map).__name__}"
        )
    sizes = {name: stop - start for name, start, stop in agents}
    seen: dict[str, str] = {}
    resolved: dict[str, list[str]] = {}
    for group, members in group_map.items():
        if not isinstance(group, str) or not group or group in RESERVED_KEYS:
            raise ConfigError(
                f"group_map: group name {group!r} must be a non-empty str other than "
                f"{list(RESERVED_KEYS)}"
            )
        if isinstance(members, str) or not isinstance(members, Sequence) or not members:
            raise ConfigError(
                f"group_map[{group!r}] must be a non-empty list of agent names, got {members!r}"
            )
        for agent in members:
            if agent not in sizes:
                raise ConfigError(
                    f"group_map[{group!r}] names {agent!r}, which this {task} env does not "
                    f"have; its agents are {names}"
                )
            if agent in seen:
                raise ConfigError(
                    f"group_map: agent {agent!r} is in both {seen[agent]!r} and {group!r}"
                )
            seen[agent] = group
        if len({sizes[agent] for agent in members}) > 1:
            detail = ", ".join(f"{agent}: {sizes[agent]}" for agent in members)
            raise ConfigError(
                f"group_map[{group!r}] mixes observation sizes ({detail}); agents of one group "
                "are stacked, so put agents with different observations in separate groups"
            )
        resolved[group] = list(members)
    missing = [name for name in names if name not in seen]
    if missing:
        raise ConfigError(f"group_map leaves out agent(s) {missing}; every agent needs a group")
    return resolved


@dataclass(frozen=True)
class AgentGroup:
    """Where one agent group's data lives in the batch's joint arrays."""

    name: str
    agents: tuple[str, ...]
    #: Each agent's column in ``agent_rewards()`` / ``agent_terminated()``, shape (K,).
    agent_columns: npt.NDArray[np.intp]
    #: The group's observation columns in the joint observation, agent-major, shape (K * D,),
    #: or the same as a slice when they are one run in order (no gather needed).
    obs_columns: npt.NDArray[np.intp] | slice
    #: The group's action columns in the joint action, agent-major (K * A,), or a slice.
    action_columns: npt.NDArray[np.intp] | slice
    #: D, the size of one agent's observation.
    obs_dim: int
    #: A, the size of one agent's action: 2 (its wheels), 5 with ``task.led_action``.
    act_dim: int

    @property
    def size(self) -> int:
        """K, the number of agents in the group."""
        return len(self.agents)


def _as_run(columns: npt.NDArray[np.intp]) -> npt.NDArray[np.intp] | slice:
    """``columns`` as a slice when they are consecutive and increasing, else themselves."""
    start = int(columns[0])
    if np.array_equal(columns, np.arange(start, start + len(columns))):
        return slice(start, start + len(columns))
    return columns


def make_groups(
    group_map: Mapping[str, Sequence[str]], agents: Sequence[Agent], act_dim: int
) -> list[AgentGroup]:
    """The :class:`AgentGroup` of each group of a checked ``group_map``, each agent acting with
    ``act_dim`` values (the batch's ``agent_act_dim``)."""
    index = {name: i for i, (name, _, _) in enumerate(agents)}
    groups = []
    for name, members in group_map.items():
        columns = np.array([index[agent] for agent in members], dtype=np.intp)
        obs_columns = np.concatenate(
            [np.arange(agents[i][1], agents[i][2], dtype=np.intp) for i in columns]
        )
        action_columns = (act_dim * columns[:, None] + np.arange(act_dim)).reshape(-1)
        groups.append(
            AgentGroup(
                name=name,
                agents=tuple(members),
                agent_columns=columns,
                obs_columns=_as_run(obs_columns),
                action_columns=_as_run(action_columns),
                obs_dim=agents[columns[0]][2] - agents[columns[0]][1],
                act_dim=act_dim,
            )
        )
    return groups


@dataclass(frozen=True)
class Specs:
    """The four composite specs of an env (batched: their shape starts with N)."""

    observation: Composite
    action: Composite
    reward: Composite
    done: Composite


def make_specs(batch: _core.Batch, groups: Sequence[AgentGroup], group_done: bool) -> Specs:
    """The specs of an env over ``batch``: flat keys without groups, else one composite per
    group (with its own done flags when ``group_done``) and the joint ``"state"``."""
    n = batch.num_worlds
    low, high = (torch.from_numpy(np.asarray(bound, np.float32)) for bound in batch.obs_bounds())

    def bounded(lo: torch.Tensor, hi: torch.Tensor, shape: tuple[int, ...]) -> Any:
        lo, hi = lo.reshape(shape[1:]), hi.reshape(shape[1:])
        if not (torch.isfinite(lo).all() and torch.isfinite(hi).all()):
            return Unbounded(shape=shape, dtype=torch.float32)
        return Bounded(
            lo.expand(shape).clone(), hi.expand(shape).clone(), shape=shape, dtype=torch.float32
        )

    def done_specs(shape: tuple[int, ...]) -> dict[str, Any]:
        return {
            key: Categorical(n=2, shape=shape, dtype=torch.bool)
            for key in ("done", "terminated", "truncated")
        }

    def action(shape: tuple[int, ...]) -> Any:
        return Bounded(-1.0, 1.0, shape=shape, dtype=torch.float32)

    observation: dict[str, Any] = {}
    actions: dict[str, Any] = {}
    reward: dict[str, Any] = {}
    done: dict[str, Any] = done_specs((n, 1))
    if not groups:
        observation["observation"] = bounded(low, high, (n, batch.obs_dim))
        actions["action"] = action((n, batch.act_dim))
        reward["reward"] = Unbounded(shape=(n, 1), dtype=torch.float32)
    for group in groups:
        shape = (n, group.size)
        columns = group.obs_columns
        group_obs = bounded(low[columns], high[columns], (*shape, group.obs_dim))
        observation[group.name] = Composite(observation=group_obs, shape=shape)
        actions[group.name] = Composite(action=action((*shape, group.act_dim)), shape=shape)
        reward[group.name] = Composite(
            reward=Unbounded(shape=(*shape, 1), dtype=torch.float32), shape=shape
        )
        if group_done:
            done[group.name] = Composite(done_specs((*shape, 1)), shape=shape)
    if groups:
        observation["state"] = bounded(low, high, (n, batch.obs_dim))
    return Specs(
        observation=Composite(observation, shape=(n,)),
        action=Composite(actions, shape=(n,)),
        reward=Composite(reward, shape=(n,)),
        done=Composite(done, shape=(n,)),
    )


__all__ = [
    "ACTION_DIM",
    "AGENTS_END_SEPARATELY",
    "AgentGroup",
    "Specs",
    "default_agents",
    "default_group_map",
    "has_agent_groups",
    "make_groups",
    "make_specs",
    "multi_agent_tasks",
    "resolve_group_map",
    "resolve_task",
    "tasks",
]
