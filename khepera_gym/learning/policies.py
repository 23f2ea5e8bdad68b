"""The policies the comparison tool knows by name: the paper's controllers, uniform random
actions, and stable-baselines3 models (``sb3:path.zip``).
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym import baselines, registry
from khepera_gym.errors import ConfigError, KheperaError

#: The baselines by their controller's name (``position_control``, ...: every controller of the
#: core with a comparable class in baselines, found by listing the subclasses).
BASELINES: dict[str, type[baselines.BaselinePolicy]] = {
    cls.CONTROLLER: cls
    for cls in baselines.BaselinePolicy.__subclasses__()
    if cls.CONTROLLER and cls.COMPARABLE
}
#: Named variants of the baselines: parameters other than the defaults, and the tasks whose
#: comparison runs the variant by default (after its baseline; see ``BaselinePolicy.TASKS``).
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "braitenberg_kteam": ("braitenberg", {"weights": "kteam"}),
    # At K-Team's demo cruise speed, 200 speed units = 0.136 m/s (its braitenbergAvoidance's
    # fwSpeed, khepera4 library's kh4test): what the real robot's own demo drives at.
    "position_control_slow": ("position_control", {"vmax": 0.136}),
    "braitenberg_slow": ("braitenberg", {"vmax": 0.136}),
    "vfh_slow": ("vfh", {"vmax": 0.136}),
    # An agent leader (formation.leader = "agent") drives like the scripted one.
    "leader_follower": ("leader_follower", {"leader": baselines.Braitenberg()}),
}
#: The tasks each variant is a default policy of (a variant named as its baseline replaces it).
VARIANT_TASKS: dict[str, tuple[str, ...]] = {
    "braitenberg_kteam": ("avoid",),
    "leader_follower": ("formation",),
}
#: Every policy name (besides ``sb3:path.zip``).
POLICY_NAMES = tuple(dict.fromkeys((*BASELINES, *VARIANTS, "random")))
#: A user's own policy function: ``module:function`` or ``path/to/file.py:function``.
USER_POLICY = re.compile(r"(?P<where>[\w./\\~-]+):(?P<attribute>[A-Za-z_]\w*)")
#: Prefix of a stable-baselines3 model file among the policies.
SB3_PREFIX = "sb3:"
#: What an ``sb3:`` model's name gets in the results when it samples its actions.
SAMPLED_SUFFIX = " (sampled)"
#: stable-baselines3 algorithms tried in turn to load a model without ``--algo``.
SB3_ALGORITHMS = ("PPO", "SAC", "TD3", "A2C", "DQN")


def _default_policies() -> dict[str, tuple[str, ...]]:
    """Each task's default policies: the comparable baselines that fit it
    (:func:`khepera_gym.baselines.for_task`), each followed by the variants declared for the
    task, then ``random``."""
    defaults: dict[str, tuple[str, ...]] = {}
    for task in registry.task_names():
        names: list[str] = []
        for cls in baselines.for_task(task):
            if cls.CONTROLLER not in BASELINES:
                continue  # not offered on the Gymnasium envs (a PettingZoo-only task's law)
            names.append(cls.CONTROLLER)
            names += [
                name
                for name, (base, _) in VARIANTS.items()
                if base == cls.CONTROLLER and task in VARIANT_TASKS.get(name, ())
            ]
        defaults[task] = (*dict.fromkeys(names), "random")
    return defaults


#: Policies compared when none is given, for every task: the baselines that fit it (and the
#: variants declared for it), then ``random``.
DEFAULT_POLICIES: dict[str, tuple[str, ...]] = _default_policies()

Policy = Callable[[npt.NDArray[np.float32]], npt.ArrayLike]


class RandomPolicy:
    """Uniform actions in [-1, 1] from a seeded generator (a reproducible lower baseline).

    Args:
        act_dim: Action length per observation.
        seed: Seed of the generator.
    """

    def __init__(self, act_dim: int, seed: int) -> None:
        self.act_dim = int(act_dim)
        self._rng = np.random.default_rng(seed)

    def __call__(self, observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """Actions of shape (N, act_dim) for observations (N, D), or (act_dim,) for (D,)."""
        shape = np.shape(observation)[:-1]
        return self._rng.uniform(-1.0, 1.0, (*shape, self.act_dim)).astype(np.float32)

    def predict(
        self,
        observation: npt.ArrayLike,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[npt.NDArray[np.float32], None]:
        """stable-baselines3's signature (the benchmark plays its baselines through it)."""
        return self(observation), None


class SB3Policy:
    """A stable-baselines3 model as a policy: ``model.predict(obs, deterministic=True)``, or,
    with ``sample_seed``, actions sampled from the model's distribution (``deterministic=False``).

    A model whose observation is one follower's block (parameter sharing, e.g. trained on
    ``khepera_gym.learning.sb3.make_formation_vec_env``) acts on a joint Formation observation of K
    blocks one block at a time, its actions joined in follower order.

    Args:
        model: Anything with SB3's ``predict`` (a model, or
        ``khepera_gym.learning.sb3.load_policy``'s
            result, which normalises observations when the model was trained under
            ``VecNormalize``).
        path: The model file, for messages.
        sample_seed: None for the model's deterministic actions (its distribution's mode);
            a seed to sample them. torch's generator is seeded with it at every ``reset()``,
            so the same episodes give the same actions.
    """

    def __init__(self, model: Any, path: str, sample_seed: int | None = None) -> None:
        self.model = model
        self.path = path
        self.sample_seed = sample_seed
        space = getattr(model, "observation_space", None)
        shape = getattr(space, "shape", None)
        #: Observation length the model takes (None if it does not say).
        self.obs_dim: int | None = int(shape[0]) if shape and len(shape) == 1 else None

    def reset(self) -> None:
        """Starts new episodes in every world: empties a frame-stacked model's stacks and
        reseeds the sampling."""
        reset = getattr(self.model, "reset", None)
        if callable(reset):
            reset()
        if self.sample_seed is not None:
            import torch  # stable-baselines3 samples with torch's global generator

            torch.manual_seed(self.sample_seed)

    def __call__(self, observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
        """The model's actions for observations (N, D) (or one (D,))."""
        array = np.asarray(observation, dtype=np.float32)
        dim = getattr(self.model, "obs_dim", self.obs_dim)
        deterministic = self.sample_seed is None
        if dim is not None and array.shape[-1] != dim and array.shape[-1] % dim == 0:
            blocks = array.reshape(-1, dim)  # world-major, then follower
            action, _ = self.model.predict(blocks, deterministic=deterministic)
            return np.asarray(action, dtype=np.float32).reshape(*array.shape[:-1], -1)
        action, _ = self.model.predict(array, deterministic=deterministic)
        return np.asarray(action, dtype=np.float32)


def load_sb3_policy(
    path: str | Path, algo: str | None = None, sample_seed: int | None = None
) -> SB3Policy:
    """Loads a stable-baselines3 model file as a policy (on the CPU).

    Without ``algo`` the model is loaded by ``khepera_gym.learning.sb3.load_policy`` (which reads
    the algorithm from the zip and applies the ``VecNormalize`` statistics saved next to it by
    ``khepera-gym train``); if that cannot tell the algorithm, PPO, SAC, TD3, A2C and DQN are
    tried in turn. With ``algo`` that class's ``load`` is used on the bare model.

    Args:
        path: The ``.zip`` saved by ``model.save`` or ``khepera-gym train``.
        algo: The algorithm class ("PPO", "SAC", ...), or None.
        sample_seed: None for deterministic actions, or the seed of sampled ones
            (:class:`SB3Policy`).

    Returns:
        The policy.

    Raises:
        ImportError: stable-baselines3 is not installed (``pip install khepera-gym[sb3]``).
        FileNotFoundError: No such file.
        ValueError: Unknown ``algo``, or no algorithm could load the file.
    """
    try:
        import stable_baselines3
    except ImportError as error:
        raise ImportError(
            f"policy '{SB3_PREFIX}{path}' needs stable-baselines3, which is not installed: "
            "pip install khepera-gym[sb3]"
        ) from error
    if not Path(path).is_file():
        raise FileNotFoundError(f"policy '{SB3_PREFIX}{path}': no such model file")
    failures = []
    if algo is None:
        try:
            from khepera_gym.learning.sb3 import load_policy
        except ImportError as error:
            failures.append(f"khepera_gym.learning.sb3: {error}")
        else:
            try:
                return SB3Policy(load_policy(path), str(path), sample_seed)
            except KheperaError as error:
                failures.append(str(error))
    names = SB3_ALGORITHMS if algo is None else (algo.upper(),)
    for name in names:
        algorithm = getattr(stable_baselines3, name, None)
        if algorithm is None:
            raise ValueError(
                f"unknown stable-baselines3 algorithm {algo!r}; known: {SB3_ALGORITHMS}"
            )
        try:
            model = algorithm.load(str(path), device="cpu")
        except Exception as error:  # any failure means "not this algorithm"
            failures.append(f"{name}: {type(error).__name__}: {error}")
            continue
        return SB3Policy(model, str(path), sample_seed)
    raise ValueError(f"cannot load {path} as a stable-baselines3 model: " + "; ".join(failures))


class UserPolicy:
    """A user's own function as a policy: ``module:function`` or ``path/to/file.py:function``.

    The function takes a batch of observations (N, D) and returns actions (N, A), or takes one
    observation (D,) and returns one action (A,), as the getting-started guide's controller does
    (anything ``np.asarray`` turns into that shape); a class is instantiated without arguments
    first. Which of the two it is, is found on the first call: the batch is tried first, and a
    function that fails on it or answers it in another shape is given the rows one by one (the
    same actions a batch function would give, a Python call a row).
    """

    def __init__(self, spec: str, act_dim: int) -> None:
        self.name = spec
        self.act_dim = int(act_dim)
        where, _, attribute = spec.rpartition(":")
        try:
            if where.endswith(".py"):
                path = Path(where).expanduser()
                if not path.is_file():
                    raise ConfigError(f"policy {spec!r}: no file {path}")
                module_spec = importlib.util.spec_from_file_location(path.stem, path)
                if module_spec is None or module_spec.loader is None:
                    raise ConfigError(f"policy {spec!r}: {path} is not a Python module")
                module = importlib.util.module_from_spec(module_spec)
                module_spec.loader.exec_module(module)
            else:
                # As `python -m` would find it: the working directory first.
                sys.path.insert(0, str(Path.cwd()))
                try:
                    module = importlib.import_module(where)
                finally:
                    sys.path.remove(str(Path.cwd()))
        except ImportError as error:
            raise ConfigError(f"policy {spec!r}: cannot import {where!r}: {error}") from error
        found = getattr(module, attribute, None)
        if found is None:
            raise ConfigError(f"policy {spec!r}: {where!r} has no {attribute!r}")
        function = found() if isinstance(found, type) else found
        if not callable(function):
            raise ConfigError(f"policy {spec!r}: {attribute!r} is not callable")
        self._function = function
        #: Whether the function takes one observation at a time (found on the first call).
        self._per_row: bool | None = None

    def _called(self, observations: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """The function's answer, an error of its own as one line naming it (a ConfigError),
        not a traceback through this package."""
        try:
            return np.asarray(self._function(observations), dtype=np.float32)
        except ConfigError:
            raise
        except Exception as error:
            raise ConfigError(
                f"policy {self.name!r} raised {type(error).__name__}: {error} (for observations "
                f"of shape {observations.shape})"
            ) from error

    def _one(self, observation: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        action = self._called(observation)
        if action.shape != (self.act_dim,):
            raise ConfigError(
                f"policy {self.name!r} returned an action of shape {action.shape} for one "
                f"observation of shape {observation.shape}; expected ({self.act_dim},)"
            )
        return action

    def __call__(self, observations: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        observations = np.asarray(observations, dtype=np.float32)
        if observations.ndim == 1:
            return self._one(observations)
        expected = (*observations.shape[:-1], self.act_dim)
        if self._per_row is None:
            try:
                actions = np.asarray(self._function(observations), dtype=np.float32)
            except Exception as error:  # a single-observation function may fail on a batch
                batch_answer = f"raised {type(error).__name__}: {error}"
            else:
                if actions.shape == expected:
                    self._per_row = False
                    return actions
                batch_answer = f"returned actions of shape {actions.shape}"
            try:
                first = self._one(observations.reshape(-1, observations.shape[-1])[0])
            except ConfigError as error:
                cause = error.__cause__ if error.__cause__ is not None else error
                raise ConfigError(
                    f"policy {self.name!r} takes neither a batch of observations (for "
                    f"{observations.shape} it {batch_answer}; expected {expected}) nor one "
                    f"observation ({type(cause).__name__}: {cause})"
                ) from error
            self._per_row = True
            rows = observations.reshape(-1, observations.shape[-1])
            rest = [self._one(row) for row in rows[1:]]
            return np.stack([first, *rest]).reshape(expected)
        if self._per_row:
            rows = observations.reshape(-1, observations.shape[-1])
            return np.stack([self._one(row) for row in rows]).reshape(expected)
        actions = self._called(observations)
        if actions.shape != expected:
            raise ConfigError(
                f"policy {self.name!r} returned actions of shape {actions.shape} for observations "
                f"of shape {observations.shape}; expected {expected}"
            )
        return actions


def is_user_policy(name: str) -> bool:
    """Whether ``name`` names a user's function (``module:function``, ``file.py:function``)."""
    return USER_POLICY.fullmatch(name) is not None and not name.startswith(SB3_PREFIX)


def make_policy(
    name: str,
    env: gym.vector.VectorEnv,
    seed: int = 0,
    algo: str | None = None,
    sample_actions: bool = False,
) -> Policy:
    """The policy of a name for an environment (see the module docstring for the names).

    Args:
        name: A policy name, ``sb3:path.zip``, or a function of one's own as
            ``module:function`` or ``path/to/file.py:function`` (:class:`UserPolicy`).
        env: The (vector) environment it will drive: its task decides which names fit, a
            formation's shape is read from its scenario, the random policy's action length
            from its action space.
        seed: Seed of the ``random`` policy.
        algo: stable-baselines3 algorithm of an ``sb3:`` model (None: try them in turn).
        sample_actions: An ``sb3:`` model samples its actions (seeded with ``seed``) instead
            of taking its distribution's mode. Baselines are deterministic either way.

    Returns:
        A callable mapping a batch of observations (N, D) to actions (N, A).

    Raises:
        ConfigError: Unknown name, or a policy that does not fit the task (it lacks an
            observation block the policy reads); both are also ValueError.
        ImportError: ``sb3:`` without stable-baselines3 installed.
    """
    task = getattr(env.unwrapped, "task", None)
    if name.startswith(SB3_PREFIX):
        return load_sb3_policy(name[len(SB3_PREFIX) :], algo, seed if sample_actions else None)
    if is_user_policy(name):
        return UserPolicy(name, env.single_action_space.shape[0])
    if name not in POLICY_NAMES:
        near = difflib.get_close_matches(name, POLICY_NAMES, n=1, cutoff=0.6)
        hint = f"did you mean {near[0]!r}? " if near else ""
        raise ConfigError(
            f"unknown policy {name!r}; {hint}known: {', '.join(POLICY_NAMES)}, "
            "sb3:path/to/model.zip or your own function as module:function"
        )
    if name == "random":
        return RandomPolicy(env.single_action_space.shape[0], seed)
    controller, params = VARIANTS.get(name, (name, {}))
    try:
        # A baseline fits the task if it finds the observation blocks it reads by name.
        return BASELINES[controller].for_env(env, **params)
    except ConfigError as error:
        fitting = ", ".join(DEFAULT_POLICIES.get(task or "", ("random",)))
        raise ConfigError(
            f"policy {name!r} does not act on {task!r} observations ({error}); for this task "
            f"use {fitting} or sb3:path/to/model.zip"
        ) from error


class BatchView:
    """What :func:`make_policy` reads of an env (its task, one agent's action space, its
    scenario and the agents' layouts), over a bare ``_core.Batch`` of any task."""

    def __init__(self, batch: Any) -> None:
        self._batch = batch
        self.unwrapped = self
        self.task = batch.task
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (batch.agent_act_dim,), np.float32)

    def config_toml(self) -> str:
        return str(self._batch.config_toml())

    def agent_layouts(self) -> dict[str, dict[str, slice]]:
        from khepera_gym.observations import layout_dict

        return {name: layout_dict(own) for name, _, _, _, own in self._batch.agents()}

    def obs_layout(self) -> dict[str, slice]:
        return next(iter(self.agent_layouts().values()))


def make_agents_policy(
    name: str, batch: Any, seed: int = 0, algo: str | None = None
) -> Callable[[npt.NDArray[np.float32]], npt.NDArray[np.float32]]:
    """The policy of a name (as :func:`make_policy`'s) on the joint observation of a batch of
    any task, a multi-agent one included: a policy that reads the joint observation (Formation's
    followers) acts on it whole; any other acts on each agent's block (every agent of a default
    scenario has the first one's layout), and its actions are put side by side.

    Raises:
        ConfigError: As :func:`make_policy`.
    """
    policy = make_policy(name, BatchView(batch), seed=seed, algo=algo)  # type: ignore[arg-type]
    return on_every_agent(policy, batch)


def on_every_agent(
    policy: Callable[[Any], Any], batch: Any
) -> Callable[[npt.NDArray[np.float32]], npt.NDArray[np.float32]]:
    """``policy`` on the joint observation of ``batch``: whole, when it acts on it (Formation's
    followers), else on each agent's block, its actions put side by side."""
    from khepera_gym.errors import ActionError

    try:
        actions = policy(np.zeros((1, batch.obs_dim), dtype=np.float32))
    except (ActionError, ConfigError):
        pass
    else:
        if np.shape(actions) == (1, batch.act_dim):
            return policy
    agents = batch.agents()
    width = batch.agent_act_dim

    def act(observation: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        actions = np.zeros((observation.shape[0], width * len(agents)), dtype=np.float32)
        for index, (_, _, start, stop, _) in enumerate(agents):
            actions[:, width * index : width * (index + 1)] = policy(observation[:, start:stop])
        return actions

    return act


__all__ = [
    "DEFAULT_POLICIES",
    "POLICY_NAMES",
    "SAMPLED_SUFFIX",
    "SB3_ALGORITHMS",
    "SB3_PREFIX",
    "BatchView",
    "Policy",
    "RandomPolicy",
    "SB3Policy",
    "UserPolicy",
    "is_user_policy",
    "load_sb3_policy",
    "make_agents_policy",
    "make_policy",
    "on_every_agent",
]
