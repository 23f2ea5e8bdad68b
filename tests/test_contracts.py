"""The extension contracts seen from Python: tasks, sensors, scenario keys and controllers are
declared once in the Rust core and everything else is derived from them (registration, layouts,
default files, controller parameters); every env face gives the same accessors; failed
constructions and old saved states fail cleanly."""

from __future__ import annotations

import gc
import inspect
import pickle
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import FORMATION, LATEST, MULTINAV

import khepera_gym
from khepera_gym import _core
from khepera_gym.baselines import VFH, Braitenberg, PositionControl, parameters
from khepera_gym.envs import ENV_CLASSES, NavEnv
from khepera_gym.errors import ConfigError, StateError
from khepera_gym.registration import latest_ids
from khepera_gym.vector import KheperaVectorEnv, NavVectorEnv

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, a dependency there
    import tomli as tomllib

DATA = Path(__file__).parent / "data"


# --- tasks --------------------------------------------------------------------------------------


def test_every_core_task_with_a_gymnasium_id_is_registered_from_the_core_list() -> None:
    exported = {name: env_id for name, env_id, _ in _core.tasks()}
    assert {name for name, env_id in exported.items() if env_id} == set(latest_ids())
    for name, env_id in exported.items():
        if env_id is None:
            continue
        spec = gym.spec(latest_ids()[name])
        assert spec.id.startswith(env_id + "-v")
        assert gym.envs.registration.load_env_creator(spec.entry_point) is ENV_CLASSES[name]


def test_default_config_lists_every_key_with_a_comment_and_loads_back() -> None:
    for name, _, _ in _core.tasks():
        text = _core.default_config(name)
        table = tomllib.loads(text)
        key_lines = [line for line in text.splitlines() if "=" in line and not line.startswith("#")]
        assert len(key_lines) == sum(len(section) for section in table.values())
        assert all(" # " in line for line in key_lines), f"{name}: a key without its comment"
        # The printed file is a scenario file: loaded over the task's own defaults it changes
        # nothing.
        default = _core.Batch(name, 1).config_toml()
        assert _core.Batch(name, 1, config_text=text, config_name="file").config_toml() == default


def test_a_task_changes_only_the_defaults_it_declares() -> None:
    nav = tomllib.loads(_core.default_config("nav"))
    avoid = tomllib.loads(_core.default_config("avoid"))
    changed = {
        f"{section}.{key}"
        for section, keys in avoid.items()
        for key, value in keys.items()
        if nav[section][key] != value
    }
    assert changed == {
        "obstacles.count",
        "obstacles.placement",
        "spawn.min_goal_distance",
        "task.max_steps",
        "task.collision_penalty",
    }


# --- sensors -------------------------------------------------------------------------------------


def test_observed_sensors_are_scenario_data_and_the_layout_follows() -> None:
    full = gym.make(LATEST["nav"])
    ir_only = gym.make(LATEST["nav"], observe=["ir"])
    assert list(full.unwrapped.obs_layout())[:2] == ["ir", "us"]
    assert "us" not in ir_only.unwrapped.obs_layout()
    assert ir_only.observation_space.shape == (full.observation_space.shape[0] - 5,)
    # The sonars are still carried (read, with their noise draws), only not observed: the same
    # seed gives the same episode, and Braitenberg, which reads `ir` and the goal by name,
    # drives both the same.
    braitenberg, narrow = Braitenberg(), Braitenberg(layout=ir_only)
    a, _ = full.reset(seed=11)
    b, _ = ir_only.reset(seed=11)
    for _ in range(200):
        action = braitenberg(a)
        np.testing.assert_array_equal(action, narrow(b))
        a, _, done_a, cut_a, _ = full.step(action)
        b, _, done_b, cut_b, _ = ir_only.step(action)
        np.testing.assert_array_equal(np.delete(a, np.s_[8:13]), b)
        assert (done_a, cut_a) == (done_b, cut_b)
        if done_a or cut_a:
            break
    assert "us_cm" in ir_only.unwrapped.sensor_readings()
    with pytest.raises(ConfigError, match="`us`"):
        VFH(layout=ir_only)


def test_a_sensor_not_carried_is_not_read() -> None:
    env = gym.make(LATEST["nav"], carry=["ir"], observe=["ir"])
    env.reset(seed=0)
    assert set(env.unwrapped.sensor_readings()) == {
        "ir_raw",
        "wheel_speeds",
        "encoders",
        "gyro_z",
    }
    with pytest.raises(ConfigError, match=r"sensors\.observe"):
        gym.make(LATEST["nav"], carry=["ir"])  # observes us, which it does not carry
    with pytest.raises(ConfigError, match='unknown sensor "lidar"'):
        gym.make(LATEST["nav"], observe=["lidar"])


# --- controllers ---------------------------------------------------------------------------------


def test_controller_parameters_come_from_the_rust_core() -> None:
    names = [name for name, _, _ in parameters("vfh")]
    assert names[:3] == ["sectors", "threshold", "hm"]
    assert list(inspect.signature(VFH).parameters)[: len(names)] == names
    assert VFH().sectors == 36 and VFH(sectors=12).sectors == 12
    assert "sectors" in (VFH.__doc__ or "")
    with pytest.raises(ConfigError, match="unknown parameter 'sectorz'"):
        VFH(sectorz=12)
    # Positional parameters in their declared order, as keywords would be.
    np.testing.assert_array_equal(
        PositionControl(0.2, 3.0)(np.eye(18, dtype=np.float32)),
        PositionControl(vmax=0.2, wmax=3.0)(np.eye(18, dtype=np.float32)),
    )


# --- one face ------------------------------------------------------------------------------------


def _faces():
    return [
        gym.make(LATEST["formation"]).unwrapped,
        gym.make_vec(LATEST["formation"], num_envs=3),
        FORMATION.parallel_env(),
    ]


@pytest.mark.parametrize("face", _faces(), ids=["single", "vector", "pettingzoo"])
def test_every_face_shows_the_same_world_through_the_same_accessors(face) -> None:
    face.reset(seed=4)
    single = gym.make(LATEST["formation"]).unwrapped
    single.reset(seed=4)
    world = (lambda a: a[0]) if isinstance(face, KheperaVectorEnv) else (lambda a: a)
    np.testing.assert_array_equal(world(face.poses()), single.poses())
    np.testing.assert_array_equal(world(face.goals()), single.goals())
    np.testing.assert_array_equal(world(face.targets()), single.targets())
    for key, values in single.sensor_readings().items():
        np.testing.assert_array_equal(world(face.sensor_readings()[key]), values)
    assert face.config_toml() == single.config_toml()
    assert face.obs_layout() == single.obs_layout()
    assert face.agent_layouts() == single.agent_layouts()


def test_pettingzoo_envs_save_and_restore_their_state() -> None:
    env = MULTINAV.parallel_env()
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    actions = [{a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents} for _ in range(40)]
    state = env.get_state()
    first = [env.step(a)[0] for a in actions]
    env.set_state(state)
    again = [env.step(a)[0] for a in actions]
    for x, y in zip(first, again, strict=True):
        assert x.keys() == y.keys()
        for agent in x:
            np.testing.assert_array_equal(x[agent], y[agent])
    clone = pickle.loads(pickle.dumps(env))
    assert clone.get_state() == env.get_state()


def test_last_outputs_show_each_world_as_it_now_is_and_are_saved() -> None:
    batch = _core.Batch("multinav", 3, autoreset=False, num_threads=1)
    batch.reset(5)
    actions = np.random.default_rng(1).uniform(-1, 1, (30, 3, batch.act_dim)).astype(np.float32)
    for step_actions in actions[:-1]:
        batch.step(step_actions)
    stepped = batch.step(actions[-1])
    for got, expected in zip(batch.last_outputs(), stepped, strict=True):
        np.testing.assert_array_equal(got, expected)
    state = batch.get_state()
    first = batch.reset_world(1)
    observations, rewards, terminated, truncated = batch.last_outputs()
    np.testing.assert_array_equal(observations[1], first)
    assert rewards[1] == 0 and not terminated[1] and not truncated[1]
    np.testing.assert_array_equal(np.delete(observations, 1, 0), np.delete(stepped[0], 1, 0))
    assert not np.array_equal(first, stepped[0][1])
    restored = _core.Batch("multinav", 3, autoreset=False, num_threads=1)
    restored.set_state(state)
    for got, expected in zip(restored.last_outputs(), stepped, strict=True):
        np.testing.assert_array_equal(got, expected)


# --- failures ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "build",
    [
        lambda: NavVectorEnv(num_envs=0),
        lambda: gym.make_vec(LATEST["nav"], num_envs=0),
        lambda: NavEnv(radius=-1.0),
        lambda: FORMATION.parallel_env(n_followers=0),
    ],
    ids=["vector", "make_vec", "single", "pettingzoo"],
)
def test_a_failed_construction_raises_its_error_and_nothing_else(build) -> None:
    unraisable = []
    hook, sys.unraisablehook = sys.unraisablehook, unraisable.append
    try:
        with pytest.raises(ConfigError):
            build()
        gc.collect()
    finally:
        sys.unraisablehook = hook
    assert unraisable == []


@pytest.mark.parametrize(
    "cls",
    [NavEnv, NavVectorEnv, FORMATION.FormationParallelEnv],
    ids=["single", "vector", "pettingzoo"],
)
def test_a_half_built_env_closes_cleanly(cls) -> None:
    # What Gymnasium 1.1's VectorEnv.__del__ does to an env whose __init__ raised.
    cls.__new__(cls).close()


def test_a_state_of_an_older_format_is_refused_not_misread() -> None:
    # Saved by khepera_gym before the sensor and task contracts (format 1): 2 Nav worlds.
    envs = gym.make_vec(LATEST["nav"], num_envs=2)
    envs.reset(seed=3)
    before = envs.get_state()
    with pytest.raises(StateError, match="format version 1"):
        envs.set_state((DATA / "nav_2worlds_format1.state").read_bytes())
    assert envs.get_state() == before


def test_the_package_version_and_ids_are_exported() -> None:
    assert khepera_gym.__version__ == _core.__version__
    assert latest_ids()["avoid"] == LATEST["avoid"]
