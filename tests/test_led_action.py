"""Robots' top LEDs set by an action (issue 15, item 4): with ``task.led_action`` every agent's
action is its two wheel values then its LEDs' red, green, blue in [-1, 1], quantised to the real
LEDs' 64 levels (6 bits a colour, ``kh4_SetRGBLeds`` 0..63, docs/robot.md §6). The LEDs change
nothing else: the same wheel actions give the same run bit for bit. Every interface (Gymnasium,
vector, PettingZoo parallel and array envs, the SB3 shared-agents VecEnv, TorchRL) takes five values
per agent; a drone, which has no LEDs, refuses the key. The camera side (another robot sees the
colour where it occludes) is tested in tests/camera.rs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from khepera_gym.baselines import Braitenberg, ConsensusLaw, PositionControl, with_leds
from khepera_gym.errors import ActionError, ConfigError
from khepera_gym.learning.sb3 import SharedAgentsVecEnv
from khepera_gym.pettingzoo import consensus_v1, multinav_v1

NAV = "KheperaIV-Avoid-v1"
#: Highest level of one LED colour (6 bits, docs/robot.md §6).
LEVELS = 63


def levels(values: np.ndarray) -> np.ndarray:
    """The LED levels normalised actions ask for: [-1, 1] to 0..63, nearest level."""
    return np.round((np.clip(values, -1.0, 1.0) + 1.0) / 2.0 * LEVELS).astype(int)


def test_leds_follow_the_action_and_change_nothing_else() -> None:
    rng = np.random.default_rng(3)
    plain = gym.make(NAV)
    lit = gym.make(NAV, led_action=True)
    assert lit.action_space.shape == (5,)
    obs_a, _ = plain.reset(seed=11)
    obs_b, _ = lit.reset(seed=11)
    # At reset the LEDs show robot.led_color, [0, 0.8, 0]: green level round(0.8 · 63) = 50.
    np.testing.assert_array_equal(lit.unwrapped.sensor_readings()["leds"], [[0, 50, 0]])
    policy = Braitenberg.for_env(plain)
    for _ in range(120):
        np.testing.assert_array_equal(obs_a, obs_b)
        np.testing.assert_array_equal(plain.unwrapped.poses(), lit.unwrapped.poses())
        wheels = policy(obs_a)
        led = rng.uniform(-1.5, 1.5, 3).astype(np.float32)  # outside [-1, 1]: clipped
        obs_a, reward_a, end_a, cut_a, _ = plain.step(wheels)
        obs_b, reward_b, end_b, cut_b, _ = lit.step(np.concatenate([wheels, led]))
        assert (reward_a, end_a, cut_a) == (reward_b, end_b, cut_b)
        np.testing.assert_array_equal(lit.unwrapped.sensor_readings()["leds"], [levels(led)])
        if end_a or cut_a:
            break
    assert "leds" not in plain.unwrapped.sensor_readings()


def test_an_action_of_the_old_width_is_an_error_naming_the_shape() -> None:
    env = gym.make(NAV, led_action=True)
    env.reset(seed=0)
    with pytest.raises(ActionError, match=r"\(5,\)"):
        env.step(np.zeros(2, np.float32))
    with pytest.raises(ActionError, match="finite"):
        env.step(np.array([0.0, 0.0, np.nan, 0.0, 0.0], np.float32))


def test_a_drone_has_no_leds() -> None:
    with pytest.raises(ConfigError, match=r"task\.led_action"):
        gym.make("KheperaIV-DroneFollow-v1", led_action=True, driver="agent")


def test_delayed_leds_and_saved_state_reproduce_bit_for_bit() -> None:
    env = gym.make(NAV, led_action=True, action_delay=2)
    env.reset(seed=4)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (12, 5)).astype(np.float32)
    shown = []
    for action in actions[:6]:
        env.step(action)
        shown.append(env.unwrapped.sensor_readings()["leds"][0])
    # The colour sent at step k shows from step k + 2 on; before, robot.led_color.
    np.testing.assert_array_equal(shown[:2], [[0, 50, 0]] * 2)
    np.testing.assert_array_equal(shown[2:], levels(actions[:4, 2:]))
    state = env.unwrapped.get_state()
    first = []
    for action in actions[6:]:
        obs, *_ = env.step(action)
        first.append((obs, env.unwrapped.sensor_readings()["leds"].copy()))
    env.unwrapped.set_state(state)
    for action, (obs_then, leds_then) in zip(actions[6:], first, strict=True):
        obs, *_ = env.step(action)
        np.testing.assert_array_equal(obs, obs_then)
        np.testing.assert_array_equal(env.unwrapped.sensor_readings()["leds"], leds_then)


def test_pettingzoo_agents_each_set_their_own_robots_leds() -> None:
    from pettingzoo.test import parallel_api_test

    parallel_api_test(multinav_v1.parallel_env(led_action=True), num_cycles=40)
    env = multinav_v1.parallel_env(led_action=True)
    env.reset(seed=2)
    colors = {agent: np.eye(3)[k % 3] for k, agent in enumerate(env.agents)}
    assert all(env.action_space(a).shape == (5,) for a in env.agents)
    env.step({a: np.concatenate([[0.2, 0.2], 2 * colors[a] - 1]) for a in env.agents})
    leds = env.sensor_readings()["leds"]
    for agent, color in colors.items():
        np.testing.assert_array_equal(leds[env.agent_robot(agent)], LEVELS * color)


def test_a_robot_that_arrived_keeps_its_last_colour() -> None:
    # Multinav robots driven home by position control, each sending a new random colour every
    # step: once a robot has arrived (its agent gone), its LEDs keep the colour it sent last.
    env = multinav_v1.parallel_env(led_action=True, n_robots=3)
    observations, _ = env.reset(seed=21)
    controller = PositionControl()
    rng = np.random.default_rng(7)
    last: dict[str, np.ndarray] = {}
    checked = 0
    while env.agents:
        actions = {}
        for agent in env.agents:
            last[agent] = rng.uniform(-1, 1, 3).astype(np.float32)
            actions[agent] = np.concatenate([controller(observations[agent]), last[agent]])
        observations, *_ = env.step(actions)
        leds = env.sensor_readings()["leds"]
        for agent in set(env.possible_agents) - set(env.agents):
            np.testing.assert_array_equal(leds[env.agent_robot(agent)], levels(last[agent]))
            checked += bool(env.agents)
    assert checked > 0, "no robot arrived before the others"


def test_array_env_and_shared_vec_env_take_five_values_per_agent() -> None:
    arrays = multinav_v1.array_env(num_envs=2, led_action=True)
    arrays.reset(seed=0)
    actions = np.zeros((2, arrays.n_agents, 5), np.float32)
    actions[1, 0, 2:] = [1.0, 1.0, -1.0]  # world 1, agent 0: yellow
    arrays.step(actions)
    leds = arrays.sensor_readings()["leds"]
    np.testing.assert_array_equal(leds[1, 0], [63, 63, 0])
    np.testing.assert_array_equal(leds[0, 0], [32, 32, 32])  # 0 asks for level 31.5: 32
    with pytest.raises(ActionError, match=r"\(2, 4, 5\)"):
        arrays.step(np.zeros((2, arrays.n_agents, 2), np.float32))

    vec = SharedAgentsVecEnv("consensus", 2, seed=1, led_action=True)
    assert vec.action_space.shape == (5,)
    rows = vec.reset()
    law = ConsensusLaw.for_env(consensus_v1.parallel_env())
    vec.step(with_leds(law(rows), [1.0, 0.0, 1.0]))
    np.testing.assert_array_equal(
        vec.sensor_readings()["leds"], np.broadcast_to([63, 0, 63], (2, 4, 3))
    )


def test_with_leds_appends_a_colour_to_each_agents_wheels() -> None:
    joint = np.array([[0.1, 0.2, 0.3, 0.4]], np.float32)  # one row, two agents
    np.testing.assert_array_equal(
        with_leds(joint, [[1.0, 0.0, 0.5], [0.0, 1.0, 0.0]]),
        np.array([[0.1, 0.2, 1.0, -1.0, 0.0, 0.3, 0.4, -1.0, 1.0, -1.0]], np.float32),
    )
    with pytest.raises(ActionError, match="color"):
        with_leds(joint, [1.0, 0.0, 2.0])
    with pytest.raises(ActionError, match="2 K"):
        with_leds(np.zeros(3), [1.0, 0.0, 0.0])


def test_frames_draw_the_three_leds_in_their_colour() -> None:
    red = np.array([255, 0, 0], np.uint8)
    frames = {}
    for led_action in (False, True):
        env = gym.make("KheperaIV-Nav-v1", render_mode="rgb_array", led_action=led_action)
        env.reset(seed=0)
        action = [0.0, 0.0, 1.0, -1.0, -1.0] if led_action else [0.0, 0.0]
        env.step(np.array(action, np.float32))
        frames[led_action] = env.render()
    red_pixels = [np.all(frame == red, axis=-1).sum() for frame in frames.values()]
    assert red_pixels[0] == 0 and red_pixels[1] > 0
