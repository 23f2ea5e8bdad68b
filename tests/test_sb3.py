"""stable-baselines3 on the Rust batch: the VecEnv's SB3 semantics, determinism, SB3 wrappers and
callbacks, and ``khepera-gym train`` end to end (a short PPO run whose zip loads and predicts)."""

from __future__ import annotations

import dataclasses
import json
import pickle
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
import pytest

pytest.importorskip(
    "stable_baselines3", reason="needs the sb3 extra: pip install 'khepera-gym[sb3]'"
)

from conftest import CONSENSUS, LATEST, random_actions
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from khepera_gym import cli
from khepera_gym.config import tomllib
from khepera_gym.envs import formation_heuristic, nav_heuristic
from khepera_gym.errors import ActionError, ConfigError, KheperaError
from khepera_gym.learning.sb3 import (
    FormationFollowersVecEnv,
    KheperaSB3VecEnv,
    NormalizedPolicy,
    SharedAgentsVecEnv,
    evaluate_episodes,
    load_policy,
    make_formation_vec_env,
    make_vec_env,
    resolve_env_id,
)
from khepera_gym.learning.train import (
    ALGORITHMS,
    HYPERPARAMS_DIR,
    build_model,
    load_hyperparams,
    parse_override,
)

pytestmark = pytest.mark.usefixtures("one_torch_thread")


class HeuristicPolicy:
    """A heuristic of khepera_gym.envs with SB3's ``predict``."""

    def __init__(self, heuristic: Any) -> None:
        self.heuristic = heuristic

    def predict(
        self, observation: npt.NDArray[np.float32], deterministic: bool = True, **_: Any
    ) -> tuple[npt.NDArray[np.float32], None]:
        return self.heuristic(observation), None


@pytest.mark.parametrize("env_id", list(LATEST.values()))
def test_sb3_check_env_passes_on_each_single_env(env_id: str) -> None:
    env = gym.make(env_id)
    check_env(env)
    check_env(env.unwrapped)
    env.close()


def test_make_vec_env_resolves_the_unversioned_id_without_a_warning() -> None:
    assert resolve_env_id("KheperaIV-Nav") == LATEST["nav"]
    assert resolve_env_id(LATEST["avoid"]) == LATEST["avoid"]
    with pytest.raises(ConfigError, match="KheperaIV-Nav-v1"):
        make_vec_env("KheperaIV-Swim", 2)


def test_vec_env_reset_and_step_have_sb3_shapes_and_dtypes() -> None:
    env = make_vec_env(LATEST["nav"], 4, seed=0, num_threads=2)
    assert isinstance(env, KheperaSB3VecEnv)
    assert env.num_envs == 4
    assert env.observation_space == gym.make(LATEST["nav"]).observation_space
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    observations = env.reset()
    assert observations.shape == (4, 18) and observations.dtype == np.float32
    assert all(env.observation_space.contains(row) for row in observations)
    observations, rewards, dones, infos = env.step(random_actions(0, 1, (4, 2))[0])
    assert observations.shape == (4, 18) and observations.dtype == np.float32
    assert rewards.shape == (4,) and rewards.dtype == np.float32
    assert dones.shape == (4,) and dones.dtype == np.bool_
    assert infos == [{}, {}, {}, {}]
    env.close()
    env.close()
    with pytest.raises(KheperaError, match="closed"):
        env.reset()


def test_vec_env_rows_replay_single_envs_seeded_seed_plus_index_with_terminal_observations() -> (
    None
):
    """Row i ≡ gym.make(id) reset with seed s + i, then reset() after each episode; at an
    episode's end the row is reset at once and infos carry the true last observation."""
    n, seed, max_steps = 4, 7, 60
    vec_env = make_vec_env(LATEST["nav"], n, seed=seed, max_steps=max_steps)
    singles = [gym.make(LATEST["nav"], max_steps=max_steps) for _ in range(n)]
    observations = vec_env.reset()
    single_observations = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    np.testing.assert_array_equal(observations, np.stack(single_observations))
    ended = {"terminated": 0, "truncated": 0}
    for _ in range(3 * max_steps):
        actions = nav_heuristic(observations)
        observations, rewards, dones, infos = vec_env.step(actions)
        for i, env in enumerate(singles):
            observation, reward, terminated, truncated, info = env.step(actions[i])
            assert rewards[i] == np.float32(reward)
            assert dones[i] == (terminated or truncated)
            if dones[i]:
                np.testing.assert_array_equal(infos[i]["terminal_observation"], observation)
                assert infos[i]["TimeLimit.truncated"] == (truncated and not terminated)
                assert infos[i]["is_success"] == info["is_success"] == terminated
                assert infos[i]["episode_stats"] == info["episode_stats"]
                ended["terminated" if terminated else "truncated"] += 1
                observation, _ = env.reset()
            else:
                assert infos[i] == {}
            np.testing.assert_array_equal(observations[i], observation)
    assert ended["terminated"] > 0 and ended["truncated"] > 0


def test_same_seed_gives_the_same_trajectory_whatever_the_thread_count() -> None:
    actions = random_actions(3, 120, (6, 2))

    def rollout(seed: int, num_threads: int) -> list[npt.NDArray[np.float32]]:
        env = make_vec_env(LATEST["avoid"], 6, seed=seed, num_threads=num_threads, max_steps=40)
        trajectory = [env.reset()]
        for action in actions:
            observations, rewards, dones, infos = env.step(action)
            trajectory += [observations, rewards, dones.astype(np.float32)]
            trajectory += [i["terminal_observation"] for i in infos if "terminal_observation" in i]
        return trajectory

    first, again, other_threads = rollout(5, 1), rollout(5, 1), rollout(5, 2)
    for a, b, c in zip(first, again, other_threads, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
    assert not np.array_equal(first[0], rollout(6, 1)[0])


def test_seed_acts_at_the_next_reset_only_and_reset_without_seed_continues_the_streams() -> None:
    env = make_vec_env(LATEST["nav"], 3)
    assert env.seed(11) == [11, 12, 13]
    seeded = env.reset()
    continued = env.reset()
    assert not np.array_equal(seeded, continued)
    env.seed(11)
    np.testing.assert_array_equal(env.reset(), seeded)
    np.testing.assert_array_equal(env.reset(), continued)
    single = gym.make(LATEST["nav"])
    np.testing.assert_array_equal(single.reset(seed=12)[0], seeded[1])
    np.testing.assert_array_equal(single.reset()[0], continued[1])


def test_vec_env_works_under_vec_monitor_and_vec_normalize() -> None:
    max_steps = 30
    env = VecNormalize(VecMonitor(make_vec_env(LATEST["nav"], 4, seed=0, max_steps=max_steps)))
    observations = env.reset()
    episodes = 0
    for actions in random_actions(1, 2 * max_steps, (4, 2)):
        observations, rewards, dones, infos = env.step(actions)
        assert np.all(np.isfinite(observations)) and np.all(np.isfinite(rewards))
        for i in np.flatnonzero(dones):
            episode, stats = infos[i]["episode"], infos[i]["episode_stats"]
            assert episode["l"] == stats["length"] == max_steps
            assert episode["r"] == pytest.approx(stats["return"], abs=1e-3)
            assert infos[i]["terminal_observation"].shape == (18,)
            episodes += 1
    assert episodes == 8
    assert env.obs_rms.count > 2 * max_steps * 4


def test_get_attr_env_method_set_attr_env_is_wrapped_and_render() -> None:
    env = make_vec_env(LATEST["formation"], 3, seed=2, n_followers=2)
    env.reset()
    assert env.get_attr("render_mode") == [None, None, None]
    assert env.get_attr("max_episode_steps", indices=[0]) == [800]
    assert env.has_attr("n_robots") and not env.has_attr("no_such_thing")
    with pytest.raises(AttributeError):
        env.get_attr("no_such_thing")
    np.testing.assert_array_equal(env.env_method("poses", indices=1)[0], env.poses()[1])
    single = gym.make(LATEST["formation"], n_followers=2)
    single.reset(seed=4)
    np.testing.assert_array_equal(env.env_method("poses", indices=[2])[0], single.unwrapped.poses())
    np.testing.assert_array_equal(
        env.env_method("formation_targets")[2], single.unwrapped.formation_targets()
    )
    assert env.env_method("scene", indices=[2])[0] == single.unwrapped.scene()
    assert env.env_method("config_toml", indices=0)[0] == single.unwrapped.config_toml()
    with pytest.raises(AttributeError):
        env.env_method("step")
    with pytest.raises(NotImplementedError, match="scenario"):
        env.set_attr("max_episode_steps", 5)
    assert env.env_is_wrapped(Monitor) == [False, False, False]
    with pytest.raises(NotImplementedError, match="rgb_array"):
        env.render()
    assert env.get_images() == [None, None, None]


def test_rgb_array_render_tiles_one_frame_per_world() -> None:
    env = make_formation_vec_env(3, seed=0, n_followers=2, render_mode="rgb_array")
    assert env.render_mode == "rgb_array" and env.get_attr("render_mode", 0) == ["rgb_array"]
    env.reset()
    frames = make_vec_env(LATEST["nav"], 2, seed=0, render_mode="rgb_array", frame_size=(64, 48))
    frames.reset()
    images = frames.get_images()
    assert [image.shape for image in images] == [(48, 64, 3), (48, 64, 3)]
    assert images[0].dtype == np.uint8 and not np.array_equal(images[0], images[1])
    mosaic = frames.render()
    assert mosaic.ndim == 3 and mosaic.shape[0] >= 48 and mosaic.shape[1] >= 2 * 64
    assert len(env.get_images()) == 3  # one per world, not per follower row
    with pytest.raises(ConfigError, match="rgb_array"):
        make_vec_env(LATEST["nav"], 1, render_mode="human")


def test_wrong_actions_raise_action_error_and_step_needs_reset() -> None:
    env = make_vec_env(LATEST["nav"], 2, seed=0)
    with pytest.raises(KheperaError, match="reset"):
        env.step(np.zeros((2, 2), np.float32))
    env.reset()
    with pytest.raises(ActionError, match="shape"):
        env.step(np.zeros((3, 2), np.float32))
    with pytest.raises(ActionError):
        env.step(np.full((2, 2), np.nan, np.float32))
    env.step(np.zeros((2, 2), np.float32))  # the env still works after refused actions


def test_formation_rows_are_world_follower_pairs_with_their_own_rewards() -> None:
    n_worlds, followers, seed, max_steps = 2, 3, 4, 25
    env = make_formation_vec_env(n_worlds, seed=seed, n_followers=followers, max_steps=max_steps)
    assert isinstance(env, FormationFollowersVecEnv)
    assert env.num_envs == n_worlds * followers
    assert env.observation_space.shape == (23,)
    assert env.action_space.shape == (2,)
    assert env.follower_names == ["follower_0", "follower_1", "follower_2"]
    singles = [
        gym.make(LATEST["formation"], n_followers=followers, max_steps=max_steps) for _ in "ab"
    ]
    rows = env.reset()
    joint = np.stack([s.reset(seed=seed + w)[0] for w, s in enumerate(singles)])
    np.testing.assert_array_equal(rows, joint.reshape(n_worlds * followers, 23))
    ends = 0
    own_returns = np.zeros(env.num_envs)  # each row's summed rewards in its episode
    for step in range(max_steps + 5):
        actions = formation_heuristic(joint)  # (worlds, 2K): follower k's pair at 2k, 2k + 1
        rows, rewards, dones, infos = env.step(actions.reshape(-1, 2))
        own_returns += rewards
        for w, single in enumerate(singles):
            block = slice(w * followers, (w + 1) * followers)
            observation, _, terminated, truncated, info = single.step(actions[w])
            np.testing.assert_array_equal(rewards[block], single.unwrapped.agent_rewards())
            assert np.all(dones[block] == (terminated or truncated))
            if terminated or truncated:
                ends += 1
                for k, row in enumerate(range(block.start, block.stop)):
                    np.testing.assert_array_equal(
                        infos[row]["terminal_observation"], observation[23 * k : 23 * (k + 1)]
                    )
                    # The world's statistics are the Gymnasium env's; the row's are its follower's.
                    assert infos[row]["world_episode_stats"] == info["episode_stats"]
                    assert "formation_error_mean" in infos[row]["world_episode_stats"]
                    own = infos[row]["episode_stats"]
                    assert own["length"] == info["episode_stats"]["length"]
                    assert own["return"] == pytest.approx(own_returns[block][k], rel=1e-5, abs=1e-4)
                own_returns[block] = 0.0
                observation, _ = single.reset()
            joint[w] = observation
            np.testing.assert_array_equal(rows[block].reshape(-1), observation)
        assert step < max_steps or ends == n_worlds
    assert env.seed(9) == [9, 9, 9, 10, 10, 10]
    with pytest.raises(ConfigError, match="scripted"):
        make_formation_vec_env(1, leader="agent")


def test_shared_agents_rows_are_a_consensus_worlds_robots() -> None:
    from khepera_gym.baselines import ConsensusLaw

    n_worlds, seed = 2, 5
    env = SharedAgentsVecEnv("consensus", n_worlds, seed=seed, max_steps=30)
    single = CONSENSUS.parallel_env(max_steps=30)
    assert env.num_envs == n_worlds * 4 and env.agent_names == single.possible_agents
    assert env.observation_space == single.observation_space("robot_0")
    rows = env.reset()
    observations, _ = single.reset(seed=seed + 1)  # world 1's rows are its robots
    law = ConsensusLaw.for_env(single)
    for _ in range(40):
        world_1 = np.stack([observations[a] for a in single.possible_agents])
        np.testing.assert_array_equal(rows[4:], world_1)
        actions = np.concatenate([law(rows[:4]), law(world_1)])
        rows, rewards, dones, infos = env.step(actions)
        observations, single_rewards, _, truncations, _ = single.step(
            dict(zip(single.possible_agents, law(world_1), strict=True))
        )
        np.testing.assert_array_equal(
            rewards[4:], [single_rewards[a] for a in single.possible_agents]
        )
        if dones[4]:
            assert all(truncations.values())
            assert "consensus_error_final" in infos[4]["world_episode_stats"]
            observations, _ = single.reset()
    # A drone and a robot observe blocks of different lengths: no policy reads both.
    with pytest.raises(ConfigError, match="one length"):
        SharedAgentsVecEnv("dronefollow", 1, driver="agent")


def test_evaluate_episodes_plays_the_episodes_seeded_seed_plus_index() -> None:
    env = make_vec_env(LATEST["avoid"], 5, max_steps=150)
    result = evaluate_episodes(HeuristicPolicy(nav_heuristic), env, seed=20)
    single = gym.make(LATEST["avoid"], max_steps=150)
    successes, returns = [], []
    for seed in range(20, 25):
        observation, _ = single.reset(seed=seed)
        while True:
            observation, _, terminated, truncated, info = single.step(nav_heuristic(observation))
            if terminated or truncated:
                successes.append(info["is_success"])
                returns.append(info["episode_stats"]["return"])
                break
    assert result.episodes == 5
    assert result.success_rate == pytest.approx(np.mean(successes))
    assert result.mean_return == pytest.approx(np.mean(returns))


def test_sb3_eval_callback_records_success_rates_on_the_batch(tmp_path: Path) -> None:
    env = VecMonitor(make_vec_env(LATEST["nav"], 4, seed=0, max_steps=20))
    eval_env = VecMonitor(make_vec_env(LATEST["nav"], 2, seed=100, max_steps=20))
    callback = EvalCallback(eval_env, n_eval_episodes=4, eval_freq=32, log_path=tmp_path)
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=64, n_epochs=1, device="cpu", seed=0)
    model.learn(256, callback=callback)
    assert callback.evaluations_timesteps == [128, 256]
    assert [len(successes) for successes in callback.evaluations_successes] == [4, 4]
    assert np.all(np.asarray(callback.evaluations_length) == 20)
    assert (tmp_path / "evaluations.npz").exists()


def test_hyperparameter_files_build_every_algorithm_they_list() -> None:
    env = make_vec_env(LATEST["nav"], 2, seed=0)
    for algo in ALGORITHMS:
        file = HYPERPARAMS_DIR / f"{algo}.toml"
        if not file.is_file():
            continue
        # Every table of the file, as the id (or follower env) it serves.
        for env_id in tomllib.loads(file.read_text(encoding="utf-8")):
            hyperparams = load_hyperparams(algo, env_id)
            assert hyperparams["n_envs"] >= 1 and hyperparams["n_timesteps"] >= 1
            if env_id == LATEST["nav"].rsplit("-v", 1)[0]:
                model = build_model(algo, env, hyperparams, seed=0)
                assert type(model).__name__ == ALGORITHMS[algo]
    assert load_hyperparams("ppo", "formation_v1-followers")["n_envs"] >= 1
    with pytest.raises(ConfigError, match="no table"):
        load_hyperparams("ppo", "KheperaIV-Swim-v1")


def test_a_versioned_table_serves_its_version_and_the_later_ones(tmp_path: Path) -> None:
    path = tmp_path / "ppo.toml"
    path.write_text(
        '["X"]\nn_steps = 1\n["X-v2"]\nn_steps = 2\n["X-v4"]\nn_steps = 4\n'
        '["x-followers"]\nn_steps = 5\n["x_v3-followers"]\nn_steps = 6\n'
    )
    steps = {
        env_id: load_hyperparams("ppo", env_id, path)["n_steps"]
        for env_id in ["X-v0", "X-v1", "X-v2", "X-v3", "X-v4", "X-v9", "X"]
    }
    assert steps == {"X-v0": 1, "X-v1": 1, "X-v2": 2, "X-v3": 2, "X-v4": 4, "X-v9": 4, "X": 1}
    assert load_hyperparams("ppo", "x_v2-followers", path)["n_steps"] == 5
    assert load_hyperparams("ppo", "x_v4-followers", path)["n_steps"] == 6


def test_parse_override_reads_toml_values() -> None:
    assert parse_override("n_steps=64") == ("n_steps", 64)
    assert parse_override("learning_rate=lin_1e-3") == ("learning_rate", "lin_1e-3")
    assert parse_override("policy_kwargs={net_arch=[32, 32]}") == (
        "policy_kwargs",
        {"net_arch": [32, 32]},
    )
    with pytest.raises(ConfigError):
        parse_override("n_steps")


def test_khepera_gym_train_runs_ppo_end_to_end_and_the_zip_loads_and_predicts(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    arguments = ["train", "--env", "KheperaIV-Nav", "--algo", "ppo", "--timesteps", "2048"]
    arguments += ["--n-envs", "8", "--seed", "0", "--out", str(out), "--eval-freq", "1024"]
    arguments += ["--eval-episodes", "8", "--no-progress", "--verbose", "0", "--num-threads", "1"]
    arguments += ["--hp", "n_steps=64", "--hp", "batch_size=128", "--hp", "n_epochs=2"]
    # Raw observations, so that the zip alone is the policy (Nav-v3's recipe normalises; the
    # normalised path has its own test below).
    arguments += ["--hp", "normalize=false"]
    assert cli.main(arguments) == 0
    assert {"model.zip", "best_model.zip", "run.json", "progress.csv"} <= {
        path.name for path in out.iterdir()
    }
    run = json.loads((out / "run.json").read_text())
    assert run["env_id"] == LATEST["nav"] and run["timesteps"] == 2048 and run["n_envs"] == 8
    assert run["hyperparams"]["n_steps"] == 64
    assert [evaluation["timesteps"] for evaluation in run["history"]] == [1024, 2048]
    assert run["final"]["episodes"] == 8 and 0.0 <= run["final"]["success_rate"] <= 1.0
    # The same episodes again, sampling the actions as in training.
    assert run["final_sampled"]["episodes"] == 8
    assert run["final_sampled"]["timesteps"] == run["final"]["timesteps"] == 2048
    assert {"date", "commit", "machine", "command"} <= run["meta"].keys()

    model = load_policy(out / "model.zip")
    assert isinstance(model, PPO)
    env = gym.make(LATEST["nav"])
    assert model.observation_space == env.observation_space
    assert model.action_space == env.action_space
    observation, _ = env.reset(seed=0)
    action, _ = model.predict(observation, deterministic=True)
    assert action.shape == (2,) and env.action_space.contains(action)
    actions, _ = PPO.load(out / "model.zip", device="cpu").predict(
        np.stack([observation] * 5), deterministic=True
    )
    assert actions.shape == (5, 2)
    env.step(action)


def test_training_with_vec_normalize_saves_statistics_that_load_policy_applies(
    tmp_path: Path,
) -> None:
    arguments = ["train", "--env", LATEST["avoid"], "--timesteps", "256", "--n-envs", "4"]
    arguments += ["--out", str(tmp_path), "--eval-freq", "0", "--eval-episodes", "2"]
    arguments += ["--no-progress", "--verbose", "0", "--hp", "normalize=true"]
    arguments += ["--hp", "n_steps=64", "--hp", "batch_size=64"]
    arguments += ["--hp", "frame_stack=1"]  # Avoid-v2's table stacks 8 (tests/test_frame_stack.py)
    assert cli.main(arguments) == 0
    policy = load_policy(tmp_path / "model.zip")
    assert isinstance(policy, NormalizedPolicy)
    assert policy.normalizer.obs_rms.count > 256
    observation, _ = gym.make(LATEST["avoid"]).reset(seed=1)
    raw = PPO.load(tmp_path / "model.zip", device="cpu")
    expected, _ = raw.predict(policy.normalizer.normalize_obs(observation), deterministic=True)
    action, _ = policy.predict(observation, deterministic=True)
    np.testing.assert_array_equal(action, expected)


def test_khepera_gym_train_runs_sac(tmp_path: Path) -> None:
    arguments = ["train", "--env", LATEST["nav"], "--algo", "sac", "--timesteps", "200"]
    arguments += ["--n-envs", "2", "--out", str(tmp_path), "--eval-freq", "0"]
    arguments += ["--eval-episodes", "2", "--no-progress", "--verbose", "0"]
    arguments += ["--hp", "learning_starts=100", "--hp", "batch_size=32"]
    assert cli.main(arguments) == 0
    assert type(load_policy(tmp_path / "model.zip")).__name__ == "SAC"


def test_vec_env_pickles_mid_episode_and_continues_like_the_original() -> None:
    # SB3 saves and copies VecEnvs (VecNormalize.save, subprocess wrappers) by pickling.
    venv = make_vec_env(LATEST["nav"], n_envs=4)
    venv.seed(3)
    venv.reset()
    actions = np.random.default_rng(0).uniform(-1, 1, (60, 4, 2)).astype(np.float32)
    for action in actions[:10]:
        venv.step(action)
    clone = pickle.loads(pickle.dumps(venv))
    for action in actions[10:]:
        expected, got = venv.step(action), clone.step(action)
        for a, b in zip(expected[:3], got[:3], strict=True):
            np.testing.assert_array_equal(a, b)


def test_a_sampled_evaluation_repeats_and_differs_from_the_deterministic_one() -> None:
    """``evaluate_episodes(sample_seed=...)``: the policy's noise (σ = 1 untrained) changes the
    episodes, and the seed makes them repeat."""
    from khepera_gym.learning.sb3.evaluate import evaluate_episodes

    env = make_vec_env(LATEST["nav"], 4, seed=0, num_threads=1, max_steps=50)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=0, device="cpu")
    figures = [
        dataclasses.replace(evaluate_episodes(model, env, 7, sample_seed=seed), seconds=0.0)
        for seed in (3, 3, 4, None)
    ]
    assert figures[0] == figures[1]
    assert figures[0].mean_return != figures[2].mean_return
    assert figures[0].mean_return != figures[3].mean_return
    env.close()
