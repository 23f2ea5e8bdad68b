"""The IMU through the public API: carried only on request, its observation block and raw
readings in the real robot's units, reproducible per seed and restored with the state, and bad
keys rejected by name. Its physics (gravity, ramp, circle, impact) is specified in tests/imu.rs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym.errors import ConfigError

IMU = {"carry": ["ir", "us", "gyro", "imu"], "observe": ["ir", "us", "imu"]}


def test_the_imu_is_carried_only_on_request() -> None:
    env = gym.make(LATEST["nav"])
    env.reset(seed=0)
    assert "accel_g" not in env.unwrapped.sensor_readings()
    assert "imu" not in env.unwrapped.obs_layout()


def test_at_rest_the_block_and_readings_show_gravity_on_z() -> None:
    env = gym.make(LATEST["nav"], **IMU)
    obs, _ = env.reset(seed=1)
    block = env.unwrapped.obs_layout()["imu"]
    assert block.stop - block.start == 6
    assert env.observation_space.shape == (18 + 6,)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(2, np.float32))
    readings = env.unwrapped.sensor_readings()
    assert readings["accel_raw"].shape == (1, 3)
    assert readings["imu_gyro"].shape == (1, 3)
    # -1 g on z over the 2 g full scale, within 5 noise sigmas (2 mg) and a count.
    np.testing.assert_allclose(readings["accel_g"][0], [0.0, 0.0, -1.0], atol=5 * 0.002 + 0.001)
    np.testing.assert_allclose(obs[block], [0, 0, -0.5, 0, 0, 0], atol=(5 * 0.002 + 0.001) / 2)
    np.testing.assert_allclose(readings["accel_g"], readings["accel_raw"] * 0.001, rtol=1e-6)


def _trace(env: gym.Env, steps: int) -> list[bytes]:
    rng = np.random.default_rng(0)
    out = []
    for _ in range(steps):
        obs, *_ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out.append(obs.tobytes() + env.unwrapped.sensor_readings()["accel_raw"].tobytes())
    return out


def test_same_seed_same_readings_and_a_restored_state_continues_bit_for_bit() -> None:
    a, b = gym.make(LATEST["nav"], **IMU), gym.make(LATEST["nav"], **IMU)
    a.reset(seed=3)
    b.reset(seed=3)
    assert _trace(a, 30) == _trace(b, 30)
    state = a.unwrapped.get_state()
    ahead = _trace(a, 30)
    b.unwrapped.set_state(state)
    assert _trace(b, 30) == ahead


def test_a_vector_world_reads_like_the_single_env_of_its_seed() -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=2, **IMU)
    single = gym.make(LATEST["nav"], **IMU)
    envs.reset(seed=10)
    single.reset(seed=11)
    for _ in range(20):
        action = np.array([0.8, 0.6], np.float32)
        vobs, *_ = envs.step(np.stack([action, action]))
        sobs, *_ = single.step(action)
        np.testing.assert_array_equal(vobs[1], sobs)


@pytest.mark.parametrize("key", ["imu_accel_noise_sigma", "imu_gyro_noise_sigma"])
def test_a_negative_noise_is_a_config_error_naming_the_key(key: str) -> None:
    with pytest.raises(ConfigError, match=rf"sensors\.{key}"):
        gym.make(LATEST["nav"], **IMU, **{key: -1.0})
