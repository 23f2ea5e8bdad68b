"""Saved states and pickling: get_state/set_state on single and vector envs reproduce a trajectory
bit for bit (across episode ends, contacts and random obstacles), in the same env, a fresh one, or
another process, for every registered id of every version (``conftest.ALL_IDS``); envs pickle and
unpickle to the same state; bad states raise StateError and leave the env unchanged."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from conftest import ALL_IDS, LATEST, PETTINGZOO_MODULES

from khepera_gym.errors import StateError


def _forward_actions(seed: int, steps: int, shape: tuple[int, ...]) -> np.ndarray:
    """Actions biased forward, so robots reach goals, walls and obstacles and episodes end."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-0.3, 1.0, size=(steps, *shape)).astype(np.float32)


def _single_trace(env: gym.Env, actions: np.ndarray) -> list[tuple]:
    trace = []
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        trace.append((obs.tobytes(), reward, terminated, truncated, repr(info)))
        if terminated or truncated:
            obs, _ = env.reset()
            trace.append((obs.tobytes(),))
    return trace


def _vector_trace(envs: gym.vector.VectorEnv, actions: np.ndarray) -> list[tuple]:
    trace = []
    for action in actions:
        obs, rewards, terminations, truncations, info = envs.step(action)
        trace.append((obs.tobytes(), rewards.tobytes(), terminations.tobytes(), repr(info)))
        trace[-1] += (truncations.tobytes(),)
    return trace


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_single_env_restored_state_replays_bit_for_bit(env_id: str) -> None:
    env = gym.make(env_id, max_steps=80)
    env.reset(seed=12)
    shape = env.action_space.shape
    _single_trace(env, _forward_actions(0, 30, shape))
    state = env.unwrapped.get_state()
    actions = _forward_actions(1, 250, shape)
    expected = _single_trace(env, actions)
    assert sum(len(step) == 1 for step in expected) >= 2, "the replay should cross episode ends"

    env.unwrapped.set_state(state)
    assert _single_trace(env, actions) == expected

    fresh = gym.make(env_id, max_steps=80)
    fresh.reset()  # Gymnasium's OrderEnforcing wrapper wants a reset before any step
    fresh.unwrapped.set_state(state)
    assert _single_trace(fresh, actions) == expected


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_vector_env_restored_state_replays_bit_for_bit(env_id: str) -> None:
    envs = gym.make_vec(env_id, num_envs=6, num_threads=2, max_steps=60)
    envs.reset(seed=4)
    shape = envs.action_space.shape
    _vector_trace(envs, _forward_actions(2, 40, shape))
    state = envs.get_state()
    actions = _forward_actions(3, 200, shape)
    expected = _vector_trace(envs, actions)

    envs.set_state(state)
    assert _vector_trace(envs, actions) == expected
    # Another thread count restores the same trajectory (results never depend on it).
    one_thread = gym.make_vec(env_id, num_envs=6, num_threads=1, max_steps=60)
    one_thread.set_state(state)
    assert _vector_trace(one_thread, actions) == expected


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_pickled_env_continues_like_the_original(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=8)
    shape = env.action_space.shape
    _single_trace(env, _forward_actions(4, 20, shape))
    clone = pickle.loads(pickle.dumps(env))
    deep = copy.deepcopy(env)
    np.testing.assert_array_equal(clone.render(), env.render())
    actions = _forward_actions(5, 150, shape)
    expected = _single_trace(env, actions)
    assert _single_trace(clone, actions) == expected
    assert _single_trace(deep, actions) == expected


def test_pickled_vector_env_keeps_its_config_and_state(tmp_path) -> None:
    # A scenario file that no longer exists when unpickling: the pickle holds the resolved scenario.
    scenario = tmp_path / "narrow.toml"
    scenario.write_text("[arena]\nwidth = 2.2\nheight = 1.6\n[task]\ngoal_radius = 0.1\n")
    envs = gym.make_vec(LATEST["avoid"], num_envs=4, config=scenario)
    envs.reset(seed=1)
    data = pickle.dumps(envs)
    scenario.unlink()
    clone = pickle.loads(data)
    assert clone.config_toml() == envs.config_toml()
    actions = _forward_actions(6, 100, envs.action_space.shape)
    assert _vector_trace(clone, actions) == _vector_trace(envs, actions)


@pytest.mark.parametrize("name", list(PETTINGZOO_MODULES))
def test_pettingzoo_env_pickles_mid_episode(name: str) -> None:
    env = PETTINGZOO_MODULES[name].parallel_env()
    env.reset(seed=2)
    rng = np.random.default_rng(0)

    def random_actions() -> dict[str, np.ndarray]:
        return {
            agent: rng.uniform(-1, 1, env.action_space(agent).shape).astype(np.float32)
            for agent in env.agents
        }

    for _ in range(10):
        env.step(random_actions())
    clone = pickle.loads(pickle.dumps(env))
    assert clone.agents == env.agents
    steps = 0
    while env.agents and steps < 40:
        actions = random_actions()
        expected, got = env.step(actions)[0], clone.step(actions)[0]
        assert list(got) == list(expected)
        for agent in expected:
            np.testing.assert_array_equal(got[agent], expected[agent])
        steps += 1
    assert clone.agents == env.agents


def test_state_restores_in_a_spawned_process() -> None:
    # AsyncVectorEnv pickles its env factories into fresh interpreters ("spawn"): a factory that
    # returns a pre-built, mid-episode env must carry its state there.
    env = gym.make(LATEST["nav"])
    env.reset(seed=21)
    _single_trace(env, _forward_actions(7, 15, (2,)))
    clone = copy.deepcopy(env)
    async_envs = gym.vector.AsyncVectorEnv(
        [lambda: clone], context="spawn", autoreset_mode="SameStep"
    )
    try:
        actions = _forward_actions(8, 30, (2,))
        for action in actions:
            obs, *_ = async_envs.step(action[None])
            expected, *_ = env.step(action)
            np.testing.assert_array_equal(obs[0], expected)
    finally:
        async_envs.close()


def test_state_survives_a_file_round_trip(tmp_path) -> None:
    envs = gym.make_vec(LATEST["formation"], num_envs=3)
    envs.reset(seed=9)
    path = tmp_path / "state.bin"
    path.write_bytes(envs.get_state())
    actions = _forward_actions(9, 60, envs.action_space.shape)
    expected = _vector_trace(envs, actions)
    envs.set_state(path.read_bytes())
    assert _vector_trace(envs, actions) == expected


def _refused(env, state, match: str) -> None:
    before = env.get_state()
    with pytest.raises(StateError, match=match):
        env.set_state(state)
    assert env.get_state() == before


def test_bad_states_raise_state_error_and_change_nothing() -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=4)
    envs.reset(seed=3)
    state = envs.get_state()
    target = gym.make_vec(LATEST["nav"], num_envs=4)
    target.reset(seed=5)
    _refused(target, b"not a state", "not a khepera_gym state")
    _refused(target, "text", "bytes")
    _refused(target, None, "bytes")
    _refused(target, state[: len(state) // 2], "corrupt")
    flipped = bytearray(state)
    flipped[-3] ^= 1
    _refused(target, bytes(flipped), "checksum")
    _refused(gym.make_vec(LATEST["nav"], num_envs=2), state, "4 worlds")
    _refused(gym.make_vec(LATEST["avoid"], num_envs=4), state, '"nav"')
    _refused(gym.make_vec(LATEST["nav"], num_envs=4, goal_radius=0.2), state, "goal_radius")
    assert issubclass(StateError, ValueError)
