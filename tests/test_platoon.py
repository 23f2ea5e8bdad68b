"""platoon_v1: robots tracking time-shifted copies of one reference, one PettingZoo agent each.

PettingZoo's own API and seed tests run on it in tests/test_pettingzoo.py; here: Kanayama's
controller on every agent converges as its linearised loop says, the reference points are
time_gap · v_r apart, lost robots leave alone, seeds and saved states replay bit for bit, bad
platoons are configuration errors naming the key, and the manual matches the env.
"""

from __future__ import annotations

import doctest
import itertools
import math
import re

import numpy as np
import pytest

import khepera_gym
from khepera_gym.baselines import Kanayama
from khepera_gym.errors import ConfigError
from khepera_gym.pettingzoo import platoon, platoon_v1

#: Scenario defaults the bounds use (configs/platoon.toml; docs/task-design.md §3).
ROBOTS = 3  # platoon.robots
TIME_GAP = 2.0  # s, platoon.time_gap
SPEED = 0.15  # m/s, platoon.speed
RADIUS = 0.6  # m, platoon.size of the circle
START_OFFSET = 0.2  # m, platoon.start_offset
START_HEADING_OFFSET = math.pi / 4  # rad, platoon.start_heading_offset
TRANSIENT = 5.0  # s, platoon.transient
DT = 0.05  # s, physics.dt
WHEEL_ACCEL = 0.2034543  # m/s², robot.wheel_accel_limit (K-Team's speed profile)
CIRCLE_STEPS = 543  # one lap 2π·0.6/0.15 = 25.13 s + 2 s margin, in 0.05 s steps
AGENTS = [f"robot_{k}" for k in range(ROBOTS)]


def kanayama_bound(t: float) -> float:
    """The error bound of Kanayama's controller t seconds after a standing start (m).

    Linearised about zero error (src/controllers/kanayama.rs), the along-track error decays at
    K_x = 1 s⁻¹ and the cross-track loop s² + v_r K_θ s + v_r² K_y is critically damped with
    ω_n = v_r √K_y = 1 rad/s at v_r = 0.15 m/s: with λ = 1 s⁻¹ an initial error E0 stays within
    E0 (1 + λt) e^{−λt}. E0 sums the start offset, the heading offset's drift v_r sin(45°)/λ and
    the lag of a standing start under the wheels' acceleration limit, v_r²/(2a); sampling at dt
    adds the reference's travel in one step. Each robot's reference is the same circle, delayed,
    so the bound holds for each while its neighbours keep out of its way.
    """
    rate = 1.0
    e0 = START_OFFSET + SPEED * math.sin(START_HEADING_OFFSET) / rate + SPEED**2 / (2 * WHEEL_ACCEL)
    return e0 * (1 + rate * t) * math.exp(-rate * t) + SPEED * DT


def _errors(env: platoon_v1.PlatoonParallelEnv) -> np.ndarray:
    """Each robot's distance to its reference point (m)."""
    return np.linalg.norm(env.poses()[:, :2] - env.goals(), axis=1)


def test_kanayama_on_every_agent_converges_on_the_circle_within_its_linear_envelope() -> None:
    env = platoon_v1.parallel_env(reference="circle")
    policy = Kanayama()
    bound = kanayama_bound(TRANSIENT)  # 2.2 cm
    skip = round(TRANSIENT / DT) - 1  # errors[i] is after step i + 1: from t = 5 s on
    for seed in range(10):
        observations, _ = env.reset(seed=seed)
        errors, steps = [], 0
        while env.agents:
            observations, _, terminations, truncations, infos = env.step(policy(observations))
            assert not any(terminations.values()), f"seed {seed}: a robot was lost"
            errors.append(_errors(env))
            steps += 1
        assert steps == CIRCLE_STEPS
        assert all(truncations.values()) and set(truncations) == set(AGENTS)
        worst = np.array(errors)[skip:].max(axis=0)
        assert (worst <= bound).all(), f"seed {seed}: {worst} m beyond {bound:.4f} m"
        stats = infos["robot_0"]["world_episode_stats"]  # the world's, with the tracking errors
        assert stats["track_error_max"] == pytest.approx(worst.max(), abs=1e-6)
        assert stats["track_converge_time"] <= TRANSIENT + DT


def test_reference_points_are_time_gap_times_speed_apart_along_the_circle() -> None:
    env = platoon_v1.parallel_env(reference="circle")
    env.reset(seed=4)
    for _ in range(60):
        goals = env.goals()
        assert goals.shape == (ROBOTS, 2)
        np.testing.assert_allclose(np.linalg.norm(goals, axis=1), RADIUS, atol=1e-5)
        for ahead, behind in itertools.pairwise(goals):
            cosine = np.dot(ahead, behind) / (np.linalg.norm(ahead) * np.linalg.norm(behind))
            arc = RADIUS * math.acos(min(1.0, cosine))
            assert arc == pytest.approx(TIME_GAP * SPEED, abs=1e-3)
        env.step({agent: np.zeros(2, dtype=np.float32) for agent in env.agents})


def test_every_agent_observes_a_track_block_that_the_track_baselines_read() -> None:
    env = platoon_v1.parallel_env(robots=4)
    track_layout = khepera_gym.obs_layout("track")
    for agent in env.possible_agents:
        assert env.agent_obs_layout(agent) == track_layout
        assert env.observation_space(agent).shape == (29,)
    observations, _ = env.reset(seed=0)
    actions = Kanayama()(observations)
    assert set(actions) == set(env.possible_agents)
    assert all(action.shape == (2,) for action in actions.values())


def test_a_lost_agent_leaves_alone_and_the_others_go_on() -> None:
    env = platoon_v1.parallel_env(start_offset=0.0, start_heading_offset=0.0, lost_distance=0.15)
    policy = Kanayama()
    observations, _ = env.reset(seed=1)
    for _ in range(100):
        actions = policy(observations)
        actions["robot_2"] = np.zeros(2, dtype=np.float32)  # the last robot stands still
        observations, rewards, terminations, *_ = env.step(actions)
        if terminations["robot_2"]:
            break
    assert terminations == {"robot_0": False, "robot_1": False, "robot_2": True}
    assert env.agents == ["robot_0", "robot_1"]
    parked = env.poses()[2].copy()
    for _ in range(40):
        actions = policy({agent: observations[agent] for agent in env.agents})
        observations, rewards, terminations, *_ = env.step(actions)
        assert set(rewards) == {"robot_0", "robot_1"}
    np.testing.assert_array_equal(env.poses()[2], parked)


def _kanayama_trace(env: platoon_v1.PlatoonParallelEnv, observations: dict, steps: int) -> bytes:
    policy = Kanayama()
    trace = []
    for _ in range(steps):
        observations, rewards, *_ = env.step(policy(observations))
        trace += [env.poses().tobytes(), env.state().tobytes(), repr(rewards).encode()]
    return b"".join(trace)


def test_same_seed_reproduces_the_episode_bit_for_bit() -> None:
    runs = []
    for seed in (7, 7, 8):
        env = platoon_v1.parallel_env(reference="spline")
        observations, _ = env.reset(seed=seed)
        runs.append(_kanayama_trace(env, observations, 120))
    assert runs[0] == runs[1]
    assert runs[0] != runs[2]


def test_saved_state_replays_bit_for_bit_here_and_in_a_fresh_env() -> None:
    env = platoon_v1.parallel_env(reference="spline")
    observations, _ = env.reset(seed=3)
    policy = Kanayama()
    for _ in range(30):
        observations, *_ = env.step(policy(observations))
    state = env.get_state()
    saved_observations = {agent: obs.copy() for agent, obs in observations.items()}
    expected = _kanayama_trace(env, observations, 100)
    env.set_state(state)
    assert _kanayama_trace(env, saved_observations, 100) == expected
    fresh = platoon_v1.parallel_env(reference="spline")
    fresh.reset(seed=99)
    fresh.set_state(state)
    assert _kanayama_trace(fresh, saved_observations, 100) == expected


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"time_gap": 0.5}, "platoon.time_gap"),  # 7.5 cm apart: closer than a diameter + 2 cm
        ({"time_gap": -1.0}, "platoon.time_gap"),
        ({"time_gap": 1.15, "reference": "lemniscate"}, "platoon.time_gap"),  # closer on lobes
        ({"robots": 13}, "platoon.robots"),  # 13 × 2 s = 26 s > the circle's 25.1 s lap
        ({"robots": 0}, "platoon.robots"),
        ({"robots": 17, "time_gap": 1.1}, "platoon.robots"),
        ({"size": 0.9}, "platoon.size"),  # Track's checks, under the platoon's table
        ({"speed": 0.6}, "platoon.speed"),
        ({"spawn": {"start": [0.0, 0.0, 0.0]}}, "spawn.start"),
        ({"platoon": {"gap": 2.0}}, "platoon.gap"),
    ],
)
def test_bad_platoons_raise_config_error_naming_the_key(overrides: dict, key: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(key)):
        platoon_v1.parallel_env(**overrides)


def test_robots_and_time_gap_arguments_reach_the_scenario() -> None:
    env = platoon_v1.parallel_env(robots=5, time_gap=2.5)
    assert env.possible_agents == [f"robot_{k}" for k in range(5)]
    assert "robots = 5" in env.config_toml() and "time_gap = 2.5" in env.config_toml()
    env.reset(seed=0)
    assert env.poses().shape == (5, 3) and env.targets().shape == (5 * 4, 2)


def test_manual_has_its_sections_a_table_matching_the_layout_and_running_examples() -> None:
    # The manual is the family's class (every platoon_vN module's env subclasses it).
    manual = platoon.PlatoonParallelEnv.__doc__ or ""
    sections = [
        "Description",
        "Agents",
        "Action Space",
        "Observation Space",
        "Rewards",
        "Starting State",
        "Episode End",
        "Arguments",
        "Scenario file",
        "Version History",
    ]
    positions = [manual.index(f"## {section}\n") for section in sections]
    assert positions == sorted(positions)
    layout = khepera_gym.obs_layout("track")
    rows = re.findall(r"^\s*\| (\d+)-(\d+)\s*\| (\w+)", manual, re.M)
    assert {name: slice(int(a), int(b) + 1) for a, b, name in rows} == layout
    assert "v1: Initial version" in manual
    results = doctest.testmod(platoon, optionflags=doctest.ELLIPSIS)
    assert results.attempted >= 4 and results.failed == 0
