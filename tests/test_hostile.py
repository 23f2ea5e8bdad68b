"""Hostile input (issue 36): the seven classes of bug the fuzzing campaign found, each kept as a
regression test, and a sample of the campaign itself (``tests/hostile``), every case in a forked
process with a memory limit, so that an abort fails the test instead of killing pytest.

The long run is one command (``python tests/hostile_campaign.py --cases 100000 --json ...``);
its figure is recorded in docs/reliability.md.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

import khepera_gym
from khepera_gym.errors import ConfigError
from khepera_gym.pettingzoo import consensus_v1, formation_v1, multinav_v1, platoon_v1

ROOT = Path(__file__).resolve().parent.parent

# --- 1. bounded resources ---------------------------------------------------------------------


def _run_limited(code: str, memory: int) -> subprocess.CompletedProcess[str]:
    """Runs ``code`` in a fresh interpreter whose address space is limited to ``memory`` bytes
    beyond what importing khepera_gym takes: an abort is a signal here, not a dead pytest."""
    prelude = textwrap.dedent(
        f"""
        import resource, gymnasium as gym, khepera_gym
        size = 0
        for line in open("/proc/self/status"):
            if line.startswith("VmSize:"):
                size = int(line.split()[1]) * 1024
        resource.setrlimit(resource.RLIMIT_AS, (size + {memory}, size + {memory}))
        """
    )
    return subprocess.run(
        [sys.executable, "-c", prelude + textwrap.dedent(code)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc (Linux)")
@pytest.mark.parametrize(
    ("call", "expected"),
    [
        # A 1,000 m arena with one fixed circle: a spawn grid of 2.5e9 cells once aborted.
        (
            f'gym.make("{LATEST["nav"]}", width=1000.0, height=1000.0, '
            'obstacles={"fixed": [{"kind": "circle", "center": [0.0, 0.0], "radius": 0.5}]})',
            r"ConfigError.*arena\.width.*reachability map.*MB",
        ),
        # 10**6 worlds of about 30 KiB: once OOM-killed; past 16 GiB it is refused.
        (
            f'gym.make_vec("{LATEST["nav"]}", num_envs=10**6)',
            r"ConfigError.*num_envs.*GiB",
        ),
        # Within the 16 GiB limit but beyond what this process may map: MemoryError.
        (
            f'gym.make_vec("{LATEST["nav"]}", num_envs=200_000)',
            r"MemoryError.*200000 worlds",
        ),
    ],
)
def test_sizes_taken_from_input_are_refused_before_allocating(call: str, expected: str) -> None:
    result = _run_limited(
        f"""
        try:
            {call}
        except BaseException as error:
            print(type(error).__name__, error)
        else:
            print("built")
        """,
        memory=1 << 30,
    )
    assert result.returncode == 0, (result.returncode, result.stderr[-2000:])
    assert re.search(expected, result.stdout), result.stdout


# --- 2. one validation rule per key -----------------------------------------------------------

#: (id, overrides, the key the ConfigError names): values the campaign saw accepted.
OUT_OF_DOMAIN = [
    (LATEST["nav"], {"wall_reflectance": math.nan}, "arena.wall_reflectance"),
    (LATEST["nav"], {"wall_reflectance": -1.0}, "arena.wall_reflectance"),
    # Unused in that scenario (no image, not a custom shape): checked all the same.
    (LATEST["nav"], {"image_scale": math.nan}, "floor.image_scale"),
    (LATEST["formation"], {"offsets": [[math.nan, 0.0]]}, "formation.offsets[0][0]"),
    # Finite values whose rewards became infinite.
    (LATEST["dronefollow"], {"speed_max": 1e20}, "drone.speed_max"),
    (LATEST["dronefollow"], {"speed_max": 1e10}, "drone.speed_max"),
    (LATEST["formation"], {"error_weight": 3.4e38}, "formation.error_weight"),
    (LATEST["track"], {"heading_weight": 3.4e38}, "track.heading_weight"),
    # A positive axle so thin that wheel speeds became infinite turn rates (NaN poses), found by
    # the 10^5-case run: body dimensions are at least a millimetre.
    (LATEST["formation"], {"axle_length": 1e-30}, "robot.axle_length"),
    (LATEST["nav"], {"robot": {"axle_length": [1e-45, 0.1]}}, "robot.axle_length"),
    # Fixed-length arrays with extra entries, once silently truncated.
    (LATEST["nav"], {"us_enabled": [True] * 6}, "sensors.us_enabled"),
    (LATEST["nav"], {"led_color": [0.0, 0.5, 0.5, 0.5]}, "robot.led_color"),
    (LATEST["nav"], {"image_origin": [0.0, 0.0, 0.0]}, "floor.image_origin"),
    (
        LATEST["nav"],
        {"floor": {"lines": [{"a": [0.0, 0.0], "b": [1.0, 0.0, 2.0], "width": 0.02}]}},
        "floor.lines[0].b",
    ),
    (LATEST["formation"], {"offsets": [[0.5, 0.0, 1.0]]}, "formation.offsets[0]"),
]


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    return repr(value)


@pytest.mark.parametrize(("env_id", "overrides", "key"), OUT_OF_DOMAIN)
def test_a_value_outside_its_keys_domain_is_a_config_error_as_keyword_and_in_a_file(
    env_id: str, overrides: dict[str, Any], key: str, tmp_path: Path
) -> None:
    pattern = re.escape(key)
    with pytest.raises(ConfigError, match=rf"<override>: {pattern}: "):
        gym.make(env_id, **overrides)
    # The same value in a scenario file, under the section the error names.
    section = key.split(".")[0]
    ((name, value),) = overrides.items()
    if isinstance(value, dict):  # a whole table given as a keyword
        body = "".join(f"{k} = {_toml(v)}\n" for k, v in value.items())
    else:
        body = f"{name} = {_toml(value)}\n"
    path = tmp_path / "hostile.toml"
    path.write_text(f"[{section}]\n{body}")
    with pytest.raises(ConfigError, match=rf"hostile\.toml: {pattern}: "):
        gym.make(env_id, config=str(path))


@pytest.mark.parametrize(
    ("env_id", "key"),
    [
        (LATEST["dronefollow"], "speed_max"),
        (LATEST["formation"], "error_weight"),
        (LATEST["track"], "heading_weight"),
    ],
)
def test_rewards_stay_finite_at_a_keys_documented_maximum(env_id: str, key: str) -> None:
    task = next(task for task, latest in LATEST.items() if latest == env_id)
    text = khepera_gym.default_config(task)
    line = next(line for line in text.splitlines() if line.startswith(f"{key} "))
    maximum = float(line.split("<= ")[-1].split(",")[0])
    env = gym.make(env_id, **{key: maximum})
    env.reset(seed=0)
    space = env.observation_space
    for _ in range(100):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert math.isfinite(reward), reward
        assert space.contains(obs)
        if terminated or truncated:
            env.reset()
    env.close()


# --- 3. typed errors at every entry point -----------------------------------------------------


@pytest.mark.parametrize(
    ("module", "keywords"),
    [
        (formation_v1, {"formation": 5}),
        (formation_v1, {"formation": "cross"}),
        (formation_v1, {"formation": 0}),
        (multinav_v1, {"multinav": 4}),
        (consensus_v1, {"consensus": "ring"}),
        (platoon_v1, {"platoon": [1, 2]}),
    ],
)
def test_pettingzoo_table_keywords_take_a_table(module: Any, keywords: dict[str, Any]) -> None:
    (table,) = keywords
    with pytest.raises(ConfigError, match=rf"{table}= takes a dict"):
        module.parallel_env(**keywords)


@pytest.mark.parametrize(
    "arguments",
    [
        {"num_envs": 2.5},
        {"num_envs": 2**64},
        {"num_envs": 0},
        {"num_envs": True},
        {"num_envs": 2, "num_threads": "2"},
        {"num_envs": 2, "num_threads": 0},
        {"num_envs": 2, "render_worlds": "a"},
        {"num_envs": 2, "frame_size": (math.inf, 16)},
        {"num_envs": 2, "frame_size": (16.5, 16)},
        {"num_envs": 2, "frame_size": "ab"},
    ],
)
def test_vector_env_arguments_are_config_errors(arguments: dict[str, Any]) -> None:
    with pytest.raises(ConfigError):
        gym.make_vec(LATEST["nav"], **arguments)


def _task_table_entry_points() -> dict[str, Any]:
    """Every public constructor that takes scenario keywords, as (kwargs) -> env."""
    entries: dict[str, Any] = {
        "gym.make": lambda **kw: gym.make(LATEST["nav"], **kw),
        "gym.make_vec": lambda **kw: gym.make_vec(LATEST["nav"], num_envs=2, **kw),
        "array_env": lambda **kw: multinav_v1.array_env(2, **kw),
        "parallel_env": lambda **kw: multinav_v1.parallel_env(**kw),
    }
    try:
        from khepera_gym.learning.sb3 import make_vec_env

        entries["sb3"] = lambda **kw: make_vec_env(LATEST["nav"], 2, **kw)
    except ImportError:
        pass
    try:
        from khepera_gym.learning.torchrl import KheperaTorchEnv

        entries["torchrl"] = lambda **kw: KheperaTorchEnv("nav", 2, **kw)
    except ImportError:
        pass
    return entries


@pytest.mark.parametrize("entry", list(_task_table_entry_points()))
def test_the_task_section_as_a_table_reaches_the_scenario_everywhere(entry: str) -> None:
    # The campaign found `task={...}` (the [task] section, as the README documents tables)
    # raising TypeError where the constructor's first parameter is also called task.
    make = _task_table_entry_points()[entry]
    env = make(task={"goal_radius": 0.1})
    batch = env._batch if hasattr(env, "_batch") else env.unwrapped._batch
    assert "goal_radius = 0.1\n" in batch.config_toml()
    env.close()
    with pytest.raises(ConfigError, match=r"task\.led_action"):
        make(task={"led_action": [[1, 2], [3]]})


@pytest.mark.parametrize("index", [-1, 2, 1.5, "1", np.float64(1.0), True])
def test_scene_takes_a_world_index(index: Any) -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=2)
    with pytest.raises(ConfigError, match=r"scene\(\)"):
        envs.scene(index)
    assert envs.scene(np.int64(1)) == envs.scene(1)
    envs.close()


@pytest.mark.parametrize("seed", [-1, 2**64, 1.0, "0", [0]])
def test_a_single_env_refuses_a_bad_seed_with_a_config_error(seed: Any) -> None:
    env = gym.make(LATEST["nav"])
    with pytest.raises(ConfigError, match="seed"):
        env.reset(seed=seed)
    env.close()


def test_reset_options_must_be_a_dict() -> None:
    env = gym.make(LATEST["nav"])
    with pytest.raises(ConfigError, match="options"):
        env.reset(options=[1])
    env.reset(options={})
    env.close()


# --- 4. the campaign, a sample ----------------------------------------------------------------


def test_a_sample_of_the_hostile_campaign_finds_no_failure(tmp_path: Path) -> None:
    """CI's sample, through the documented command: every case built or was refused with its
    typed error; nothing aborted, hung, gave a non-finite reward or an observation outside its
    space."""
    report_path = tmp_path / "fuzz.json"
    command = [sys.executable, str(ROOT / "tests" / "hostile_campaign.py"), "--cases", "60"]
    command += ["--seed", "36"]
    command += ["--workers", "2", "--timeout", "120", "--json", str(report_path)]
    result = subprocess.run(
        command, cwd=ROOT, capture_output=True, text=True, timeout=1800, check=False
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    summary = json.loads(report_path.read_text())
    assert summary["cases"] == 60
    assert summary["failures"] == 0, summary["failure_list"]
    # A fuzzer whose cases are all refused (or all accepted) tests little.
    assert summary["accepted"] > 0 and summary["refused"] > 0, summary
