"""A TorchRL environment over the Rust batch: N worlds in one ``EnvBase``, no subprocesses.

:class:`KheperaTorchEnv` is a ``torchrl.envs.EnvBase`` with ``batch_size=[N]`` whose row i is
world i of one ``_core.Batch`` (built without autoreset). TorchRL drives it as any batched env:
``env.rollout(...)``, ``SyncDataCollector``, BenchMARL (see :mod:`khepera_gym.benchmarl`).

TensorDict layout (N worlds; K agents in a group; D values of an agent's observation):

* single-agent tasks ("nav", "avoid"): flat keys, as TorchRL's Gym wrappers give:
  ``"observation"`` [N, 18] float32, ``"action"`` [N, 2] in [-1, 1], ``"reward"`` [N, 1];
* multi-agent tasks ("formation", "multinav"): one sub-TensorDict per agent group, of batch
  size [N, K]: ``(group, "observation")`` [N, K, D], ``(group, "action")`` [N, K, 2] in
  [-1, 1], ``(group, "reward")`` [N, K, 1] (each agent's own reward), and ``"state"``
  [N, S] at the root, the joint observation of every agent, for centralised critics. Default
  groups: formation ``{"followers": ["follower_0", ...]}`` plus ``{"leader": ["leader"]}``
  when the scenario's ``formation.leader = "agent"`` (its observation is the 18-value Nav one,
  a follower's has 23 values); multinav ``{"robots": ["robot_0", ...]}``. ``group_map=``
  regroups them (a dict group → agent names, or ``torchrl.envs.utils.MarlGroupMapType``);
* ``"done"``, ``"terminated"``, ``"truncated"`` [N, 1] bool at the root: the world's episode
  ended (reached the goal, or the leader did, or every multinav robot did; truncated after the
  scenario's ``max_steps``). Multinav robots end separately, so each multinav group also has
  ``(group, "done" | "terminated" | "truncated")`` [N, K, 1]: a robot that reached its goal is
  terminated (and stays so until its world is reset: it parks and its action is ignored); when
  the episode is truncated, every robot still driving is truncated.

Resets follow TorchRL's partial-reset contract: ``reset()`` resets every world;
``reset(TensorDict({"_reset": mask}, [N]))`` with a bool mask [N, 1] resets exactly the
worlds where it is True, one ``Batch.reset_world`` call each (a Python loop; a full mask takes
the batch's parallel reset). ``rollout(..., break_when_any_done=False)`` and the collectors
reset finished worlds that way; stepping a world whose episode ended without resetting it
raises :class:`~khepera_gym.errors.KheperaError`, as the single Gymnasium env does.

Seeds: ``set_seed(s)`` (TorchRL's API) makes the next reset seed world i with ``s + i``, as
``gym.make_vec(...).reset(seed=s)`` does; a partial reset applies it to the worlds it resets.
Without a pending seed a world's reset continues its own random stream, so row i replays
``gym.make(id)`` reset with seed ``s + i`` and then ``reset()`` after each episode, bit for bit.
The first reset without any seed draws s from the operating system's entropy.

Units are those of the Gymnasium envs (SI, robot frame x forward, y left); observations and
rewards are float32, bit for bit those of the native batch. Threading and copies: ``step`` and
``reset`` release the GIL inside the Rust core, which steps the worlds on its own pool of
``num_threads`` threads; returned tensors share memory with fresh NumPy arrays of that step only
(never reused later). One env must not be stepped from two threads at once. The env lives on
the CPU (``device="cpu"``); move data to a GPU with TorchRL's transforms or collectors.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym._inputs import check_seed
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.errors import ActionError, ConfigError, KheperaError


@contextlib.contextmanager
def torchrl_import_warnings_ignored() -> Iterator[None]:
    """Imports torchrl without its warnings about itself: torchrl 0.11 warns at import that its
    own weight updaters subclass a deprecated base class, which no user can act on (and which
    pytest's ``-W error`` would turn into an import failure)."""
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore",
            message=r"Creating \w+ which inherits from WeightUpdaterBase is deprecated",
            category=DeprecationWarning,
        )
        yield


try:
    import torch
    from tensordict import TensorDict, TensorDictBase

    with torchrl_import_warnings_ignored():
        from torchrl.data import Bounded, Categorical, Composite, Unbounded
        from torchrl.envs import EnvBase
        from torchrl.envs.utils import MarlGroupMapType
except ImportError as error:  # pragma: no cover - exercised with the extra missing
    raise ImportError(
        "khepera_gym.torchrl needs torchrl and tensordict: pip install 'khepera-gym[torchrl]'"
    ) from error

#: Tasks whose env has flat keys (one robot).
SINGLE_AGENT_TASKS = ("nav", "avoid")
#: Tasks whose env has agent groups.
MULTI_AGENT_TASKS = ("formation", "multinav")
#: Every task of :class:`KheperaTorchEnv`.
TASKS = SINGLE_AGENT_TASKS + MULTI_AGENT_TASKS
#: Actions per agent: normalised (left, right) wheel speeds, or (v, ω) with "unicycle".
ACTION_DIM = 2
#: Root keys a group may not be named after.
_RESERVED_KEYS = ("done", "terminated", "truncated", "state", "_reset", "observation", "action")
#: Seeds drawn when none was ever given lie in [0, this).
_SEED_BOUND = 2**62
#: Seeds wrap at 2**64, as the core's ``reset(seed)`` does for world i (seed + i).
_SEED_MODULUS = 2**64
#: The env's only device.
_CPU = torch.device("cpu")


def _tensordict(entries: dict[str, Any], batch_size: tuple[int, ...]) -> TensorDictBase:
    """A CPU TensorDict of tensors built here with the right shapes and device.

    TensorDict's public constructor checks and casts every entry, tens of microseconds per
    TensorDict at every step (a Formation step builds two). The entries here are made to the
    specs (TorchRL's check_env_specs verifies them in the tests), so tensordict's unchecked
    constructor ``_new_unsafe`` (which TorchRL's own envs use) is taken when it exists.
    """
    new_unsafe = getattr(TensorDict, "_new_unsafe", None)
    if new_unsafe is None:  # pragma: no cover - tensordict without it
        return TensorDict(entries, batch_size=batch_size, device=_CPU)
    return new_unsafe(entries, batch_size=torch.Size(batch_size), device=_CPU)


@dataclass(frozen=True)
class _Group:
    """Where one agent group's data lives in the batch's joint arrays."""

    name: str
    agents: tuple[str, ...]
    #: Each agent's column in ``agent_rewards()`` / ``agent_terminated()``, shape (K,).
    agent_columns: npt.NDArray[np.intp]
    #: The group's observation columns in the joint observation, agent-major, shape (K * D,).
    obs_columns: npt.NDArray[np.intp]
    #: The group's action columns in the joint action, agent-major, shape (K * 2,).
    action_columns: npt.NDArray[np.intp]
    #: D, the size of one agent's observation.
    obs_dim: int
    #: The same columns as slices when they are one run in order (no gather needed).
    obs_slice: slice | None
    action_slice: slice | None

    @property
    def size(self) -> int:
        """K, the number of agents in the group."""
        return len(self.agents)


@dataclass
class _WorldOutputs:
    """The last outputs of every world (what a reset leaves alone is reported from here).

    A plain object, so that updating it at every step skips ``torch.nn.Module.__setattr__``
    (EnvBase is a Module), which costs microseconds per attribute.
    """

    #: Joint observations (N, obs_dim); replaced, never written in place once handed out.
    observation: npt.NDArray[np.float32]
    #: Episode flags (N,).
    terminated: npt.NDArray[np.bool_]
    truncated: npt.NDArray[np.bool_]
    #: Each agent's termination (N, n_agents) (multinav only; zeros otherwise).
    agent_terminated: npt.NDArray[np.bool_]
    #: ``Batch.episode_stats()`` of the last step that ended an episode.
    episode_stats: dict[str, npt.NDArray[Any]]


def _as_run(columns: npt.NDArray[np.intp]) -> slice | None:
    """``columns`` as a slice when they are consecutive and increasing, else None."""
    if len(columns) and np.array_equal(columns, np.arange(columns[0], columns[0] + len(columns))):
        return slice(int(columns[0]), int(columns[0]) + len(columns))
    return None


def _resolve_group_map(
    task: str, group_map: Any, agents: Sequence[tuple[str, int, int]]
) -> dict[str, list[str]]:
    """The group map to use, checked against the env's agents (name, obs start, obs stop).

    Raises:
        ConfigError: ``group_map`` is not a dict or MarlGroupMapType, names an agent the env does
            not have, leaves one out or lists it twice, uses a reserved or empty group name, or
            mixes observation sizes in one group.
    """
    names = [name for name, _, _ in agents]
    if group_map is None:
        if task == "formation":
            followers = [name for name in names if name != "leader"]
            default = {"followers": followers}
            return {"leader": ["leader"], **default} if "leader" in names else default
        return {"robots": names}
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
        if not isinstance(group, str) or not group or group in _RESERVED_KEYS:
            raise ConfigError(
                f"group_map: group name {group!r} must be a non-empty str other than "
                f"{list(_RESERVED_KEYS)}"
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
        member_sizes = {sizes[agent] for agent in members}
        if len(member_sizes) > 1:
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


class KheperaTorchEnv(EnvBase):
    """N Khepera IV worlds of one task as a batched TorchRL env (see the module docstring).

    Args:
        task: "nav", "avoid" (flat keys) or "formation", "multinav" (agent groups).
        num_worlds: Number of worlds N (>= 1), the env's ``batch_size``.
        config: None (the task's defaults), a built-in scenario name, or a path to a TOML file.
        group_map: Multi-agent tasks only: None for the default groups, a dict group name →
            agent names, or a ``torchrl.envs.utils.MarlGroupMapType``.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        max_steps: If given, overrides the scenario's ``task.max_steps`` (truncation length).
        num_threads: Threads of the batch's rayon pool; None uses all cores.
        seed: If given, the first reset seeds world i with ``seed + i`` (as ``set_seed``).
        device: "cpu" or None (the simulator's arrays live on the CPU).
        **overrides: Scenario keys overriding the file, as for the Gymnasium envs
            (``n_followers=3``, ``shape="wedge"``, ``n_robots=6``, ``leader="agent"``, ...).

    Raises:
        ConfigError: Unknown task, an unknown or impossible scenario key, a ``group_map`` that
            does not fit the env's agents (or any ``group_map`` for a single-agent task), a
            device other than the CPU, a bad seed.

    ``step`` raises :class:`~khepera_gym.errors.ActionError` for a missing or wrongly shaped
    action or a NaN/inf in one, and :class:`~khepera_gym.errors.KheperaError` for a world whose
    episode ended and was not reset.
    """

    def __init__(
        self,
        task: str,
        num_worlds: int,
        *,
        config: ConfigArg = None,
        group_map: Any = None,
        action_type: str = "wheels",
        max_steps: int | None = None,
        num_threads: int | None = None,
        seed: int | None = None,
        device: Any = "cpu",
        **overrides: Any,
    ) -> None:
        if task not in TASKS:
            raise ConfigError(f"unknown task {task!r} for KheperaTorchEnv; tasks: {list(TASKS)}")
        try:
            device_type = torch.device("cpu" if device is None else device).type
        except (RuntimeError, TypeError) as error:
            raise ConfigError(f"device={device!r} is not a torch device: {error}") from None
        if device_type != "cpu":
            raise ConfigError(
                f"KheperaTorchEnv runs on the CPU, got device={device!r}; keep the env (and "
                "BenchMARL's sampling_device) on the CPU and train on the GPU"
            )
        if task in SINGLE_AGENT_TASKS and group_map is not None:
            raise ConfigError(
                f"{task} has one robot and flat keys; group_map applies to "
                f"{list(MULTI_AGENT_TASKS)} only"
            )
        pending_seed = check_seed(seed)
        batch = make_batch(
            task,
            num_worlds,
            config,
            overrides,
            action_type=action_type,
            num_threads=num_threads,
            autoreset=False,
            episode_steps=("max_steps", max_steps),
        )
        super().__init__(device="cpu", batch_size=torch.Size([batch.num_worlds]))
        self.task = task
        self._batch = batch
        self._pending_seed = pending_seed
        self._has_reset = False
        agents = [(name, start, stop) for name, _, start, stop, _ in batch.agents()]
        self.agent_names: list[str] = [name for name, _, _ in agents]
        self._groups: list[_Group] = []
        if task in MULTI_AGENT_TASKS:
            self.group_map: dict[str, list[str]] = _resolve_group_map(task, group_map, agents)
            self._groups = [
                self._make_group(name, members, agents) for name, members in self.group_map.items()
            ]
        else:
            self.group_map = {}
        #: Multinav's robots end separately: its groups carry their own done flags.
        self._group_done = task == "multinav"
        n = batch.num_worlds
        # The last outputs of every world, for reset outputs of the worlds a reset leaves alone.
        self._last = _WorldOutputs(
            observation=np.zeros((n, batch.obs_dim), np.float32),
            terminated=np.zeros(n, bool),
            truncated=np.zeros(n, bool),
            agent_terminated=np.zeros((n, len(self.agent_names)), bool),
            episode_stats={},
        )
        self._joint_action = np.zeros((n, batch.act_dim), np.float32)
        self._make_specs()

    # --- construction --------------------------------------------------------------------------

    def _make_group(
        self, name: str, members: list[str], agents: Sequence[tuple[str, int, int]]
    ) -> _Group:
        index = {agent: i for i, (agent, _, _) in enumerate(agents)}
        columns = np.array([index[agent] for agent in members], dtype=np.intp)
        obs_columns = np.concatenate(
            [np.arange(agents[i][1], agents[i][2], dtype=np.intp) for i in columns]
        )
        action_columns = (ACTION_DIM * columns[:, None] + np.arange(ACTION_DIM)).reshape(-1)
        return _Group(
            name=name,
            agents=tuple(members),
            agent_columns=columns,
            obs_columns=obs_columns,
            action_columns=action_columns,
            obs_dim=agents[columns[0]][2] - agents[columns[0]][1],
            obs_slice=_as_run(obs_columns),
            action_slice=_as_run(action_columns),
        )

    def _make_specs(self) -> None:
        n = self.batch_size[0]
        low, high = (
            torch.from_numpy(np.asarray(bound, np.float32)) for bound in self._batch.obs_bounds()
        )

        def bounded(lo: torch.Tensor, hi: torch.Tensor, shape: tuple[int, ...]) -> Any:
            lo, hi = lo.reshape(shape[1:]), hi.reshape(shape[1:])
            if not (torch.isfinite(lo).all() and torch.isfinite(hi).all()):
                return Unbounded(shape=shape, dtype=torch.float32)
            return Bounded(
                lo.expand(shape).clone(), hi.expand(shape).clone(), shape=shape, dtype=torch.float32
            )

        def flag(shape: tuple[int, ...]) -> Any:
            return Categorical(n=2, shape=shape, dtype=torch.bool)

        def done_specs(shape: tuple[int, ...]) -> dict[str, Any]:
            return {key: flag(shape) for key in ("done", "terminated", "truncated")}

        observation: dict[str, Any] = {}
        action: dict[str, Any] = {}
        reward: dict[str, Any] = {}
        done: dict[str, Any] = done_specs((n, 1))
        if not self._groups:
            observation["observation"] = bounded(low, high, (n, self._batch.obs_dim))
            action["action"] = Bounded(
                -1.0, 1.0, shape=(n, self._batch.act_dim), dtype=torch.float32
            )
            reward["reward"] = Unbounded(shape=(n, 1), dtype=torch.float32)
        else:
            for group in self._groups:
                shape = (n, group.size)
                group_obs = bounded(
                    low[group.obs_columns], high[group.obs_columns], (*shape, group.obs_dim)
                )
                observation[group.name] = Composite(observation=group_obs, shape=shape)
                action[group.name] = Composite(
                    action=Bounded(-1.0, 1.0, shape=(*shape, ACTION_DIM), dtype=torch.float32),
                    shape=shape,
                )
                reward[group.name] = Composite(
                    reward=Unbounded(shape=(*shape, 1), dtype=torch.float32), shape=shape
                )
                if self._group_done:
                    done[group.name] = Composite(done_specs((*shape, 1)), shape=shape)
            observation["state"] = bounded(low, high, (n, self._batch.obs_dim))
        self.full_observation_spec = Composite(observation, shape=(n,))
        self.full_action_spec = Composite(action, shape=(n,))
        self.full_reward_spec = Composite(reward, shape=(n,))
        self.full_done_spec = Composite(done, shape=(n,))

    # --- EnvBase -------------------------------------------------------------------------------

    def _set_seed(self, seed: int | None) -> None:
        """Seeds the next reset: world i gets ``seed + i`` (None: streams continue)."""
        self._pending_seed = check_seed(seed)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = None
        if tensordict is not None:
            mask = tensordict.get("_reset", None)
            if mask is None and any(
                isinstance(key, tuple) and key[-1] == "_reset"
                for key in tensordict.keys(include_nested=True)
            ):
                raise KheperaError(
                    "a world resets as a whole: give the root '_reset' mask of shape "
                    f"({self.batch_size[0]}, 1), not only a group's (single robots cannot reset)"
                )
        n = self.batch_size[0]
        if mask is not None:
            mask = mask.detach().cpu().numpy().reshape(n).astype(bool, copy=False)
            if self._has_reset and not mask.any():
                return self._output(None)  # nothing to reset; a pending seed stays pending
        seed = self._pending_seed
        self._pending_seed = None
        if mask is None or mask.all() or not self._has_reset:
            # The first reset resets every world, whatever the mask: none has a state before it.
            if seed is None and not self._has_reset:
                seed = int(np.random.default_rng().integers(_SEED_BOUND))
            last = self._last
            last.observation = self._batch.reset(seed)
            last.terminated = np.zeros(n, bool)
            last.truncated = np.zeros(n, bool)
            last.agent_terminated = np.zeros_like(last.agent_terminated)
            self._has_reset = True
        else:
            worlds = np.flatnonzero(mask)
            # Fresh arrays: the previous ones may be shared with tensors already returned.
            last = self._last
            observation = last.observation.copy()
            for world in worlds:
                world_seed = None if seed is None else (seed + int(world)) % _SEED_MODULUS
                observation[world] = self._batch.reset_world(int(world), world_seed)
            last.observation = observation
            last.terminated = last.terminated.copy()
            last.truncated = last.truncated.copy()
            last.agent_terminated = last.agent_terminated.copy()
            last.terminated[worlds] = False
            last.truncated[worlds] = False
            last.agent_terminated[worlds] = False
        return self._output(None)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        if not self._groups:
            joint = self._actions_of(tensordict, "action", (self._batch.act_dim,))
        else:
            joint = self._joint_action
            for group in self._groups:
                actions = self._actions_of(
                    tensordict, (group.name, "action"), (group.size, ACTION_DIM)
                )
                if group.action_slice is not None:
                    joint[:, group.action_slice] = actions
                else:
                    joint[:, group.action_columns] = actions
        observation, reward, terminated, truncated = self._batch.step(joint)
        last = self._last
        last.observation, last.terminated, last.truncated = observation, terminated, truncated
        if self._group_done:
            last.agent_terminated = self._batch.agent_terminated()
        if terminated.any() or truncated.any():
            last.episode_stats = self._batch.episode_stats()
        return self._output(reward)

    def _actions_of(
        self, tensordict: TensorDictBase, key: str | tuple[str, str], shape: tuple[int, ...]
    ) -> npt.NDArray[np.float32]:
        """The actions at ``key`` as a float32 (N, prod(shape)) array (NaN/inf are left to
        the core, which names the world and element).

        Raises:
            ActionError: ``key`` is missing or its tensor does not have shape (N, *shape).
        """
        actions = tensordict.get(key, None)
        expected = (self.batch_size[0], *shape)
        if actions is None or tuple(actions.shape) != expected:
            got = "nothing" if actions is None else f"shape {tuple(actions.shape)}"
            raise ActionError(f"{key!r} must be a tensor of shape {expected}, got {got}")
        if actions.dtype != torch.float32 or actions.device != _CPU:
            actions = actions.to(_CPU, torch.float32)
        return np.ascontiguousarray(actions.detach().numpy().reshape(expected[0], -1))

    def _output(self, reward: npt.NDArray[np.float32] | None) -> TensorDictBase:
        """The TensorDict of the current outputs; with ``reward`` (a step) or without (a reset).

        Shapes are made in NumPy and each entry crosses into torch once (``from_numpy``, no
        copy): a torch operation costs microseconds of dispatch, a NumPy view far less.
        """
        n = self.batch_size[0]
        last = self._last
        observation = last.observation
        terminated = last.terminated[:, None]
        truncated = last.truncated[:, None]
        out: dict[str, Any] = {
            "done": torch.from_numpy(terminated | truncated),
            "terminated": torch.from_numpy(terminated),
            "truncated": torch.from_numpy(truncated),
        }
        if not self._groups:
            out["observation"] = torch.from_numpy(observation)
            if reward is not None:
                out["reward"] = torch.from_numpy(reward[:, None])
            return _tensordict(out, self.batch_size)
        agent_rewards = self._batch.agent_rewards() if reward is not None else None
        for group in self._groups:
            shape = (n, group.size)
            columns = group.obs_slice if group.obs_slice is not None else group.obs_columns
            group_obs = observation[:, columns].reshape(*shape, group.obs_dim)
            entries: dict[str, Any] = {"observation": torch.from_numpy(group_obs)}
            if agent_rewards is not None:
                entries["reward"] = torch.from_numpy(agent_rewards[:, group.agent_columns, None])
            if self._group_done:
                agent_terminated = last.agent_terminated[:, group.agent_columns, None]
                agent_truncated = truncated[:, None] & ~agent_terminated
                entries["done"] = torch.from_numpy(agent_terminated | agent_truncated)
                entries["terminated"] = torch.from_numpy(agent_terminated)
                entries["truncated"] = torch.from_numpy(agent_truncated)
            out[group.name] = _tensordict(entries, shape)
        out["state"] = torch.from_numpy(observation)
        return _tensordict(out, self.batch_size)

    # --- ground truth and statistics -----------------------------------------------------------

    @property
    def max_episode_steps(self) -> int:
        """Steps after which an episode is truncated (the scenario's ``task.max_steps``)."""
        return self._batch.max_episode_steps

    @property
    def num_threads(self) -> int:
        """Threads of the batch's rayon pool."""
        return self._batch.num_threads

    def episode_stats(self) -> dict[str, npt.NDArray[Any]]:
        """Statistics of the episodes that ended on the last step that ended any (valid where
        that step's ``"done"`` was True): "return", "length", "success", "path_length" (m),
        "collisions"; formation adds "formation_error_mean" and "formation_error_max" (m).
        Each of shape (N,); resets do not clear them. Empty before any episode ended."""
        return {name: values.copy() for name, values in self._last.episode_stats.items()}

    def poses(self) -> npt.NDArray[np.float64]:
        """Ground-truth robot poses, shape (N, n_robots, 3): x, y (m), θ (rad, (-π, π])."""
        return self._batch.poses()

    def goals(self) -> npt.NDArray[np.float64]:
        """Goal positions, shape (N, n_goals, 2), in metres."""
        return self._batch.goals()

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """Followers' target points (eq. 12), shape (N, K, 2) in metres; K = 0 off formation."""
        return self._batch.formation_targets()

    def config_toml(self) -> str:
        """The fully resolved scenario (defaults + file + overrides) as TOML text."""
        return self._batch.config_toml()


__all__ = ["MULTI_AGENT_TASKS", "SINGLE_AGENT_TASKS", "TASKS", "KheperaTorchEnv"]
