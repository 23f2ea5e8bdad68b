"""Behaviour versions: v3 (v2's drive, contacts with the scene solved as a rigid disc's) is the
default; v2 (K-Team's speed profile at Acc_Inc 40, which the exported program sets on the robot,
contacts through rapier), v1 (a plain 0.203 m/s² ramp) and v0 (the paper's V-REP-like dynamics)
stay registered with their behaviour, and the version is checked like any other argument."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import khepera_gym
from khepera_gym import _core
from khepera_gym.errors import ConfigError
from khepera_gym.pettingzoo import formation_v2
from khepera_gym.registration import registered_ids, resolve_env_id


def test_every_task_registers_each_of_its_versions_and_the_bare_id_is_the_latest() -> None:
    # The core says which versions each task has (from the one that added it to the latest);
    # every one of them is registered, and nothing else.
    for task, ids in registered_ids().items():
        versions = _core.task_versions(task)
        assert versions[-1] == _core.LATEST_VERSION, task
        assert [int(i.rsplit("-v", 1)[1]) for i in ids] == versions, task
        bare = ids[-1].rsplit("-v", 1)[0]
        assert resolve_env_id(bare) == ids[-1]
    latest = _core.LATEST_VERSION
    assert _core.task_versions("nav") == list(range(latest + 1))  # from v0, the paper's
    assert _core.task_versions("track") == list(range(1, latest + 1))  # added with v1
    assert "KheperaIV-Track-v0" not in gym.registry
    with pytest.raises(ConfigError, match="version"):
        gym.make("KheperaIV-Track-v2", version=0)


@pytest.mark.parametrize(
    ("env_id", "drive", "mode", "scene_solver"),
    [
        ("KheperaIV-Nav-v0", "kinematic", "ramp", "rapier"),
        ("KheperaIV-Nav-v1", "traction", "ramp", "rapier"),
        ("KheperaIV-Nav-v2", "traction", "profile", "rapier"),
        ("KheperaIV-Nav-v3", "traction", "profile", "disc"),
    ],
)
def test_each_id_builds_its_versions_defaults(
    env_id: str, drive: str, mode: str, scene_solver: str
) -> None:
    env = gym.make(env_id)
    assert f'drive = "{drive}"' in env.unwrapped.config_toml()
    assert f'mode = "{mode}"' in env.unwrapped.config_toml()
    assert f'scene_solver = "{scene_solver}"' in env.unwrapped.config_toml()
    envs = gym.make_vec(env_id, num_envs=2)
    assert f'drive = "{drive}"' in envs.unwrapped.config_toml()
    env.close()
    envs.close()


@pytest.mark.parametrize("version", [_core.LATEST_VERSION + 1, -1, 1.0, "1", True])
def test_an_unknown_version_is_a_config_error(version: object) -> None:
    with pytest.raises(ConfigError, match="version"):
        gym.make("KheperaIV-Nav-v2", version=version)


def test_each_versions_wheels_after_one_step_of_full_command() -> None:
    # v0: at the command within the step; v1: 0.203 m/s² for 50 ms (a plain ramp); v2 and v3:
    # K-Team's profile at Acc_Inc 40, 40 units of 0.678181 mm/s every 10 ms, for 50 ms.
    speeds = {}
    for version in (0, 1, 2, 3):
        env = gym.make("KheperaIV-Nav-v2", version=version)
        env.reset(seed=3)
        env.step(np.ones(2, np.float32))
        speeds[version] = env.unwrapped.sensor_readings()["wheel_speeds"][0]
        env.close()
    np.testing.assert_allclose(speeds[0], [0.813, 0.813], rtol=1e-6)
    np.testing.assert_allclose(speeds[1], [0.2034543 * 0.05] * 2, rtol=1e-5)
    np.testing.assert_allclose(speeds[2], [40 * 0.678181e-3 / 0.01 * 0.05] * 2, rtol=1e-5)
    np.testing.assert_array_equal(speeds[3], speeds[2])


def test_a_preset_sets_the_drive_real_programs_set_and_refuses_explicit_keys() -> None:
    presets = khepera_gym.motor_presets()
    assert {"kteam_default", "kteam_braitenberg", "khepera_gym_v2", "speed_mode"} <= set(presets)
    env = gym.make("KheperaIV-Nav-v2", preset="kteam_braitenberg")
    assert "acc_inc = 10" in env.unwrapped.config_toml()
    env.close()
    with pytest.raises(ConfigError, match=r"motors\.acc_inc"):
        gym.make("KheperaIV-Nav-v2", preset="kteam_default", acc_inc=7)
    with pytest.raises(ConfigError, match=r"robot\.wheel_accel_limit.*motors\.acc_inc"):
        gym.make("KheperaIV-Nav-v2", wheel_accel_limit=0.678)
    par = formation_v2.parallel_env(motors={"preset": "speed_mode"})
    assert 'mode = "speed"' in par.unwrapped.config_toml()
    par.close()


def test_odometry_localization_exposes_the_estimate_next_to_the_truth() -> None:
    # From the centre, (0.6, 0.4) circles with a radius of about 0.27 m: clear of the walls.
    env = gym.make("KheperaIV-Nav-v2", localization="odometry", start=[0.0, 0.0, 0.0])
    env.reset(seed=4)
    start = env.unwrapped.sensor_readings()["odometry"][0]
    np.testing.assert_allclose(start, env.unwrapped.poses()[0], atol=1e-6)
    for _ in range(100):
        env.step(np.array([0.6, 0.4], np.float32))
    estimate = env.unwrapped.sensor_readings()["odometry"][0]
    truth = env.unwrapped.poses()[0]
    assert 0 < np.linalg.norm(estimate[:2] - truth[:2]) < 0.2  # drifts, within the errors' scale
    assert "odometry" not in gym.make("KheperaIV-Nav-v2").unwrapped.sensor_readings()
    env.close()


@pytest.mark.parametrize("key", ["action_delay", "observation_delay"])
def test_delays_are_checked(key: str) -> None:
    with pytest.raises(ConfigError, match=f"task.{key}: must be >= 0, <= 100, got 101"):
        gym.make("KheperaIV-Nav-v2", **{key: 101})
    with pytest.raises(ConfigError, match=f"task.{key}"):
        gym.make("KheperaIV-Nav-v2", **{key: -1})
