"""Per-agent episode statistics: in every multi-agent env, an agent's ``episode_stats`` are its
own (the sum of its rewards, its steps, its success as the task defines it for one agent, its
path and contacts), and the world's aggregate is under ``"world_episode_stats"``.

Checked against the rewards each agent was handed, summed, in every PettingZoo module (from the
registry), the array env, and through the RLlib, TorchRL and SB3 shared-agent adapters; and
``step`` before ``reset`` raises in every env kind.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import ALL_IDS, PETTINGZOO_MODULES, latest_module, random_actions

from khepera_gym import _core
from khepera_gym.batch_face import WORLD_STATS_KEY
from khepera_gym.envs import formation_follower_heuristic, nav_heuristic
from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv

#: Episode length of these tests (steps), so that episodes end within them.
EPISODE = 60
#: The statistics every agent has.
AGENT_STATS = {"return", "length", "success", "path_length", "collisions"}
#: Settings that give a module more agents (an agent leader, an agent-driven Khepera).
MORE_AGENTS = [("formation", {"leader": "agent"}), ("drone_follow", {"driver": "agent"})]
#: (module, kwargs) of the multi-agent envs checked: every module with its defaults, then those.
PARALLEL_ENVS = [(module, {}) for module in PETTINGZOO_MODULES.values()] + [
    (latest_module(stem), kwargs) for stem, kwargs in MORE_AGENTS
]
PARALLEL_IDS = list(PETTINGZOO_MODULES) + [f"{stem}-{next(iter(kw))}" for stem, kw in MORE_AGENTS]


def _close(value: float, expected: float) -> bool:
    """float32 sums in the core against float64 sums here."""
    return bool(np.isclose(value, expected, rtol=1e-5, atol=1e-4))


def _random_policy(env: Any, rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {
        agent: rng.uniform(-1, 1, env.action_space(agent).shape).astype(np.float32)
        for agent in env.agents
    }


def _play(env: Any, policy: Any, seed: int) -> tuple[dict, dict, dict, dict, float, int]:
    """One episode of a PettingZoo parallel env: each agent's summed rewards, steps and the info
    it left with, the world's infos at the end, the world's return (each step's mean over every
    agent's reward) and its length."""
    observations, _ = env.reset(seed=seed)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    steps = dict.fromkeys(env.possible_agents, 0)
    left_with: dict[str, dict] = {}
    world_return, length, last_infos = 0.0, 0, {}
    while env.agents:
        live = list(env.agents)
        observations, rewards, terminations, truncations, infos = env.step(policy(observations))
        length += 1
        world_return += float(np.mean(env.agent_rewards(), dtype=np.float32))
        for agent in live:
            returns[agent] += rewards[agent]
            steps[agent] += 1
            if terminations[agent] or truncations[agent]:
                left_with[agent] = infos[agent]
        last_infos = infos
    return returns, steps, left_with, last_infos, world_return, length


@pytest.mark.parametrize(("module", "kwargs"), PARALLEL_ENVS, ids=PARALLEL_IDS)
def test_each_agent_leaves_with_its_own_statistics_and_the_worlds(
    module: Any, kwargs: dict[str, Any]
) -> None:
    env = module.parallel_env(max_steps=EPISODE, **kwargs)
    rng = np.random.default_rng(3)
    returns, steps, left_with, last_infos, world_return, length = _play(
        env, lambda _: _random_policy(env, rng), seed=4
    )
    assert set(left_with) == set(env.possible_agents)
    for agent, info in left_with.items():
        stats = info["episode_stats"]
        assert set(stats) == AGENT_STATS, agent
        assert _close(stats["return"], returns[agent]), (agent, stats, returns[agent])
        assert stats["length"] == steps[agent]
        assert 0 <= stats["collisions"] <= stats["length"]
        assert stats["path_length"] >= 0.0
    for info in last_infos.values():
        world = info[WORLD_STATS_KEY]
        assert world["length"] == length
        assert _close(world["return"], world_return)
        assert set(world) >= AGENT_STATS
        # The world's path and contacts are every robot's: at least any one agent's robot's.
        robots = [a for a in env.possible_agents if env.agent_robot(a) < env.n_robots]
        own = [left_with[a]["episode_stats"] for a in robots]
        assert world["path_length"] >= max((s["path_length"] for s in own), default=0) - 1e-5
        assert world["collisions"] >= max((s["collisions"] for s in own), default=0)
    if len(env.possible_agents) > 1 and module.__name__.rpartition(".")[2].startswith(
        ("multinav", "formation", "drone_follow")
    ):
        # Agents with rewards of their own do not all report one return (issue 33's symptom).
        assert len({round(returns[a], 3) for a in env.possible_agents}) > 1


def test_a_drone_agent_has_its_flight_for_path_and_no_contacts() -> None:
    env = latest_module("drone_follow").parallel_env(max_steps=EPISODE, driver="agent")
    rng = np.random.default_rng(0)
    _, _, left_with, last_infos, _, _ = _play(env, lambda _: _random_policy(env, rng), seed=1)
    drone = left_with["drone"]["episode_stats"]
    robot = left_with["robot"]["episode_stats"]
    assert drone["collisions"] == 0 and drone["path_length"] > 0.0
    # The world's path is the robots' (the Khepera's): the drone's flight is its own.
    assert last_infos["drone"][WORLD_STATS_KEY]["path_length"] == pytest.approx(
        robot["path_length"], rel=1e-6
    )


def test_multinav_robots_that_arrive_leave_with_their_own_success() -> None:
    env = latest_module("multinav").parallel_env()
    returns, steps, left_with, last_infos, _, length = _play(
        env, lambda obs: {a: nav_heuristic(obs[a]) for a in env.agents}, seed=1
    )
    early = [a for a, info in left_with.items() if WORLD_STATS_KEY not in info]
    assert early, "no robot arrived before the others"
    for agent, info in left_with.items():
        stats = info["episode_stats"]
        assert stats["success"]  # every robot reached its goal
        assert stats["length"] == steps[agent] <= length
        assert _close(stats["return"], returns[agent])
    assert all(steps[a] < length for a in early)
    assert all(info[WORLD_STATS_KEY]["success"] for info in last_infos.values())


def test_random_formation_followers_do_not_succeed_where_the_heuristic_does() -> None:
    module = latest_module("formation")
    env = module.parallel_env()
    rng = np.random.default_rng(0)
    _, _, left_with, last_infos, _, _ = _play(env, lambda _: _random_policy(env, rng), seed=0)
    assert all(info[WORLD_STATS_KEY]["success"] for info in last_infos.values())  # the leader
    assert not any(info["episode_stats"]["success"] for info in left_with.values())
    _, _, left_with, _, _, _ = _play(
        env, lambda obs: {a: formation_follower_heuristic(obs[a]) for a in env.agents}, seed=0
    )
    assert all(info["episode_stats"]["success"] for info in left_with.values())


def _array_env_tasks() -> list[tuple[str, int | None]]:
    """(task, version) of the latest PettingZoo module of each task."""
    latest: dict[str, Any] = {}
    for module in PETTINGZOO_MODULES.values():
        env_class = module.parallel_env().unwrapped
        latest[env_class.TASK] = env_class.VERSION
    return sorted(latest.items())


@pytest.mark.parametrize(("task", "version"), _array_env_tasks(), ids=lambda x: str(x))
def test_array_env_reports_each_agents_own_statistics(task: str, version: int | None) -> None:
    try:
        env = MultiAgentArrayEnv(task, 3, version=version, max_steps=40, num_threads=2)
    except ConfigError:
        pytest.skip(f"{task}'s agents observe blocks of different sizes (no array env)")
    with pytest.raises(KheperaError, match="before reset"):
        env.step(np.zeros((3, env.n_agents, 2), np.float32))
    env.reset(seed=7)
    sums = np.zeros((3, env.n_agents))
    steps = np.zeros((3, env.n_agents), int)
    live = np.ones((3, env.n_agents), bool)
    world_sums = np.zeros(3)
    starting = np.zeros(3, bool)  # the next step resets these worlds (NEXT_STEP)
    ended_episodes = 0
    actions = random_actions(2, 100, (3, env.n_agents, 2))
    for step_actions in actions:
        _, rewards, terminated, truncated, info = env.step(step_actions)
        for world in np.flatnonzero(starting):
            sums[world], steps[world], live[world], world_sums[world] = 0, 0, True, 0
        counted = live & ~starting[:, None]  # an autoreset step is no step of an episode
        sums += np.where(counted, rewards, 0.0)
        steps += counted
        world_sums += np.where(starting, 0.0, rewards.mean(axis=1, dtype=np.float32))
        live &= ~terminated
        ended = (terminated.all(axis=1) | truncated) & ~starting
        if ended.any():
            own, world = info["episode_stats"], info[WORLD_STATS_KEY]
            assert own["return"].shape == (3, env.n_agents)
            np.testing.assert_array_equal(own["_return"], ended)
            for w in np.flatnonzero(ended):
                np.testing.assert_allclose(own["return"][w], sums[w], rtol=1e-5, atol=1e-4)
                np.testing.assert_array_equal(own["length"][w], steps[w])
                assert world["length"][w] == steps[w].max()
                assert world["return"][w] == pytest.approx(world_sums[w], rel=1e-5, abs=1e-4)
                ended_episodes += 1
        starting = ended
    assert ended_episodes >= 3


# --- the adapters ------------------------------------------------------------------------------


#: The tasks with several agents in their default scenario, from the registry.
MULTI_AGENT_TASKS = [t for t, _, _ in _core.tasks() if len(_core.Batch(t, 1).agents()) > 1]


@pytest.mark.parametrize("task", MULTI_AGENT_TASKS)
def test_sb3_shared_agent_rows_report_their_agents_own_statistics(task: str) -> None:
    pytest.importorskip("stable_baselines3")
    from khepera_gym.learning.sb3 import SharedAgentsVecEnv

    worlds = 2
    env = SharedAgentsVecEnv(task, worlds, max_episode_steps=EPISODE, seed=3)
    with pytest.raises(KheperaError, match="before reset"):
        env.step(np.zeros((env.num_envs, 2), np.float32))
    env.reset()
    rows = env.rows_per_world
    sums = np.zeros(env.num_envs)
    checked = 0
    for step_actions in random_actions(4, 2 * EPISODE, (env.num_envs, 2)):
        _, rewards, dones, infos = env.step(step_actions)
        sums += rewards
        for row in np.flatnonzero(dones):
            own, world = infos[row]["episode_stats"], infos[row][WORLD_STATS_KEY]
            assert set(own) == AGENT_STATS
            assert infos[row]["is_success"] == own["success"]
            assert _close(own["return"], sums[row]), (row, own["return"], sums[row])
            assert own["length"] <= world["length"] == EPISODE or world["length"] < EPISODE
            mean = np.mean(sums[(row // rows) * rows : (row // rows + 1) * rows])
            assert world["return"] == pytest.approx(mean, rel=1e-4, abs=1e-3)
            checked += 1
        sums[dones] = 0.0
    assert checked >= env.num_envs


def test_rllib_multi_agent_env_reports_each_agents_own_statistics() -> None:
    pytest.importorskip("ray.rllib")
    from khepera_gym.learning.rllib.followers import FormationFollowersVectorEnv
    from khepera_gym.learning.rllib.multi_agent import KheperaMultiAgentEnv

    env = KheperaMultiAgentEnv(latest_module("multinav").parallel_env(max_steps=EPISODE))
    env.reset(seed=5)
    rng = np.random.default_rng(1)
    returns = dict.fromkeys(env.possible_agents, 0.0)
    left: dict[str, dict] = {}
    while env.agents:
        actions = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}
        _, rewards, terminateds, truncateds, infos = env.step(actions)
        for agent, reward in rewards.items():
            returns[agent] += reward
            if terminateds[agent] or truncateds[agent]:
                left[agent] = infos[agent]["episode_stats"]
    assert set(left) == set(env.possible_agents)
    for agent, stats in left.items():
        assert _close(stats["return"], returns[agent])

    followers = FormationFollowersVectorEnv(2, max_episode_steps=30, num_threads=1)
    with pytest.raises(KheperaError, match="before reset"):
        followers.step(np.zeros((followers.num_envs, 2), np.float32))
    followers.reset(seed=0)
    sums = np.zeros(followers.num_envs)
    for step_actions in random_actions(6, 30, (followers.num_envs, 2)):
        _, rewards, terminations, truncations, infos = followers.step(step_actions)
        sums += rewards
    assert (terminations | truncations).all()
    np.testing.assert_allclose(infos["episode_stats"]["return"], sums, rtol=1e-5, atol=1e-4)
    np.testing.assert_array_equal(infos["_episode_stats"], np.ones(followers.num_envs, bool))
    world_returns = infos[WORLD_STATS_KEY]["return"].reshape(2, -1)
    assert (world_returns == world_returns[:, :1]).all()  # the world's, on each of its rows
    np.testing.assert_allclose(
        world_returns[:, 0], sums.reshape(2, -1).mean(axis=1), rtol=1e-4, atol=1e-3
    )


def test_torchrl_agent_episode_stats_are_each_agents_own() -> None:
    pytest.importorskip("torchrl")
    import torch

    from khepera_gym.learning.torchrl import KheperaTorchEnv

    worlds = 2
    env = KheperaTorchEnv("multinav", worlds, n_robots=3, max_steps=40, seed=2)
    group = "robots"
    tensordict = env.reset()
    sums = np.zeros((worlds, 3))
    ended_any = np.zeros(worlds, bool)
    for step_actions in random_actions(9, 40, (worlds, 3, 2)):
        tensordict[group, "action"] = torch.from_numpy(step_actions)
        stepped, tensordict = env.step_and_maybe_reset(tensordict)
        sums += stepped["next", group, "reward"][..., 0].numpy()
        ended_any |= stepped["next", "done"][:, 0].numpy()
    assert ended_any.all()
    stats = env.agent_episode_stats()[group]
    np.testing.assert_array_equal(stats["_return"], np.ones(worlds, bool))
    np.testing.assert_allclose(stats["return"], sums, rtol=1e-5, atol=1e-4)
    assert stats["length"].shape == (worlds, 3)
    with pytest.raises(KheperaError, match="one agent"):
        KheperaTorchEnv("nav", 1).agent_episode_stats()


# --- step before reset ---------------------------------------------------------------------------


@pytest.mark.parametrize("env_id", ALL_IDS)
@pytest.mark.parametrize("mode", [gym.vector.AutoresetMode.NEXT_STEP, "Disabled"])
def test_vector_env_step_before_reset_raises_and_steps_nothing(env_id: str, mode: Any) -> None:
    envs = gym.make_vec(env_id, num_envs=2, num_threads=1, autoreset_mode=mode)
    state = envs.unwrapped.get_state()
    with pytest.raises(KheperaError, match="before reset"):
        envs.step(np.zeros(envs.action_space.shape, np.float32))
    assert envs.unwrapped.get_state() == state
    envs.reset(seed=0)
    envs.step(np.zeros(envs.action_space.shape, np.float32))
    envs.close()


@pytest.mark.parametrize("name", list(PETTINGZOO_MODULES))
def test_parallel_env_step_before_reset_raises_and_steps_nothing(name: str) -> None:
    env = PETTINGZOO_MODULES[name].parallel_env()
    state = env.unwrapped.get_state()
    actions = {agent: np.zeros(2, np.float32) for agent in env.possible_agents}
    with pytest.raises(KheperaError, match="before reset"):
        env.step(actions)
    assert env.unwrapped.get_state() == state
    env.reset(seed=0)
    env.step({agent: env.action_space(agent).sample() * 0 for agent in env.agents})
    env.close()
