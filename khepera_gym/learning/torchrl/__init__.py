"""A TorchRL environment over the Rust batch: N worlds in one ``EnvBase``, no subprocesses.

:class:`KheperaTorchEnv` is a ``torchrl.envs.EnvBase`` with ``batch_size=[N]`` whose row i is
world i of one ``_core.Batch`` (built without autoreset). TorchRL drives it as any batched env:
``env.rollout(...)``, ``SyncDataCollector``, BenchMARL (see
:mod:`khepera_gym.learning.torchrl.benchmarl`).
Its task is one of the Rust core's (``khepera_gym.learning.torchrl.tasks()``: "nav", "multinav",
...) or a khepera_gym Gymnasium id ("KheperaIV-Nav-v3", "KheperaIV-Nav").

TensorDict layout (N worlds; K agents in a group; D values of an agent's observation):

* tasks with one agent ("nav", "avoid"): flat keys, as TorchRL's Gym wrappers give:
  ``"observation"`` [N, 18] float32, ``"action"`` [N, 2] in [-1, 1], ``"reward"`` [N, 1];
* multi-agent tasks (``multi_agent_tasks()``: "formation", "multinav", ...): one sub-TensorDict per
  agent group, of batch size [N, K]: ``(group, "observation")`` [N, K, D], ``(group, "action")``
  [N, K, 2] in [-1, 1], ``(group, "reward")`` [N, K, 1] (each agent's own reward), and ``"state"``
  [N, S] at the root, the joint observation of every agent, for centralised critics. Default
  groups, one per agent kind: formation ``{"followers": ["follower_0", ...]}`` plus ``{"leader":
  ["leader"]}`` when the scenario's ``formation.leader = "agent"`` (its observation is the
  18-value Nav one, a follower's has 23 values); multinav, platoon and consensus ``{"robots":
  ["robot_0", ...]}``. ``group_map=`` regroups them (a dict group → agent names, or
  ``torchrl.envs.utils.MarlGroupMapType``);
* ``"done"``, ``"terminated"``, ``"truncated"`` [N, 1] bool at the root: the world's episode
  ended (reached the goal, or the leader did, or every multinav robot did; truncated after the
  scenario's ``max_steps``). Multinav and platoon robots end separately, so each of their
  groups also has ``(group, "done" | "terminated" | "truncated")`` [N, K, 1]: a robot that
  reached its goal (multinav) or is lost (platoon) is terminated (and stays so until its world
  is reset: it parks and its action is ignored); when the episode is truncated, every robot
  still driving is truncated.

Resets follow TorchRL's partial-reset contract: ``reset()`` resets every world;
``reset(TensorDict({"_reset": mask}, [N]))`` with a bool mask [N, 1] resets exactly the
worlds where it is True, one ``Batch.reset_world`` call each (a full mask takes the batch's
parallel reset); the other rows of its output show their worlds as they are.
``rollout(..., break_when_any_done=False)`` and the collectors reset finished worlds that way;
stepping a world whose episode ended without resetting it raises
:class:`~khepera_gym.errors.KheperaError`, as the single Gymnasium env does.

Seeds: ``set_seed(s)`` (TorchRL's API) makes the next reset seed world i with ``s + i``, as
``gym.make_vec(...).reset(seed=s)`` does; a partial reset applies it to the worlds it resets.
Without a pending seed a world's reset continues its own random stream, so row i replays
``gym.make(id)`` reset with seed ``s + i`` and then ``reset()`` after each episode, bit for bit.
The first reset without any seed draws s from the operating system's entropy.

What every khepera_gym env shows of its batch comes from :class:`khepera_gym.batch_face.BatchFace`,
with the world axis first: ``poses()``, ``goals()``, ``targets()``, ``sensor_readings()``,
``scene(i)``, ``config_toml()``, ``obs_layout()``, ``agent_layouts()``, ``max_episode_steps``,
``get_state()``/``set_state()`` (restore, then step on bit for bit; the env pickles too), and
``episode_stats()``: each world's last finished episode, in the form of the native vector env's
``info["episode_stats"]`` (arrays of N values with masks of the worlds that have finished one);
with agent groups, ``agent_episode_stats()`` gives each agent's own (group → arrays (N, K)).

Units are those of the Gymnasium envs (SI, robot frame x forward, y left); observations and
rewards are float32, bit for bit those of the native batch. Threading and copies: ``step`` and
``reset`` release the GIL inside the Rust core, which steps the worlds on its own pool of
``num_threads`` threads; returned tensors share memory with fresh NumPy arrays of that call only
(never reused later). One env must not be stepped from two threads at once. The env lives on
the CPU (``device="cpu"``); move data to a GPU with TorchRL's transforms or collectors.
"""

from __future__ import annotations

import contextlib
import importlib
import warnings
from collections.abc import Iterator


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
    importlib.import_module("tensordict")
    with torchrl_import_warnings_ignored():
        importlib.import_module("torchrl.envs")
except ImportError as error:  # pragma: no cover - exercised with the extra missing
    raise ImportError(
        "khepera_gym.learning.torchrl needs torchrl and tensordict: "
        "pip install 'khepera-gym[torchrl]'"
    ) from error

from khepera_gym.learning.torchrl.env import KheperaTorchEnv  # noqa: E402
from khepera_gym.learning.torchrl.groups import (  # noqa: E402
    has_agent_groups,
    multi_agent_tasks,
    tasks,
)

__all__ = [
    "KheperaTorchEnv",
    "has_agent_groups",
    "multi_agent_tasks",
    "tasks",
    "torchrl_import_warnings_ignored",
]
