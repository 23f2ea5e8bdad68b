"""Seeding and determinism: world i of a batch equals a single env seeded s + i, bit for bit, and a
batch's results do not depend on its thread count, for every registered id of every version
(``conftest.ALL_IDS``, from the registry)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import ALL_IDS, LATEST, random_actions

from khepera_gym.envs import NavEnv
from khepera_gym.vector import KheperaVectorEnv

#: Short episodes so that several end (and autoreset) within the compared steps.
SHORT_EPISODE = 60


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_batch_world_equals_single_env_with_seed_plus_index_across_autoreset(env_id: str) -> None:
    num_envs, seed, steps = 4, 1234, 200
    envs = gym.make_vec(env_id, num_envs=num_envs, num_threads=2, max_steps=SHORT_EPISODE)
    singles = [gym.make(env_id, max_steps=SHORT_EPISODE).unwrapped for _ in range(num_envs)]
    actions = random_actions(seed, steps, (num_envs, *envs.single_action_space.shape))

    batch_observations, _ = envs.reset(seed=seed)
    for index, env in enumerate(singles):
        observation, _ = env.reset(seed=seed + index)
        np.testing.assert_array_equal(batch_observations[index], observation)

    single_ended = np.zeros(num_envs, dtype=bool)
    episodes_ended = 0
    for step in range(steps):
        observations, rewards, terminations, truncations, infos = envs.step(actions[step])
        for index, env in enumerate(singles):
            if single_ended[index]:
                # NEXT_STEP autoreset: the batch resets this world and ignores its action.
                expected, _ = env.reset()
                expected_reward, expected_terminated, expected_truncated = 0.0, False, False
                single_ended[index] = False
            else:
                expected, expected_reward, expected_terminated, expected_truncated, info = env.step(
                    actions[step, index]
                )
                single_ended[index] = expected_terminated or expected_truncated
                if single_ended[index]:
                    episodes_ended += 1
                    assert infos["_episode_stats"][index]
                    for key, value in info["episode_stats"].items():
                        assert infos["episode_stats"][key][index] == value, (step, index, key)
            context = f"step {step}, world {index}"
            np.testing.assert_array_equal(observations[index], expected, err_msg=context)
            assert rewards[index] == np.float32(expected_reward), context
            assert terminations[index] == expected_terminated, context
            assert truncations[index] == expected_truncated, context
    assert episodes_ended >= 2 * num_envs  # every world went through autoresets
    envs.close()
    for env in singles:
        env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_batch_results_do_not_depend_on_thread_count(env_id: str) -> None:
    num_envs, seed, steps = 64, 99, 150
    runs = []
    for num_threads in (1, 2):
        envs = gym.make_vec(
            env_id, num_envs=num_envs, num_threads=num_threads, max_steps=SHORT_EPISODE
        )
        actions = random_actions(seed, steps, (num_envs, *envs.single_action_space.shape))
        assert envs.unwrapped.num_threads == num_threads
        trajectory = [envs.reset(seed=seed)[0]]
        episode_returns = []
        for step_actions in actions:
            observations, rewards, terminations, truncations, infos = envs.step(step_actions)
            trajectory += [observations, rewards, terminations, truncations]
            if infos:
                # Every statistic (formation: the formation errors too), in a fixed order.
                episode_returns += [
                    infos["episode_stats"][key] for key in sorted(infos["episode_stats"])
                ]
        runs.append((trajectory, episode_returns, envs.unwrapped.poses()))
        envs.close()
    (trajectory_1, returns_1, poses_1), (trajectory_2, returns_2, poses_2) = runs
    assert len(trajectory_1) == len(trajectory_2)
    for array_1, array_2 in zip(trajectory_1, trajectory_2, strict=True):
        np.testing.assert_array_equal(array_1, array_2)
    assert len(returns_1) == len(returns_2) > 0
    for array_1, array_2 in zip(returns_1, returns_2, strict=True):
        np.testing.assert_array_equal(array_1, array_2)
    np.testing.assert_array_equal(poses_1, poses_2)


def _rollout(env: gym.Env, seed: int | None, actions: np.ndarray) -> list[np.ndarray]:
    observation, _ = env.reset(seed=seed)
    trajectory = [observation]
    for action in actions:
        observation, reward, terminated, truncated, _ = env.step(action)
        trajectory += [observation, np.float64(reward)]
        if terminated or truncated:
            break
    return trajectory


def test_same_seed_twice_gives_same_trajectory(nav_env: gym.Env) -> None:
    actions = random_actions(5, 100, (2,))
    first = _rollout(nav_env, 5, actions)
    second = _rollout(nav_env, 5, actions)
    other_env = gym.make(LATEST["nav"])
    third = _rollout(other_env, 5, actions)
    other_env.close()
    for run in (second, third):
        assert len(run) == len(first)
        for array_1, array_2 in zip(first, run, strict=True):
            np.testing.assert_array_equal(array_1, array_2)


def test_different_seeds_give_different_starts(nav_env: gym.Env) -> None:
    observation_1, _ = nav_env.reset(seed=1)
    poses_1 = nav_env.unwrapped.poses().copy()
    observation_2, _ = nav_env.reset(seed=2)
    assert not np.array_equal(poses_1, nav_env.unwrapped.poses())
    assert not np.array_equal(observation_1, observation_2)


def test_reset_without_seed_continues_the_stream_reproducibly() -> None:
    runs = []
    for _ in range(2):
        env = NavEnv()
        seeded, _ = env.reset(seed=11)
        continued, _ = env.reset()
        continued_again, _ = env.reset()
        runs.append((seeded, continued, continued_again))
        env.close()
    (seeded, continued, continued_again), repeat = runs
    assert not np.array_equal(seeded, continued)
    assert not np.array_equal(continued, continued_again)
    for array_1, array_2 in zip(runs[0], repeat, strict=True):
        np.testing.assert_array_equal(array_1, array_2)


def test_first_reset_without_seed_draws_from_np_random() -> None:
    starts = []
    for _ in range(2):
        env = NavEnv()
        env.np_random, _ = gym.utils.seeding.np_random(42)
        starts.append(env.reset()[0])
        env.close()
    np.testing.assert_array_equal(starts[0], starts[1])


def test_vector_reset_without_seed_continues_each_world() -> None:
    envs = KheperaVectorEnv(3)
    seeded, _ = envs.reset(seed=5)
    continued, _ = envs.reset()
    for index in range(3):
        assert not np.array_equal(seeded[index], continued[index])
    envs.close()


def test_vector_reset_with_per_world_seeds_equals_int_seed() -> None:
    envs_int = KheperaVectorEnv(3)
    envs_list = KheperaVectorEnv(3)
    by_int, _ = envs_int.reset(seed=20)
    by_list, _ = envs_list.reset(seed=[20, 21, 22])
    np.testing.assert_array_equal(by_int, by_list)
    actions = random_actions(0, 30, (3, 2))
    for step_actions in actions:
        np.testing.assert_array_equal(
            envs_int.step(step_actions)[0], envs_list.step(step_actions)[0]
        )
    envs_int.close()
    envs_list.close()


@pytest.mark.parametrize("num_envs", [1, 3])
def test_vector_env_of_one_seed_matches_single_env(num_envs: int) -> None:
    envs = KheperaVectorEnv(num_envs)
    env = NavEnv()
    observations, _ = envs.reset(seed=77)
    observation, _ = env.reset(seed=77)
    np.testing.assert_array_equal(observations[0], observation)
    np.testing.assert_array_equal(envs.poses()[0], env.poses())
    np.testing.assert_array_equal(envs.goals()[0], env.goals())
    envs.close()
    env.close()
