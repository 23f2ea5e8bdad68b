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

#: The versioned ids; the unversioned "KheperaIV-Nav" makes Gymnasium warn that it picked v0.
NAV_ID = "KheperaIV-Nav-v0"
AVOID_ID = "KheperaIV-Avoid-v0"
FORMATION_ID = "KheperaIV-Formation-v0"


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
