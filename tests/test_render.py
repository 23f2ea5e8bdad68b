"""Rendering: rgb_array frames of the documented shape, drawn headless, that follow the robot;
the pygame window on SDL's dummy driver; videos."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym.errors import ConfigError, KheperaError
from khepera_gym.render import mosaic, save_video


def _robot_centre(frame: np.ndarray) -> np.ndarray:
    """Mean pixel (x, y) of the first robot's body colour (31, 119, 180)."""
    mask = np.abs(frame.astype(int) - [31, 119, 180]).sum(axis=2) < 40
    ys, xs = np.nonzero(mask)
    assert len(xs) > 50, "robot not found in the frame"
    return np.array([xs.mean(), ys.mean()])


@pytest.mark.parametrize("env_id", list(LATEST.values()))
def test_rgb_array_frames_have_the_documented_shape(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array", frame_size=(320, 240))
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # something is drawn
    env.close()


def test_robot_pixels_move_with_the_robot_and_renders_repeat() -> None:
    env = gym.make(LATEST["nav"], render_mode="rgb_array", config="paper_fig6")
    env.reset(seed=0)
    first = env.render()
    np.testing.assert_array_equal(first, env.render())
    start_pixel = _robot_centre(first)
    start_pose = env.unwrapped.poses()[0].copy()
    for _ in range(10):
        env.step(np.array([0.8, 0.8], np.float32))
    moved = env.unwrapped.poses()[0][:2] - start_pose[:2]
    pixel_shift = _robot_centre(env.render()) - start_pixel
    scale = 480 / 2.1  # pixels per metre: a 2 m arena with 5 cm walls
    np.testing.assert_allclose(pixel_shift, [moved[0] * scale, -moved[1] * scale], atol=3.0)
    env.close()


def test_rendering_needs_no_display() -> None:
    code = (
        "import gymnasium as gym, khepera_gym;"
        "e = gym.make('KheperaIV-Avoid-v1', render_mode='rgb_array'); e.reset(seed=1);"
        "print(e.render().shape)"
    )
    environment = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=environment, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "(480, 480, 3)"


def test_vector_env_renders_a_mosaic_of_the_first_worlds() -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=6, render_mode="rgb_array", frame_size=(100, 100))
    envs.reset(seed=0)
    image = envs.render()
    # 4 worlds by default in a 2 x 2 grid with 4-pixel gaps.
    assert image.shape == (204, 204, 3)
    envs.close()


def test_human_window_runs_and_closes_without_a_display() -> None:
    env = gym.make(LATEST["nav"], render_mode="human")
    env.reset(seed=0)
    for _ in range(3):
        assert env.step(np.zeros(2, np.float32))[0].shape == (18,)
    assert env.render() is None
    env.close()
    env.close()


def test_bad_frame_sizes_and_videos_raise_clear_errors(tmp_path) -> None:
    with pytest.raises(ConfigError, match="frame_size"):
        gym.make(LATEST["nav"], render_mode="rgb_array", frame_size=(8, 8))
    with pytest.raises(KheperaError, match="no frames"):
        save_video([], tmp_path / "x.gif")
    with pytest.raises(KheperaError, match=r"\.avi"):
        save_video([np.zeros((16, 16, 3), np.uint8)], tmp_path / "x.avi")
    # What render() returns without render_mode="rgb_array", and frames a video cannot hold.
    plain = gym.make(LATEST["nav"])
    plain.reset(seed=0)
    unrendered = plain.render()
    with pytest.raises(KheperaError, match=r"frame 0 is None.*rgb_array"):
        save_video([unrendered], tmp_path / "x.gif")
    with pytest.raises(KheperaError, match=r"frame 0 has shape \(16, 16\)"):
        save_video([np.zeros((16, 16), np.uint8)], tmp_path / "x.gif")
    with pytest.raises(KheperaError, match=r"frame 1 is \(8, 8, 3\), frame 0 \(16, 16, 3\)"):
        save_video([np.zeros((16, 16, 3), np.uint8), np.zeros((8, 8, 3))], tmp_path / "x.gif")
    assert not (tmp_path / "x.gif").exists()


def test_gif_of_a_rollout_is_written(tmp_path) -> None:
    env = gym.make(LATEST["avoid"], render_mode="rgb_array", frame_size=(96, 96))
    env.reset(seed=0)
    frames = [env.render()]
    for _ in range(5):
        env.step(np.array([0.5, 0.6], np.float32))
        frames.append(env.render())
    path = save_video(frames, tmp_path / "run.gif", fps=10)
    from PIL import Image

    with Image.open(path) as gif:
        assert gif.n_frames == 6 and gif.size == (96, 96)
    assert mosaic(frames[:3], columns=3).shape == (96, 3 * 96 + 8, 3)


def test_pettingzoo_envs_render_frames() -> None:
    from khepera_gym.pettingzoo import formation_v1, multinav_v1, platoon_v1

    for module in (formation_v1, multinav_v1, platoon_v1):
        env = module.parallel_env(render_mode="rgb_array", frame_size=(200, 160))
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (160, 200, 3) and frame.dtype == np.uint8
        env.close()


def test_render_command_records_a_baseline_episode(tmp_path) -> None:
    from khepera_gym.cli import main

    out = tmp_path / "fig6.gif"
    argv = ["render", "--env", LATEST["avoid"], "--config", "paper_fig6", "--policy", "braitenberg"]
    assert main([*argv, "--size", "64", "64", "--steps", "12", "--out", str(out)]) == 0
    from PIL import Image

    with Image.open(out) as gif:
        assert gif.n_frames == 13 and gif.size == (64, 64)


def test_a_recorded_rollout_replays_from_its_file_without_simulating(tmp_path) -> None:
    from khepera_gym.analysis.plots import Rollout, plot_rollouts, record_rollout
    from khepera_gym.baselines import Braitenberg

    rollout = record_rollout(
        LATEST["avoid"], Braitenberg(), seed=3, max_steps=60, label="braitenberg"
    )
    path = rollout.save(tmp_path / "run.npz")
    again = Rollout.load(path)
    for name in ("poses", "goals", "actions", "rewards", "ir_raw", "us_cm"):
        np.testing.assert_array_equal(getattr(again, name), getattr(rollout, name), err_msg=name)
    steps = len(rollout.actions)
    assert again.poses.shape == (steps + 1, 1, 3) and again.ir_raw.shape == (steps + 1, 1, 8)
    assert again.stats == rollout.stats
    assert again.scene == json.loads(json.dumps(rollout.scene))  # tuples come back as lists
    assert again.env_id == LATEST["avoid"] and "[obstacles]" in again.config and again.seed == 3
    # The file is all a plot needs.
    figure = plot_rollouts([again])
    figure.savefig(tmp_path / "replay.png")
    assert (tmp_path / "replay.png").stat().st_size > 0


def test_gymnasium_record_video_writes_an_mp4(tmp_path) -> None:
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(
        gym.make(LATEST["nav"], render_mode="rgb_array", frame_size=(96, 96)),
        str(tmp_path / "videos"),
        episode_trigger=lambda episode: True,
        disable_logger=True,
    )
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.array([0.5, 0.6], np.float32))
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 0
