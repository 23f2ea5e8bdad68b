"""PettingZoo: every versioned module (``conftest.PETTINGZOO_MODULES``, from the registry) passes
PettingZoo's own API and seed tests, and the formation, multinav, platoon and consensus modules
keep the contract."""

from __future__ import annotations

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import FORMATION, LATEST, MULTINAV, PETTINGZOO_MODULES, latest_module, module_name
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

from khepera_gym.envs import (
    formation_follower_heuristic,
    formation_heuristic,
    nav_heuristic,
    track_heuristic,
)
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.pettingzoo import formation_v0, multinav_v0

FOLLOWERS = ["follower_0", "follower_1", "follower_2", "follower_3"]
ROBOTS = ["robot_0", "robot_1", "robot_2", "robot_3"]
#: Settings of the latest modules PettingZoo's tests also run on: (module without its version,
#: test id suffix, constructor kwargs).
SETTINGS = [
    ("formation", "fig7", {"config": "paper_fig7"}),
    ("formation", "line", {"n_followers": 2, "shape": "line", "max_cycles": 150}),
    ("multinav", "obstacles", {"n_robots": 2, "count": 4}),
    ("platoon", "lemniscate", {"robots": 5, "reference": "lemniscate", "max_cycles": 200}),
    (
        "consensus",
        "geometric-event-lossy",
        {"n_robots": 6, "graph": "geometric", "trigger": "event", "drop": 0.2, "delay_steps": 3},
    ),
]
#: (module, constructor kwargs) of the environments PettingZoo's tests run on: every versioned
#: module of the package with its defaults (from the registry, ``modules()``), then
#: :data:`SETTINGS`.
ENVS = [(module, {}) for module in PETTINGZOO_MODULES.values()] + [
    (latest_module(stem), kwargs) for stem, _, kwargs in SETTINGS
]
#: Test ids: the module's name, with the setting's suffix.
ENV_IDS = list(PETTINGZOO_MODULES) + [
    f"{latest_module(stem).__name__.rpartition('.')[2]}-{suffix}" for stem, suffix, _ in SETTINGS
]
#: The modules with their defaults (PettingZoo's seed tests run on each).
MODULE_ENVS = ENVS[: len(PETTINGZOO_MODULES)]


def _heuristic_actions(env: ParallelEnv, observations: dict) -> dict:
    if env.metadata["name"].startswith("multinav"):
        return {agent: nav_heuristic(observations[agent]) for agent in env.agents}
    if env.metadata["name"].startswith("platoon"):
        return {agent: track_heuristic(observations[agent]) for agent in env.agents}
    return {agent: formation_follower_heuristic(observations[agent]) for agent in env.agents}


#: Every version's module of the tasks since v0, from the registry, with its behaviour version.
VERSIONED = {
    name: (module, int(name.rpartition("_v")[2]))
    for name, module in PETTINGZOO_MODULES.items()
    if name.rpartition("_v")[0] in ("formation", "multinav")
}


@pytest.mark.parametrize(("module", "version"), VERSIONED.values(), ids=VERSIONED.keys())
def test_each_module_keeps_its_versions_dynamics(module, version: int) -> None:
    # v0: the paper's imposed velocities; v1 on: tyres with bounded grip.
    drive = "kinematic" if version == 0 else "traction"
    env = module.parallel_env()
    assert env.metadata["name"].endswith(f"_v{version}")
    assert f'drive = "{drive}"' in env.config_toml()
    assert version == env.VERSION


@pytest.mark.parametrize(("module", "kwargs"), ENVS, ids=ENV_IDS)
def test_parallel_api_test_passes(module, kwargs: dict) -> None:
    env = module.parallel_env(**kwargs)
    assert isinstance(env, ParallelEnv)
    parallel_api_test(env, num_cycles=1000)


#: PettingZoo's advice (a warning) on an agent not named "<descriptor>_<number>" ("drone",
#: "leader"): the only warning its API test may give, and only for such an agent.
NAMING_ADVICE = "We recommend agents to be named"


@pytest.mark.parametrize(("module", "kwargs"), ENVS, ids=ENV_IDS)
def test_aec_api_test_passes(module, kwargs: dict) -> None:
    env = module.env(**kwargs)
    assert isinstance(env, AECEnv)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        api_test(env, num_cycles=1000)
    unnamed = [a for a in env.possible_agents if not re.fullmatch(r"[a-z]+_[0-9]+", a)]
    for warning in caught:
        assert unnamed and str(warning.message).startswith(NAMING_ADVICE), warning


@pytest.mark.parametrize(("module", "kwargs"), MODULE_ENVS, ids=list(PETTINGZOO_MODULES))
def test_seed_tests_pass(module, kwargs: dict) -> None:
    parallel_seed_test(lambda: module.parallel_env(**kwargs))
    seed_test(lambda: module.env(**kwargs))


def test_agent_leader_passes_the_api_tests_with_only_naming_advice() -> None:
    """ "leader" is not "<name>_<number>", and its Nav block is shorter than a follower's."""
    expected_advice = (
        "We recommend agents to be named",
        "Agents have different observation space sizes",
        "Observations are different shapes",
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parallel_api_test(FORMATION.parallel_env(leader="agent"), num_cycles=1000)
        api_test(FORMATION.env(leader="agent"), num_cycles=1000)
    for warning in caught:
        assert str(warning.message).startswith(expected_advice), warning


def test_metadata_and_agents() -> None:
    formation = FORMATION.parallel_env()
    assert formation.metadata["name"] == module_name(FORMATION)
    assert formation.metadata["is_parallelizable"] is True
    assert formation.metadata["render_modes"] == ["rgb_array", "human"]
    assert formation.possible_agents == FOLLOWERS
    assert formation.agents == []
    observations, infos = formation.reset(seed=0)
    assert formation.agents == FOLLOWERS
    assert list(observations) == list(infos) == FOLLOWERS
    assert all(info == {} for info in infos.values())
    assert FORMATION.parallel_env(leader="agent").possible_agents == ["leader", *FOLLOWERS]
    assert FORMATION.parallel_env(n_followers=2).possible_agents == FOLLOWERS[:2]

    multinav = MULTINAV.parallel_env()
    assert multinav.metadata["name"] == module_name(MULTINAV)
    assert multinav.possible_agents == ROBOTS
    assert MULTINAV.parallel_env(n_robots=6).max_num_agents == 6


def test_spaces_are_cached_and_followers_share_one_space() -> None:
    env = FORMATION.parallel_env(leader="agent")
    for agent in env.possible_agents:
        assert env.observation_space(agent) is env.observation_space(agent)
        assert env.action_space(agent) is env.action_space(agent)
        assert env.action_space(agent) == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    follower_spaces = [env.observation_space(agent) for agent in FOLLOWERS]
    assert all(space == follower_spaces[0] for space in follower_spaces)
    assert follower_spaces[0].shape == (23,)
    assert env.observation_space("leader").shape == (18,)
    assert list(env.agent_obs_layout("follower_2")) == [
        "ir",
        "us",
        "target_offset",
        "leader_offset",
        "leader_heading",
        "leader_velocity",
        "wheel_speeds",
    ]


def test_observations_are_slices_of_the_state_and_match_the_gymnasium_env() -> None:
    parallel = FORMATION.parallel_env(config="paper_fig7")
    single = gym.make(LATEST["formation"], config="paper_fig7")
    observations, _ = parallel.reset(seed=9)
    joint, _ = single.reset(seed=9)
    np.testing.assert_array_equal(parallel.state(), joint)
    assert parallel.state() in parallel.state_space
    for _ in range(60):
        np.testing.assert_array_equal(np.concatenate([observations[a] for a in FOLLOWERS]), joint)
        actions = _heuristic_actions(parallel, observations)
        observations, rewards, _, _, _ = parallel.step(actions)
        joint, reward, *_ = single.step(np.concatenate([actions[a] for a in FOLLOWERS]))
        np.testing.assert_array_equal(list(rewards.values()), single.unwrapped.agent_rewards())
        assert np.mean(list(rewards.values()), dtype=np.float32) == pytest.approx(reward, abs=1e-6)
    np.testing.assert_array_equal(parallel.poses(), single.unwrapped.poses())
    targets = single.unwrapped.formation_targets()
    np.testing.assert_array_equal(parallel.formation_targets(), targets)
    single.close()


def test_formation_episode_ends_for_every_follower_with_stats() -> None:
    env = formation_v0.parallel_env()  # the paper's gains, on the dynamics they were tuned for
    observations, _ = env.reset(seed=1)
    while env.agents:
        live = list(env.agents)
        observations, rewards, terminations, truncations, infos = env.step(
            _heuristic_actions(env, observations)
        )
        assert list(rewards) == live
    assert all(terminations.values()) or all(truncations.values())
    for agent in FOLLOWERS:
        stats = infos[agent]["world_episode_stats"]  # the world's, with the formation errors
        assert stats["formation_error_mean"] < 0.1
        assert stats["formation_error_max"] >= stats["formation_error_mean"]
    with pytest.raises(KheperaError, match="reset"):
        env.step({})


def test_max_cycles_truncates_every_agent() -> None:
    env = FORMATION.parallel_env(max_cycles=7)
    assert env.max_cycles == 7
    env.reset(seed=0)
    for step in range(7):
        zero = {agent: np.zeros(2, np.float32) for agent in env.agents}
        _, _, terminations, truncations, infos = env.step(zero)
        assert not any(terminations.values())
        assert all(truncations.values()) == (step == 6)
    assert env.agents == []
    assert all(infos[agent]["episode_stats"]["length"] == 7 for agent in FOLLOWERS)
    # Lowering max_cycles after construction truncates earlier (the core keeps its limit).
    env.max_cycles = 3
    env.reset(seed=0)
    for _ in range(3):
        _, _, _, truncations, infos = env.step({a: np.zeros(2) for a in env.agents})
    assert all(truncations.values()) and env.agents == []
    with pytest.raises(ConfigError, match="max_cycles"):
        FORMATION.parallel_env(max_cycles=5, max_steps=6)


def test_multinav_robots_that_arrive_leave_and_park() -> None:
    env = multinav_v0.parallel_env()  # v0: a robot given zero commands stops within the step
    observations, _ = env.reset(seed=1)
    arrived: dict[str, np.ndarray] = {}
    while env.agents:
        live = list(env.agents)
        observations, rewards, terminations, truncations, infos = env.step(
            _heuristic_actions(env, observations)
        )
        assert set(rewards) == set(terminations) == set(truncations) == set(live)
        poses = env.poses()
        for agent, pose in arrived.items():  # parked robots do not move
            np.testing.assert_allclose(poses[env.agent_robot(agent)], pose, atol=1e-3)
        for agent in live:
            if terminations[agent]:
                goal = env.goals()[env.agent_robot(agent)]
                assert np.linalg.norm(poses[env.agent_robot(agent), :2] - goal) < 0.05
                arrived[agent] = poses[env.agent_robot(agent)].copy()
                assert agent not in env.agents
    assert set(arrived) == set(ROBOTS)  # every robot reached its goal, one after another
    assert all(info["episode_stats"]["success"] for info in infos.values())


@pytest.mark.parametrize(
    "module",
    [m for name, (m, version) in VERSIONED.items() if name.startswith("multinav") and version >= 1],
)
def test_multinav_robots_that_arrive_brake_to_rest_within_their_stopping_distance(module) -> None:
    """A parked robot's wheels follow the drive down to 0 (v1: the 0.203 m/s² ramp; v2 and v3:
    K-Team's profile at 2.71 m/s², whose last order drops from at most its minimum to 0), so it
    rolls on for at most v^2 / (2 a) and then stands still."""
    env = module.parallel_env()
    scenario = tomllib.loads(env.config_toml())
    motors = scenario["motors"]
    if motors["mode"] == "profile":
        accel = motors["acc_inc"] * 0.678181e-3 / ((motors["acc_div"] + 1) * 0.01)
    else:
        accel = scenario["robot"]["wheel_accel_limit"]
    observations, _ = env.reset(seed=1)
    arrivals: dict[str, tuple[np.ndarray, float, int]] = {}
    step = 0
    while env.agents:
        observations, _, terminations, *_ = env.step(_heuristic_actions(env, observations))
        step += 1
        speeds = env.sensor_readings()["wheel_speeds"]
        for agent, ended in terminations.items():
            if ended:
                robot = env.agent_robot(agent)
                speed = float(np.abs(speeds[robot]).max())
                arrivals[agent] = (env.poses()[robot, :2].copy(), speed, step)
    assert arrivals, "no robot arrived"
    speeds = env.sensor_readings()["wheel_speeds"]
    dt = 0.05
    for agent, (position, speed, arrived) in arrivals.items():
        robot = env.agent_robot(agent)
        rolled = np.linalg.norm(env.poses()[robot, :2] - position)
        assert rolled <= speed**2 / (2 * accel) + 1e-3, (agent, rolled, speed)
        if arrived + np.ceil(speed / (accel * dt)) < step:  # it had the time to stop
            np.testing.assert_array_equal(speeds[robot], [0.0, 0.0])


def test_actions_for_finished_or_unknown_agents_raise_action_error() -> None:
    env = MULTINAV.parallel_env()
    observations, _ = env.reset(seed=1)
    while len(env.agents) == len(ROBOTS):
        observations, *_ = env.step(_heuristic_actions(env, observations))
    finished = next(agent for agent in ROBOTS if agent not in env.agents)
    actions = _heuristic_actions(env, observations)
    with pytest.raises(ActionError, match=f"{finished}.*finished"):
        env.step({**actions, finished: np.zeros(2)})
    with pytest.raises(ActionError, match="robot_9"):
        env.step({**actions, "robot_9": np.zeros(2)})
    env.step(actions)  # the env is still usable


@pytest.mark.parametrize(
    ("actions", "message"),
    [
        ({"follower_0": np.zeros(2)}, "follower_1"),
        ({agent: np.zeros(3) for agent in FOLLOWERS}, r"follower_0.*\(2,\)"),
        ({**dict.fromkeys(FOLLOWERS, np.zeros(2)), "follower_2": [0.0, np.nan]}, "follower_2"),
        ({**dict.fromkeys(FOLLOWERS, np.zeros(2)), "follower_3": "fast"}, "follower_3"),
        ([np.zeros(2)] * 4, "dict"),
    ],
)
def test_bad_actions_raise_action_error_naming_the_agent(actions, message: str) -> None:
    env = FORMATION.parallel_env()
    env.reset(seed=0)
    with pytest.raises(ActionError, match=message):
        env.step(actions)


def test_reset_without_seed_continues_and_seed_reproduces() -> None:
    env = FORMATION.parallel_env()
    first, _ = env.reset(seed=5)
    continued, _ = env.reset()
    again, _ = env.reset(seed=5)
    assert not np.array_equal(first["follower_0"], continued["follower_0"])
    for agent in FOLLOWERS:
        np.testing.assert_array_equal(first[agent], again[agent])


def test_kwargs_reach_the_scenario() -> None:
    env = FORMATION.parallel_env(n_followers=3, shape="wedge", spacing=0.4)
    env.reset(seed=0)
    poses = env.poses()
    assert poses.shape == (4, 3)
    distances = np.linalg.norm(poses[1:, :2] - poses[0, :2], axis=1)
    np.testing.assert_allclose(distances, [0.4, 0.4, 0.8], atol=1e-5)
    assert env.formation_targets().shape == (3, 2)
    assert 'shape = "wedge"' in env.config_toml()
    with pytest.raises(ConfigError, match="n_followers"):
        FORMATION.parallel_env(n_followers=0)
    multinav = MULTINAV.parallel_env(n_robots=3, config="multinav", max_cycles=50)
    multinav.reset(seed=0)
    assert multinav.poses().shape == (3, 3) and multinav.goals().shape == (3, 2)
    assert multinav.max_cycles == 50


def test_aec_env_runs_the_heuristic_to_the_end() -> None:
    env = FORMATION.env(config="paper_fig7")
    env.reset(seed=0)
    for _agent in env.agent_iter():
        observation, _, terminated, truncated, info = env.last()
        action = None if terminated or truncated else formation_follower_heuristic(observation)
        env.step(action)
    assert info["world_episode_stats"]["success"]  # the leader arrived
    assert env.unwrapped.formation_targets().shape == (4, 2)
    # The joint action the Gymnasium env takes for the same observation:
    joint = env.unwrapped.state()
    np.testing.assert_array_equal(
        formation_heuristic(joint).reshape(4, 2),
        formation_follower_heuristic(joint.reshape(4, 23)),
    )
