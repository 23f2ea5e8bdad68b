"""The env manuals stay true: examples run, tables cover the layout, bounds and every key."""

from __future__ import annotations

import doctest
import re
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, a dependency there
    import tomli as tomllib

import gymnasium as gym
import numpy as np
import pytest
from conftest import (
    AVOID_ID,
    DRONE_ID,
    FORMATION_ID,
    LINEFOLLOW_ID,
    NAV_ID,
    PATHFOLLOW_ID,
    SEEK_ID,
    TRACK_ID,
)

import khepera_gym
from khepera_gym import _core, envs
from khepera_gym.envs import (
    AvoidEnv,
    DroneFollowEnv,
    FormationEnv,
    LineFollowEnv,
    NavEnv,
    PathFollowEnv,
    SeekEnv,
    TrackEnv,
)

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
#: (env class, registered id, task) of every manual.
MANUALS = [
    (NavEnv, NAV_ID, "nav"),
    (AvoidEnv, AVOID_ID, "avoid"),
    (FormationEnv, FORMATION_ID, "formation"),
    (TrackEnv, TRACK_ID, "track"),
    (PathFollowEnv, PATHFOLLOW_ID, "pathfollow"),
    (DroneFollowEnv, DRONE_ID, "dronefollow"),
    (LineFollowEnv, LINEFOLLOW_ID, "linefollow"),
    (SeekEnv, SEEK_ID, "seek"),
]
MANUAL_IDS = [
    "nav",
    "avoid",
    "formation",
    "track",
    "pathfollow",
    "dronefollow",
    "linefollow",
    "seek",
]


def _section(manual: str, name: str) -> str:
    start = manual.index(f"## {name}\n")
    end = manual.find("\n    ## ", start + 1)
    return manual[start : None if end < 0 else end]


def _observation_rows(manual: str) -> list[tuple[range, str, float, float]]:
    """Rows of the Observation Space table: (indices, name, min, max); "0-7" covers 0..7."""
    rows = []
    for line in _section(manual, "Observation Space").splitlines():
        cells = [cell.strip() for cell in line.split("|")[1:-1]]
        match = re.fullmatch(r"(\d+)(?:-(\d+))?", cells[0]) if cells else None
        if match:
            first = int(match.group(1))
            last = int(match.group(2) or first)
            rows.append((range(first, last + 1), cells[1], float(cells[-2]), float(cells[-1])))
    return rows


def _block_layout(task: str) -> dict[str, slice]:
    """The layout the table describes: the whole observation, or one follower's block."""
    layout = khepera_gym.obs_layout(task)
    if task != "formation":
        return layout
    prefix = "follower_0/"
    return {name.removeprefix(prefix): s for name, s in layout.items() if name.startswith(prefix)}


def _toml_text(value: Any) -> str:
    """A scenario value as the manuals write it in their Default column."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(_toml_text(item) for item in value) + "]"
    return str(value)


def _key_row(manual: str, key: str) -> str:
    """The Scenario file table's line that names ``key`` (in backquotes)."""
    for line in _section(manual, "Scenario file").splitlines():
        if line.strip().startswith("|") and f"`{key}`" in line:
            return line
    raise AssertionError(f"{key} has no row in the Scenario file table")


@pytest.mark.parametrize("env_class", [m[0] for m in MANUALS], ids=MANUAL_IDS)
def test_manual_has_every_section_in_order(env_class: type) -> None:
    manual = env_class.__doc__ or ""
    positions = [manual.index(f"## {section}\n") for section in MANUAL_SECTIONS]
    assert positions == sorted(positions)


def test_manual_examples_run() -> None:
    results = doctest.testmod(envs, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert results.attempted >= 10  # Nav, Avoid and Formation examples
    assert results.failed == 0


@pytest.mark.parametrize(("env_class", "env_id", "task"), MANUALS, ids=MANUAL_IDS)
def test_manual_observation_table_matches_layout_and_bounds(
    env_class: type, env_id: str, task: str
) -> None:
    rows = _observation_rows(env_class.__doc__ or "")
    layout = _block_layout(task)
    named = {index: name for indices, name, _, _ in rows for index in indices}
    assert sorted(named) == list(range(max(s.stop for s in layout.values())))
    for name, block in layout.items():
        for index in range(block.start, block.stop):
            assert named[index] == name, index
    env = gym.make(env_id)
    low, high = env.observation_space.low, env.observation_space.high
    for indices, name, minimum, maximum in rows:
        for index in indices:
            assert low[index] == pytest.approx(minimum, abs=0.01), (name, index)
            assert high[index] == pytest.approx(maximum, abs=0.01), (name, index)
    env.close()


def test_formation_manual_states_the_agent_leader_block_is_navs() -> None:
    manual = FormationEnv.__doc__ or ""
    assert "Nav block (18 values" in _section(manual, "Observation Space")
    env = gym.make(FORMATION_ID, leader="agent")
    layout = env.unwrapped.obs_layout()
    nav_layout = khepera_gym.obs_layout("nav")
    assert {name.removeprefix("leader/"): s for name, s in layout.items() if "leader/" in name} == (
        nav_layout
    )
    np.testing.assert_array_equal(
        env.observation_space.low[:18], gym.make(NAV_ID).observation_space.low
    )
    env.close()


def test_nav_manual_documents_every_scenario_key() -> None:
    manual = NavEnv.__doc__ or ""
    scenario = tomllib.loads(_core.default_config("nav"))
    assert scenario
    for section, keys in scenario.items():
        for key in keys:
            assert f"`{section}.{key}`" in manual, f"{section}.{key} missing from the manual"


@pytest.mark.parametrize(
    ("env_class", "task"),
    [
        (AvoidEnv, "avoid"),
        (FormationEnv, "formation"),
        (TrackEnv, "track"),
        (PathFollowEnv, "pathfollow"),
    ],
)
def test_task_manual_documents_every_key_that_differs_from_nav(env_class: type, task: str) -> None:
    """A task manual tables the keys whose default differs from Nav's and its own sections; for
    the other keys it refers to NavEnv's table, which documents them (test above)."""
    manual = env_class.__doc__ or ""
    assert ":class:`NavEnv`" in _section(manual, "Scenario file")
    nav = tomllib.loads(_core.default_config("nav"))
    scenario = tomllib.loads(_core.default_config(task))
    documented = set()
    for section, keys in scenario.items():
        for key, value in keys.items():
            name = f"{section}.{key}"
            if section in nav and nav[section].get(key) == value:
                continue
            row = _key_row(manual, name)
            assert _toml_text(value) in row, f"{name}: default {value!r} not in {row!r}"
            documented.add(name)
    assert documented
    # Every key the table lists is one of them, with the default the file has.
    listed = re.findall(r"^\s*\| `([a-z_]+\.[a-z_]+)`", _section(manual, "Scenario file"), re.M)
    assert set(listed) == documented
