"""KheperaIV-Track: the manual's promises through Gymnasium: Kanayama's controller converges
within its linearised envelope on the circle and the lemniscate, the chase of eqs. 1-4 lags by
v_r k_r / v_max, episodes last one period plus the margin, bad references are ConfigErrors
naming the key, and the frame draws the reference."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym.baselines import Kanayama, PositionChase
from khepera_gym.envs import track_heuristic
from khepera_gym.errors import ConfigError, KheperaError

#: Scenario defaults the bounds below use (configs/track.toml; docs/task-design.md §3).
START_OFFSET = 0.2  # m, track.start_offset
START_HEADING_OFFSET = math.pi / 4  # rad, track.start_heading_offset
TRANSIENT = 5.0  # s, track.transient
WHEEL_ACCEL_LIMIT = 0.2034543  # m/s², robot.wheel_accel_limit (K-Team's speed profile)
DT = 0.05  # s, physics.dt
#: Kanayama's defaults: K_x (1/s) and K_y (1/m²).
KX, KY = 1.0, 44.44


def _envelope(v_min: float, v_max: float, t: float) -> float:
    """Kanayama's linearised error envelope E0 (1 + λt) e^{-λt} + v_max dt, λ = min(K_x,
    v_min √K_y), E0 = start offset + heading drift v sin(e_θ) / λ + standing-start lag v² / 2a."""
    rate = min(KX, v_min * math.sqrt(KY))
    e0 = (
        START_OFFSET
        + v_max * math.sin(START_HEADING_OFFSET) / rate
        + v_max**2 / (2 * WHEEL_ACCEL_LIMIT)
    )
    return e0 * (1 + rate * t) * math.exp(-rate * t) + v_max * DT


def _first_episodes(envs: gym.vector.VectorEnv, policy, seed: int) -> dict[str, np.ndarray]:
    """Each world's first episode statistics, and the reference speeds seen (m/s)."""
    obs, _ = envs.reset(seed=seed)
    layout = envs.obs_layout()
    rates = layout["reference_rates"]
    n = envs.num_envs
    stats: dict[str, np.ndarray] = {}
    done = np.zeros(n, dtype=bool)
    terminated_any = np.zeros(n, dtype=bool)
    speeds = []
    while not done.all():
        speeds.append(obs[~done, rates.start] * 0.813)
        obs, _, terminated, truncated, info = envs.step(policy(obs))
        ended = (terminated | truncated) & ~done
        if ended.any():
            for key, values in info["episode_stats"].items():
                stats.setdefault(key, np.zeros(n))[ended] = values[ended]
            terminated_any |= terminated & ended
        done |= terminated | truncated
    stats["terminated"] = terminated_any
    stats["speeds"] = np.concatenate(speeds)
    return stats


@pytest.mark.parametrize("reference", ["circle", "lemniscate"])
def test_kanayama_converges_within_its_linearised_envelope(reference: str) -> None:
    envs = gym.make_vec(LATEST["track"], num_envs=32, reference=reference)
    stats = _first_episodes(envs, Kanayama(), seed=50)
    envs.close()
    assert not stats["terminated"].any()
    bound = _envelope(stats["speeds"].min(), stats["speeds"].max(), TRANSIENT)
    assert stats["track_error_max"].max() <= bound
    assert np.all(stats["track_error_rms"] <= stats["track_error_max"])
    assert np.all(np.isfinite(stats["track_converge_time"]))


def test_position_chase_lags_by_speed_over_bandwidth() -> None:
    env = gym.make(LATEST["track"], start_offset=0.0, start_heading_offset=0.0, direction="ccw")
    obs, _ = env.reset(seed=2)
    policy = PositionChase()
    errors = []
    terminated = truncated = False
    while not (terminated or truncated):
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        layout = env.unwrapped.obs_layout()
        errors.append(np.hypot(*obs[layout["tracking_error"]]))
    assert truncated
    lag = float(np.mean(errors[len(errors) // 2 :]))
    # v = d v_max / k_r inside k_r: d = v_r k_r / v_max = 0.15 * 0.15 / 0.3 m.
    assert lag == pytest.approx(0.15 * 0.15 / 0.3, rel=0.25)
    env.close()


def test_episode_lasts_one_period_plus_the_margin() -> None:
    env = gym.make(LATEST["track"])
    obs, _ = env.reset(seed=0)
    steps, truncated, terminated = 0, False, False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(track_heuristic(obs))
        steps += 1
    # 2π · 0.6 m / 0.15 m/s + 2 s = 27.13 s → 543 steps of 50 ms.
    assert (steps, truncated, info["is_success"]) == (543, True, False)
    env.close()


def test_standing_still_is_lost_and_terminates() -> None:
    env = gym.make(LATEST["track"])
    env.reset(seed=1)
    for _ in range(200):
        _, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        assert reward < 0
        if terminated:
            break
    assert terminated and not truncated and not info["is_success"]
    assert info["episode_stats"]["track_error_max"] > 0.5
    assert info["episode_stats"]["track_converge_time"] == math.inf
    env.close()


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"size": 0.9}, "track.size"),
        ({"speed": 0.6}, "track.speed"),
        ({"size": 0.05, "speed": 0.2}, "track.speed"),
        ({"speed": float("nan")}, "track.speed"),
        ({"reference": "heart"}, "track.reference"),
        ({"preview_points": -1}, "track.preview_points"),
        ({"spline_irregularity": 0.9}, "track.spline_irregularity"),
        ({"track": {"direction": 3}}, "track.direction"),
    ],
)
def test_bad_references_raise_config_error_naming_the_key(overrides: dict, key: str) -> None:
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        gym.make(LATEST["track"], **overrides)


def test_baselines_refuse_observations_without_their_blocks() -> None:
    nav = gym.make("KheperaIV-Nav-v1")
    with pytest.raises(KheperaError, match="tracking_error"):
        Kanayama(layout=nav)
    nav.close()


def test_frame_draws_the_reference_curve() -> None:
    frames = []
    for reference in ("circle", "square"):
        env = gym.make(LATEST["track"], reference=reference, render_mode="rgb_array")
        env.reset(seed=0)
        frames.append(env.render())
        env.close()
    assert frames[0].shape == frames[1].shape
    assert (frames[0] != frames[1]).any()


def test_waypoints_from_a_scenario_file_are_tracked(tmp_path) -> None:
    # Eight points on a 0.5 m circle, 2.5 s apart, the ninth closing the loop at 20 s.
    angles = np.linspace(0.0, 2 * np.pi, 9)
    points = [[2.5 * k, 0.5 * np.cos(a), 0.5 * np.sin(a)] for k, a in enumerate(angles)]
    rows = ", ".join(f"[{t}, {x:.6f}, {y:.6f}]" for t, x, y in points)
    path = tmp_path / "loop.toml"
    path.write_text(f'[track]\nreference = "waypoints"\nwaypoints = [{rows}]\n')
    env = gym.make(LATEST["track"], config=str(path), random_phase=False, direction="ccw")
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped.goals()[0], [0.5, 0.0], atol=1e-6)
    truncated = terminated = False
    steps = 0
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(track_heuristic(obs))
        steps += 1
    assert truncated and steps == 440  # (20 s + 2 s) / 50 ms
    assert info["episode_stats"]["track_converge_time"] < math.inf
    env.close()


def test_non_increasing_waypoint_times_raise_config_error() -> None:
    points = [[0, 0.3, 0], [5, 0, 0.3], [4, -0.3, 0], [15, 0, -0.3], [20, 0.3, 0]]
    with pytest.raises(ConfigError, match=r"track\.waypoints.*increasing"):
        gym.make(LATEST["track"], reference="waypoints", waypoints=points)
