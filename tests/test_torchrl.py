"""The TorchRL env (khepera_gym.learning.torchrl) and the BenchMARL tasks
(khepera_gym.learning.torchrl.benchmarl).

Needs the ``torchrl`` and ``benchmarl`` extras, which ``make test`` installs.
"""

from __future__ import annotations

import importlib
import importlib.util
import pickle
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("torchrl", reason="needs the torchrl extra: pip install 'khepera-gym[torchrl]'")

import torch
from conftest import FORMATION, LATEST, MULTINAV, random_actions

from khepera_gym import _core
from khepera_gym.baselines import PositionControl
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.learning.torchrl import (
    KheperaTorchEnv,
    multi_agent_tasks,
    torchrl_import_warnings_ignored,
)

with torchrl_import_warnings_ignored():
    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models import MlpConfig
    from tensordict import TensorDict
    from torchrl.envs import EnvBase
    from torchrl.envs.utils import MarlGroupMapType, check_env_specs, step_mdp

from khepera_gym.learning.torchrl.benchmarl import KheperaTask, default_task_config

#: Smaller scenarios for the multi-robot tasks, to keep the checks quick.
SMALL = {
    "multinav": {"n_robots": 3},
    "platoon": {"robots": 2},
    "consensus": {"n_robots": 3, "trigger": "event"},
}
#: Every kind of env: every task of the core (from the registry), then the variants that change
#: the agents (an agent leader, LED actions): (task, scenario overrides).
ENV_KINDS = [(task, SMALL.get(task, {})) for task, _, _ in _core.tasks()] + [
    ("formation", {"leader": "agent", "n_followers": 3, "shape": "wedge"}),
    ("multinav", {"n_robots": 2, "led_action": True}),
]


def group_action(env: KheperaTorchEnv, actions: np.ndarray) -> dict[Any, torch.Tensor]:
    """The TensorDict entries of joint actions (N, act_dim) for ``env``'s layout."""
    if not env.group_map:
        return {"action": torch.from_numpy(actions)}
    per_agent = actions.reshape(actions.shape[0], -1, 2)
    index = {name: i for i, name in enumerate(env.agent_names)}
    return {
        (group, "action"): torch.from_numpy(per_agent[:, [index[a] for a in members]].copy())
        for group, members in env.group_map.items()
    }


def step_with(env: KheperaTorchEnv, tensordict: TensorDict, actions: np.ndarray) -> TensorDict:
    """One ``env.step`` with joint actions; returns the step's TensorDict (with "next")."""
    for key, value in group_action(env, actions).items():
        tensordict[key] = value
    return env.step(tensordict)


# --- TorchRL's checker and the layout ---------------------------------------------------------


@pytest.mark.parametrize(("task", "overrides"), ENV_KINDS)
def test_check_env_specs_passes(task: str, overrides: dict[str, Any]) -> None:
    env = KheperaTorchEnv(task, 4, max_steps=2, num_threads=1, **overrides)
    # Episodes of 2 steps: the 3-step rollouts cross an episode end and a partial reset.
    check_env_specs(env, seed=0)
    check_env_specs(env, seed=0, break_when_any_done="both")


@pytest.mark.parametrize(("task", "overrides"), ENV_KINDS)
def test_torchrls_step_post_processing_would_change_nothing(
    task: str, overrides: dict[str, Any]
) -> None:
    """The env skips EnvBase._step_proc_data (reward reshapes, missing done keys): on its own
    step outputs, ended episodes included, TorchRL's version must be the identity."""
    env = KheperaTorchEnv(task, 3, max_steps=2, seed=0, **overrides)
    tensordict = env.reset()
    for _ in range(2):
        tensordict = env.rand_action(tensordict)
        skipped = env._step(tensordict)
        processed = EnvBase._step_proc_data(env, skipped.clone())
        assert set(processed.keys(True, True)) == set(skipped.keys(True, True))
        assert (processed == skipped).all()
        for key in skipped.keys(True, True):
            assert processed[key].shape == skipped[key].shape
        tensordict = step_mdp(tensordict.set("next", skipped))
    assert skipped["done"].all()
    env.run_type_checks = True  # TorchRL's checks on: its post-processing runs, and passes
    env.rollout(3, break_when_any_done=False)


def test_layout_of_groups_and_flat_keys() -> None:
    nav = KheperaTorchEnv("nav", 5)
    assert nav.group_map == {}
    assert nav.full_observation_spec["observation"].shape == (5, 18)
    assert nav.full_action_spec["action"].shape == (5, 2)
    assert nav.full_reward_spec["reward"].shape == (5, 1)

    formation = KheperaTorchEnv("formation", 5, leader="agent")
    assert formation.group_map == {
        "leader": ["leader"],
        "followers": ["follower_0", "follower_1", "follower_2", "follower_3"],
    }
    observation = formation.full_observation_spec
    assert observation["followers", "observation"].shape == (5, 4, 23)
    assert observation["leader", "observation"].shape == (5, 1, 18)
    assert observation["state"].shape == (5, 18 + 4 * 23)
    action = formation.full_action_spec["followers", "action"]
    assert action.shape == (5, 4, 2)
    assert torch.all(action.space.low == -1) and torch.all(action.space.high == 1)
    assert formation.full_reward_spec["followers", "reward"].shape == (5, 4, 1)
    assert set(formation.full_done_spec.keys()) == {"done", "terminated", "truncated"}

    multinav = KheperaTorchEnv("multinav", 5, n_robots=6)
    assert multinav.group_map == {"robots": [f"robot_{i}" for i in range(6)]}
    assert multinav.full_done_spec["robots", "terminated"].shape == (5, 6, 1)
    assert multinav.full_done_spec["done"].shape == (5, 1)


def test_led_actions_are_five_values_per_agent_and_reach_the_leds() -> None:
    env = KheperaTorchEnv("formation", 2, led_action=True, n_followers=3, seed=0)
    assert env.full_action_spec["followers", "action"].shape == (2, 3, 5)
    tensordict = env.reset()
    actions = torch.zeros((2, 3, 5))
    actions[1, 2, 2:] = torch.tensor([-1.0, -1.0, 1.0])  # world 1, follower 2: blue
    tensordict["followers", "action"] = actions
    env.step(tensordict)
    robot = env.agent_names.index("follower_2") + 1  # robot 0 is the scripted leader
    leds = env.sensor_readings()["leds"]
    assert leds[1, robot].tolist() == [0, 0, 63]
    assert leds[0, robot].tolist() == [32, 32, 32]


def test_group_map_types_regroup_the_agents() -> None:
    env = KheperaTorchEnv("formation", 3, group_map=MarlGroupMapType.ONE_GROUP_PER_AGENT)
    assert env.group_map == {f"follower_{k}": [f"follower_{k}"] for k in range(4)}
    check_env_specs(env, seed=1)
    # Followers in reverse order in one group: agent j of the group is follower 3 - j.
    reverse = [f"follower_{k}" for k in (3, 2, 1, 0)]
    reversed_env = KheperaTorchEnv("formation", 3, group_map={"team": reverse}, seed=1)
    plain = KheperaTorchEnv("formation", 3, seed=1)
    actions = random_actions(0, 5, (3, 8))
    reversed_td, plain_td = reversed_env.reset(), plain.reset()
    for step_actions in actions:
        reversed_td = step_with(reversed_env, reversed_td, step_actions)
        plain_td = step_with(plain, plain_td, step_actions)
        assert torch.equal(
            reversed_td["next", "team", "observation"],
            plain_td["next", "followers", "observation"].flip(1),
        )
        assert torch.equal(
            reversed_td["next", "team", "reward"], plain_td["next", "followers", "reward"].flip(1)
        )
        reversed_td, plain_td = step_mdp(reversed_td), step_mdp(plain_td)


# --- bit for bit against the native envs ------------------------------------------------------


def test_nav_rollout_equals_single_envs_across_episodes() -> None:
    """Row i replays gym.make(...) reset with seed s + i, then reset() after each episode."""
    worlds, steps, seed = 3, 70, 11
    env = KheperaTorchEnv("nav", worlds, max_steps=25, seed=seed)
    actions = random_actions(1, steps, (worlds, 2))
    tensordict = env.reset()
    records = []
    for step_actions in actions:
        tensordict["action"] = torch.from_numpy(step_actions)
        stepped, tensordict = env.step_and_maybe_reset(tensordict)
        records.append(stepped)
    episodes_ended = 0
    for world in range(worlds):
        single = gym.make(LATEST["nav"], max_steps=25)
        observation, _ = single.reset(seed=seed + world)
        for step, record in enumerate(records):
            assert np.array_equal(record["observation"][world].numpy(), observation)
            observation, reward, terminated, truncated, _ = single.step(actions[step, world])
            assert np.array_equal(record["next", "observation"][world].numpy(), observation)
            assert record["next", "reward"][world, 0].item() == np.float32(reward)
            assert record["next", "terminated"][world, 0].item() == terminated
            assert record["next", "truncated"][world, 0].item() == truncated
            if terminated or truncated:
                episodes_ended += 1
                observation, _ = single.reset()
    assert episodes_ended >= 2 * worlds


def test_first_episode_equals_the_native_vector_env() -> None:
    worlds, steps = 6, 40
    for env_id, task in ((LATEST["nav"], "nav"), (LATEST["formation"], "formation")):
        native = gym.make_vec(env_id, num_envs=worlds)
        env = KheperaTorchEnv(task, worlds, seed=3)
        native_obs, _ = native.reset(seed=3)
        tensordict = env.reset()
        key = "observation" if task == "nav" else "state"
        for step_actions in random_actions(2, steps, (worlds, native.single_action_space.shape[0])):
            assert np.array_equal(tensordict[key].numpy(), native_obs)
            native_obs, native_reward, terminated, truncated, _ = native.step(step_actions)
            assert not (terminated.any() or truncated.any())
            tensordict = step_with(env, tensordict, step_actions)
            if task == "nav":
                assert np.array_equal(tensordict["next", "reward"][:, 0].numpy(), native_reward)
            tensordict = step_mdp(tensordict)
        native.close()


@pytest.mark.parametrize(
    ("task", "module", "overrides"),
    [
        ("formation", FORMATION, {"n_followers": 3, "max_steps": 30}),
        ("multinav", MULTINAV, {"n_robots": 3, "max_steps": 120}),
    ],
)
def test_multi_agent_rollout_equals_pettingzoo_envs(
    task: str, module: Any, overrides: dict[str, Any]
) -> None:
    """Each group row holds that agent's observation, reward and flags of the PettingZoo env
    reset with seed s + i (multinav robots driven home, so some arrive before the others)."""
    worlds, seed = 2, 21
    env = KheperaTorchEnv(task, worlds, seed=seed, **overrides)
    group = "followers" if task == "formation" else "robots"
    agents = env.group_map[group]
    controller = PositionControl()
    rng = np.random.default_rng(5)
    tensordict = env.reset()
    records, joint_actions = [], []
    for _ in range(overrides["max_steps"] + 10):
        observation = tensordict[group, "observation"].numpy()
        if task == "multinav":
            actions, _ = controller.predict(observation.reshape(-1, 18))
            actions = actions.reshape(worlds, -1).astype(np.float32)
        else:
            actions = rng.uniform(-1, 1, (worlds, 2 * len(agents))).astype(np.float32)
        tensordict[group, "action"] = torch.from_numpy(actions.reshape(worlds, -1, 2))
        stepped, tensordict = env.step_and_maybe_reset(tensordict)
        records.append(stepped)
        joint_actions.append(actions)
    arrivals_before_the_end = 0
    for world in range(worlds):
        reference = module.parallel_env(**overrides)
        observations, _ = reference.reset(seed=seed + world)
        for record, actions in zip(records, joint_actions, strict=True):
            live = list(reference.agents)
            for k, agent in enumerate(agents):
                if agent in live:
                    assert np.array_equal(
                        record[group, "observation"][world, k].numpy(), observations[agent]
                    )
            per_agent = {a: actions[world, 2 * k : 2 * k + 2] for k, a in enumerate(agents)}
            observations, rewards, terminations, truncations, _ = reference.step(
                {agent: per_agent[agent] for agent in live}
            )
            for k, agent in enumerate(agents):
                if agent not in live:
                    continue
                next_group = record["next", group]
                assert np.array_equal(
                    next_group["observation"][world, k].numpy(), observations[agent]
                )
                assert next_group["reward"][world, k, 0].item() == np.float32(rewards[agent])
                if task == "multinav":
                    assert next_group["terminated"][world, k, 0].item() == terminations[agent]
                    assert next_group["truncated"][world, k, 0].item() == truncations[agent]
                    if terminations[agent] and reference.agents:
                        arrivals_before_the_end += 1
            assert record["next", "done"][world, 0].item() == (not reference.agents)
            if not reference.agents:
                observations, _ = reference.reset()
    if task == "multinav":
        assert arrivals_before_the_end > 0


# --- partial resets ---------------------------------------------------------------------------


def test_partial_reset_resets_exactly_the_masked_worlds() -> None:
    worlds, seed = 5, 100
    env = KheperaTorchEnv("avoid", worlds, seed=seed)
    twin = KheperaTorchEnv("avoid", worlds, seed=seed)  # never partially reset
    actions = random_actions(3, 20, (worlds, 2))
    tensordict, twin_td = env.reset(), twin.reset()
    for step_actions in actions[:10]:
        tensordict = step_mdp(step_with(env, tensordict, step_actions))
        twin_td = step_mdp(step_with(twin, twin_td, step_actions))
    poses_before = env.poses()
    observation_before = tensordict["observation"].clone()
    mask = torch.tensor([False, True, False, True, False])
    tensordict["_reset"] = mask.unsqueeze(-1)
    after = env.reset(tensordict)

    kept = ~mask
    assert torch.equal(after["observation"][kept], observation_before[kept])
    assert np.array_equal(env.poses()[kept.numpy()], poses_before[kept.numpy()])
    for world in (1, 3):
        # The reset continues world i's stream: a single env reset with seed s + i, driven
        # the same way, then reset() without a seed.
        single = gym.make("KheperaIV-Avoid-v1")
        single.reset(seed=seed + world)
        for step_actions in actions[:10]:
            single.step(step_actions[world])
        observation, _ = single.reset()
        assert np.array_equal(after["observation"][world].numpy(), observation)
        assert not np.array_equal(observation, observation_before[world].numpy())
    # The worlds left alone go on exactly as in a twin that never saw the reset.
    for step_actions in actions[10:]:
        after = step_mdp(step_with(env, after, step_actions))
        twin_td = step_mdp(step_with(twin, twin_td, step_actions))
        assert torch.equal(after["observation"][kept], twin_td["observation"][kept])
        assert not torch.equal(after["observation"][mask], twin_td["observation"][mask])


def test_partial_reset_after_set_seed_seeds_world_i_with_seed_plus_i() -> None:
    env = KheperaTorchEnv("formation", 4, seed=0)
    tensordict = env.reset()
    env.set_seed(500)
    tensordict["_reset"] = torch.tensor([[True], [False], [False], [True]])
    after = env.reset(tensordict)
    for world in (0, 3):
        single = gym.make(LATEST["formation"])
        observation, _ = single.reset(seed=500 + world)
        assert np.array_equal(after["state"][world].numpy(), observation)
    assert torch.equal(after["state"][1:3], tensordict["state"][1:3])
    # The seed was used up: the next full reset continues every stream.
    again = env.reset()
    single = gym.make(LATEST["formation"])
    single.reset(seed=500)
    assert np.array_equal(again["state"][0].numpy(), single.reset()[0])


def test_set_seed_makes_runs_repeat_bit_for_bit() -> None:
    first = KheperaTorchEnv("multinav", 4, max_steps=15)
    second = KheperaTorchEnv("multinav", 4, max_steps=15)
    torch.manual_seed(0)
    first.set_seed(9)
    run_a = first.rollout(40, break_when_any_done=False)
    torch.manual_seed(0)
    second.set_seed(9)
    run_b = second.rollout(40, break_when_any_done=False)
    assert (run_a == run_b).all()
    assert run_a["next", "done"].sum() == 2 * 4  # two episode ends per world, then resets


# --- the face: ids, ground truth, statistics, saved state -------------------------------------


def test_gymnasium_ids_name_their_task() -> None:
    by_id = KheperaTorchEnv("KheperaIV-Avoid-v1", 2, seed=1)
    by_name = KheperaTorchEnv("avoid", 2, seed=1)
    assert by_id.task == "avoid" and by_id.group_map == {}
    assert torch.equal(by_id.reset()["observation"], by_name.reset()["observation"])
    # An id's version picks its dynamics: -v0 is the task with version=0, not the latest.
    v0 = KheperaTorchEnv("KheperaIV-Avoid-v0", 2, seed=1).reset()["observation"]
    assert torch.equal(v0, KheperaTorchEnv("avoid", 2, seed=1, version=0).reset()["observation"])
    assert not torch.equal(v0, by_name.reset()["observation"])
    assert KheperaTorchEnv("KheperaIV-Formation", 1).group_map == {
        "followers": [f"follower_{k}" for k in range(4)]
    }


def test_ground_truth_and_episode_stats_are_the_vector_envs() -> None:
    """Accessors from BatchFace keep the world axis first, and episode_stats() is the native
    vector env's info["episode_stats"] of the step where worlds ended."""
    worlds, seed = 4, 8
    env = KheperaTorchEnv("formation", worlds, max_steps=30, seed=seed)
    native = gym.make_vec(LATEST["formation"], num_envs=worlds, max_episode_steps=30)
    native.reset(seed=seed)
    tensordict = env.reset()
    assert not any(env.episode_stats()["_return"])
    info: dict[str, Any] = {}
    for step_actions in random_actions(4, 30, (worlds, 8)):
        _, _, _, _, info = native.step(step_actions)
        tensordict = step_mdp(step_with(env, tensordict, step_actions))
        if info:
            break
    assert info and info["_episode_stats"].any()
    stats, expected = env.episode_stats(), info["episode_stats"]
    assert stats.keys() == expected.keys() and "formation_error_mean" in stats
    for name, values in expected.items():
        assert np.array_equal(stats[name], values)
    vector = native.unwrapped
    for accessor in ("poses", "goals", "targets", "obs_layout", "agent_layouts"):
        ours, theirs = getattr(env, accessor)(), getattr(vector, accessor)()
        if isinstance(theirs, np.ndarray):
            assert ours.shape[0] == worlds and np.array_equal(ours, theirs)
        else:
            assert ours == theirs
    assert env.scene(2) == vector.scene(2)
    assert env.max_episode_steps == 30 and env.n_robots == 5
    native.close()


def _drive(
    env: KheperaTorchEnv, tensordict: TensorDict, actions: np.ndarray
) -> tuple[list[TensorDict], TensorDict]:
    """Multinav steps as a collector makes them: each step's data, and the next step's input."""
    steps = []
    for step_actions in actions:
        per_robot = step_actions.reshape(env.batch_size[0], -1, 2)
        tensordict["robots", "action"] = torch.from_numpy(per_robot)
        stepped, tensordict = env.step_and_maybe_reset(tensordict)
        steps.append(stepped.clone())
    return steps, tensordict


def test_saved_state_restores_and_replays_bit_for_bit() -> None:
    worlds = 3
    env = KheperaTorchEnv("multinav", worlds, n_robots=3, max_steps=20, seed=4)
    actions = random_actions(6, 70, (worlds, 6))
    _, tensordict = _drive(env, env.reset(), actions[:25])
    state = env.get_state()
    first, _ = _drive(env, tensordict.clone(), actions[25:])
    for restored in (env, pickle.loads(pickle.dumps(env))):
        restored.set_state(state)
        again, _ = _drive(restored, tensordict.clone(), actions[25:])
        assert all((a == b).all() for a, b in zip(first, again, strict=True))
    assert sum(int(s["next", "done"].sum()) for s in first) >= worlds  # crossed episode ends
    # The statistics are part of the state: a fresh env restored shows the same.
    fresh = KheperaTorchEnv("multinav", worlds, n_robots=3, max_steps=20)
    fresh.set_state(state)
    env.set_state(state)
    ours, theirs = env.episode_stats(), fresh.episode_stats()
    assert ours["_return"].all()  # every world finished an episode in the first 25 steps
    assert all(np.array_equal(ours[name], theirs[name]) for name in ours)


# --- multinav's per-robot done flags ----------------------------------------------------------


def test_multinav_robots_end_separately_and_stay_done() -> None:
    worlds = 4
    env = KheperaTorchEnv("multinav", worlds, n_robots=4, max_steps=90, seed=7)
    controller = PositionControl()
    tensordict = env.reset()
    steps = []
    for _ in range(90):
        observation = tensordict["robots", "observation"].numpy()
        actions, _ = controller.predict(observation.reshape(-1, 18))
        tensordict["robots", "action"] = torch.from_numpy(actions.reshape(worlds, 4, 2))
        tensordict = env.step(tensordict)
        steps.append(tensordict["next"].clone())
        if tensordict["next", "done"].any():
            break
        tensordict = step_mdp(tensordict)
    terminated = torch.stack([s["robots", "terminated"][..., 0] for s in steps])  # (T, N, K)
    truncated = torch.stack([s["robots", "truncated"][..., 0] for s in steps])
    done = torch.stack([s["robots", "done"][..., 0] for s in steps])
    rewards = torch.stack([s["robots", "reward"][..., 0] for s in steps])
    root_done = torch.stack([s["done"][:, 0] for s in steps])
    assert torch.equal(done, terminated | truncated)
    # Some robot arrived while its world went on.
    early = terminated & ~root_done[..., None]
    assert early.any()
    # Once terminated a robot stays so, parks and earns nothing more.
    assert torch.all(terminated[1:] >= terminated[:-1])
    after_arrival = terminated[:-1] & terminated[1:]
    assert torch.all(rewards[1:][after_arrival] == 0)
    # The world's episode ends when every robot arrived, or at max_steps for every robot left.
    final = steps[-1]
    for world in range(worlds):
        robots_terminated = final["robots", "terminated"][world, :, 0]
        if final["terminated"][world, 0]:
            assert robots_terminated.all()
        elif final["truncated"][world, 0]:
            assert torch.equal(final["robots", "truncated"][world, :, 0], ~robots_terminated)
    assert final["done"].any()


# --- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"task": "walk"}, "unknown task 'walk'"),
        ({"task": "KheperaIV-Walk-v0"}, "or the Gymnasium ids"),
        ({"task": "nav", "group_map": {"agents": ["robot"]}}, "group_map does not apply"),
        (
            {"task": "formation", "group_map": {"followers": ["follower_0", "follower_7"]}},
            "names 'follower_7', which this formation env does not have",
        ),
        ({"task": "formation", "group_map": {"a": ["follower_0"]}}, "leaves out"),
        (
            {"task": "multinav", "group_map": {"a": ["robot_0"], "b": ["robot_0"]}},
            "is in both 'a' and 'b'",
        ),
        ({"task": "multinav", "group_map": {"state": ["robot_0"]}}, "group name 'state'"),
        ({"task": "multinav", "group_map": ["robot_0"]}, "group_map must be a dict"),
        (
            {
                "task": "formation",
                "leader": "agent",
                "group_map": MarlGroupMapType.ALL_IN_ONE_GROUP,
            },
            "mixes observation sizes",
        ),
        ({"task": "nav", "device": "cuda"}, "runs on the CPU"),
        ({"task": "nav", "device": "abacus"}, "not a torch device"),
        ({"task": "nav", "seed": -1}, "seed must be an int"),
        ({"task": "formation", "n_followerz": 3}, "n_followerz"),
        ({"task": "nav", "action_type": "discrete"}, "action_type"),
    ],
)
def test_bad_configs_raise_config_errors(kwargs: dict[str, Any], message: str) -> None:
    kwargs = dict(kwargs)
    task = kwargs.pop("task")
    with pytest.raises(ConfigError, match=message):
        KheperaTorchEnv(task, 2, **kwargs)


def test_bad_actions_raise_action_errors_and_change_nothing() -> None:
    env = KheperaTorchEnv("nav", 2, seed=0)
    tensordict = env.reset()
    poses = env.poses()
    with pytest.raises(ActionError, match=r"'action' must be a tensor of shape \(2, 2\), got "):
        env.step(tensordict.clone())  # no action
    tensordict["action"] = torch.zeros(2, 3)
    with pytest.raises(ActionError, match=r"got shape \(2, 3\)"):
        env.step(tensordict.clone())
    tensordict["action"] = torch.tensor([[0.5, 0.5], [float("nan"), 0.0]])
    with pytest.raises(ActionError, match="world 1 element 0 is NaN"):
        env.step(tensordict.clone())
    assert np.array_equal(env.poses(), poses)
    tensordict["action"] = torch.ones(2, 2, dtype=torch.float64)  # any real dtype is taken
    assert env.step(tensordict)["next", "observation"].dtype == torch.float32


def test_bad_uses_raise_khepera_errors() -> None:
    env = KheperaTorchEnv("multinav", 2, max_steps=1, seed=0)
    tensordict = env.rand_step(env.reset())
    assert tensordict["next", "done"].all()
    with pytest.raises(KheperaError, match="call reset"):
        env.rand_step(step_mdp(tensordict))  # the episode ended: reset first
    robots_reset = TensorDict({"_reset": torch.ones(2, 4, 1, dtype=torch.bool)}, batch_size=(2, 4))
    only_group = TensorDict({"robots": robots_reset}, batch_size=(2,))
    with pytest.raises(KheperaError, match="root '_reset' mask"):
        env.reset(only_group)


@pytest.mark.parametrize(
    ("hidden", "module", "extra"),
    [
        ("torchrl", "khepera_gym.learning.torchrl", "torchrl"),
        ("benchmarl", "khepera_gym.learning.torchrl.benchmarl", "benchmarl"),
    ],
)
def test_a_missing_extra_names_the_pip_command(
    monkeypatch: pytest.MonkeyPatch, hidden: str, module: str, extra: str
) -> None:
    for name in [name for name in sys.modules if name.split(".")[0] == hidden]:
        monkeypatch.setitem(sys.modules, name, None)  # importing it now raises ImportError
    for name in [n for n in sys.modules if n.startswith(("khepera_gym.learning.torchrl", module))]:
        monkeypatch.delitem(sys.modules, name)  # imported afresh (monkeypatch restores them)
    monkeypatch.delitem(sys.modules, "khepera_gym.learning.torchrl.benchmarl", raising=False)
    with pytest.raises(ImportError, match=rf"pip install 'khepera-gym\[{extra}\]'"):
        importlib.import_module(module)


# --- BenchMARL --------------------------------------------------------------------------------


@pytest.mark.parametrize("task", [KheperaTask.FORMATION, KheperaTask.MULTINAV])
def test_benchmarl_task_builds_a_batched_env(task: KheperaTask) -> None:
    task_class = task.get_from_yaml()
    assert task_class.config == default_task_config(task.name.lower())
    env = task_class.get_env_fun(num_envs=3, continuous_actions=True, seed=4, device="cpu")()
    assert env.batch_size == (3,)
    check_env_specs(env, seed=4)
    group = "followers" if task is KheperaTask.FORMATION else "robots"
    assert list(task_class.group_map(env)) == [group]
    assert task_class.max_steps(env) == default_task_config(task.name.lower())["max_steps"]
    obs_dim = 23 if group == "followers" else 18
    assert task_class.observation_spec(env)[group, "observation"].shape == (4, obs_dim)
    assert "state" not in list(task_class.observation_spec(env).keys())
    assert task_class.state_spec(env)["state"].shape == (
        env.full_observation_spec["state"].shape[1],
    )
    assert task_class.action_spec(env)[group, "action"].shape == (4, 2)
    assert task_class.supports_continuous_actions() and not task_class.supports_discrete_actions()
    rollout = env.rollout(5)
    assert rollout.shape == (3, 5)


def test_benchmarl_tasks_are_the_cores_multi_agent_tasks() -> None:
    assert [task.name.lower() for task in KheperaTask] == multi_agent_tasks()
    # Multi-agent: more than one agent in the task's default scenario (a scripted leader or
    # Khepera is no agent: DroneFollow has one by default).
    assert {"formation", "multinav"} <= set(multi_agent_tasks())
    assert not {"nav", "dronefollow"} & set(multi_agent_tasks())
    # The default config is the built-in scenario's: an env built from it is the default env.
    for task in KheperaTask:
        name = task.name.lower()
        config = default_task_config(name)
        assert config["max_steps"] == KheperaTorchEnv(name, 1).max_episode_steps
        assert KheperaTorchEnv(name, 1, **config).config_toml() == (
            KheperaTorchEnv(name, 1).config_toml()
        )
    assert {"n_followers", "shape", "leader"} <= set(default_task_config("formation"))


def test_benchmarl_task_config_from_yaml_and_errors(tmp_path: Any) -> None:
    path = tmp_path / "formation.yaml"
    path.write_text("n_followers: 3\nshape: line\nmax_steps: 50\n")
    task = KheperaTask.FORMATION.get_from_yaml(path)
    env = task.get_env_fun(num_envs=2, continuous_actions=True, seed=0, device="cpu")()
    assert env.group_map == {"followers": ["follower_0", "follower_1", "follower_2"]}
    assert env.max_episode_steps == 50
    with pytest.raises(ConfigError, match="continuous actions only"):
        task.get_env_fun(num_envs=2, continuous_actions=False, seed=0, device="cpu")
    clashing = KheperaTask.MULTINAV.get_task(config={"seed": 3})
    with pytest.raises(ConfigError, match="BenchMARL passes itself"):
        clashing.get_env_fun(num_envs=2, continuous_actions=True, seed=0, device="cpu")
    unknown = KheperaTask.MULTINAV.get_task(config={"n_robotz": 3})
    with pytest.raises(ConfigError, match="n_robotz"):
        unknown.get_env_fun(num_envs=2, continuous_actions=True, seed=0, device="cpu")()
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="mapping"):
        KheperaTask.FORMATION.get_from_yaml(tmp_path / "list.yaml")


def small_mappo(tmp_path: Any, algorithm: MappoConfig | None = None) -> Experiment:
    """Two MAPPO iterations of 1,200 frames on Formation with two followers in a line."""
    torch.manual_seed(0)
    config = ExperimentConfig.get_from_yaml()
    config.sampling_device = config.train_device = config.buffer_device = "cpu"
    config.max_n_frames = 2 * 1_200
    config.on_policy_collected_frames_per_batch = 1_200
    config.on_policy_n_envs_per_worker = 12
    config.on_policy_minibatch_size = 400
    config.on_policy_n_minibatch_iters = 2
    config.evaluation = False
    config.loggers = []
    config.render = False
    config.create_json = False
    config.checkpoint_at_end = False
    config.save_folder = str(tmp_path)
    model = MlpConfig.get_from_yaml()
    model.num_cells = [32, 32]
    return Experiment(
        task=KheperaTask.FORMATION.get_task(config={"n_followers": 2, "shape": "line"}),
        algorithm_config=algorithm or MappoConfig.get_from_yaml(),
        model_config=model,
        critic_model_config=model,
        seed=0,
        config=config,
    )


@pytest.mark.filterwarnings("ignore::DeprecationWarning:torchrl")
@pytest.mark.filterwarnings("ignore:No episode terminated this iteration:UserWarning")
def test_benchmarl_mappo_trains_on_formation(tmp_path: Any) -> None:
    """Two MAPPO iterations on the batch: BenchMARL collects the frames asked for, from the
    batch itself, and the policy's weights change."""
    experiment = small_mappo(tmp_path)
    assert isinstance(experiment.test_env.base_env, KheperaTorchEnv)
    weights = [p.detach().clone() for p in experiment.policy.parameters()]
    experiment.run()
    assert experiment.total_frames == 2_400
    assert experiment.n_iters_performed == 2
    changed = [
        not torch.equal(w, p) for w, p in zip(weights, experiment.policy.parameters(), strict=True)
    ]
    assert any(changed)


@pytest.mark.filterwarnings("ignore::DeprecationWarning:torchrl")
@pytest.mark.filterwarnings("ignore:No episode terminated this iteration:UserWarning")
def test_mappo_example_learns_one_sigma_per_action_whatever_the_state(tmp_path: Any) -> None:
    """examples/benchmarl_mappo.py --shared-sigma: σ is one trained number per action (SB3's
    PPO), the same in every state, where BenchMARL's actor outputs it per state."""
    path = Path(__file__).resolve().parents[1] / "examples" / "benchmarl_mappo.py"
    spec = importlib.util.spec_from_file_location("benchmarl_mappo_example", path)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    algorithm = MappoConfig.get_from_yaml()
    shared = example.SharedSigma(algorithm)
    experiment = small_mappo(tmp_path, algorithm)
    shared.train_with(experiment)
    assert torch.equal(shared.sigma, torch.ones(2))
    experiment.run()
    assert experiment.n_iters_performed == 2
    sigma = shared.sigma
    assert not torch.equal(sigma, torch.ones(2))  # the actor's loss trained it
    env = KheperaTorchEnv("formation", 3, seed=5, n_followers=2, shape="line")
    with torch.no_grad():
        output = experiment.policy(env.reset())
    scale = output["followers", "scale"]
    assert scale.shape == (3, 2, 2)  # worlds, followers, wheels: different states
    assert torch.equal(scale, sigma.expand_as(scale))
    loc = output["followers", "loc"]
    assert not torch.equal(loc[0], loc[1])  # the states differ; their σ does not
