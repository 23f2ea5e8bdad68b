"""The NavEnv manual stays true: its examples run and its tables cover the layout and every key."""

from __future__ import annotations

import doctest

import pytest

import khepera_gym
from khepera_gym import _core, envs
from khepera_gym.envs import NavEnv

MANUAL_SECTIONS = [
    "Description",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Starting State",
    "Episode End",
    "Arguments",
    "Vectorized environment",
    "Robot model",
    "Sensors",
    "Scenario file",
    "Version History",
]


def test_nav_manual_has_every_section_in_order() -> None:
    manual = NavEnv.__doc__ or ""
    positions = [manual.index(f"## {section}\n") for section in MANUAL_SECTIONS]
    assert positions == sorted(positions)


def test_nav_manual_examples_run() -> None:
    results = doctest.testmod(envs, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert results.attempted > 0
    assert results.failed == 0


def test_nav_manual_observation_table_matches_layout() -> None:
    manual = NavEnv.__doc__ or ""
    rows = [line.split("|")[1:3] for line in manual.splitlines() if line.strip()[:2] == "| "]
    named = {int(index): name.strip() for index, name in rows if index.strip().isdigit()}
    for name, block in khepera_gym.obs_layout("nav").items():
        for index in range(block.start, block.stop):
            assert named[index] == name


def test_nav_manual_documents_every_scenario_key() -> None:
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    manual = NavEnv.__doc__ or ""
    scenario = tomllib.loads(_core.default_config("nav"))
    assert scenario
    for section, keys in scenario.items():
        for key in keys:
            assert f"`{section}.{key}`" in manual, f"{section}.{key} missing from the manual"
