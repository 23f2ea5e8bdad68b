"""Swarms through Python (issue 16): the array env returns every agent's data at once and agrees
with the PettingZoo env step for step; a 1,000-robot world spawns apart and steps with finite
observations; bad actions and impossible swarms raise typed errors naming the problem."""

from __future__ import annotations

import numpy as np
import pytest

from khepera_gym.errors import ActionError, ConfigError
from khepera_gym.pettingzoo import multinav_v1


def test_the_array_env_agrees_with_the_pettingzoo_env() -> None:
    kwargs = {"n_robots": 40, "width": 5.0, "height": 5.0}
    arrays = multinav_v1.array_env(num_threads=1, **kwargs)
    dicts = multinav_v1.parallel_env(**kwargs)
    obs, _ = arrays.reset(seed=4)
    dicts.reset(seed=4)
    assert obs.shape == (1, 40, arrays.agent_obs_dim)
    assert arrays.agents == dicts.possible_agents
    rng = np.random.default_rng(0)
    for _ in range(30):
        action = rng.uniform(-0.2, 1.0, (1, 40, 2)).astype(np.float32)
        live = list(dicts.agents)
        obs, rewards, terminated, truncated, _ = arrays.step(action)
        step = dicts.step(
            {agent: action[0, k] for k, agent in enumerate(dicts.possible_agents) if agent in live}
        )
        for k, agent in enumerate(dicts.possible_agents):
            if agent in live:
                np.testing.assert_array_equal(obs[0, k], step[0][agent])
                assert rewards[0, k] == np.float32(step[1][agent])
                assert terminated[0, k] == step[2][agent]
        assert not truncated[0]


def test_a_thousand_robots_spawn_apart_and_step_with_finite_observations() -> None:
    env = multinav_v1.array_env(config="swarm")
    obs, _ = env.reset(seed=0)
    assert obs.shape[:2] == (1, 1000)
    poses = env.poses()[0]
    gaps = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    # Centres at least two radii (0.0704 m) + the spawn clearance (0.05 m) apart.
    assert gaps.min() >= 2 * 0.0704 + 0.05 - 1e-5
    for _ in range(10):
        obs, rewards, *_ = env.step(np.full((1, 1000, 2), 0.5, np.float32))
    assert np.isfinite(obs).all() and np.isfinite(rewards).all()


def test_bad_actions_raise_action_error() -> None:
    env = multinav_v1.array_env(n_robots=3)
    env.reset(seed=0)
    with pytest.raises(ActionError, match=r"shape \(1, 3, 2\)"):
        env.step(np.zeros((1, 2, 2), np.float32))
    bad = np.zeros((1, 3, 2), np.float32)
    bad[0, 1, 0] = np.nan
    with pytest.raises(ActionError, match="finite"):
        env.step(bad)


def test_too_many_robots_for_the_arena_says_how_many_fit() -> None:
    with pytest.raises(ConfigError, match=r"multinav\.n_robots.*fits about \d+"):
        multinav_v1.array_env(n_robots=500)
    with pytest.raises(ConfigError, match=r"multinav\.n_robots: must be >= 1, <= 10000, got 10001"):
        multinav_v1.array_env(config="swarm", n_robots=10001, width=200.0, height=200.0)


def test_ten_thousand_robots_are_allowed_where_the_arena_holds_them() -> None:
    """The cap is 10,000 robots (issue 54); the arena still bounds them."""
    with pytest.raises(ConfigError, match=r"multinav\.n_robots.*fits about \d+"):
        multinav_v1.array_env(config="swarm", n_robots=10000)
    env = multinav_v1.array_env(config="swarm", n_robots=10000, width=63.0, height=63.0)
    obs, _ = env.reset(seed=0)
    assert obs.shape[:2] == (1, 10000)
    obs, rewards, *_ = env.step(np.full((1, 10000, 2), 0.5, np.float32))
    assert np.isfinite(obs).all() and np.isfinite(rewards).all()


def test_split_by_robot_is_a_scenario_key_with_typed_errors() -> None:
    """``physics.split = "robot"`` (rapier only for the robots that can touch something) reaches
    the core from a keyword, gives a swarm the same results on one thread or two, and moves
    free robots differently from ``"world"``; bad values and the kinematic drive are refused."""
    kwargs = {"n_robots": 60, "width": 4.0, "height": 4.0}
    one = multinav_v1.array_env(num_threads=1, split="robot", **kwargs)
    two = multinav_v1.array_env(num_threads=2, split="robot", **kwargs)
    world = multinav_v1.array_env(num_threads=1, **kwargs)
    for env in (one, two, world):
        env.reset(seed=3)
    rng = np.random.default_rng(1)
    for _ in range(40):
        action = rng.uniform(-0.2, 1.0, (1, 60, 2)).astype(np.float32)
        a, *_ = one.step(action)
        b, *_ = two.step(action)
        world.step(action)
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(one.poses(), world.poses())
    with pytest.raises(ConfigError, match=r"physics\.split.*`world` or `robot`"):
        multinav_v1.array_env(split="robots", **kwargs)
    with pytest.raises(ConfigError, match=r"physics\.split.*traction"):
        multinav_v1.array_env(split="robot", drive="kinematic", **kwargs)
