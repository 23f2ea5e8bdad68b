"""The Nav task: observations mean what the docstring says, rewards, episode ends, the heuristic."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST, NAV_V0_ID

from khepera_gym import obs_layout
from khepera_gym.envs import NavEnv, nav_heuristic
from khepera_gym.vector import KheperaVectorEnv

LAYOUT = obs_layout("nav")
GOAL_RADIUS = 0.05  # m, configs/nav.toml [task] goal_radius
PROGRESS_WEIGHT = 10.0
TIME_COST = 0.01
SUCCESS_BONUS = 10.0
MAX_WHEEL_SPEED = 0.813  # m/s


def _goal_distance(observation: np.ndarray) -> float:
    return float(observation[LAYOUT["goal_distance"]][0])


def test_nav_heuristic_reaches_the_goal_in_most_seeded_episodes() -> None:
    env = gym.make(NAV_V0_ID)  # the paper's gains, on the dynamics they were tuned for
    successes = 0
    episodes = 50
    for seed in range(episodes):
        observation, _ = env.reset(seed=seed)
        while True:
            observation, _, terminated, truncated, info = env.step(nav_heuristic(observation))
            if terminated or truncated:
                break
        assert info["is_success"] == terminated == info["episode_stats"]["success"]
        successes += terminated
    env.close()
    assert successes >= 0.95 * episodes, f"{successes}/{episodes} episodes reached the goal"


def test_nav_heuristic_is_batched() -> None:
    envs = KheperaVectorEnv(6)
    observations, _ = envs.reset(seed=3)
    actions = nav_heuristic(observations)
    assert actions.shape == (6, 2) and actions.dtype == np.float32
    assert np.all(np.abs(actions) <= 1.0)
    for index in range(6):
        np.testing.assert_array_equal(actions[index], nav_heuristic(observations[index]))
    envs.close()


def test_nav_heuristic_turns_toward_the_goal() -> None:
    observation = np.zeros(18, dtype=np.float32)
    observation[LAYOUT["goal_distance"]] = 1.0
    observation[LAYOUT["goal_bearing_cos"]] = 1.0
    left, right = nav_heuristic(observation)
    assert left == pytest.approx(right) == pytest.approx(0.3 / MAX_WHEEL_SPEED)
    observation[LAYOUT["goal_bearing_sin"]] = 1.0  # goal to the left
    observation[LAYOUT["goal_bearing_cos"]] = 0.0
    left, right = nav_heuristic(observation)
    assert right > left
    observation[LAYOUT["goal_distance"]] = 0.0  # on the goal: stop
    observation[LAYOUT["goal_bearing_sin"]] = 0.0
    observation[LAYOUT["goal_bearing_cos"]] = 1.0
    np.testing.assert_array_equal(nav_heuristic(observation), [0.0, 0.0])


def test_goal_observations_match_ground_truth_poses(nav_env: gym.Env) -> None:
    observation, _ = nav_env.reset(seed=8)
    for _ in range(20):
        x, y, theta = nav_env.unwrapped.poses()[0]
        goal_x, goal_y = nav_env.unwrapped.goals()[0]
        distance = np.hypot(goal_x - x, goal_y - y)
        bearing = np.arctan2(goal_y - y, goal_x - x) - theta
        assert _goal_distance(observation) == pytest.approx(distance, abs=1e-5)
        assert observation[LAYOUT["goal_bearing_sin"]][0] == pytest.approx(
            np.sin(bearing), abs=1e-5
        )
        assert observation[LAYOUT["goal_bearing_cos"]][0] == pytest.approx(
            np.cos(bearing), abs=1e-5
        )
        observation, *_ = nav_env.step(np.array([0.3, 0.5], np.float32))


def test_wheel_speed_observations_follow_commands() -> None:
    nav_env = gym.make(NAV_V0_ID)  # v0: the wheels reach their command within the step
    nav_env.reset(seed=8)
    observation, *_ = nav_env.step(np.array([0.25, -0.5], np.float32))
    np.testing.assert_allclose(observation[LAYOUT["wheel_speeds"]], [0.25, -0.5], atol=1e-5)
    speeds = nav_env.unwrapped.sensor_readings()["wheel_speeds"][0]
    np.testing.assert_allclose(speeds, [0.25 * MAX_WHEEL_SPEED, -0.5 * MAX_WHEEL_SPEED], atol=1e-4)
    nav_env.close()


def test_commands_below_the_speed_floor_do_not_move_the_robot(nav_env: gym.Env) -> None:
    nav_env.reset(seed=8)
    start = nav_env.unwrapped.poses().copy()
    tiny = 0.002 / MAX_WHEEL_SPEED  # 2 mm/s, under the real controller's 3 mm/s floor
    for _ in range(10):
        observation, *_ = nav_env.step(np.array([tiny, tiny], np.float32))
    np.testing.assert_array_equal(nav_env.unwrapped.poses(), start)
    np.testing.assert_array_equal(observation[LAYOUT["wheel_speeds"]], [0.0, 0.0])


def test_reward_is_progress_minus_time_cost_and_positive_toward_goal() -> None:
    env = gym.make(NAV_V0_ID, collision_penalty=0.0)  # where the heuristic reaches seed 12's goal
    observation, _ = env.reset(seed=12)
    positive_rewards = 0
    while True:
        previous_distance = _goal_distance(observation)
        observation, reward, terminated, truncated, _ = env.step(nav_heuristic(observation))
        progress = previous_distance - _goal_distance(observation)
        expected = PROGRESS_WEIGHT * progress - TIME_COST + (SUCCESS_BONUS if terminated else 0.0)
        assert reward == pytest.approx(expected, abs=1e-4)
        if progress > 0.002:
            assert reward > 0.0
            positive_rewards += 1
        if terminated or truncated:
            break
    assert terminated
    assert positive_rewards > 10
    env.close()


def test_reward_is_negative_when_driving_away_from_goal() -> None:
    env = gym.make(LATEST["nav"], collision_penalty=0.0)
    observation, _ = env.reset(seed=12)
    # Turn until the goal is behind, then drive straight on: the goal distance grows.
    for _ in range(200):
        if observation[LAYOUT["goal_bearing_cos"]][0] < -0.95:
            break
        observation, *_ = env.step(np.array([-0.3, 0.3], np.float32))
    previous_distance = _goal_distance(observation)
    observation, reward, *_ = env.step(np.array([0.5, 0.5], np.float32))
    assert _goal_distance(observation) > previous_distance
    assert reward < 0.0
    env.close()


def test_terminated_on_success_with_episode_statistics(nav_env: gym.Env) -> None:
    observation, _ = nav_env.reset(seed=21)
    total_reward, steps = 0.0, 0
    while True:
        observation, reward, terminated, truncated, info = nav_env.step(nav_heuristic(observation))
        total_reward += reward
        steps += 1
        if terminated or truncated:
            break
        assert info == {}
    assert terminated and not truncated
    assert _goal_distance(observation) < GOAL_RADIUS
    x, y, _ = nav_env.unwrapped.poses()[0]
    assert np.hypot(*(nav_env.unwrapped.goals()[0] - [x, y])) < GOAL_RADIUS
    episode = info["episode_stats"]
    assert set(episode) == {"return", "length", "success", "path_length", "collisions"}
    assert episode["success"] is True and info["is_success"] is True
    assert episode["length"] == steps
    assert episode["return"] == pytest.approx(total_reward, abs=1e-3)
    assert type(episode["return"]) is float and type(episode["length"]) is int
    assert episode["path_length"] > 0.5 - GOAL_RADIUS  # the goal starts at least 0.5 m away
    assert episode["collisions"] == 0


def test_truncated_at_max_steps_when_standing_still(nav_env: gym.Env) -> None:
    nav_env.reset(seed=2)
    assert nav_env.unwrapped.max_episode_steps == 400
    for step in range(1, 401):
        _, reward, terminated, truncated, info = nav_env.step(np.zeros(2, np.float32))
        assert not terminated
        assert reward == pytest.approx(-TIME_COST)
        assert truncated == (step == 400)
    assert info["episode_stats"]["length"] == 400
    assert info["episode_stats"]["success"] is False and info["is_success"] is False
    assert info["episode_stats"]["path_length"] == 0.0
    assert info["episode_stats"]["return"] == pytest.approx(-400 * TIME_COST, abs=1e-3)


def test_driving_into_a_wall_counts_collisions_and_penalises() -> None:
    env = NavEnv(max_steps=200, terminate_on_collision=False)
    env.reset(seed=5)
    collided_rewards = []
    for _ in range(200):
        _, reward, terminated, truncated, info = env.step(np.array([1.0, 1.0], np.float32))
        if terminated or truncated:
            break
        collided_rewards.append(reward)
    assert not terminated  # seed 5 does not start facing its goal
    assert info["episode_stats"]["collisions"] > 0
    assert min(collided_rewards) <= -(TIME_COST + 0.1) + 1e-4
    x, y, _ = env.poses()[0]
    assert abs(x) <= 1.0 - 0.0704 + 1e-3 and abs(y) <= 1.0 - 0.0704 + 1e-3  # walls hold
    ir = env.sensor_readings()["ir_raw"][0]
    assert ir.max() > 500  # touching the wall saturates the front IR
    env.close()


def test_vector_episode_statistics_only_at_episode_end_with_masks() -> None:
    num_envs, max_steps = 6, 40
    envs = KheperaVectorEnv(num_envs, max_steps=max_steps)
    observations, _ = envs.reset(seed=30)
    ended_before = np.zeros(num_envs, dtype=bool)
    episodes = 0
    for _ in range(3 * max_steps):
        actions = nav_heuristic(observations)
        actions[0] = 0.0  # world 0 stands still and can only be truncated
        observations, rewards, terminations, truncations, infos = envs.step(actions)
        ended = terminations | truncations
        np.testing.assert_array_equal(rewards[ended_before], 0.0)  # autoreset steps
        assert not np.any(ended & ended_before)
        if not ended.any():
            assert infos == {}
        else:
            episodes += int(ended.sum())
            np.testing.assert_array_equal(infos["_episode_stats"], ended)
            episode = infos["episode_stats"]
            for key in ("return", "length", "success", "path_length", "collisions"):
                np.testing.assert_array_equal(episode[f"_{key}"], ended)
                assert episode[key].shape == (num_envs,)
                np.testing.assert_array_equal(episode[key][~ended], 0)
            np.testing.assert_array_equal(episode["success"][ended], terminations[ended])
            assert np.all(episode["length"][ended] >= 1)
            assert np.all(episode["length"][ended] <= max_steps)
            if ended[0]:
                assert truncations[0] and episode["length"][0] == max_steps
        ended_before = ended
    assert episodes > num_envs
    envs.close()


def test_vector_autoreset_step_returns_a_new_start() -> None:
    envs = KheperaVectorEnv(2, max_steps=5)
    envs.reset(seed=0)
    zeros = np.zeros((2, 2), np.float32)
    for _ in range(5):
        _, _, _, truncations, infos = envs.step(zeros)
    assert truncations.all() and "episode_stats" in infos
    before = envs.poses().copy()
    _, rewards, terminations, truncations, infos = envs.step(np.ones((2, 2), np.float32))
    assert infos == {}
    np.testing.assert_array_equal(rewards, 0.0)
    assert not terminations.any() and not truncations.any()
    assert not np.array_equal(envs.poses(), before)  # respawned, not driven
    _, _, _, truncations, _ = envs.step(zeros)
    assert not truncations.any()
    envs.close()
