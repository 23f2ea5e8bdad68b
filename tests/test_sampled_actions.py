"""``compare --sample-actions``: an SB3 model that samples its actions from its Gaussian (as PPO
does while it trains) instead of acting on its mean, seeded so that a comparison repeats."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
import torch
from conftest import LATEST
from stable_baselines3 import PPO

from khepera_gym import cli
from khepera_gym.analysis.compare import compare
from khepera_gym.learning.policies import load_sb3_policy
from khepera_gym.learning.sb3 import make_vec_env

pytestmark = pytest.mark.usefixtures("one_torch_thread")

#: The untrained model's action noise: PPO's σ = exp(log_std).
SIGMA = 0.2


@pytest.fixture(scope="module")
def model_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained PPO model on Nav whose Gaussian has σ = SIGMA on both wheels."""
    env = make_vec_env(LATEST["nav"], 2, seed=0, num_threads=1)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=64, seed=0, device="cpu")
    with torch.no_grad():
        model.policy.log_std.fill_(float(np.log(SIGMA)))
    path = tmp_path_factory.mktemp("sampled") / "model.zip"
    model.save(path)
    env.close()
    return path


def test_sampled_actions_spread_around_the_mean_with_the_models_sigma(model_path: Path) -> None:
    """The same observations: the sampled actions' mean is the deterministic action's and their
    spread is σ (the mean stays well inside ±1 for an untrained model, so clipping is rare);
    a reset reseeds, so the same calls give the same draws."""
    deterministic = load_sb3_policy(model_path)
    sampled = load_sb3_policy(model_path, sample_seed=7)
    env = make_vec_env(LATEST["nav"], 4, seed=0, num_threads=1)
    observations = np.repeat(env.reset(), 500, axis=0)  # 2,000 rows, 4 distinct
    env.close()
    mean = deterministic(observations)
    assert np.all(np.abs(mean) < 1.0 - 4 * SIGMA)
    sampled.reset()
    first = sampled(observations)
    noise = first - mean
    # 2,000 draws per wheel: the mean's standard error is σ/√2000 ≈ 0.0045, the σ estimate's
    # about σ/√4000 ≈ 0.003; 5 standard errors.
    np.testing.assert_allclose(noise.mean(axis=0), 0.0, atol=5 * SIGMA / np.sqrt(2000))
    np.testing.assert_allclose(noise.std(axis=0), SIGMA, atol=5 * SIGMA / np.sqrt(4000))
    sampled.reset()
    np.testing.assert_array_equal(sampled(observations), first)
    assert not np.array_equal(sampled(observations), first)  # the draws go on without a reset


def test_compare_samples_actions_reproducibly_and_says_so(model_path: Path, tmp_path: Path) -> None:
    """The same comparison twice gives the same episodes; sampling changes them; the results
    name the sampled model apart from the deterministic one, on the command line too."""
    name = f"sb3:{model_path}"
    runs = [
        compare(
            LATEST["nav"],
            [name],
            episodes=3,
            progress=False,
            sample_actions=True,
            overrides={"max_steps": 60},
            record_worlds=0,
        )
        for _ in range(2)
    ]
    plain = compare(
        LATEST["nav"],
        [name],
        episodes=3,
        progress=False,
        overrides={"max_steps": 60},
        record_worlds=0,
    )
    assert list(runs[0].results) == [f"{name} (sampled)"]
    assert list(plain.results) == [name]
    assert runs[0].results == runs[1].results
    paths = [
        [r.path_length for r in run.results[key]]
        for run, key in ((runs[0], f"{name} (sampled)"), (plain, name))
    ]
    assert paths[0] != paths[1]
    out = tmp_path / "out"
    code = cli.main(
        [
            "compare",
            "--env",
            LATEST["nav"],
            "--policy",
            name,
            "--sample-actions",
            "--episodes",
            "2",
            "--set",
            "max_steps=30",
            "--no-plot",
            "--no-progress",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    (results,) = out.glob("*_results.json")
    shown = [row["policy"] for row in json.loads(results.read_text())["summaries"]]
    assert shown == [f"{name} (sampled)"]


def test_sampling_without_a_model_to_sample_is_refused(tmp_path: Path) -> None:
    """The baselines are deterministic: asking them to sample is an error, not a no-op."""
    from khepera_gym.errors import ConfigError

    with pytest.raises(ConfigError, match=r"sample-actions.*sb3: models"):
        compare(
            LATEST["nav"], ["position_control"], episodes=2, progress=False, sample_actions=True
        )
    with pytest.raises(SystemExit, match="sample-actions"):
        cli.main(
            [
                "compare",
                "--env",
                LATEST["nav"],
                "--policy",
                "position_control",
                "--sample-actions",
                "--episodes",
                "2",
                "--no-plot",
                "--no-progress",
                "--out",
                str(tmp_path / "o"),
            ]
        )
