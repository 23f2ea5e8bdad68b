"""The paper's controllers as baseline policies (khepera_gym.baselines): they solve the tasks the
paper shows them on, act the same on one observation or a batch, and reject bad input."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import AVOID_V0_ID, FORMATION_V0_ID, LATEST, NAV_V0_ID

from khepera_gym import _core
from khepera_gym.analysis.plots import record_rollout
from khepera_gym.baselines import (
    VFH,
    BaselinePolicy,
    Braitenberg,
    LeaderFollower,
    PositionControl,
    braitenberg_weights,
    formation_offsets,
)
from khepera_gym.errors import ActionError
from khepera_gym.pettingzoo import formation_v1

FIG6_START = (-0.75, 0.05, 0.0)  # configs/paper_fig6.toml spawn.start
FIG6_GOAL = (0.75, 0.05)  # configs/paper_fig6.toml spawn.goal
FOLLOWER_OBS_DIM = 23


def _one_episode_per_world(
    env_id: str, policy, n: int, seed: int = 1000, **kwargs
) -> dict[str, np.ndarray]:
    """Runs world i (seed + i) of an n-world vector env for exactly one episode; returns each
    world's episode statistics."""
    envs = gym.make_vec(env_id, num_envs=n, num_threads=2, **kwargs)
    observations, _ = envs.reset(seed=seed)
    done = np.zeros(n, dtype=bool)
    results: dict[str, np.ndarray] = {}
    while not done.all():
        observations, _, terminations, truncations, infos = envs.step(policy(observations))
        ended = (terminations | truncations) & ~done
        if ended.any():
            for key, values in infos["episode_stats"].items():
                if not key.startswith("_"):
                    results.setdefault(key, np.zeros(n, values.dtype))[ended] = values[ended]
        done |= ended
    envs.close()
    return results


# The paper's controllers with the paper's gains, on the dynamics they were tuned for (v0: wheels at
# their command within a step, frictionless contacts). On v1 the README's tables give their rates.
def test_position_control_reaches_the_goal_in_99_percent_of_nav_episodes() -> None:
    stats = _one_episode_per_world(NAV_V0_ID, PositionControl(), 200)
    assert stats["success"].mean() >= 0.99, stats["success"].mean()


@pytest.mark.parametrize("policy", [Braitenberg(), VFH()], ids=["braitenberg", "vfh"])
def test_braitenberg_and_vfh_reach_the_target_past_the_fig6_wall(policy: BaselinePolicy) -> None:
    # From the scene's start pose; tests/controllers.rs checks VFH over 20 seeds (>= 18 reach).
    rollout = record_rollout(AVOID_V0_ID, policy, seed=0, config="paper_fig6")
    np.testing.assert_allclose(rollout.poses[0, 0], FIG6_START, atol=1e-6)
    np.testing.assert_allclose(rollout.goals[0], FIG6_GOAL, atol=1e-6)
    assert rollout.stats["success"], rollout.stats
    assert np.linalg.norm(rollout.poses[-1, 0, :2] - FIG6_GOAL) < 0.05


def test_position_control_alone_is_stopped_by_the_fig6_wall() -> None:
    rollout = record_rollout(LATEST["avoid"], PositionControl(), seed=0, config="paper_fig6")
    assert not rollout.stats["success"]
    assert rollout.stats["collisions"] > 100  # pressed against the wall
    assert rollout.poses[-1, 0, 0] < -0.15  # never past the wall (x = -0.15)


def test_braitenberg_reaches_90_percent_of_avoid_goals_among_random_obstacles() -> None:
    stats = _one_episode_per_world(AVOID_V0_ID, Braitenberg(), 200)
    assert stats["success"].mean() >= 0.9, stats["success"].mean()


def test_leader_follower_keeps_the_formation_error_under_10_cm_without_obstacles() -> None:
    stats = _one_episode_per_world(FORMATION_V0_ID, LeaderFollower(), 50)
    assert stats["formation_error_mean"].mean() < 0.1, stats["formation_error_mean"]
    assert stats["success"].mean() >= 0.95


@pytest.mark.parametrize(
    ("shape", "n_followers"), [("cross", 4), ("cross", 6), ("line", 3), ("wedge", 4), ("circle", 5)]
)
def test_leader_follower_offsets_are_the_scenarios_eq12_offsets(
    shape: str, n_followers: int
) -> None:
    """Followers computing eq. 12 from (r, β) aim where the env's own targets are."""
    env = gym.make(LATEST["formation"], shape=shape, n_followers=n_followers, spacing=0.4)
    observation, _ = env.reset(seed=5)
    for _ in range(20):  # the leader moves and turns
        observation, *_ = env.step(np.full(2 * n_followers, 0.2, np.float32))
    own_offsets = LeaderFollower(shape=shape, r=0.4, n_followers=n_followers)
    from_observation = LeaderFollower(shape=None)
    from_env = LeaderFollower.for_env(env)
    assert from_env.offsets == own_offsets.offsets
    np.testing.assert_allclose(own_offsets(observation), from_observation(observation), atol=1e-5)
    env.close()


def test_formation_offsets_follow_the_shapes() -> None:
    cross = formation_offsets("cross", 0.5, 5)
    np.testing.assert_allclose(
        cross, [(0.5, 0), (0.5, math.pi / 2), (0.5, math.pi), (0.5, 1.5 * math.pi), (1.0, 0)]
    )
    np.testing.assert_allclose(
        formation_offsets("line", 0.3, 3),
        [(0.3, math.pi / 2), (0.3, -math.pi / 2), (0.6, math.pi / 2)],
    )
    np.testing.assert_allclose(
        formation_offsets("wedge", 0.3, 2), [(0.3, 0.75 * math.pi), (0.3, -0.75 * math.pi)]
    )
    np.testing.assert_allclose(
        formation_offsets("circle", 0.5, 3),
        [(0.5, 0), (0.5, 2 * math.pi / 3), (0.5, 4 * math.pi / 3)],
    )
    explicit = LeaderFollower(r=[0.5, 0.6], beta=[math.pi, -math.pi / 2])
    assert explicit.offsets == [(0.5, math.pi), (0.6, -math.pi / 2)]
    with pytest.raises(ValueError, match="unknown formation shape"):
        LeaderFollower(shape="star")
    with pytest.raises(ValueError, match="2 distances for 3 angles"):
        LeaderFollower(r=[0.5, 0.6], beta=[0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="n_followers=2 but beta has 3"):
        LeaderFollower(beta=[0.0, 1.0, 2.0], n_followers=2)


def _avoid_observations(n: int = 16) -> np.ndarray:
    """Observations with obstacles in sight: a few steps into seeded Avoid episodes."""
    envs = gym.make_vec(LATEST["avoid"], num_envs=n, num_threads=1)
    observations, _ = envs.reset(seed=4)
    policy = Braitenberg()
    for _ in range(30):
        observations, *_ = envs.step(policy(observations))
    envs.close()
    assert np.any(observations[:, :8] > 0.05)  # some IR sees something
    return observations


@pytest.mark.parametrize(
    "policy",
    [PositionControl(), Braitenberg(), Braitenberg(weights="kteam"), VFH()],
    ids=["position_control", "braitenberg", "braitenberg_kteam", "vfh"],
)
def test_single_and_batched_actions_are_identical(policy) -> None:
    observations = _avoid_observations()
    batched = policy(observations)
    assert batched.shape == (16, 2) and batched.dtype == np.float32
    assert np.all(np.abs(batched) <= 1.0)
    for index, observation in enumerate(observations):
        np.testing.assert_array_equal(policy(observation), batched[index])
    np.testing.assert_array_equal(policy(observations), batched)  # no state between calls
    np.testing.assert_array_equal(policy(observations.astype(np.float64)), batched)
    np.testing.assert_array_equal(policy(observations.tolist()), batched)
    # Column-major input: the Rust core reads rows of C-ordered buffers; the wrapper converts.
    np.testing.assert_array_equal(policy(np.asfortranarray(observations)), batched)
    np.testing.assert_array_equal(policy(observations.reshape(4, 4, -1)), batched.reshape(4, 4, 2))


def test_leader_follower_acts_on_joint_observations_single_blocks_and_dicts() -> None:
    env = formation_v1.parallel_env(config="paper_fig7")
    observations, _ = env.reset(seed=1)
    for _ in range(40):
        observations, *_ = env.step({agent: np.full(2, 0.1, np.float32) for agent in env.agents})
    joint = env.state()
    policy = LeaderFollower()
    joint_action = policy(joint)
    assert joint_action.shape == (8,)
    by_agent = policy(observations)
    assert list(by_agent) == [f"follower_{k}" for k in range(4)]
    np.testing.assert_allclose(np.concatenate(list(by_agent.values())), joint_action, atol=1e-6)
    # Following the observation's own targets, one block at a time is the same as jointly.
    own_targets = LeaderFollower(shape=None)
    blocks = joint.reshape(4, FOLLOWER_OBS_DIM)
    np.testing.assert_array_equal(own_targets(blocks).ravel(), own_targets(joint))
    with pytest.raises(ActionError, match="4 follower offsets but the observation has 1"):
        policy(blocks[0])
    with pytest.raises(ActionError, match="robot_0"):
        policy({"robot_0": blocks[0]})
    env.close()


def test_leader_follower_drives_an_agent_leader_with_its_leader_policy() -> None:
    env = gym.make(LATEST["formation"], leader="agent")
    observation, _ = env.reset(seed=3)
    for leader in (PositionControl(), Braitenberg(), VFH()):
        action = LeaderFollower(leader=leader)(observation)
        assert action.shape == (10,)
        np.testing.assert_array_equal(action[:2], leader(observation[:18]))
    env.close()
    parallel = formation_v1.parallel_env(leader="agent", n_followers=2, shape="line")
    observations, _ = parallel.reset(seed=3)
    actions = LeaderFollower.for_env(parallel, leader=VFH())(observations)
    assert list(actions) == ["leader", "follower_0", "follower_1"]
    np.testing.assert_array_equal(actions["leader"], VFH()(observations["leader"]))
    np.testing.assert_array_equal(
        np.concatenate(list(actions.values())),
        LeaderFollower(shape="line", n_followers=2, leader=VFH())(parallel.state()),
    )
    parallel.close()
    with pytest.raises(ValueError, match="leader must be"):
        LeaderFollower(leader=LeaderFollower())


@pytest.mark.parametrize(
    "policy",
    [PositionControl(), Braitenberg(), VFH(), LeaderFollower()],
    ids=lambda policy: type(policy).__name__,
)
def test_predict_returns_action_and_state_like_stable_baselines3(policy) -> None:
    dim = 4 * FOLLOWER_OBS_DIM if isinstance(policy, LeaderFollower) else 18
    act_dim = 8 if isinstance(policy, LeaderFollower) else 2
    batch = np.zeros((5, dim), np.float32)
    action, state = policy.predict(batch)
    assert action.shape == (5, act_dim) and state is None
    action, state = policy.predict(batch[0], state=("kept",), episode_start=np.ones(1, bool))
    assert action.shape == (act_dim,) and state == ("kept",)
    np.testing.assert_array_equal(policy.predict(batch, deterministic=False)[0], policy(batch))


def test_wrong_observations_raise_action_error_naming_the_problem() -> None:
    policy = Braitenberg()
    with pytest.raises(ActionError, match="18 values, got 17"):
        policy(np.zeros(17, np.float32))
    bad = np.zeros((3, 18), np.float32)
    bad[2, 5] = np.nan
    with pytest.raises(ActionError, match="row 2 element 5 is NaN"):
        policy(bad)
    with pytest.raises(ActionError, match="scalar"):
        policy(1.0)
    with pytest.raises(ActionError, match="numeric"):
        policy(["a"] * 18)
    with pytest.raises(ActionError, match="inf"):
        policy(np.full(18, 1e300))  # overflows float32
    with pytest.raises(ActionError, match="formation observation"):
        LeaderFollower()(np.zeros(18, np.float32))


def test_bad_parameters_raise_value_errors() -> None:
    with pytest.raises(ValueError, match="unknown Braitenberg weights 'nope'"):
        Braitenberg(weights="nope")
    with pytest.raises(ValueError, match="2 x 8"):
        Braitenberg(weights=np.zeros((8, 2)))
    with pytest.raises(ValueError, match="smax"):
        Braitenberg(smax=0.0)
    with pytest.raises(ValueError, match="vmax"):
        PositionControl(vmax=-1.0)
    with pytest.raises(ValueError, match="sectors"):
        VFH(sectors=2)
    with pytest.raises(ValueError, match="sectors must be an integer"):
        VFH(sectors=36.5)


def test_braitenberg_weights_come_from_the_rust_core_and_smax_scales_them() -> None:
    np.testing.assert_array_equal(
        braitenberg_weights("kteam"), np.array(_core.braitenberg_weights("kteam"))
    )
    observations = _avoid_observations()
    default = braitenberg_weights("default")
    np.testing.assert_array_equal(
        Braitenberg(smax=0.5)(observations), Braitenberg(weights=2 * default)(observations)
    )
    assert not np.array_equal(Braitenberg(smax=0.5)(observations), Braitenberg()(observations))
    # With nothing in sight the block is off: Braitenberg is position control.
    clear = np.zeros(18, np.float32)
    clear[13], clear[15] = 1.0, 1.0  # goal 1 m straight ahead
    np.testing.assert_array_equal(Braitenberg()(clear), PositionControl()(clear))
    clear[3] = 0.5  # obstacle straight ahead: turn right
    left, right = Braitenberg()(clear)
    assert left > right
