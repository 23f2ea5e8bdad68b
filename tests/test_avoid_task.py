"""The Avoid task: registration, Gymnasium conformance, random obstacles, the heuristic."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import AVOID_V0_ID, LATEST
from gymnasium.utils.env_checker import check_env

import khepera_gym
from khepera_gym.envs import AvoidEnv, avoid_heuristic, nav_heuristic
from khepera_gym.vector import AvoidVectorEnv, KheperaVectorEnv

ROBOT_RADIUS = 0.0704  # m
SPAWN_CLEARANCE = 0.05  # m, configs/avoid.toml [obstacles] spawn_clearance
OBSTACLE_COUNT = 10  # configs/avoid.toml [obstacles] count


def _distance_to_obstacle(point: np.ndarray, obstacle: dict) -> float:
    """Distance (m) from a point to an obstacle of ``scene()``, 0 inside it."""
    point = np.asarray(point, dtype=float)
    if obstacle["kind"] == "circle":
        return max(0.0, float(np.linalg.norm(point - obstacle["center"])) - obstacle["radius"])
    if obstacle["kind"] == "box":
        angle = obstacle["angle"]
        rotation = np.array([[np.cos(angle), np.sin(angle)], [-np.sin(angle), np.cos(angle)]])
        local = rotation @ (point - np.asarray(obstacle["center"]))
        outside = np.maximum(np.abs(local) - np.asarray(obstacle["half_extents"]), 0.0)
        return float(np.linalg.norm(outside))
    a, b = np.asarray(obstacle["a"]), np.asarray(obstacle["b"])
    t = np.clip((point - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return float(np.linalg.norm(point - (a + t * (b - a))))


def test_avoid_is_registered_with_entry_point_and_vector_entry_point() -> None:
    spec = gym.spec(LATEST["avoid"])
    assert spec.entry_point == "khepera_gym.envs:AvoidEnv"
    assert spec.vector_entry_point == "khepera_gym.vector:AvoidVectorEnv"
    assert spec.max_episode_steps is None
    env = gym.make(LATEST["avoid"])
    assert isinstance(env.unwrapped, AvoidEnv)
    assert env.unwrapped.max_episode_steps == 600
    env.close()


def test_avoid_passes_the_gymnasium_env_checker_without_warnings() -> None:
    env = gym.make(LATEST["avoid"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_avoid_spaces_and_layout_are_navs() -> None:
    env = gym.make(LATEST["avoid"])
    nav = gym.make(LATEST["nav"])
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert env.observation_space.shape == (18,)
    assert khepera_gym.obs_layout("avoid") == khepera_gym.obs_layout("nav")
    assert env.unwrapped.obs_layout() == khepera_gym.obs_layout("avoid")
    np.testing.assert_array_equal(env.observation_space.low, nav.observation_space.low)
    np.testing.assert_array_equal(env.observation_space.high, nav.observation_space.high)
    env.close()
    nav.close()


def test_make_vec_avoid_gives_native_rust_vector_env() -> None:
    envs = gym.make_vec(LATEST["avoid"], num_envs=3, num_threads=1)
    assert isinstance(envs, AvoidVectorEnv)
    assert not isinstance(envs, gym.vector.SyncVectorEnv)
    assert envs.single_action_space.shape == (2,)
    observations, _ = envs.reset(seed=0)
    assert observations.shape == (3, 18)
    assert envs.scene(2)["obstacles"] != envs.scene(0)["obstacles"]
    envs.close()


def test_avoid_vector_env_refuses_another_task() -> None:
    with pytest.raises(khepera_gym.errors.ConfigError, match="avoid"):
        AvoidVectorEnv(2, task="nav")
    assert isinstance(KheperaVectorEnv(2, task="avoid"), KheperaVectorEnv)


def test_random_obstacles_change_between_episodes_and_repeat_with_the_seed() -> None:
    env = gym.make(LATEST["avoid"])
    layouts = []
    for seed in (3, None, 3, 4):
        env.reset(seed=seed)
        scene = env.unwrapped.scene()
        assert len(scene["obstacles"]) == OBSTACLE_COUNT
        assert {o["kind"] for o in scene["obstacles"]} <= {"circle", "box", "segment"}
        layouts.append(scene["obstacles"])
    seeded, continued, seeded_again, other_seed = layouts
    assert seeded == seeded_again
    assert continued != seeded
    assert other_seed != seeded
    env.close()


def test_random_obstacles_have_all_kinds_over_a_few_episodes() -> None:
    env = gym.make(LATEST["avoid"])
    kinds = set()
    for seed in range(5):
        env.reset(seed=seed)
        kinds |= {o["kind"] for o in env.unwrapped.scene()["obstacles"]}
    assert kinds == {"circle", "box", "segment"}
    env.close()


def test_no_obstacle_overlaps_the_start_or_the_goal() -> None:
    env = gym.make(LATEST["avoid"])
    clearance = ROBOT_RADIUS + SPAWN_CLEARANCE - 1e-4
    for seed in range(30):
        env.reset(seed=seed)
        start = env.unwrapped.poses()[0, :2]
        goal = env.unwrapped.goals()[0]
        assert np.linalg.norm(goal - start) >= 1.0 - 1e-6  # spawn.min_goal_distance
        for obstacle in env.unwrapped.scene()["obstacles"]:
            assert _distance_to_obstacle(start, obstacle) >= clearance, (seed, obstacle)
            assert _distance_to_obstacle(goal, obstacle) >= clearance, (seed, obstacle)
    env.close()


def test_robot_never_passes_through_obstacles_under_random_actions() -> None:
    env = gym.make(LATEST["avoid"], max_steps=200)
    rng = np.random.default_rng(0)
    for seed in range(3):
        env.reset(seed=seed)
        obstacles = env.unwrapped.scene()["obstacles"]
        for _ in range(200):
            *_, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            centre = env.unwrapped.poses()[0, :2]
            for obstacle in obstacles:
                # Contacts allow a few millimetres of penetration, never the body's half.
                assert _distance_to_obstacle(centre, obstacle) > ROBOT_RADIUS - 0.01
            if terminated or truncated:
                break
    env.close()


def test_avoid_heuristic_reaches_most_goals_and_beats_position_control() -> None:
    envs = gym.make_vec(AVOID_V0_ID, num_envs=32, num_threads=2)  # the paper's gains' dynamics
    results = {}
    for name, policy in (("avoid", avoid_heuristic), ("nav", nav_heuristic)):
        observations, _ = envs.reset(seed=100)
        success = np.zeros(32, dtype=bool)
        ended = np.zeros(32, dtype=bool)
        for _ in range(envs.max_episode_steps):
            observations, _, terminations, truncations, infos = envs.step(policy(observations))
            first_end = (terminations | truncations) & ~ended
            if first_end.any():
                success[first_end] = infos["episode_stats"]["success"][first_end]
            ended |= terminations | truncations
        assert ended.all()
        results[name] = success.mean()
    envs.close()
    assert results["avoid"] >= 0.8, results
    assert results["avoid"] > results["nav"], results


def test_avoid_heuristic_matches_nav_heuristic_with_nothing_in_sight() -> None:
    observation = np.zeros(18, dtype=np.float32)
    observation[13] = 1.0  # goal_distance
    observation[15] = 1.0  # goal_bearing_cos
    np.testing.assert_array_equal(avoid_heuristic(observation), nav_heuristic(observation))
    observation[3] = 0.5  # obstacle straight ahead: turn right (left wheel faster)
    left, right = avoid_heuristic(observation)
    assert left > right
    batch = np.stack([observation, observation])
    assert avoid_heuristic(batch).shape == (2, 2)


def test_avoid_episode_end_info_has_episode_stats() -> None:
    env = gym.make(LATEST["avoid"], max_steps=5)
    env.reset(seed=0)
    for _ in range(5):
        *_, truncated, info = env.step(np.zeros(2, np.float32))
    assert truncated
    stats = info["episode_stats"]
    assert set(stats) == {"return", "length", "success", "path_length", "collisions"}
    assert stats["length"] == 5 and type(stats["collisions"]) is int
    assert info["is_success"] is False
    env.close()
