"""Shared fixtures of the Python tests: environment ids and small helpers."""

from __future__ import annotations

import os
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest

import khepera_gym  # noqa: F401  (registers the environments)

# render_mode="human" opens a pygame window: on SDL's dummy driver where there is no display.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

#: The latest versioned ids (v1: tyre grip, contact friction, the motor's speed profile).
NAV_ID = "KheperaIV-Nav-v1"
AVOID_ID = "KheperaIV-Avoid-v1"
FORMATION_ID = "KheperaIV-Formation-v1"
#: Trajectory tracking exists only from v1 (it was added with the real robot's dynamics).
TRACK_ID = "KheperaIV-Track-v1"
#: Path following, likewise only from v1.
PATHFOLLOW_ID = "KheperaIV-PathFollow-v1"
#: The quadcopter of Fig. 8 following a Khepera IV, likewise only from v1.
DRONE_ID = "KheperaIV-DroneFollow-v1"
#: Line following with the ground sensors, likewise only from v1.
LINEFOLLOW_ID = "KheperaIV-LineFollow-v1"
#: Seeking a colour with the camera, likewise only from v1.
SEEK_ID = "KheperaIV-Seek-v1"
#: The v0 ids: the paper's V-REP-like dynamics (kinematic drive, frictionless contacts, wheels at
#: their command within a step), which the paper's controllers and gains were tuned for. Tests of
#: those controllers' published success rates, and tests of the action mapping that read the wheel
#: speeds one step after a command, pin them.
NAV_V0_ID = "KheperaIV-Nav-v0"
AVOID_V0_ID = "KheperaIV-Avoid-v0"
FORMATION_V0_ID = "KheperaIV-Formation-v0"


@pytest.fixture
def nav_env() -> Iterator[gym.Env]:
    """The single Nav env as users get it, through gym.make and its wrappers."""
    env = gym.make(NAV_ID)
    yield env
    env.close()


def random_actions(seed: int, steps: int, shape: tuple[int, ...]) -> np.ndarray:
    """Uniform actions in [-1, 1], float32, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, size=(steps, *shape)).astype(np.float32)
