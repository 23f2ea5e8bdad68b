"""Ray RLlib (khepera_gym.learning.rllib): seeds per EnvRunner, RLlib's env checks, multi-agent
envs, a short local PPO that learns Nav, and the errors for configs the envs cannot serve.

Needs the rllib extra (ray[rllib], torch), which ``make test`` installs. One local Ray instance
serves the module; EnvRunners are built in this process (``num_env_runners=0``, or RLlib's
runner classes constructed with a worker index), so no remote actor is started. About a minute
on 2 cores.
"""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

pytest.importorskip("ray.rllib", reason="needs the rllib extra: pip install 'khepera-gym[rllib]'")

import ray
import torch
from conftest import FORMATION, module_name
from ray.rllib.core.rl_module.rl_module import RLModule, RLModuleSpec
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner

from khepera_gym.batch_face import BatchFace
from khepera_gym.cli import main as cli_main
from khepera_gym.errors import ConfigError
from khepera_gym.learning import rllib
from khepera_gym.pettingzoo import multinav_v0
from khepera_gym.registration import latest_ids

NAV = "khepera_gym/KheperaIV-Nav-v0"
#: A small, quick PPO for the tests that only need RLlib to run (not to learn).
TINY_PPO = {
    "train_batch_size_per_learner": 256,
    "minibatch_size": 128,
    "num_epochs": 1,
    "model": {"fcnet_hiddens": [16, 16]},
}

pytestmark = [
    # Several RLlib EnvRunners built in one process each register their env under the same
    # Gymnasium id (RLlib's own "rllib-single-agent-env-v0"), which makes Gymnasium warn.
    pytest.mark.filterwarnings("ignore:.*Overriding environment rllib-:UserWarning"),
    # Ray 2.52's ray.init announces a change of its GPU environment variables (no GPU here).
    pytest.mark.filterwarnings("ignore:Tip. In future versions of Ray:FutureWarning"),
    # Ray 2.52 leaves the Popen handles of its own processes (raylet, GCS) unwaited and their
    # /dev/null files open.
    pytest.mark.filterwarnings("ignore:subprocess [0-9]+ is still running:ResourceWarning"),
    pytest.mark.filterwarnings("ignore:unclosed file .*/dev/null:ResourceWarning"),
    # Ray 2.52's Algorithm still builds Tune's deprecated UnifiedLogger (2.60 no longer does).
    pytest.mark.filterwarnings(
        "ignore:This API is deprecated and may be removed in future Ray:DeprecationWarning"
    ),
]


@pytest.fixture(scope="module", autouse=True)
def local_ray(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """One local Ray instance for the module, and torch on one thread (as `train` uses)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    patch = pytest.MonkeyPatch()
    # Every Algorithm (a Tune Trainable) makes a log folder under ~/ray_results: keep them here
    # (Ray 2.52's Algorithm module has a copy of the path of its own).
    results = str(tmp_path_factory.mktemp("ray_results"))
    patch.setattr("ray.tune.trainable.trainable.DEFAULT_STORAGE_PATH", results)
    patch.setattr("ray.rllib.algorithms.algorithm.DEFAULT_STORAGE_PATH", results, raising=False)
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()
    patch.undo()
    torch.set_num_threads(threads)


def first_observations(runner: SingleAgentEnvRunner | MultiAgentEnvRunner) -> list:
    """The first observation of every episode of one short sample of ``runner``."""
    episodes = runner.sample(num_timesteps=runner.num_envs, random_actions=True)
    runner.stop()
    return [episode.get_observations(0) for episode in episodes]


# --- seeds ---------------------------------------------------------------------------------------


def test_env_runners_get_disjoint_worlds_equal_to_single_envs_with_expected_seeds() -> None:
    seed, runners, worlds = 7, (1, 2), 4
    config = rllib.ppo_config(
        NAV, TINY_PPO, seed=seed, num_env_runners=2, num_envs_per_env_runner=worlds
    )
    observations = [
        observation
        for worker_index in runners
        for observation in first_observations(
            SingleAgentEnvRunner(config=config, worker_index=worker_index)
        )
    ]
    assert len(observations) == 8
    assert len({observation.tobytes() for observation in observations}) == 8
    expected_seeds = [
        rllib.runner_world_seed(seed, worker_index, worlds, world)
        for worker_index in runners
        for world in range(worlds)
    ]
    assert expected_seeds == [(seed + w) * worlds + i for w in runners for i in range(worlds)]
    for observation, world_seed in zip(observations, expected_seeds, strict=True):
        single_observation, _ = gym.make("KheperaIV-Nav-v0").reset(seed=world_seed)
        np.testing.assert_array_equal(observation, single_observation)


def test_plain_gym_id_repeats_worlds_across_runners_which_the_adapter_prevents() -> None:
    # Why the adapter exists: through the plain Gymnasium id RLlib seeds runner w with seed + w
    # and the batch world i with that + i, so world 1 of runner 1 is world 0 of runner 2.
    config = rllib.ppo_config(NAV, TINY_PPO, seed=7, num_envs_per_env_runner=4).environment(
        "KheperaIV-Nav-v0"
    )
    runner_1, runner_2 = (
        first_observations(SingleAgentEnvRunner(config=config, worker_index=w)) for w in (1, 2)
    )
    np.testing.assert_array_equal(runner_1[1], runner_2[0])


def test_multi_agent_runners_get_disjoint_worlds() -> None:
    seed, env_config = 3, {"n_robots": 2}
    config = rllib.ppo_config(
        "khepera_gym/multinav_v0",
        TINY_PPO,
        seed=seed,
        num_env_runners=2,
        num_envs_per_env_runner=2,
        env_config=env_config,
    )
    joint = []
    for worker_index in (1, 2):
        for copy, observation in enumerate(
            first_observations(MultiAgentEnvRunner(config=config, worker_index=worker_index))
        ):
            world = multinav_v0.parallel_env(**env_config)
            # RLlib resets copy j of runner w with seed + w + j.
            expected, _ = world.reset(
                seed=rllib.multi_agent_world_seed(seed + worker_index + copy, worker_index)
            )
            for agent in world.possible_agents:
                np.testing.assert_array_equal(observation[agent], expected[agent])
            joint.append(np.concatenate([observation[a] for a in world.possible_agents]))
    assert len({observation.tobytes() for observation in joint}) == 4


def test_env_names_survive_a_ray_restart() -> None:
    # Ray's registry gives what was registered before ray.init() (here: on import) to the first
    # Ray session only; ppo_config registers the names again for the session at hand.
    ray.shutdown()
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    config = rllib.ppo_config(NAV, TINY_PPO, seed=5, num_envs_per_env_runner=2)
    observations = first_observations(SingleAgentEnvRunner(config=config, worker_index=0))
    world_seed = rllib.runner_world_seed(5, 0, 2, 1)  # (seed + runner) · worlds + world
    expected, _ = gym.make("KheperaIV-Nav-v0").reset(seed=world_seed)
    np.testing.assert_array_equal(observations[1], expected)


# --- envs under RLlib --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "rows"),
    [
        (NAV, 4),
        ("khepera_gym/KheperaIV-Avoid-v0", 4),
        ("khepera_gym/KheperaIV-Formation-v0", 4),
        (rllib.FOLLOWERS_ENV, 8),
    ],
)
def test_vector_envs_pass_rllib_checks_and_train(name: str, rows: int) -> None:
    config = rllib.ppo_config(name, TINY_PPO, num_env_runners=0, num_envs_per_env_runner=rows)
    algo = rllib.build_algo(config)  # RLlib builds the module from the env's spaces
    try:
        result = algo.train()
        runner_env = algo.env_runner.env.unwrapped
        assert runner_env.num_envs == rows
        assert runner_env.num_threads == 1  # the driver's runner: 1 CPU
        module = algo.get_module()
        assert module.observation_space == runner_env.single_observation_space
        assert module.action_space == runner_env.single_action_space
        assert result["env_runners"]["num_env_steps_sampled_lifetime"] >= 256
    finally:
        algo.stop()


@ray.remote
class RunnerLikeActor:
    """An actor like an EnvRunner: builds the vector env the registered creator makes."""

    def batch_threads(self) -> int:
        return rllib.VectorEnvCreator(NAV)({"num_envs": 2}).unwrapped.num_threads


@pytest.mark.parametrize("cpus", [1, 2])
def test_batch_threads_default_to_the_cpus_ray_gives_the_runner(cpus: int) -> None:
    actor = RunnerLikeActor.options(num_cpus=cpus).remote()  # type: ignore[attr-defined]
    assert ray.get(actor.batch_threads.remote()) == cpus
    ray.kill(actor)


def test_followers_rows_replay_pettingzoo_followers_across_an_episode_end() -> None:
    seed, worlds, steps = 11, 2, 12
    env = rllib.FormationFollowersVectorEnv(worlds, n_followers=3, max_steps=5, num_threads=1)
    followers = env.followers_per_world
    observations, _ = env.reset(seed=seed)
    references = [FORMATION.parallel_env(n_followers=3, max_cycles=5) for _ in range(worlds)]
    reference_obs = [ref.reset(seed=seed + w)[0] for w, ref in enumerate(references)]
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, env.num_envs, 2))
    for step in range(steps):
        for world, reference in enumerate(references):
            for k, agent in enumerate(reference.possible_agents):
                np.testing.assert_array_equal(
                    observations[world * followers + k], reference_obs[world][agent]
                )
        observations, rewards, terminated, truncated, infos = env.step(actions[step])
        for world, reference in enumerate(references):
            rows = slice(world * followers, (world + 1) * followers)
            if not reference.agents:  # the vector env reset this world on this step
                reference_obs[world], _ = reference.reset()
                assert np.all(rewards[rows] == 0.0)
                assert not terminated[rows].any() and not truncated[rows].any()
                continue
            step_actions = {
                agent: actions[step][world * followers + k]
                for k, agent in enumerate(reference.possible_agents)
            }
            reference_obs[world], ref_rewards, _, ref_truncated, _ = reference.step(step_actions)
            np.testing.assert_array_equal(
                rewards[rows], np.float32([ref_rewards[a] for a in reference.possible_agents])
            )
            assert list(truncated[rows]) == [ref_truncated[a] for a in reference.possible_agents]
            if truncated[rows].all():
                assert infos["episode_stats"]["_length"][rows].all()
                assert np.all(infos["episode_stats"]["length"][rows] == 5)


def test_multi_agent_env_agents_leave_as_they_terminate_under_rllib() -> None:
    # robot_0 starts on its goal: one step moves it at most 0.813 m/s x 0.05 s = 4.1 cm, inside
    # goal_radius (5 cm), so it arrives at the first step whatever its action and leaves, while
    # robot_1 (1.7 m from its goal) drives on until the time limit.
    env_config = {
        "n_robots": 2,
        "start": [0.0, 0.0, 0.0, -0.6, -0.6, 0.0],
        "goal": [0.0, 0.0, 0.6, 0.6],
        "max_cycles": 20,
        "render_mode": "rgb_array",
    }
    env = rllib.MultiAgentEnvCreator("khepera_gym/multinav_v0")(env_config)
    env.reset(seed=0)
    assert env.agents == env.possible_agents == ["robot_0", "robot_1"]
    _, _, terminateds, truncateds, _ = env.step(
        {agent: np.zeros(2, np.float32) for agent in env.agents}
    )
    assert terminateds == {"robot_0": True, "robot_1": False, "__all__": False}
    assert truncateds == {"robot_0": False, "robot_1": False, "__all__": False}
    assert env.agents == ["robot_1"]
    assert env.render().shape == (480, 480, 3)

    config = rllib.ppo_config(
        "khepera_gym/multinav_v0",
        TINY_PPO,
        num_env_runners=0,
        num_envs_per_env_runner=1,
        env_config=env_config,
    ).environment(
        # RLlib's env checker steps once after reset and wants every key of that step's results
        # in env.agents, i.e. it assumes no agent leaves on the first step, which this one does.
        disable_env_checking=True
    )
    runner = MultiAgentEnvRunner(config=config, worker_index=0)
    episodes = runner.sample(num_episodes=1, random_actions=True)
    runner.stop()
    agent_episodes = episodes[0].agent_episodes
    assert len(agent_episodes["robot_0"]) == 1 and agent_episodes["robot_0"].is_terminated
    assert len(agent_episodes["robot_1"]) == 20 and agent_episodes["robot_1"].is_truncated
    assert episodes[0].is_truncated


@pytest.mark.parametrize(
    ("name", "env_config", "shared"),
    [
        ("khepera_gym/formation_v0", {"n_followers": 3, "max_cycles": 50}, True),
        ("khepera_gym/formation_v0", {"n_followers": 2, "leader": "agent"}, False),
        ("khepera_gym/multinav_v0", {"n_robots": 3, "max_cycles": 50}, True),
        ("khepera_gym/multinav_v0", {"n_robots": 2, "max_cycles": 50}, False),
    ],
)
def test_multi_agent_ppo_steps_with_shared_and_per_agent_policies(
    name: str, env_config: dict, shared: bool
) -> None:
    mapping = rllib.policy_mapping(name, env_config, shared=shared)
    config = rllib.ppo_config(
        name,
        TINY_PPO,
        num_env_runners=0,
        num_envs_per_env_runner=1,
        env_config=env_config,
        shared=shared,
    )
    algo = rllib.build_algo(config)
    try:
        result = algo.train()
    finally:
        algo.stop()
    agents = rllib.KheperaMultiAgentEnv(rllib.MULTI_AGENT_ENVS[name].parallel_env(**env_config))
    steps = result["env_runners"]["num_agent_steps_sampled_lifetime"]
    assert set(steps) == set(agents.possible_agents)
    assert all(count >= 256 for count in steps.values())
    modules = {"shared_policy"} if shared else set(agents.possible_agents)
    assert modules == mapping["policies"]
    assert modules <= set(result["learners"])


# --- faces over the batch ----------------------------------------------------------------------


def test_rllib_envs_show_their_world_through_the_shared_face() -> None:
    # Both RLlib faces of a 3-follower Formation world reset with seed 4 show the world a single
    # FormationEnv reset with seed 4 shows, through the same BatchFace accessors.
    single = gym.make(latest_ids()["formation"], n_followers=3).unwrapped
    single.reset(seed=4)
    followers = rllib.FormationFollowersVectorEnv(2, n_followers=3, num_threads=1)
    followers.reset(seed=4)
    multi_agent = rllib.make_multi_agent_env(
        f"khepera_gym/{module_name(FORMATION)}", {"n_followers": 3}
    )
    multi_agent.reset(seed=4)
    for face, world in ((followers, lambda a: a[0]), (multi_agent, lambda a: a)):
        assert isinstance(face, BatchFace)
        np.testing.assert_array_equal(world(face.poses()), single.poses())
        np.testing.assert_array_equal(world(face.goals()), single.goals())
        np.testing.assert_array_equal(world(face.targets()), single.targets())
        for key, values in single.sensor_readings().items():
            np.testing.assert_array_equal(world(face.sensor_readings()[key]), values)
        assert face.config_toml() == single.config_toml()
        assert face.obs_layout() == single.obs_layout()
        assert face.agent_layouts() == single.agent_layouts()
        assert face.max_episode_steps == single.max_episode_steps
    np.testing.assert_array_equal(followers.formation_targets(), followers.targets())
    assert followers.follower_layout == single.agent_layouts()["follower_0"]


def test_followers_env_saves_restores_and_pickles_its_state_across_an_episode_end() -> None:
    env = rllib.FormationFollowersVectorEnv(2, n_followers=2, max_steps=6, num_threads=1)
    env.reset(seed=5)
    actions = np.random.default_rng(1).uniform(-1, 1, (10, env.num_envs, 2)).astype(np.float32)
    for step in actions[:3]:
        env.step(step)
    state = env.get_state()
    first = [env.step(step) for step in actions[3:]]  # the worlds end at step 6, reset at 7
    clone = pickle.loads(pickle.dumps(env))
    for restored in (env, clone):
        restored.set_state(state)
        again = [restored.step(step) for step in actions[3:]]
        for before, after in zip(first, again, strict=True):
            for x, y in zip(before[:4], after[:4], strict=True):
                np.testing.assert_array_equal(x, y)
            assert before[4].keys() == after[4].keys()
    assert any(result[4] for result in first)  # the replay crossed an episode end


def test_multi_agent_env_saves_and_restores_its_world() -> None:
    env = rllib.make_multi_agent_env("khepera_gym/multinav_v0", {"n_robots": 2})
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    actions = [{a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents} for _ in range(30)]
    state = env.get_state()
    first = [env.step(action)[0] for action in actions]
    env.set_state(state)
    again = [env.step(action)[0] for action in actions]
    for x, y in zip(first, again, strict=True):
        assert x.keys() == y.keys()
        for agent in x:
            np.testing.assert_array_equal(x[agent], y[agent])
    # In a fresh env, a reset without a seed after set_state continues the restored world's
    # stream (rather than drawing a first seed), as in the PettingZoo env.
    fresh = rllib.make_multi_agent_env("khepera_gym/multinav_v0", {"n_robots": 2})
    fresh.set_state(env.get_state())
    twin = multinav_v0.parallel_env(n_robots=2)
    twin.set_state(env.get_state())
    np.testing.assert_array_equal(fresh.reset()[0]["robot_0"], twin.reset()[0]["robot_0"])


# --- learning ----------------------------------------------------------------------------------


def test_train_cli_rllib_ppo_learns_nav_and_saves_a_restorable_policy(tmp_path: Path) -> None:
    # 6 PPO iterations of 4096 steps (the rllib_ppo.toml table, sampled in this process).
    # Criterion from the task: every goal lies at least spawn.min_goal_distance (0.5 m) from the
    # start, so a policy reaching every goal closes at least that much per episode; random
    # wheels drift about 0. The learned policy must beat random by that on the 100 evaluation
    # episodes (seeds 10000..10099), both measured here.
    out = tmp_path / "run"
    code = cli_main(
        [
            "train",
            "--backend",
            "rllib",
            "--env",
            "KheperaIV-Nav",
            "--timesteps",
            "24576",
            "--num-env-runners",
            "0",
            "--eval-freq",
            "0",
            "--out",
            str(out),
            "--verbose",
            "0",
        ]
    )
    assert code == 0
    run = json.loads((out / "run.json").read_text())
    assert run["backend"] == "rllib" and run["timesteps"] >= 24576 and run["steps_per_second"] > 0
    assert {"date", "commit", "machine", "command"} <= run["meta"].keys()
    final = rllib.Evaluation(**run["final"])
    nav = gym.make_vec(latest_ids()["nav"], num_envs=1, vectorization_mode="vector_entry_point")
    min_goal_distance = tomllib.loads(nav.unwrapped.config_toml())["spawn"]["min_goal_distance"]
    random = rllib.evaluate_policy(rllib.random_policy(2, seed=0), latest_ids()["nav"], 100)
    assert final.mean_progress > random.mean_progress + min_goal_distance, (final, random)

    module = RLModule.from_checkpoint(
        out / "checkpoint" / "learner_group" / "learner" / "rl_module" / "default_policy"
    )
    restored = rllib.evaluate_policy(rllib.module_policy(module), latest_ids()["nav"], 100)
    assert restored.mean_return == pytest.approx(final.mean_return, rel=1e-5)
    assert restored.success_rate == final.success_rate


# --- bad input ---------------------------------------------------------------------------------


def test_unknown_env_names_and_ids_raise_config_error_listing_the_known_ones() -> None:
    config = rllib.ppo_config(NAV, TINY_PPO).environment("khepera_gym/KheperaIV-Fly-v0")
    with pytest.raises(ConfigError, match=r"unknown khepera_gym RLlib env .*KheperaIV-Nav-v0"):
        rllib.check_config(config)
    with pytest.raises(ConfigError, match="unknown environment 'KheperaIV-Fly'"):
        rllib.ppo_config("KheperaIV-Fly", TINY_PPO)
    with pytest.raises(ConfigError, match="not a multi-agent env"):
        rllib.policy_mapping(NAV)


def test_config_asking_for_spaces_the_env_lacks_raises_config_error() -> None:
    config = rllib.ppo_config(NAV, TINY_PPO)
    discrete = config.copy().rl_module(
        rl_module_spec=RLModuleSpec(action_space=gym.spaces.Discrete(4))
    )
    with pytest.raises(ConfigError, match=r"action space Discrete\(4\), but the env has Box"):
        rllib.check_config(discrete)
    wrong_shape = config.copy().environment(
        observation_space=gym.spaces.Box(-1.0, 1.0, (10,), np.float32)
    )
    with pytest.raises(ConfigError, match=r"observation space Box\(-1..1, \(10,\).*\(18,\)"):
        rllib.build_algo(wrong_shape)
    with pytest.raises(ConfigError, match="gym_env_vectorize_mode='vector_entry_point'"):
        rllib.check_config(config.copy().env_runners(gym_env_vectorize_mode="sync"))
    with pytest.raises(ConfigError, match="is single-agent, but the config is multi-agent"):
        rllib.check_config(
            config.copy().multi_agent(**rllib.policy_mapping("khepera_gym/multinav_v0"))
        )


def test_config_asking_for_a_task_or_scenario_the_env_lacks_raises_config_error() -> None:
    config = rllib.ppo_config(NAV, TINY_PPO)
    with pytest.raises(ConfigError, match=r"asks for task='avoid', but .*Nav-v0 runs its own"):
        rllib.check_config(config.copy().environment(NAV, env_config={"task": "avoid"}))
    with pytest.raises(ConfigError, match="wings"):
        rllib.check_config(config.copy().environment(NAV, env_config={"wings": 2}))
    with pytest.raises(ConfigError, match="needs the scripted leader"):
        rllib.check_config(
            config.copy().environment(rllib.FOLLOWERS_ENV, env_config={"leader": "agent"})
        )
    with pytest.raises(ConfigError, match=r"multiple of the 3 followers per world"):
        rllib.check_config(
            rllib.ppo_config(
                rllib.FOLLOWERS_ENV,
                TINY_PPO,
                num_envs_per_env_runner=4,
                env_config={"n_followers": 3},
            )
        )
    with pytest.raises(ConfigError, match="is a native vector env"):
        rllib.VectorEnvCreator(NAV)({"max_steps": 10})  # RLlib's single-env entry point
    with pytest.raises(ConfigError, match="RLlib PPO hyperparameters"):
        rllib.ppo_config(NAV, {"learning_rate": 1e-3})  # SB3's name; RLlib's is lr


def test_multi_agent_config_mismatches_raise_config_error() -> None:
    name, leader = "khepera_gym/formation_v0", {"n_followers": 2, "leader": "agent"}
    with pytest.raises(ConfigError, match="cannot share one policy; use shared=False"):
        rllib.policy_mapping(name, leader, shared=True)
    with pytest.raises(ConfigError, match="cannot share one policy"):
        rllib.ppo_config(name, TINY_PPO, env_config=leader)
    config = rllib.ppo_config(name, TINY_PPO, env_config=leader, shared=False)
    shared = config.copy().multi_agent(
        policies={"shared_policy"}, policy_mapping_fn=rllib.SharedPolicy("shared_policy")
    )
    with pytest.raises(ConfigError, match="share module 'shared_policy' but their spaces"):
        rllib.check_config(shared)
    missing = config.copy().multi_agent(
        policies={"leader"}, policy_mapping_fn=rllib.policy_per_agent
    )
    with pytest.raises(ConfigError, match="maps agent 'follower_0' to 'follower_0', which is not"):
        rllib.check_config(missing)
    single = rllib.ppo_config(NAV, TINY_PPO).environment(name, env_config=leader)
    with pytest.raises(ConfigError, match="is multi-agent: configure its policies"):
        rllib.check_config(single)


def test_missing_extra_names_the_pip_command() -> None:
    # A fresh interpreter in which `import ray` fails, as without the extra.
    script = (
        "import sys; sys.modules['ray'] = None\n"
        "try:\n"
        "    import khepera_gym.learning.rllib\n"
        "except ImportError as error:\n"
        "    print(error)\n"
        "from khepera_gym.cli import main\n"
        "main(['train', '--backend', 'rllib', '--env', 'KheperaIV-Nav'])\n"
    )
    completed = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert "pip install 'khepera-gym[rllib]'" in completed.stdout
    assert completed.returncode != 0
    assert "train --backend rllib needs Ray RLlib" in completed.stderr
    assert "pip install 'khepera-gym[rllib]'" in completed.stderr


def test_every_rllib_env_runs_the_version_in_its_name() -> None:
    """The RLlib adapters, like every other entry point (tests/test_module_versions.py): each
    registered name reports the behaviour version in it and resolves that version's scenario."""
    from khepera_gym import _core
    from khepera_gym.registration import task_and_version

    for name, module in rllib.creators.MULTI_AGENT_ENVS.items():
        task, version = task_and_version(name.removeprefix(rllib.creators.ENV_PREFIX))
        env = rllib.creators.make_multi_agent_env(name, {})
        assert env.behaviour_version == version, name
        expected = _core.Batch(task, 1, version=version, num_threads=1).config_toml()
        assert env.config_toml() == expected, name
        assert module.parallel_env().behaviour_version == version
    for name in rllib.creators.env_names():
        if name in rllib.creators.MULTI_AGENT_ENVS:
            continue
        version = rllib.creators.FOLLOWERS_ENVS.get(name)
        if version is None:
            version = task_and_version(name.removeprefix(rllib.creators.ENV_PREFIX))[1]
        env = rllib.creators.VectorEnvCreator(name)({"num_envs": 4, "num_threads": 1})
        assert env.unwrapped.behaviour_version == version, name
        env.close()
