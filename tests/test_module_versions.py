"""Every entry point runs the behaviour version in its name.

For every PettingZoo module (``multinav_v3``) and every Gymnasium id (``KheperaIV-Nav-v0``), each
way of building it (the parallel and AEC envs, the array env, the SB3 VecEnv, the TorchRL env;
RLlib's in tests/test_rllib.py) reports that version, resolves that version's scenario, and
steps like the reference of that version: the Gymnasium env of the same id and version where the
task has one, else the core's batch built with that version. The cases come from the registries,
so a new version or module is covered without an edit. A module that ran another version (a
copied ``version=2`` in ``multinav_v3``) fails here even where the two versions' trajectories
happen to agree, because their scenarios do not.
"""

from __future__ import annotations

import hashlib
import importlib.util
from types import ModuleType

import gymnasium as gym
import numpy as np
import pytest

import khepera_gym
import khepera_gym.pettingzoo
import khepera_gym.registry
from khepera_gym import _core
from khepera_gym.registration import registered_ids, task_and_version

#: Steps each comparison runs (short: the scenario check is what tells versions apart).
STEPS = 25
#: Every PettingZoo module, name → module.
MODULES = khepera_gym.pettingzoo.modules()
#: Every registered Gymnasium id.
IDS = [env_id for ids in registered_ids().values() for env_id in ids]


def _reference_config(task: str, version: int) -> str:
    return _core.Batch(task, 1, version=version, num_threads=1).config_toml()


def _digest(arrays: list[np.ndarray]) -> str:
    digest = hashlib.sha256()
    for array in arrays:
        digest.update(np.ascontiguousarray(array, dtype=np.float32).tobytes())
    return digest.hexdigest()


def _actions(act_dim: int) -> np.ndarray:
    return np.random.default_rng(23).uniform(-1, 1, (STEPS, act_dim)).astype(np.float32)


def _reference_trajectory(task: str, version: int, env_id: str | None) -> str:
    """Joint observations of seed 4 under seeded joint actions: through the Gymnasium env of
    ``env_id`` (that version's id) when the task has one, else the core's batch of
    ``version``."""
    if env_id is not None:
        env = gym.make(env_id)
        observations = [env.reset(seed=4)[0]]
        for action in _actions(env.action_space.shape[0]):
            observations.append(env.step(action)[0])
        env.close()
        return _digest(observations)
    batch = _core.Batch(task, 1, version=version, num_threads=1, autoreset=False)
    observations = [batch.reset(4)[0]]
    for action in _actions(batch.act_dim):
        observations.append(batch.step(action[None, :])[0][0])
    return _digest(observations)


def _gym_id(task: str, version: int) -> str | None:
    ids = [i for i in registered_ids().get(task, []) if i.endswith(f"-v{version}")]
    return ids[0] if ids else None


@pytest.mark.parametrize("name", list(MODULES))
def test_a_pettingzoo_module_runs_the_version_in_its_name(name: str) -> None:
    module: ModuleType = MODULES[name]
    task, version = task_and_version(name)
    assert name.endswith(f"_v{version}")
    expected_config = _reference_config(task, version)

    parallel = module.parallel_env()
    assert parallel.behaviour_version == version
    assert parallel.metadata["name"] == name
    assert type(parallel).__module__ == module.__name__
    assert parallel.config_toml() == expected_config
    parallel.reset(seed=4)
    joint = [parallel.state()]
    for action in _actions(parallel.unwrapped._batch.act_dim):
        actions, start = {}, 0
        for agent in parallel.possible_agents:
            width = parallel.action_space(agent).shape[0]
            actions[agent] = action[start : start + width]
            start += width
        parallel.step(actions)
        joint.append(parallel.state())
        assert parallel.agents == parallel.possible_agents, "an agent left within the steps"
    parallel.close()
    assert _digest(joint) == _reference_trajectory(task, version, _gym_id(task, version))

    aec = module.env()
    assert aec.unwrapped.behaviour_version == version
    assert aec.unwrapped.config_toml() == expected_config
    aec.close()
    if hasattr(module, "array_env"):
        arrays = module.array_env(2)
        assert arrays.behaviour_version == version
        assert arrays.config_toml() == expected_config


@pytest.mark.parametrize("name", list(MODULES))
def test_the_sb3_and_torchrl_adapters_of_a_module_run_its_version(name: str) -> None:
    pytest.importorskip("stable_baselines3")
    from khepera_gym.learning.sb3 import make_vec_env

    task, version = task_and_version(name)
    expected_config = _reference_config(task, version)
    envs = make_vec_env(name, 2, seed=0, num_threads=1)
    assert envs.behaviour_version == version
    assert envs.config_toml() == expected_config
    envs.close()
    if importlib.util.find_spec("torchrl") is None:
        pytest.skip("torchrl is not installed (the torchrl extra)")
    from khepera_gym.learning.torchrl import KheperaTorchEnv

    torch_env = KheperaTorchEnv(name, 2, num_threads=1)
    assert torch_env.behaviour_version == version
    assert torch_env.config_toml() == expected_config


@pytest.mark.parametrize("env_id", IDS)
def test_every_entry_point_of_a_gymnasium_id_runs_its_version(env_id: str) -> None:
    task, version = task_and_version(env_id)
    assert env_id.endswith(f"-v{version}")
    expected_config = _reference_config(task, version)
    env = gym.make(env_id)
    assert env.unwrapped.behaviour_version == version
    assert env.unwrapped.config_toml() == expected_config
    env.close()
    envs = gym.make_vec(env_id, num_envs=2, num_threads=1)
    assert envs.unwrapped.behaviour_version == version
    assert envs.unwrapped.config_toml() == expected_config
    envs.close()
    if importlib.util.find_spec("stable_baselines3") is not None:
        from khepera_gym.learning.sb3 import make_vec_env

        sb3_envs = make_vec_env(env_id, 2, num_threads=1)
        assert sb3_envs.behaviour_version == version
        assert sb3_envs.config_toml() == expected_config
        sb3_envs.close()
    if importlib.util.find_spec("torchrl") is not None:
        from khepera_gym.learning.torchrl import KheperaTorchEnv

        torch_env = KheperaTorchEnv(env_id, 2, num_threads=1)
        assert torch_env.behaviour_version == version
        assert torch_env.config_toml() == expected_config


def test_the_versions_of_the_core_differ_in_their_scenarios() -> None:
    """What the tests above rely on to tell versions apart: each version changes defaults, so
    two versions of a task never resolve the same scenario."""
    for task, _, _ in _core.tasks():
        configs = [_reference_config(task, v) for v in _core.task_versions(task)]
        assert len(set(configs)) == len(configs), task
    assert [v for v, *_ in _core.versions()] == list(range(_core.LATEST_VERSION + 1))
    assert khepera_gym.registry.LATEST_VERSION == _core.LATEST_VERSION
