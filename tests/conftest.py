"""Shared fixtures of the Python tests: environment ids and PettingZoo modules from the
registries, and small helpers."""

from __future__ import annotations

import os
from collections.abc import Iterator
from types import ModuleType

import gymnasium as gym
import numpy as np
import pytest

import khepera_gym
import khepera_gym.pettingzoo
from khepera_gym.registration import latest_ids, registered_ids

# render_mode="human" opens a pygame window: on SDL's dummy driver where there is no display.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

#: Every registered id of every task and version (``registered_ids()``, oldest version first
#: within a task): what the cross-cutting tests (determinism, thread count, saved states,
#: Gymnasium's env checker) run over, so that a new task or version is covered without touching
#: them; ``tests/test_registry_coverage.py`` checks that none is left out.
ALL_IDS = [env_id for ids in registered_ids().values() for env_id in ids]
#: Every versioned PettingZoo module (``khepera_gym.pettingzoo.modules()``), name → module: what
#: PettingZoo's API and seed tests run over.
PETTINGZOO_MODULES = khepera_gym.pettingzoo.modules()


def latest_module(task_module: str) -> ModuleType:
    """The latest version of a PettingZoo module (``"formation"`` → ``formation_v3``)."""
    versions = [
        m for name, m in PETTINGZOO_MODULES.items() if name.rpartition("_v")[0] == task_module
    ]
    return versions[-1]


#: The latest PettingZoo module of the tasks tests use as "the current one", from the registry
#: (``formation_v3`` while v3 is the latest): a new version is covered without editing a test.
FORMATION = latest_module("formation")
MULTINAV = latest_module("multinav")
CONSENSUS = latest_module("consensus")


def module_name(module: ModuleType) -> str:
    """A PettingZoo module's own name (``formation_v3``), as its envs' metadata and RLlib's
    registry name it."""
    return module.__name__.rpartition(".")[2]


#: The latest versioned id of every task with a Gymnasium env, from the registry: task →
#: id (``LATEST["nav"]``). Tests of behaviour every version shares use these, so a new version
#: or task is covered without an edit.
LATEST = latest_ids()
#: The v1 ids (tyre grip, contact friction, a plain 0.203 m/s² ramp of the wheels): tests that
#: specify v1's own dynamics pin them, so that v1 keeps its behaviour.
NAV_V1_ID = "KheperaIV-Nav-v1"
AVOID_V1_ID = "KheperaIV-Avoid-v1"
FORMATION_V1_ID = "KheperaIV-Formation-v1"
#: The v0 ids: the paper's V-REP-like dynamics (kinematic drive, frictionless contacts, wheels at
#: their command within a step), which the paper's controllers and gains were tuned for. Tests of
#: those controllers' published success rates, and tests of the action mapping that read the wheel
#: speeds one step after a command, pin them.
NAV_V0_ID = "KheperaIV-Nav-v0"
AVOID_V0_ID = "KheperaIV-Avoid-v0"
FORMATION_V0_ID = "KheperaIV-Formation-v0"


@pytest.fixture
def one_torch_thread() -> Iterator[None]:
    """One torch thread, as ``khepera-gym train`` uses (far faster on 2 cores); the modules that
    train take it with ``pytestmark = pytest.mark.usefixtures("one_torch_thread")``."""
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.fixture
def nav_env() -> Iterator[gym.Env]:
    """The single Nav env as users get it, through gym.make and its wrappers."""
    env = gym.make(LATEST["nav"])
    yield env
    env.close()


def random_actions(seed: int, steps: int, shape: tuple[int, ...]) -> np.ndarray:
    """Uniform actions in [-1, 1], float32, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, size=(steps, *shape)).astype(np.float32)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """Names the vector paths whose golden digests ran (tests/test_simd_paths.py), so that the
    CI log says which of the CPU's paths were checked and which this machine lacks."""
    import sys

    module = sys.modules.get("test_simd_paths")
    ran = getattr(module, "RAN", None)
    if ran:
        terminalreporter.write_line(
            "vector paths: " + "; ".join(f"{path}: {what}" for path, what in ran.items())
        )
