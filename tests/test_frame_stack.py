"""Frame stacking (``frame_stack`` in the hyperparameter tables): a policy that acts on its last
n observations, trained under SB3's ``VecFrameStack`` and run from raw observations by
:class:`khepera_gym.learning.sb3.FrameStackPolicy` in evaluation, ``load_policy``, compare and
render."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
from conftest import LATEST
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor, VecNormalize

from khepera_gym import cli
from khepera_gym.analysis.compare import compare
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import load_sb3_policy
from khepera_gym.learning.sb3 import FrameStackPolicy, load_policy, make_vec_env
from khepera_gym.robot.export import export_policy
from khepera_gym.rollout import run_episodes

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.mark.parametrize("normalize", [False, True])
def test_the_policy_feeds_the_model_exactly_what_vec_frame_stack_feeds_it(normalize: bool) -> None:
    """Through episode ends (autoreset), with and without VecNormalize inside the stack."""
    worlds, n_stack = 4, 3
    base = VecMonitor(make_vec_env(LATEST["avoid"], worlds, seed=0, num_threads=1, max_steps=40))
    inner = base
    normalizer = None
    if normalize:
        normalizer = VecNormalize(base, gamma=0.99, training=False)
        dim = base.observation_space.shape[0]
        normalizer.obs_rms.mean = np.linspace(-0.5, 0.5, dim)
        normalizer.obs_rms.var = np.linspace(0.1, 2.0, dim)
        inner = normalizer
    stacked = VecFrameStack(inner, n_stack)
    model = PPO("MlpPolicy", stacked, n_steps=64, batch_size=64, seed=0, device="cpu")
    policy = FrameStackPolicy(model, n_stack, normalizer)
    assert policy.obs_dim == base.observation_space.shape[0]

    def raw(observation: np.ndarray) -> np.ndarray:
        if normalizer is not None:
            return normalizer.get_original_obs()
        return observation[:, -policy.obs_dim :]

    observation = stacked.reset()
    starts = np.ones(worlds, dtype=bool)
    policy.reset()
    ends = 0
    for _ in range(100):
        expected, _ = model.predict(observation, deterministic=True)
        actual, _ = policy.predict(raw(observation), episode_start=starts, deterministic=True)
        np.testing.assert_array_equal(actual, expected)
        observation, _, starts, _ = stacked.step(expected)
        ends += int(starts.sum())
    assert ends >= worlds  # every world went through an episode end (max_steps 40)


def test_a_stack_that_does_not_divide_the_model_observation_is_refused() -> None:
    env = make_vec_env(LATEST["avoid"], 2, seed=0, num_threads=1)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=64, device="cpu")
    with pytest.raises(ConfigError, match="not 4 stacked observations"):
        FrameStackPolicy(model, 4)
    with pytest.raises(ConfigError, match="frame_stack must be an integer >= 2"):
        FrameStackPolicy(model, 1)


def test_train_stacks_frames_and_the_saved_model_stacks_them_again(tmp_path: Path) -> None:
    arguments = ["train", "--env", LATEST["avoid"], "--timesteps", "256", "--n-envs", "4"]
    arguments += ["--out", str(tmp_path), "--eval-freq", "128", "--eval-episodes", "3"]
    arguments += ["--no-progress", "--verbose", "0", "--num-threads", "1"]
    arguments += ["--hp", "frame_stack=3", "--hp", "n_steps=32", "--hp", "batch_size=64"]
    arguments += ["--hp", "normalize=true"]
    assert cli.main(arguments) == 0
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["hyperparams"]["frame_stack"] == 3
    policy = load_policy(tmp_path / "model.zip")
    assert isinstance(policy, FrameStackPolicy) and policy.n_stack == 3
    assert policy.observation_space.shape == (3 * policy.obs_dim,)
    assert policy.normalizer is not None and policy.normalizer.obs_rms.count > 256

    # The comparison tool's sb3: policy plays it from raw observations; the episode loop resets
    # its stacks, so the same seeds replay the same episodes with the same policy object.
    sb3_policy = load_sb3_policy(tmp_path / "model.zip")
    batch = make_vec_env(LATEST["avoid"], 3, seed=0, num_threads=1, max_steps=60)._batch
    first, second = (run_episodes(batch, sb3_policy, 7) for _ in range(2))
    assert [s["return"] for s in first] == [s["return"] for s in second]
    comparison = compare(
        LATEST["avoid"], [f"sb3:{tmp_path / 'model.zip'}"], episodes=3, progress=False
    )
    assert [len(results) for results in comparison.results.values()] == [3]

    # The export reads the stack from run.json's model and writes a program that keeps it; its
    # own check compares the C policy with this one over whole episodes.
    result = export_policy(tmp_path / "model.zip", tmp_path / "export", formats=("c",))
    assert result.network.frame_stack == 3 and result.network.obs_dim == policy.obs_dim
    assert result.network.normalization is not None
    assert result.checks["c_max_abs_error"] < 1e-5


def test_a_bad_frame_stack_is_a_config_error(tmp_path: Path) -> None:
    arguments = ["train", "--env", LATEST["avoid"], "--timesteps", "64", "--out", str(tmp_path)]
    arguments += ["--no-progress", "--verbose", "0", "--hp"]
    for bad in ("0", "2.5", "true"):
        with pytest.raises(SystemExit, match="frame_stack must be an integer >= 1"):
            cli.main([*arguments, f"frame_stack={bad}"])
