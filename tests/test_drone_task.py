"""KheperaIV-DroneFollow through the public API: the PD pursuit keeps the robot in view where a
random policy loses it; seeds reproduce episodes bit for bit, a vector world matches the single
env of its seed, a saved state continues identically; the PettingZoo form passes PettingZoo's
API test; bad keys raise ConfigError naming them. The model's physics: tests/drone.rs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST
from pettingzoo.test import parallel_api_test

from khepera_gym.envs import dronefollow_heuristic
from khepera_gym.errors import ConfigError
from khepera_gym.pettingzoo import drone_follow_v1


def _episode(env: gym.Env, seed: int, policy) -> dict:
    obs, _ = env.reset(seed=seed)
    while True:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            return info["episode_stats"]


def test_pursuit_keeps_the_robot_in_view_and_random_flight_loses_it() -> None:
    env = gym.make(LATEST["dronefollow"])
    rng = np.random.default_rng(0)
    for seed in range(5):
        stats = _episode(env, seed, dronefollow_heuristic)
        # In view all along, within a few cm: the PD lags a robot accelerating by a by a / k_p
        # (about 4 cm for its turns), far inside the 0.29 m footprint (tests/drone.rs).
        assert stats["in_view_share"] == 1.0 and stats["length"] == 800
        assert stats["horizontal_error_rms"] < 0.05
        lost = _episode(env, seed, lambda _: rng.uniform(-1, 1, 2).astype(np.float32))
        # A random command drifts at up to 1 m/s: the robot leaves the 0.29 m footprint within
        # a second or two and the episode ends 3 s later.
        assert lost["length"] < 800 and lost["in_view_share"] < 0.9


def _trace(env: gym.Env, seed: int, steps: int) -> list[bytes]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(steps):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, reward, terminated, truncated, _ = env.step(action)
        out.append(obs.tobytes() + np.float32(reward).tobytes())
        if terminated or truncated:
            env.reset()
    return out


@pytest.mark.parametrize("driver", ["scripted", "agent"])
def test_seeds_reproduce_and_a_saved_state_continues_bit_for_bit(driver: str) -> None:
    # With the agent driver the trace drives the robot too (and its reward is in the mean).
    a, b = (
        gym.make(LATEST["dronefollow"], driver=driver),
        gym.make(LATEST["dronefollow"], driver=driver),
    )
    a.reset(seed=7)
    b.reset(seed=7)
    assert _trace(a, 1, 100) == _trace(b, 1, 100)
    state = a.unwrapped.get_state()
    ahead = _trace(a, 2, 100)
    b.unwrapped.set_state(state)
    assert _trace(b, 2, 100) == ahead


def test_a_vector_world_matches_the_single_env_of_its_seed() -> None:
    envs = gym.make_vec(LATEST["dronefollow"], num_envs=3)
    single = gym.make(LATEST["dronefollow"])
    obs, _ = envs.reset(seed=20)
    single_obs, _ = single.reset(seed=22)
    np.testing.assert_array_equal(obs[2], single_obs)
    for _ in range(50):
        obs, *_ = envs.step(dronefollow_heuristic(obs))
        single_obs, *_ = single.step(dronefollow_heuristic(single_obs))
        np.testing.assert_array_equal(obs[2], single_obs)


def test_the_pettingzoo_env_passes_the_api_test() -> None:
    env = drone_follow_v1.parallel_env()
    parallel_api_test(env, num_cycles=200)
    observations, _ = env.reset(seed=0)
    assert list(observations) == ["drone"]


@pytest.mark.parametrize(
    ("key", "value"),
    [("tilt_max", 2.0), ("fov", -1.0), ("route_points", 99), ("search_altitude", 0.1)],
)
def test_a_bad_key_is_a_config_error_naming_it(key: str, value: float) -> None:
    with pytest.raises(ConfigError, match=rf"drone\.{key}"):
        gym.make(LATEST["dronefollow"], **{key: value})


def _waypoints_reached(env, seed: int, policies: dict) -> tuple[int, dict, dict]:
    """Runs one PettingZoo episode; returns the robot's waypoint switches (from ``goals()``),
    the episode's statistics and each agent's return."""
    observations, _ = env.reset(seed=seed)
    goal = env.goals()[0].copy()
    switches, returns, stats = 0, dict.fromkeys(env.agents, 0.0), {}
    while env.agents:
        actions = {agent: policies[agent](observations[agent]) for agent in env.agents}
        observations, rewards, _, _, infos = env.step(actions)
        for agent, reward in rewards.items():
            returns[agent] += reward
        if len(env.goals()) and not np.array_equal(env.goals()[0], goal):
            switches += 1
            goal = env.goals()[0].copy()
        stats = next(iter(infos.values())).get("world_episode_stats", stats)  # the world's
    return switches, stats, returns


def test_an_agent_applying_the_script_s_law_drives_the_route_as_the_script_does() -> None:
    from khepera_gym.baselines import Braitenberg

    scripted = drone_follow_v1.parallel_env()
    driven = drone_follow_v1.parallel_env(driver="agent")
    assert driven.possible_agents == ["drone", "robot"]
    # The robot observes Nav's blocks toward its waypoint, after none of the drone's.
    assert list(driven.agent_obs_layout("robot"))[-4:] == [
        "goal_distance",
        "goal_bearing_sin",
        "goal_bearing_cos",
        "wheel_speeds",
    ]
    # The script's own law: position control (v_max 0.15 m/s, omega_max 1 rad/s, k_r 0.15 m,
    # no stop radius) then Braitenberg avoidance on the IR ring.
    law = Braitenberg(
        vmax=0.15, wmax=1.0, kr=0.15, stop_radius=0.0, layout=driven.agent_obs_layout("robot")
    )
    for seed in range(3):
        n_script, _, _ = _waypoints_reached(scripted, seed, {"drone": dronefollow_heuristic})
        idle, _, idle_returns = _waypoints_reached(
            driven, seed, {"drone": dronefollow_heuristic, "robot": lambda _: np.zeros(2, "f")}
        )
        n_agent, stats, returns = _waypoints_reached(
            driven, seed, {"drone": dronefollow_heuristic, "robot": law}
        )
        # 40 s at 0.15 m/s is 6 m: several waypoints of a route whose legs are about 0.8 m
        # (the mean distance between two uniform points of the 1.6 m square). The agent's
        # wheels go through the normalised action, so it drives the script's path to rounding
        # and reaches the same waypoints, give or take the last one.
        assert n_script >= 3 and abs(n_agent - n_script) <= 1
        assert stats["in_view_share"] == 1.0
        # A robot that stays put reaches no waypoint but the one it may start on (within
        # 0.1 m) and pays the time cost every step; the driving one earns the progress of every
        # leg and task.success_bonus (10) per waypoint.
        assert idle <= 1
        assert returns["robot"] > idle_returns["robot"] + (n_agent - idle) * 10.0


def test_the_agent_driver_passes_the_api_test_and_keeps_the_joint_env_consistent() -> None:
    parallel_api_test(drone_follow_v1.parallel_env(driver="agent"), num_cycles=200)
    env = gym.make(LATEST["dronefollow"], driver="agent")
    # The joint action: the drone's two numbers, then the robot's wheels.
    assert env.action_space.shape == (4,)
    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape and obs.shape[0] > 8
    with pytest.raises(ConfigError, match=r"drone\.driver"):
        gym.make(LATEST["dronefollow"], driver="autopilot")
