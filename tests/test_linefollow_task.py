"""KheperaIV-LineFollow and floors through the public API: K-Team's follower laps where a random
policy gets lost; the ground readings are raw counts; seeds reproduce episodes bit for bit, a
vector world matches the single env of its seed, a saved state continues identically; frames draw
the floor; a bad floor image raises ConfigError naming it. Geometry and baselines in depth:
tests/ground.rs."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym.baselines import LineProportional
from khepera_gym.envs import linefollow_heuristic
from khepera_gym.errors import ConfigError


def _episode(env: gym.Env, seed: int, policy) -> dict:
    obs, _ = env.reset(seed=seed)
    while True:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            return info["episode_stats"]


@pytest.mark.parametrize("track", ["circle", "spline"])
def test_the_followers_lap_and_a_random_policy_does_not(track: str) -> None:
    env = gym.make(LATEST["linefollow"], track=track)
    rng = np.random.default_rng(0)
    for seed in range(3):
        for policy in (linefollow_heuristic, LineProportional()):
            stats = _episode(env, seed, policy)
            # On the line all along: a front sensor over black at every step but a few.
            assert stats["success"] and stats["on_line_share"] > 0.95
            assert stats["line_offset_rms"] < 0.0135  # within the tape's half width
        lost = _episode(env, seed, lambda _: rng.uniform(-1, 1, 2).astype(np.float32))
        assert not lost["success"]


def test_ground_readings_are_raw_counts_that_see_the_line() -> None:
    env = gym.make(LATEST["linefollow"])
    obs, _ = env.reset(seed=1)
    raw = env.unwrapped.sensor_readings()["ground_raw"][0]
    layout = env.unwrapped.obs_layout()
    np.testing.assert_allclose(obs[layout["ground"]], raw / 1023, rtol=1e-6)
    # The robot starts on the line: a front sensor (front-left, front-right) reads black.
    assert min(raw[1], raw[2]) < 800 and max(raw) > 900


def _trace(env: gym.Env, seed: int, steps: int) -> list[bytes]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out.append(obs.tobytes() + np.float32(reward).tobytes())
        if terminated or truncated:
            env.reset()
    return out


def test_seeds_reproduce_and_a_saved_state_continues_bit_for_bit() -> None:
    a, b = (
        gym.make(LATEST["linefollow"], track="spline"),
        gym.make(LATEST["linefollow"], track="spline"),
    )
    a.reset(seed=5)
    b.reset(seed=5)
    assert _trace(a, 1, 150) == _trace(b, 1, 150)
    state = a.unwrapped.get_state()
    ahead = _trace(a, 2, 150)
    b.unwrapped.set_state(state)
    assert _trace(b, 2, 150) == ahead


def test_a_vector_world_matches_the_single_env_of_its_seed() -> None:
    envs = gym.make_vec(LATEST["linefollow"], num_envs=3, track="spline")
    single = gym.make(LATEST["linefollow"], track="spline")
    obs, _ = envs.reset(seed=30)
    single_obs, _ = single.reset(seed=32)
    for _ in range(60):
        np.testing.assert_array_equal(obs[2], single_obs)
        obs, *_ = envs.step(linefollow_heuristic(obs))
        single_obs, *_ = single.step(linefollow_heuristic(single_obs))


def test_frames_draw_the_floor() -> None:
    plain = gym.make(LATEST["nav"], render_mode="rgb_array", frame_size=(200, 200))
    drawn = gym.make(
        LATEST["nav"],
        render_mode="rgb_array",
        frame_size=(200, 200),
        lines=[{"a": [-0.9, -0.5], "b": [0.9, -0.5], "width": 0.05}],
    )
    plain.reset(seed=0)
    drawn.reset(seed=0)
    a, b = plain.render(), drawn.render()
    # The 5 cm black line at y = −0.5 m: rows 145-150 of 200 in a 2.1 m-high view (95 px/m).
    assert a[148, 30:170].mean() > 200 and b[148, 30:170].mean() < 80


def test_a_bad_floor_image_is_a_config_error_naming_it(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"floor\.image"):
        gym.make(LATEST["nav"], image=str(tmp_path / "missing.png"))
    text = tmp_path / "floor.png"
    text.write_text("not a picture")
    with pytest.raises(ConfigError, match=r"floor\.image.*not a PNG"):
        gym.make(LATEST["nav"], image=str(text))
