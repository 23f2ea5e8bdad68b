"""BenchMARL tasks over the Rust batch: Formation, MultiNav, Platoon and Consensus, without touching
BenchMARL.

:class:`KheperaTask` is a BenchMARL ``Task`` enum (members ``FORMATION``, ``MULTINAV``,
``PLATOON`` and ``CONSENSUS``) whose :class:`KheperaTaskClass` builds a
:class:`khepera_gym.learning.torchrl.KheperaTorchEnv` of ``num_envs`` worlds
(``batch_size=[num_envs]``, so BenchMARL uses the batch as it is, with no ``SerialEnv`` or
``ParallelEnv`` around it)::

    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models import MlpConfig
    from khepera_gym.learning.torchrl.benchmarl import KheperaTask

    experiment = Experiment(
        task=KheperaTask.FORMATION.get_task(config={"n_followers": 4, "max_steps": 300}),
        algorithm_config=MappoConfig.get_from_yaml(),
        model_config=MlpConfig.get_from_yaml(),
        critic_model_config=MlpConfig.get_from_yaml(),
        seed=0,
        config=ExperimentConfig.get_from_yaml(),
    )
    experiment.run()

A task's config is a dict of :class:`~khepera_gym.learning.torchrl.KheperaTorchEnv` arguments:
scenario overrides (``n_followers``, ``shape``, ``leader``, ``n_robots``, ``max_steps``, ...)
and ``config`` (a scenario file or built-in name), ``group_map``, ``action_type``,
``num_threads``; BenchMARL itself passes ``num_envs``, ``seed`` (world i of a batch is seeded
``seed + i``) and ``device`` (the CPU). ``get_from_yaml()`` gives :func:`default_task_config`,
the task's own keys and ``max_steps`` as the Rust core's built-in scenario sets them
(BenchMARL's own YAML folder is not used); ``get_from_yaml(path)`` reads a YAML file of such
keys. The members of :class:`KheperaTask` are the core's multi-agent tasks. Groups: formation
``"followers"`` (and ``"leader"`` with ``leader: agent``), multinav, platoon and consensus
``"robots"`` with per-robot done flags; the ``state`` (every agent's observation) feeds
centralised critics (MAPPO, MASAC, QMIX-style mixers). Actions are continuous only.
BenchMARL's Hydra command line does not know these tasks (they are not in its registry);
use the Python API.

Threading: each env steps its worlds on its own rayon pool (``num_threads``, all cores by
default); BenchMARL builds two (training and evaluation), used one after the other.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

try:
    from khepera_gym.learning.torchrl import KheperaTorchEnv, torchrl_import_warnings_ignored

    with torchrl_import_warnings_ignored():
        from benchmarl.environments.common import Task, TaskClass
    from torchrl.data import Composite
    from torchrl.envs import EnvBase
except ImportError as error:  # pragma: no cover - exercised with the extra missing
    raise ImportError(
        "khepera_gym.learning.torchrl.benchmarl needs BenchMARL: "
        "pip install 'khepera-gym[benchmarl]'"
    ) from error

from khepera_gym import _core
from khepera_gym.errors import ConfigError

#: Arguments BenchMARL passes itself; a task config may not set them.
_BENCHMARL_ARGUMENTS = ("num_envs", "num_worlds", "seed", "device")


def default_task_config(task: str) -> dict[str, Any]:
    """The config a task gets from ``get_from_yaml()`` without a path: its own scenario table
    and ``max_steps`` (the episode length BenchMARL reads), with the values of the Rust core's
    built-in scenario (``_core.default_config(task)``, every key documented there).

    Raises:
        ConfigError: ``task`` is not a task of the Rust core.
    """
    scenario = tomllib.loads(_core.default_config(task))
    return {**scenario.get(task, {}), "max_steps": scenario["task"]["max_steps"]}


class KheperaTaskClass(TaskClass):
    """A Khepera IV task of BenchMARL: how to build its env and read its specs.

    Args:
        name: The task's name, "FORMATION", "MULTINAV", "PLATOON" or "CONSENSUS" (the enum
            member's).
        config: Arguments of :class:`~khepera_gym.learning.torchrl.KheperaTorchEnv` (see the module
            docstring).
    """

    def get_env_fun(
        self,
        num_envs: int,
        continuous_actions: bool,
        seed: int | None,
        device: Any,
    ) -> Callable[[], EnvBase]:
        """A function building the env of ``num_envs`` worlds (world i seeded ``seed + i``).

        Raises:
            ConfigError: Discrete actions asked for, or the config sets an argument BenchMARL
                passes itself. Scenario errors are raised when the function is called.
        """
        if not continuous_actions:
            raise ConfigError(
                f"khepera {self.name.lower()} has continuous actions only (normalised wheel "
                "speeds in [-1, 1]); use an algorithm with continuous actions (MAPPO, IPPO, "
                "MASAC, MADDPG, ISAC, IDDPG) and prefer_continuous_actions=True"
            )
        clashing = [key for key in _BENCHMARL_ARGUMENTS if key in self.config]
        if clashing:
            raise ConfigError(
                f"task config sets {clashing}, which BenchMARL passes itself (number of envs, "
                "seed, sampling device); set them in the ExperimentConfig or Experiment instead"
            )
        return functools.partial(
            KheperaTorchEnv, self.name.lower(), num_envs, seed=seed, device=device, **self.config
        )

    def supports_continuous_actions(self) -> bool:
        """True: actions are normalised wheel speeds."""
        return True

    def supports_discrete_actions(self) -> bool:
        """False: there is no discrete action set."""
        return False

    def max_steps(self, env: EnvBase) -> int:
        """The episode length (the scenario's ``task.max_steps``)."""
        return int(env.max_episode_steps)

    def has_render(self, env: EnvBase) -> bool:
        """False: BenchMARL's video logging is not wired (``env.poses()`` gives ground truth)."""
        return False

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        """The env's agent groups, e.g. ``{"followers": ["follower_0", ...]}``."""
        return dict(env.group_map)

    def observation_spec(self, env: EnvBase) -> Composite:
        """Each group's ``observation`` spec, unbatched (without the root ``state``)."""
        spec = env.full_observation_spec_unbatched.clone()
        del spec["state"]
        return spec

    def info_spec(self, env: EnvBase) -> Composite | None:
        """None: the env has no per-agent info entries."""
        return None

    def state_spec(self, env: EnvBase) -> Composite | None:
        """The ``state`` spec (every agent's observation), unbatched, for centralised critics."""
        return Composite(state=env.full_observation_spec_unbatched["state"].clone())

    def action_spec(self, env: EnvBase) -> Composite:
        """Each group's ``action`` spec, ``Bounded(-1, 1, [K, 2])`` unbatched."""
        return env.full_action_spec_unbatched.clone()

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        """None: every action is always allowed."""
        return None

    @staticmethod
    def env_name() -> str:
        """The environment's name in BenchMARL's terms."""
        return "khepera"


class KheperaTask(Task):
    """The Khepera IV tasks of BenchMARL, one per multi-agent task of the Rust core
    (``khepera_gym.learning.torchrl.multi_agent_tasks()``; the tests check they match).
    ``KheperaTask.FORMATION.get_task(config={...})`` or ``.get_from_yaml([path])`` gives the task
    to pass to ``benchmarl.experiment.Experiment``."""

    FORMATION = None
    MULTINAV = None
    PLATOON = None
    CONSENSUS = None

    @staticmethod
    def associated_class() -> type[KheperaTaskClass]:
        """The class that builds these tasks' envs."""
        return KheperaTaskClass

    def get_from_yaml(self, path: str | os.PathLike[str] | None = None) -> KheperaTaskClass:
        """The task with :func:`default_task_config`, or with the config of a YAML file.

        Args:
            path: A YAML file holding a mapping of env arguments (e.g. ``n_followers: 3``); None
                for the defaults.

        Raises:
            ConfigError: The file is missing, not YAML, or not a mapping.
        """
        if path is None:
            return self.get_task(config=default_task_config(self.name.lower()))
        import yaml  # PyYAML comes with BenchMARL (through hydra-core and omegaconf)

        try:
            with open(path, encoding="utf-8") as file:
                config = yaml.safe_load(file)
        except OSError as error:
            raise ConfigError(f"{os.fspath(path)}: cannot read task config: {error}") from None
        except yaml.YAMLError as error:
            raise ConfigError(f"{os.fspath(path)}: not YAML: {error}") from None
        if config is None:
            config = {}
        if not isinstance(config, dict):
            raise ConfigError(
                f"{os.fspath(path)}: a task config is a mapping of env arguments, got "
                f"{type(config).__name__}"
            )
        return self.get_task(config=config)


__all__ = ["KheperaTask", "KheperaTaskClass", "default_task_config"]
