"""``khepera-gym export --sample-actions``: the C program samples its actions from the policy's
Gaussian, as PPO acted while it trained, instead of acting on its mean. Avoid-v2's deterministic
policies stall where their sampled ones do not (docs/training.md)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from test_export import compile_check, robot_program_on_fake_robot, run_check

pytest.importorskip("stable_baselines3")
import torch
from conftest import LATEST
from stable_baselines3 import PPO, SAC

from khepera_gym import cli
from khepera_gym.errors import ConfigError
from khepera_gym.robot import export

#: The test policy's σ: small enough that its mean, well inside ±1, is rarely clipped.
SIGMA = (0.15, 0.3)
#: Draws per check: the mean's standard error is σ/√DRAWS, the σ estimate's about σ/√(2 DRAWS).
DRAWS = 4000


@pytest.fixture(scope="module")
def model() -> PPO:
    """An untrained Nav PPO whose Gaussian has σ = SIGMA (one value per wheel)."""
    model = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    with torch.no_grad():
        model.policy.log_std.copy_(torch.log(torch.tensor(SIGMA)))
    return model


def sample(binary: Path, seed: int, rows: np.ndarray) -> np.ndarray:
    """``export_check sample SEED`` on rows of (episode-start flag, observation)."""
    text = "\n".join(" ".join(f"{v:.9g}" for v in row) for row in rows) + "\n"
    out = subprocess.run(
        [str(binary), "sample", str(seed)], input=text, capture_output=True, text=True, check=True
    )
    return np.array([[float(v) for v in line.split()] for line in out.stdout.splitlines()])


def test_sampled_actions_are_the_mean_plus_the_trained_sigma(model: PPO, tmp_path: Path) -> None:
    result = export.export_policy(model, tmp_path, env_id=LATEST["nav"], sample_seed=3)
    np.testing.assert_allclose(result.network.action_std, SIGMA, rtol=1e-6)
    manifest = json.loads((tmp_path / export.MANIFEST_FILE).read_text())
    assert manifest["actions"]["sampled"] and manifest["actions"]["seed"] == 3
    binary = compile_check(tmp_path)
    observation = gym.make(LATEST["nav"]).reset(seed=0)[0]
    mean = run_check(binary, "policy", [observation])[0]
    assert np.all(np.abs(mean) < 1.0 - 3 * max(SIGMA))  # so the clip hardly matters
    rows = np.column_stack([np.ones(DRAWS), np.tile(observation, (DRAWS, 1))])
    actions = sample(binary, 3, rows)
    noise = actions - mean
    # 5 standard errors of the mean and of the standard deviation.
    np.testing.assert_allclose(noise.mean(axis=0), 0.0, atol=5 * max(SIGMA) / np.sqrt(DRAWS))
    np.testing.assert_allclose(noise.std(axis=0), SIGMA, atol=5 * max(SIGMA) / np.sqrt(2 * DRAWS))
    # Gaussian tails: about 4.6 % of the draws beyond 2σ (2 Φ(-2)), 4 standard errors.
    beyond = np.mean(np.abs(noise) > 2 * np.array(SIGMA), axis=0)
    share, error = 0.0455, np.sqrt(0.0455 * 0.9545 / DRAWS)
    np.testing.assert_allclose(beyond, share, atol=4 * error)
    # A seed repeats its draws; another seed gives others.
    np.testing.assert_array_equal(sample(binary, 3, rows[:50]), actions[:50])
    assert not np.array_equal(sample(binary, 4, rows[:50]), actions[:50])
    # The mean itself is the deterministic export's, bit for bit.
    plain = tmp_path / "plain"
    export.export_policy(model, plain, env_id=LATEST["nav"], check=False)
    np.testing.assert_array_equal(run_check(compile_check(plain), "policy", [observation])[0], mean)


def test_the_program_samples_from_the_seed_it_was_exported_with(model: PPO, tmp_path: Path) -> None:
    export.export_policy(model, tmp_path, env_id=LATEST["nav"], check=False, sample_seed=11)
    program = robot_program_on_fake_robot(tmp_path)

    def actions() -> tuple[np.ndarray, str]:
        run = subprocess.run(
            [str(program), "1.0", "0.5", "6"],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        )
        rows = [[float(v) for v in line.split()[4:6]] for line in run.stdout.splitlines()]
        return np.array(rows), run.stderr

    first, stderr = actions()
    assert "actions: sampled from the policy's Gaussian, seed 11" in stderr
    # The fake robot's readings do not change, so neither does the mean: the actions vary
    # by the noise alone, and a second run repeats them.
    assert len({tuple(row) for row in first}) == 6
    np.testing.assert_array_equal(actions()[0], first)


def test_sampling_needs_a_policy_with_a_state_independent_sigma(tmp_path: Path) -> None:
    sac = SAC("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", learning_starts=0)
    with pytest.raises(ConfigError, match="action noise cannot be exported"):
        export.export_policy(sac, tmp_path / "sac", env_id=LATEST["nav"], sample_seed=0)
    # gSDE's noise depends on the state: its mean action exports, its noise does not.
    gsde = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64, use_sde=True)
    with pytest.raises(ConfigError, match=r"action noise cannot be exported.*not gSDE's"):
        export.export_policy(gsde, tmp_path / "gsde", env_id=LATEST["nav"], sample_seed=0)
    ppo = PPO("MlpPolicy", gym.make(LATEST["nav"]), seed=0, device="cpu", n_steps=64)
    for seed in (-1, 2**64, 1.5, True):
        with pytest.raises(ConfigError, match="sampling seed"):
            export.export_policy(ppo, tmp_path / "seed", env_id=LATEST["nav"], sample_seed=seed)


def test_the_command_says_what_the_program_does(model: PPO, tmp_path: Path, capsys) -> None:
    path = tmp_path / "model.zip"
    model.save(path)
    base = ["export", str(path), "--env", LATEST["nav"], "--no-check"]
    assert cli.main([*base, "--out", str(tmp_path / "a"), "--sample-actions"]) == 0
    assert "actions: sampled from the policy's Gaussian (sigma 0.15, 0.3), seed 0" in (
        capsys.readouterr().out
    )
    assert cli.main([*base, "--out", str(tmp_path / "b")]) == 0
    assert "actions: the policy's mean" in capsys.readouterr().out
    with pytest.raises((SystemExit, ConfigError), match="--sample-seed"):
        cli.main([*base, "--out", str(tmp_path / "c"), "--sample-seed", "5"])
