"""Behaviour versions: v1 (the real robot's dynamics) is the default, v0 stays registered with the
paper's V-REP-like dynamics, and the version is checked like any other argument."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from khepera_gym import _core
from khepera_gym.errors import ConfigError
from khepera_gym.registration import registered_ids, resolve_env_id

#: Tasks added with the v1 dynamics: only v1 exists (v0 means the paper's older dynamics).
V1_ONLY_TASKS = {"track", "pathfollow", "dronefollow", "linefollow", "seek"}


def test_every_task_registers_v0_and_v1_and_the_bare_id_is_the_latest() -> None:
    for task, ids in registered_ids().items():
        expected = ["1"] if task in V1_ONLY_TASKS else ["0", "1"]
        assert [i.rsplit("-v", 1)[1] for i in ids] == expected, task
    assert resolve_env_id("KheperaIV-Nav") == "KheperaIV-Nav-v1"
    assert resolve_env_id("KheperaIV-Track") == "KheperaIV-Track-v1"
    assert "KheperaIV-Track-v0" not in gym.registry
    with pytest.raises(ConfigError, match="version"):
        gym.make("KheperaIV-Track-v1", version=0)
    assert _core.LATEST_VERSION == 1


@pytest.mark.parametrize(
    ("env_id", "drive"), [("KheperaIV-Nav-v0", "kinematic"), ("KheperaIV-Nav-v1", "traction")]
)
def test_each_id_builds_its_versions_defaults(env_id: str, drive: str) -> None:
    env = gym.make(env_id)
    assert f'drive = "{drive}"' in env.unwrapped.config_toml()
    envs = gym.make_vec(env_id, num_envs=2)
    assert f'drive = "{drive}"' in envs.unwrapped.config_toml()
    env.close()
    envs.close()


@pytest.mark.parametrize("version", [2, -1, 1.0, "1", True])
def test_an_unknown_version_is_a_config_error(version: object) -> None:
    with pytest.raises(ConfigError, match="version"):
        gym.make("KheperaIV-Nav-v1", version=version)


def test_v1_wheels_follow_the_speed_profile_and_v0_wheels_jump() -> None:
    speeds = {}
    for version in (0, 1):
        env = gym.make("KheperaIV-Nav-v1", version=version)
        env.reset(seed=3)
        env.step(np.ones(2, np.float32))
        speeds[version] = env.unwrapped.sensor_readings()["wheel_speeds"][0]
        env.close()
    np.testing.assert_allclose(speeds[0], [0.813, 0.813], rtol=1e-6)
    # 0.203 m/s^2 for one 50 ms step (K-Team's default speed profile).
    np.testing.assert_allclose(speeds[1], [0.2034543 * 0.05] * 2, rtol=1e-5)


def test_odometry_localization_exposes_the_estimate_next_to_the_truth() -> None:
    # From the centre, (0.6, 0.4) circles with a radius of about 0.27 m: clear of the walls.
    env = gym.make("KheperaIV-Nav-v1", localization="odometry", start=[0.0, 0.0, 0.0])
    env.reset(seed=4)
    start = env.unwrapped.sensor_readings()["odometry"][0]
    np.testing.assert_allclose(start, env.unwrapped.poses()[0], atol=1e-6)
    for _ in range(100):
        env.step(np.array([0.6, 0.4], np.float32))
    estimate = env.unwrapped.sensor_readings()["odometry"][0]
    truth = env.unwrapped.poses()[0]
    assert 0 < np.linalg.norm(estimate[:2] - truth[:2]) < 0.2  # drifts, within the errors' scale
    assert "odometry" not in gym.make("KheperaIV-Nav-v1").unwrapped.sensor_readings()
    env.close()


@pytest.mark.parametrize("key", ["action_delay", "observation_delay"])
def test_delays_are_checked(key: str) -> None:
    with pytest.raises(ConfigError, match=f"task.{key}: must be at most 100"):
        gym.make("KheperaIV-Nav-v1", **{key: 101})
    with pytest.raises(ConfigError, match=f"task.{key}"):
        gym.make("KheperaIV-Nav-v1", **{key: -1})
