"""Recurrent policies (sb3-contrib's RecurrentPPO, an LSTM): trained by ``khepera-gym train
--algo recurrent_ppo`` and played from raw observations by
:class:`khepera_gym.learning.sb3.RecurrentPolicy` in evaluation, ``load_policy``, compare, render
and export, the LSTM state carried from step to step and reset at each episode's start.

The reference is SB3's own convention for recurrent models (as its ``evaluate_policy`` drives
them): the caller passes the state ``predict`` returned and ``episode_start`` flags.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

pytest.importorskip("sb3_contrib", reason="needs the sb3 extra: pip install 'khepera-gym[sb3]'")
from conftest import LATEST
from sb3_contrib import RecurrentPPO
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from khepera_gym import cli
from khepera_gym.analysis.compare import compare
from khepera_gym.analysis.record import record_video
from khepera_gym.config import tomllib
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import load_sb3_policy
from khepera_gym.learning.recipes import HYPERPARAMS_DIR, load_hyperparams
from khepera_gym.learning.sb3 import RecurrentPolicy, algorithm_of, load_policy, make_vec_env
from khepera_gym.learning.train import build_model
from khepera_gym.rollout import run_episodes

pytestmark = pytest.mark.usefixtures("one_torch_thread")

#: A small LSTM policy, for speed.
SMALL = {"lstm_hidden_size": 8, "net_arch": [16]}


def small_model(env: object) -> RecurrentPPO:
    return RecurrentPPO(
        "MlpLstmPolicy", env, n_steps=32, batch_size=64, seed=0, device="cpu", policy_kwargs=SMALL
    )


@pytest.mark.parametrize("normalize", [False, True])
def test_the_policy_carries_the_state_as_sb3s_own_loop_does(normalize: bool) -> None:
    """Through episode ends (SB3's autoreset), with and without VecNormalize."""
    worlds = 4
    base = VecMonitor(make_vec_env(LATEST["avoid"], worlds, seed=0, num_threads=1, max_steps=40))
    env = base
    normalizer = None
    if normalize:
        normalizer = VecNormalize(base, gamma=0.99, training=False)
        dim = base.observation_space.shape[0]
        normalizer.obs_rms.mean = np.linspace(-0.5, 0.5, dim)
        normalizer.obs_rms.var = np.linspace(0.1, 2.0, dim)
        env = normalizer
    model = small_model(env)
    policy = RecurrentPolicy(model, normalizer)
    assert policy.obs_dim == base.observation_space.shape[0]

    def raw(observation: np.ndarray) -> np.ndarray:
        return normalizer.get_original_obs() if normalizer is not None else observation

    observation = env.reset()
    starts = np.ones(worlds, dtype=bool)
    state = None
    policy.reset()
    ends = 0
    for _ in range(100):
        expected, state = model.predict(
            observation, state=state, episode_start=starts, deterministic=True
        )
        actual, _ = policy.predict(raw(observation), episode_start=starts, deterministic=True)
        np.testing.assert_array_equal(actual, expected)
        observation, _, starts, _ = env.step(expected)
        ends += int(starts.sum())
    assert ends >= worlds  # every world went through an episode end (max_steps 40)


def test_the_state_changes_the_action_and_resets_per_row() -> None:
    env = make_vec_env(LATEST["avoid"], 3, seed=0, num_threads=1)
    policy = RecurrentPolicy(small_model(env))
    with torch.no_grad():  # an LSTM whose state weighs on the action
        for weight in policy.model.policy.lstm_actor.parameters():
            weight.mul_(4.0)
        policy.model.policy.action_net.weight.mul_(30.0)
    observations = env.reset()
    first, _ = policy.predict(observations, deterministic=True)
    second, (hidden, cell) = policy.predict(observations, deterministic=True)
    assert np.max(np.abs(second - first)) > 1e-3  # the same observation, another state
    assert hidden.shape == cell.shape == (1, 3, 8)
    # episode_start zeros the flagged rows only; reset() zeros them all.
    starts = np.array([True, False, False])
    third, _ = policy.predict(observations, episode_start=starts, deterministic=True)
    np.testing.assert_array_equal(third[0], first[0])
    assert np.max(np.abs(third[1:] - first[1:])) > 1e-3
    policy.reset()
    np.testing.assert_array_equal(policy.predict(observations, deterministic=True)[0], first)
    # One observation (no batch axis) is one world; another number of worlds starts afresh.
    single, _ = policy.predict(observations[1], deterministic=True)
    assert single.shape == (2,)
    np.testing.assert_allclose(single, first[1], atol=1e-6)  # a batch of 1: other sums
    with pytest.raises(ConfigError, match="takes observations of"):
        policy.predict(observations[:, :5])


def test_train_recurrent_ppo_and_the_saved_model_plays_with_its_state(tmp_path: Path) -> None:
    arguments = ["train", "--env", LATEST["avoid"], "--algo", "recurrent_ppo"]
    arguments += ["--timesteps", "256", "--n-envs", "4", "--out", str(tmp_path)]
    arguments += ["--eval-freq", "128", "--eval-episodes", "3", "--no-progress", "--verbose", "0"]
    arguments += ["--num-threads", "1", "--hp", "n_steps=32", "--hp", "batch_size=64"]
    arguments += ["--hp", "normalize=true", "--hp", "policy_kwargs={lstm_hidden_size=8}"]
    assert cli.main(arguments) == 0
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["algo"] == "recurrent_ppo" and run["timesteps"] == 256
    assert [evaluation["timesteps"] for evaluation in run["history"]] == [128, 256]
    model_path = tmp_path / "model.zip"
    assert algorithm_of(model_path) == "RecurrentPPO"
    policy = load_policy(model_path)
    assert isinstance(policy, RecurrentPolicy) and isinstance(policy.model, RecurrentPPO)
    assert policy.normalizer is not None and policy.normalizer.obs_rms.count > 256

    # The comparison tool's sb3: policy plays it from raw observations; the episode loop resets
    # its state, so the same seeds replay the same episodes with the same policy object, and
    # those are the episodes of SB3's own loop (state passed back, episode_start at the reset).
    sb3_policy = load_sb3_policy(model_path)
    batch = make_vec_env(LATEST["avoid"], 3, seed=0, num_threads=1, max_steps=60)._batch
    first, second = (run_episodes(batch, sb3_policy, 7) for _ in range(2))
    assert [s["return"] for s in first] == [s["return"] for s in second]
    model, normalizer = policy.model, policy.normalizer
    state: list[object] = [None]
    started = [True]

    def sb3_loop(observations: np.ndarray) -> np.ndarray:
        starts = np.full(len(observations), started[0])
        started[0] = False
        actions, state[0] = model.predict(
            normalizer.normalize_obs(observations), state[0], starts, deterministic=True
        )
        return actions

    own = run_episodes(batch, sb3_loop, 7)
    assert [s["return"] for s in own] == [s["return"] for s in first]
    comparison = compare(LATEST["avoid"], [f"sb3:{model_path}"], episodes=3, progress=False)
    assert [len(results) for results in comparison.results.values()] == [3]
    gif, frames = record_video(
        LATEST["avoid"], f"sb3:{model_path}", tmp_path / "run.gif", seed=3, max_steps=20
    )
    assert gif.is_file() and frames == 21

    # The export reads the model and its statistics from the run and writes a program that
    # carries the LSTM state; its own check compares it with this policy over whole episodes.
    from khepera_gym.robot.export import export_policy

    result = export_policy(model_path, tmp_path / "export", formats=("c",))
    assert result.network.recurrent and result.network.lstm_hidden_size == 8
    assert result.network.normalization is not None
    assert result.checks["c_max_abs_error"] < 1e-5


def test_a_recurrent_model_with_a_frame_stack_is_a_config_error(tmp_path: Path) -> None:
    arguments = ["train", "--env", LATEST["avoid"], "--algo", "recurrent_ppo"]
    arguments += ["--timesteps", "64", "--out", str(tmp_path), "--no-progress", "--verbose", "0"]
    with pytest.raises(SystemExit, match="keeps its memory in its LSTM"):
        cli.main([*arguments, "--hp", "frame_stack=2"])
    assert not (tmp_path / "model.zip").exists()


def test_the_recurrent_hyperparameter_tables_build_recurrent_ppo() -> None:
    tables = (HYPERPARAMS_DIR / "recurrent_ppo.toml").read_text(encoding="utf-8")
    names = list(tomllib.loads(tables))
    assert {"KheperaIV-Avoid-v2", "KheperaIV-Seek"} <= set(names)
    for name in names:
        hyperparams = load_hyperparams("recurrent_ppo", name)
        assert hyperparams["policy"] == "MlpLstmPolicy"
        assert hyperparams.get("frame_stack", 1) == 1
        env_id = LATEST[name.removeprefix("KheperaIV-").split("-")[0].lower()]
        env = make_vec_env(env_id, 2, seed=0, num_threads=1)
        model = build_model("recurrent_ppo", env, hyperparams, seed=0)
        assert isinstance(model, RecurrentPPO)
        lstm = model.policy.lstm_actor
        assert lstm.hidden_size == hyperparams["policy_kwargs"]["lstm_hidden_size"]
