"""The Formation task: spaces, the paper's Fig. 7 cross, observations, rewards, the heuristic."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import FORMATION_V0_ID, LATEST
from gymnasium.utils.env_checker import check_env

import khepera_gym
from khepera_gym.envs import (
    FormationEnv,
    avoid_heuristic,
    formation_follower_heuristic,
    formation_heuristic,
)
from khepera_gym.errors import ActionError
from khepera_gym.vector import FormationVectorEnv

N_FOLLOWERS = 4  # configs/formation.toml [formation] n_followers
FOLLOWER_OBS_DIM = 23
NAV_OBS_DIM = 18
SPACING = 0.5  # m, configs/formation.toml formation.spacing
FIG7_START = (-0.85, 0.0, 0.0)  # configs/paper_fig7.toml spawn.start
FIG7_GOAL = (0.85, 0.2)


def _run_episode(env: gym.Env, policy, seed: int) -> tuple[dict, list[np.ndarray]]:
    observation, _ = env.reset(seed=seed)
    errors = []
    while True:
        observation, _, terminated, truncated, info = env.step(policy(observation))
        targets = env.unwrapped.formation_targets()
        errors.append(np.linalg.norm(env.unwrapped.poses()[1:, :2] - targets, axis=1))
        if terminated or truncated:
            return info, errors


def test_formation_is_registered_with_entry_point_and_vector_entry_point() -> None:
    spec = gym.spec(LATEST["formation"])
    assert spec.entry_point == "khepera_gym.envs:FormationEnv"
    assert spec.vector_entry_point == "khepera_gym.vector:FormationVectorEnv"
    env = gym.make(LATEST["formation"])
    assert isinstance(env.unwrapped, FormationEnv)
    assert env.unwrapped.n_robots == N_FOLLOWERS + 1
    assert env.unwrapped.max_episode_steps == 800
    env.close()


@pytest.mark.parametrize("overrides", [{}, {"leader": "agent"}, {"shape": "wedge"}])
def test_formation_passes_the_gymnasium_env_checker_without_warnings(overrides: dict) -> None:
    env = gym.make(LATEST["formation"], **overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_action_space_is_two_wheels_per_follower_plus_an_agent_leader() -> None:
    env = gym.make(LATEST["formation"])
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2 * N_FOLLOWERS,), np.float32)
    assert env.observation_space.shape == (FOLLOWER_OBS_DIM * N_FOLLOWERS,)
    env.close()
    for overrides in ({"leader": "agent"}, {"formation": {"leader": "agent"}}):
        env = gym.make(LATEST["formation"], **overrides)
        assert env.action_space.shape == (2 + 2 * N_FOLLOWERS,)
        assert env.observation_space.shape == (NAV_OBS_DIM + FOLLOWER_OBS_DIM * N_FOLLOWERS,)
        env.close()
    env = gym.make(LATEST["formation"], n_followers=2, shape="line")
    assert env.action_space.shape == (4,)
    env.close()


def test_obs_layout_names_each_followers_blocks() -> None:
    layout = khepera_gym.obs_layout("formation")
    block_names = [
        "ir",
        "us",
        "target_offset",
        "leader_offset",
        "leader_heading",
        "leader_velocity",
        "wheel_speeds",
    ]
    expected = [f"follower_{k}/{name}" for k in range(N_FOLLOWERS) for name in block_names]
    assert list(layout) == expected
    assert layout["follower_1/ir"] == slice(FOLLOWER_OBS_DIM, FOLLOWER_OBS_DIM + 8)
    end = N_FOLLOWERS * FOLLOWER_OBS_DIM
    assert layout["follower_3/wheel_speeds"] == slice(end - 2, end)
    env = gym.make(LATEST["formation"], leader="agent")
    agent_layout = env.unwrapped.obs_layout()
    assert list(agent_layout)[:6] == [f"leader/{name}" for name in khepera_gym.obs_layout("nav")]
    assert agent_layout["follower_0/ir"] == slice(18, 26)
    env.close()


def test_every_follower_block_has_the_same_bounds_for_parameter_sharing() -> None:
    env = gym.make(LATEST["formation"])
    space = env.observation_space
    blocks = np.split(np.stack([space.low, space.high]), N_FOLLOWERS, axis=1)
    for block in blocks[1:]:
        np.testing.assert_array_equal(block, blocks[0])
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    env.close()


def test_paper_fig7_starts_the_cross_around_the_leader() -> None:
    env = gym.make(LATEST["formation"], config="paper_fig7")
    env.reset(seed=0)
    poses = env.unwrapped.poses()
    np.testing.assert_allclose(poses[0], FIG7_START, atol=1e-6)
    np.testing.assert_allclose(env.unwrapped.goals()[0], FIG7_GOAL, atol=1e-6)
    x, y, heading = FIG7_START
    for k, beta in enumerate((0.0, np.pi / 2, np.pi, -np.pi / 2)):  # ahead, left, behind, right
        expected = (x + SPACING * np.cos(beta + heading), y + SPACING * np.sin(beta + heading))
        np.testing.assert_allclose(poses[k + 1, :2], expected, atol=1e-6)
        assert poses[k + 1, 2] == pytest.approx(heading, abs=1e-6)
    np.testing.assert_allclose(env.unwrapped.formation_targets(), poses[1:, :2], atol=1e-6)
    assert len(env.unwrapped.scene()["obstacles"]) == 4
    env.close()


def test_followers_start_on_eq_12_targets_for_a_turned_leader() -> None:
    heading = 0.7
    env = gym.make(LATEST["formation"], config="paper_fig7", spawn={"start": [-0.6, 0.1, heading]})
    observation, _ = env.reset(seed=1)
    poses = env.unwrapped.poses()
    leader = poses[0]
    for k, beta in enumerate((0.0, np.pi / 2, np.pi, -np.pi / 2)):
        angle = beta + heading
        expected = leader[:2] + SPACING * np.array([np.cos(angle), np.sin(angle)])
        np.testing.assert_allclose(poses[k + 1, :2], expected, atol=1e-6)
    np.testing.assert_allclose(env.unwrapped.formation_targets(), poses[1:, :2], atol=1e-6)
    layout = env.unwrapped.obs_layout()
    for k in range(N_FOLLOWERS):
        np.testing.assert_allclose(observation[layout[f"follower_{k}/target_offset"]], 0, atol=1e-5)
    env.close()


def test_target_offset_is_the_target_in_the_followers_frame() -> None:
    env = gym.make(LATEST["formation"])
    observation, _ = env.reset(seed=5)
    layout = env.unwrapped.obs_layout()
    rng = np.random.default_rng(5)
    for _ in range(30):
        observation, *_ = env.step(rng.uniform(-0.5, 0.5, 8).astype(np.float32))
        poses, targets = env.unwrapped.poses(), env.unwrapped.formation_targets()
        for k in range(N_FOLLOWERS):
            x, y, theta = poses[k + 1]
            dx, dy = targets[k] - (x, y)
            ahead = np.cos(theta) * dx + np.sin(theta) * dy
            left = -np.sin(theta) * dx + np.cos(theta) * dy
            np.testing.assert_allclose(
                observation[layout[f"follower_{k}/target_offset"]], (ahead, left), atol=1e-4
            )
    env.close()


def test_joint_reward_is_the_mean_of_the_followers_negative_errors() -> None:
    env = gym.make(LATEST["formation"])
    env.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(20):
        _, reward, *_ = env.step(rng.uniform(-1, 1, 8).astype(np.float32))
        agent_rewards = env.unwrapped.agent_rewards()
        errors = np.linalg.norm(
            env.unwrapped.poses()[1:, :2] - env.unwrapped.formation_targets(), axis=1
        )
        assert agent_rewards.shape == (N_FOLLOWERS,)
        assert reward == pytest.approx(float(np.mean(agent_rewards)), abs=1e-6)
        # error_weight 1; no contacts this early in an open 3 m arena
        np.testing.assert_allclose(agent_rewards, -errors, atol=1e-4)
    env.close()


def test_formation_error_grows_when_followers_stand_still() -> None:
    env = gym.make(LATEST["formation"], max_steps=200)
    info, errors = _run_episode(env, lambda obs: np.zeros(8, np.float32), seed=0)
    mean_errors = np.array([e.mean() for e in errors])
    assert mean_errors[0] < 0.02
    assert mean_errors[50] > 0.2 and mean_errors[-1] > mean_errors[50] + 0.2
    stats = info["episode_stats"]
    assert stats["formation_error_max"] == pytest.approx(np.max(errors), rel=1e-4)
    assert stats["formation_error_mean"] == pytest.approx(np.mean(errors), rel=1e-3)
    env.close()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_leader_follower_heuristic_keeps_the_formation(seed: int) -> None:
    """LeaderFollower toward target_offset keeps the formation, so the observation is useful."""
    env = gym.make(FORMATION_V0_ID)  # the paper's gains, on the dynamics they were tuned for
    info, errors = _run_episode(env, formation_heuristic, seed)
    stats = info["episode_stats"]
    assert stats["formation_error_mean"] < 0.1, stats
    assert stats["formation_error_mean"] == pytest.approx(np.mean(errors), rel=1e-3)
    assert set(stats) >= {"formation_error_mean", "formation_error_max", "success", "length"}
    env.close()


def test_agent_leader_is_driven_by_the_first_action_pair() -> None:
    env = gym.make(LATEST["formation"], leader="agent")
    observation, _ = env.reset(seed=3)
    start = env.unwrapped.poses()[0].copy()
    for _ in range(10):
        observation, *_ = env.step(np.zeros(10, np.float32))
    np.testing.assert_allclose(env.unwrapped.poses()[0], start, atol=1e-6)  # no script moves it
    action = formation_heuristic(observation)
    np.testing.assert_array_equal(action[:2], avoid_heuristic(observation[:NAV_OBS_DIM]))
    for _ in range(20):
        observation, *_ = env.step(formation_heuristic(observation))
    assert np.linalg.norm(env.unwrapped.poses()[0, :2] - start[:2]) > 0.05
    assert env.unwrapped.agent_rewards().shape == (N_FOLLOWERS + 1,)
    env.close()


def test_formation_heuristic_splits_blocks_and_is_batched() -> None:
    env = gym.make(LATEST["formation"])
    observation, _ = env.reset(seed=0)
    observation, *_ = env.step(np.full(8, 0.3, np.float32))
    action = formation_heuristic(observation)
    assert action.shape == (8,) and action.dtype == np.float32
    blocks = observation.reshape(N_FOLLOWERS, FOLLOWER_OBS_DIM)
    np.testing.assert_array_equal(action, formation_follower_heuristic(blocks).reshape(-1))
    batch = np.stack([observation, observation, observation])
    np.testing.assert_array_equal(formation_heuristic(batch), np.stack([action] * 3))
    with pytest.raises(ActionError, match="neither K x 23"):
        formation_heuristic(np.zeros(20, np.float32))
    env.close()


def test_follower_heuristic_drives_toward_its_target() -> None:
    block = np.zeros(FOLLOWER_OBS_DIM, dtype=np.float32)
    block[13:15] = (0.2, 0.0)  # target ahead
    left, right = formation_follower_heuristic(block)
    assert left == pytest.approx(right) and left > 0
    block[13:15] = (0.0, 0.2)  # target to the left: turn left
    left, right = formation_follower_heuristic(block)
    assert right > left
    block[13:15] = (-0.2, -0.05)  # target behind on the right: turn right (never reverses)
    left, right = formation_follower_heuristic(block)
    assert left > right
    block[13:15] = 0.0  # on target, leader at rest: stay
    np.testing.assert_array_equal(formation_follower_heuristic(block), [0.0, 0.0])


def test_make_vec_formation_gives_native_env_with_targets_and_stats() -> None:
    envs = gym.make_vec(LATEST["formation"], num_envs=3, num_threads=2, max_steps=10)
    assert isinstance(envs, FormationVectorEnv)
    assert not isinstance(envs, gym.vector.SyncVectorEnv)
    observations, _ = envs.reset(seed=0)
    assert observations.shape == (3, FOLLOWER_OBS_DIM * N_FOLLOWERS)
    assert envs.formation_targets().shape == (3, N_FOLLOWERS, 2)
    assert envs.poses().shape == (3, N_FOLLOWERS + 1, 3)
    np.testing.assert_allclose(envs.formation_targets(), envs.poses()[:, 1:, :2], atol=1e-6)
    for _ in range(10):
        observations, _, _, truncations, infos = envs.step(formation_heuristic(observations))
    assert truncations.all()
    stats = infos["episode_stats"]
    for key in ("formation_error_mean", "formation_error_max", "return", "length"):
        assert stats[key].shape == (3,) and stats[f"_{key}"].all()
    assert infos["_episode_stats"].all()
    assert np.all(stats["formation_error_max"] >= stats["formation_error_mean"])
    envs.close()
