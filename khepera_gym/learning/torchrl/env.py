"""KheperaTorchEnv: a TorchRL ``EnvBase`` whose row i is world i of one ``_core.Batch``.

The layout, reset and seed rules are in the package docstring (:mod:`khepera_gym.learning.torchrl`).
This env is another face over the batch: ground truth (``poses``, ``goals``, ``targets``, ``scene``,
``sensor_readings``), layouts, saved state and episode statistics come from
:class:`khepera_gym.batch_face.BatchFace` (a face of every world, ``_WORLD = None``); the batch
keeps every world's last outputs, so the env holds no copy of them.

Units are those of the Gymnasium envs (SI, robot frame x forward, y left); observations and
rewards are float32, bit for bit those of the native batch. Threading and copies: ``step`` and
``reset`` release the GIL inside the Rust core, which steps the worlds on its own pool of
``num_threads`` threads; returned tensors share memory with fresh NumPy arrays of that call only.
One env must not be stepped from two threads at once.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import EnvBase

from khepera_gym._inputs import check_seed
from khepera_gym.batch_face import BatchFace, first_seed
from khepera_gym.config import ConfigArg, make_batch
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.learning.torchrl.groups import (
    AGENTS_END_SEPARATELY,
    has_agent_groups,
    make_groups,
    make_specs,
    resolve_group_map,
    resolve_task,
    resolve_version,
)

#: Seeds wrap at 2**64, as the core's ``reset(seed)`` does for world i (seed + i).
_SEED_MODULUS = 2**64
#: The env's only device.
_CPU = torch.device("cpu")
#: tensordict's unchecked constructor (TorchRL's own envs use it), when this version has it.
_NEW_UNSAFE = getattr(TensorDict, "_new_unsafe", None)


def _tensordict(entries: dict[str, Any], batch_size: torch.Size) -> TensorDictBase:
    """A CPU TensorDict of tensors built here with the right shapes and device.

    TensorDict's public constructor checks and casts every entry, tens of microseconds per
    TensorDict at every step (a Formation step builds two). The entries here are made to the
    specs (TorchRL's check_env_specs verifies them in the tests), so the unchecked constructor is
    taken when it exists.
    """
    if _NEW_UNSAFE is None:  # pragma: no cover - tensordict without it
        return TensorDict(entries, batch_size=batch_size, device=_CPU)
    return _NEW_UNSAFE(entries, batch_size=batch_size, device=_CPU)


def _check_device(device: Any) -> None:
    try:
        device_type = torch.device("cpu" if device is None else device).type
    except (RuntimeError, TypeError) as error:
        raise ConfigError(f"device={device!r} is not a torch device: {error}") from None
    if device_type != "cpu":
        raise ConfigError(
            f"KheperaTorchEnv runs on the CPU, got device={device!r}; keep the env (and "
            "BenchMARL's sampling_device) on the CPU and train on the GPU"
        )


class KheperaTorchEnv(BatchFace, EnvBase):
    """N Khepera IV worlds of one task as a batched TorchRL env (see
    :mod:`khepera_gym.learning.torchrl`).

    Args:
        task: A task of the Rust core (one agent, as "nav": flat keys; several, as "multinav":
            agent groups; the latest behaviour version, or ``version=0`` among the overrides) or a
            khepera_gym Gymnasium id ("KheperaIV-Nav"; an older version's id, as
            "KheperaIV-Nav-v0" → v0, runs that version's dynamics).
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

    _WORLD: ClassVar[int | None] = None

    def __init__(
        self,
        task: str,
        /,
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
        task, version = resolve_task(task), resolve_version(task)
        _check_device(device)
        grouped = has_agent_groups(task)
        if not grouped and group_map is not None:
            raise ConfigError(f"{task} has one agent and flat keys; group_map does not apply")
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
            version=version,
        )
        super().__init__(device="cpu", batch_size=torch.Size([batch.num_worlds]))
        self.task = task
        self._batch = batch
        self._pending_seed = pending_seed
        self._has_reset = False
        agents = [(name, start, stop) for name, _, start, stop, _ in batch.agents()]
        #: The agents' names in the batch's joint order.
        self.agent_names: list[str] = [name for name, _, _ in agents]
        #: Group name → agent names ({} for a task with flat keys).
        self.group_map: dict[str, list[str]] = (
            resolve_group_map(task, group_map, agents) if grouped else {}
        )
        self._groups = make_groups(self.group_map, agents, self._batch.agent_act_dim)
        self._group_done = task in AGENTS_END_SEPARATELY
        n = batch.num_worlds
        self._joint_action = np.zeros((n, batch.act_dim), np.float32)
        self._flat_action_shape = torch.Size([n, batch.act_dim])
        specs = make_specs(batch, self._groups, self._group_done)
        self.full_observation_spec = specs.observation
        self.full_action_spec = specs.action
        self.full_reward_spec = specs.reward
        self.full_done_spec = specs.done

    # --- EnvBase -------------------------------------------------------------------------------

    def _set_seed(self, seed: int | None) -> None:
        """Seeds the next reset: world i gets ``seed + i`` (None: streams continue)."""
        self._pending_seed = check_seed(seed)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        mask = self._reset_mask(tensordict)
        if mask is not None and self._has_reset and not mask.any():
            return self._last_output()  # nothing to reset; a pending seed stays pending
        seed, self._pending_seed = self._pending_seed, None
        if mask is None or mask.all() or not self._has_reset:
            # The first reset resets every world, whatever the mask: none has a state before it.
            if seed is None and not self._has_reset:
                seed = first_seed()
            observation = self._batch.reset(seed)
            self._has_reset = True
            n = self.batch_size[0]
            return self._output(observation, None, np.zeros(n, bool), np.zeros(n, bool))
        for world in np.flatnonzero(mask):
            world_seed = None if seed is None else (seed + int(world)) % _SEED_MODULUS
            self._batch.reset_world(int(world), world_seed)
        return self._last_output()

    def _reset_mask(self, tensordict: TensorDictBase | None) -> npt.NDArray[np.bool_] | None:
        """The root ``"_reset"`` mask as N bools, or None (reset every world).

        Raises:
            KheperaError: Only a group's ``"_reset"`` is given (a world resets as a whole).
        """
        if tensordict is None:
            return None
        mask = tensordict.get("_reset", None)
        if mask is None:
            if any(
                isinstance(key, tuple) and key[-1] == "_reset"
                for key in tensordict.keys(include_nested=True)
            ):
                raise KheperaError(
                    "a world resets as a whole: give the root '_reset' mask of shape "
                    f"({self.batch_size[0]}, 1), not only a group's (single robots cannot reset)"
                )
            return None
        return mask.detach().cpu().numpy().reshape(self.batch_size[0]).astype(bool, copy=False)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        if not self._groups:
            joint = self._actions_of(tensordict, "action", self._flat_action_shape)
        else:
            joint = self._joint_action
            for group in self._groups:
                shape = torch.Size([self.batch_size[0], group.size, group.act_dim])
                joint[:, group.action_columns] = self._actions_of(
                    tensordict, (group.name, "action"), shape
                )
        return self._output(*self._batch.step(joint))

    def _step_proc_data(self, next_tensordict_out: TensorDictBase) -> TensorDictBase:
        """``EnvBase.step``'s post-processing of ``_step``'s output, skipped unless
        ``run_type_checks`` is on: it reshapes rewards to their specs and fills in missing done
        keys, and ``_step`` already returns every key at its spec's shape
        (tests/test_torchrl.py checks that TorchRL's version changes nothing). That saves about
        12 µs of every step (an eighth of a 64-world Nav step)."""
        if self.run_type_checks:
            return super()._step_proc_data(next_tensordict_out)
        return next_tensordict_out

    def _actions_of(
        self, tensordict: TensorDictBase, key: str | tuple[str, str], shape: torch.Size
    ) -> npt.NDArray[np.float32]:
        """The actions at ``key`` as a float32 (N, prod(shape[1:])) array (NaN/inf are left to
        the core, which names the world and element).

        Raises:
            ActionError: ``key`` is missing or its tensor does not have shape ``shape``.
        """
        actions = tensordict.get(key, None)
        if actions is None or actions.shape != shape:
            got = "nothing" if actions is None else f"shape {tuple(actions.shape)}"
            raise ActionError(f"{key!r} must be a tensor of shape {tuple(shape)}, got {got}")
        if actions.dtype != torch.float32 or actions.device != _CPU:
            actions = actions.to(_CPU, torch.float32)
        return np.ascontiguousarray(actions.detach().numpy().reshape(shape[0], -1))

    def _last_output(self) -> TensorDictBase:
        """The reset output of every world as it now is (the batch keeps each one's last
        outputs; a world reset since shows its first observation and cleared flags)."""
        observation, _, terminated, truncated = self._batch.last_outputs()
        return self._output(observation, None, terminated, truncated)

    def _output(
        self,
        observation: npt.NDArray[np.float32],
        reward: npt.NDArray[np.float32] | None,
        terminated: npt.NDArray[np.bool_],
        truncated: npt.NDArray[np.bool_],
    ) -> TensorDictBase:
        """The TensorDict of these outputs; with ``reward`` (a step) or without (a reset).

        Shapes are made in NumPy and each entry crosses into torch once (``from_numpy``, no
        copy): a torch operation costs microseconds of dispatch, a NumPy view far less.
        """
        terminated = terminated[:, None]
        truncated = truncated[:, None]
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
        n = self.batch_size[0]
        agent_rewards = self._batch.agent_rewards() if reward is not None else None
        agent_terminated = self._batch.agent_terminated() if self._group_done else None
        for group in self._groups:
            shape = torch.Size([n, group.size])
            group_obs = observation[:, group.obs_columns].reshape(*shape, group.obs_dim)
            entries: dict[str, Any] = {"observation": torch.from_numpy(group_obs)}
            if agent_rewards is not None:
                entries["reward"] = torch.from_numpy(agent_rewards[:, group.agent_columns, None])
            if agent_terminated is not None:
                ended = agent_terminated[:, group.agent_columns, None]
                cut = truncated[:, None] & ~ended
                entries["done"] = torch.from_numpy(ended | cut)
                entries["terminated"] = torch.from_numpy(ended)
                entries["truncated"] = torch.from_numpy(cut)
            out[group.name] = _tensordict(entries, shape)
        out["state"] = torch.from_numpy(observation)
        return _tensordict(out, self.batch_size)

    # --- statistics ---------------------------------------------------------------------------

    def episode_stats(self) -> dict[str, npt.NDArray[Any]]:
        """Statistics of each world's last finished episode, in the form of the native vector
        env's ``info["episode_stats"]``: arrays of N values, "return", "length", "success",
        "path_length" (m), "collisions" (steps in contact) and the task's own (formation:
        "formation_error_mean", "formation_error_max", m), each with a mask ``"_return"``, ...
        True for the worlds that have finished an episode (values are 0 elsewhere).

        World i's entries change on the step that ends its next episode (where
        ``("next", "done")`` is True for it); resets leave them, ``set_state`` restores them.
        """
        finished = self._batch.episode_stats()["length"] > 0
        return self._vector_episode_info(finished)["episode_stats"]

    def agent_episode_stats(self) -> dict[str, dict[str, npt.NDArray[Any]]]:
        """Each agent's own statistics of each world's last finished episode, by group: group
        name → "return" (the sum of its rewards while it took part), "length" (its steps),
        "success" (as the task defines it for one agent), "path_length" (m), "collisions"
        (steps its robot was in contact), arrays of shape (N, group size) in the group's agent
        order, each with a mask ``"_return"``, ... of shape (N,) True for the worlds that have
        finished an episode (values are 0 elsewhere). :meth:`episode_stats` is the world's.

        Raises:
            KheperaError: The env has no agent groups (a single-agent task: its
                :meth:`episode_stats` is the agent's).
        """
        if not self._groups:
            raise KheperaError(
                "agent_episode_stats() needs agent groups; this env's one agent has episode_stats()"
            )
        finished = self._batch.episode_stats()["length"] > 0
        stats = self._batch.agent_episode_stats()
        result: dict[str, dict[str, npt.NDArray[Any]]] = {}
        for group in self._groups:
            entries: dict[str, npt.NDArray[Any]] = {}
            for name, values in stats.items():
                group_values = values[:, group.agent_columns]
                group_values[~finished] = 0
                entries[name] = group_values
                entries[f"_{name}"] = finished.copy()
            result[group.name] = entries
        return result


__all__ = ["KheperaTorchEnv"]
