"""Errors: bad actions and configs raise khepera_gym.errors classes naming the fix; no panics."""

from __future__ import annotations

import re
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym import _core
from khepera_gym.envs import NavEnv
from khepera_gym.errors import ActionError, ConfigError, KheperaError, StateError
from khepera_gym.vector import KheperaVectorEnv


def test_error_classes_form_the_documented_tree() -> None:
    assert issubclass(ConfigError, KheperaError) and issubclass(ConfigError, ValueError)
    assert issubclass(ActionError, KheperaError) and issubclass(ActionError, ValueError)
    assert issubclass(StateError, KheperaError) and issubclass(StateError, ValueError)


# --- actions ----------------------------------------------------------------------------------


@pytest.mark.parametrize("bad_value", [np.nan, np.inf, -np.inf])
def test_non_finite_action_raises_action_error(nav_env: gym.Env, bad_value: float) -> None:
    nav_env.reset(seed=0)
    with pytest.raises(ActionError) as raised:
        nav_env.step(np.array([0.1, bad_value], dtype=np.float32))
    assert isinstance(raised.value, ValueError)


@pytest.mark.parametrize("bad_value", [np.nan, np.inf])
def test_non_finite_action_in_vector_env_raises_action_error(bad_value: float) -> None:
    envs = KheperaVectorEnv(4)
    envs.reset(seed=0)
    actions = np.zeros((4, 2), dtype=np.float32)
    actions[2, 0] = bad_value
    with pytest.raises(ActionError):
        envs.step(actions)
    envs.close()


def test_action_error_leaves_the_env_usable(nav_env: gym.Env) -> None:
    nav_env.reset(seed=0)
    with pytest.raises(ActionError):
        nav_env.step(np.array([np.nan, 0.0]))
    observation, *_ = nav_env.step(np.array([0.2, 0.2]))
    assert observation in nav_env.observation_space


@pytest.mark.parametrize("bad_shape", [(3,), (1,), (1, 2), (2, 2), ()])
def test_wrong_action_shape_raises_action_error_naming_shapes(
    nav_env: gym.Env, bad_shape: tuple[int, ...]
) -> None:
    nav_env.reset(seed=0)
    with pytest.raises(ActionError, match=r"\(2,\)"):
        nav_env.unwrapped.step(np.zeros(bad_shape, dtype=np.float32))


def test_non_numeric_action_raises_action_error(nav_env: gym.Env) -> None:
    nav_env.reset(seed=0)
    with pytest.raises(ActionError):
        nav_env.unwrapped.step(["left", "right"])
    with pytest.raises(ActionError):
        nav_env.unwrapped.step(None)


@pytest.mark.parametrize("bad_shape", [(4, 3), (3, 2), (8,), (4, 2, 1)])
def test_wrong_vector_action_shape_names_expected_and_got(bad_shape: tuple[int, ...]) -> None:
    envs = KheperaVectorEnv(4)
    envs.reset(seed=0)
    with pytest.raises(ActionError, match=re.escape("(4, 2)") + ".*" + re.escape(repr(bad_shape))):
        envs.step(np.zeros(bad_shape, dtype=np.float32))
    envs.close()


def test_out_of_range_finite_actions_are_clipped(nav_env: gym.Env) -> None:
    runs = []
    for action in ([1.0, 1.0], [5.0, 7.0]):
        nav_env.reset(seed=4)
        observation, reward, *_ = nav_env.step(np.array(action, dtype=np.float32))
        runs.append((observation, reward))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]


def test_stepping_a_finished_episode_without_reset_raises() -> None:
    env = NavEnv(max_steps=3)
    env.reset(seed=0)
    for _ in range(3):
        *_, truncated, _ = env.step(np.zeros(2, np.float32))
    assert truncated
    with pytest.raises(KheperaError):
        env.step(np.zeros(2, np.float32))
    env.reset()
    env.step(np.zeros(2, np.float32))


# --- configuration ----------------------------------------------------------------------------


def test_unknown_override_key_raises_config_error_naming_it() -> None:
    with pytest.raises(ConfigError, match="goal_radiuss"):
        gym.make(LATEST["nav"], goal_radiuss=0.1)
    with pytest.raises(ConfigError, match="bogus"):
        gym.make(LATEST["nav"], task={"bogus": 1})


def test_unknown_key_in_scenario_file_names_file_and_key(tmp_path) -> None:
    scenario = tmp_path / "typo.toml"
    scenario.write_text("[robot]\nradiuss = 0.07\n")
    with pytest.raises(ConfigError, match="radiuss") as raised:
        NavEnv(config=scenario)
    assert "typo.toml" in str(raised.value)


def test_negative_robot_radius_names_robot_radius() -> None:
    with pytest.raises(ConfigError, match=r"robot\.radius"):
        NavEnv(robot={"radius": -1.0})
    with pytest.raises(ConfigError, match=r"robot\.radius"):
        NavEnv(**{"robot.radius": -1.0})


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"goal_radius": -0.05}, "goal_radius"),
        ({"goal_radius": float("nan")}, "goal_radius"),
        ({"min_goal_distance": 10.0}, "min_goal_distance"),
        ({"max_steps": 0}, "max_steps"),
        ({"max_steps": "many"}, "max_steps"),
        ({"dt": 0.0}, "dt"),
        ({"substeps": 0}, "substeps"),
        ({"arena": {"width": -2.0}}, "arena.width"),
        # Found by the long hypothesis run: an infinite range panicked when sampled at reset.
        ({"wheel_accel_limit": [1.0, float("inf")]}, "robot.wheel_accel_limit"),
        ({"robot": {0: 1.0}}, "robot: keys must be str"),
        ({"robot": {"mass": {"kg": 1.0}}}, "robot.mass: is a single setting"),
    ],
)
def test_impossible_values_raise_config_error_naming_the_key(
    overrides: dict[str, Any], key: str
) -> None:
    with pytest.raises(ConfigError, match=key):
        NavEnv(**overrides)


def test_missing_config_file_raises_config_error_naming_it(tmp_path) -> None:
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(ConfigError, match=r"nowhere\.toml"):
        gym.make(LATEST["nav"], config=str(missing))


def test_unknown_builtin_scenario_lists_known_names() -> None:
    with pytest.raises(ConfigError, match="nav"):
        NavEnv(config="no_such_scenario")


def test_malformed_toml_raises_config_error(tmp_path) -> None:
    scenario = tmp_path / "broken.toml"
    scenario.write_text("[task\nmax_steps = \n")
    with pytest.raises(ConfigError, match=r"broken\.toml"):
        NavEnv(config=scenario)


def test_a_line_that_is_not_a_key_is_named_by_its_line_number(tmp_path) -> None:
    scenario = tmp_path / "dot.toml"
    scenario.write_text("[task]\n.= 1\n")
    with pytest.raises(ConfigError, match=r"dot\.toml: line 2: "):
        NavEnv(config=scenario)


def test_unknown_action_type_raises_config_error() -> None:
    with pytest.raises(ConfigError, match="action_type"):
        NavEnv(action_type="tank")


def test_vector_reset_with_wrong_number_of_seeds_raises() -> None:
    envs = KheperaVectorEnv(3)
    with pytest.raises(ConfigError, match="3 seeds"):
        envs.reset(seed=[1, 2])
    envs.close()


# --- no Rust panic reaches Python -------------------------------------------------------------


def _outcome(call: Any) -> BaseException | None:
    """Runs ``call``; returns the exception it raised (any BaseException, panics included)."""
    try:
        call()
    except BaseException as error:  # PanicException derives from BaseException
        return error
    return None


def _exercise_batch(**kwargs: Any) -> None:
    batch = _core.Batch(**kwargs)
    batch.reset(0)
    actions = np.ones((batch.num_worlds, batch.act_dim), dtype=np.float32)
    for _ in range(3):
        batch.step(actions)
    batch.poses()
    batch.sensor_readings()
    batch.episode_stats()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"task": "nav", "num_worlds": 0},
        {"task": "nav", "num_worlds": -1},
        {"task": "no_such_task", "num_worlds": 1},
        {"task": "nav", "num_worlds": 1, "num_threads": 0},
        {"task": "nav", "num_worlds": 1, "action_type": "tank"},
        {"task": "nav", "num_worlds": 1, "config_text": "[robot\n"},
        {"task": "nav", "num_worlds": 1, "overrides": {"radius": 5.0}},
        {"task": "nav", "num_worlds": 1, "overrides": {"width": 1e30, "height": 1e30}},
        {"task": "nav", "num_worlds": 1, "overrides": {"wheel_accel_limit": -1.0}},
        {"task": "nav", "num_worlds": 1, "overrides": {"max_wheel_speed": 1e30}},
        {"task": "nav", "num_worlds": 1, "overrides": {"dt": 1e-30}},
        {"task": "nav", "num_worlds": 1, "overrides": {"max_steps": 2**40}},
        {"task": "nav", "num_worlds": 1, "overrides": {"substeps": -3}},
        {"task": "nav", "num_worlds": 1, "overrides": {"robot": 3}},
        {"task": "nav", "num_worlds": 1, "overrides": {"us_enabled": [True]}},
    ],
)
def test_no_rust_panic_reaches_python(kwargs: dict[str, Any]) -> None:
    error = _outcome(lambda: _exercise_batch(**kwargs))
    if error is not None:
        assert isinstance(error, (KheperaError, TypeError, OverflowError)), repr(error)


def test_zero_worlds_raises_khepera_error() -> None:
    error = _outcome(lambda: _core.Batch("nav", 0))
    assert isinstance(error, KheperaError), repr(error)


def test_robot_larger_than_arena_raises_config_error() -> None:
    error = _outcome(lambda: _core.Batch("nav", 1, overrides={"radius": 5.0}))
    assert isinstance(error, ConfigError), repr(error)


def test_unknown_task_raises_khepera_error() -> None:
    with pytest.raises(KheperaError, match="no_such_task"):
        _core.Batch("no_such_task", 1)


def test_batch_misuse_raises_khepera_error_not_panic() -> None:
    batch = _core.Batch("nav", 2, autoreset=False)
    batch.reset(0)
    for call in (
        lambda: batch.reset_world(2),
        lambda: batch.reset_world(-1),
        lambda: batch.scene(5),
        lambda: batch.step(np.zeros((2, 2), dtype=np.float64)),
        lambda: batch.step(np.zeros((2, 2), dtype=np.float32)[:, :1]),
        lambda: batch.step(np.zeros((4,), dtype=np.float32)),
        lambda: batch.step(np.zeros((2, 2), dtype=np.float32).T),
    ):
        error = _outcome(call)
        if error is not None:
            assert isinstance(error, (KheperaError, TypeError, OverflowError)), repr(error)


def test_a_real_rust_panic_surfaces_as_khepera_error() -> None:
    """A panic inside the core (here a deliberate out-of-bounds index) is caught at the binding."""
    error = _outcome(_core._panic_for_test)
    assert type(error) is KheperaError, type(error)
    assert "internal error" in str(error) and "index out of bounds" in str(error)


def test_every_command_reads_key_values_with_one_parser_and_refuses_bad_items() -> None:
    """``--set`` (compare, export) and ``--hp`` (train) read ``KEY=VALUE`` alike: a TOML value or
    else a string; an item without ``=``, with an empty key, or a key given twice is a
    ConfigError naming the option (a repeated key would otherwise silently keep the last)."""
    import argparse

    from khepera_gym.config import parse_key_values
    from khepera_gym.learning.recipes import parse_override
    from khepera_gym.robot.export.command import run_from_args as export_from_args

    assert parse_key_values(["a=0.5", "b=[1, 2]", "c=square", 'd="ccw"', "e = true"], "--set") == {
        "a": 0.5,
        "b": [1, 2],
        "c": "square",
        "d": "ccw",
        "e": True,
    }
    for items, message in (
        (["a"], "expected KEY=VALUE"),
        ([" =1"], "expected KEY=VALUE"),
        (["a=1", "a=2"], "given twice"),
    ):
        with pytest.raises(ConfigError, match=f"--hp.*{message}"):
            parse_key_values(items, "--hp")
    assert parse_override("n_steps=64") == ("n_steps", 64)
    with pytest.raises(ConfigError, match="--hp"):
        parse_override("n_steps")
    # The export command refuses a repeated key before it opens the model.
    args = argparse.Namespace(model="missing.zip", out=None, set=["mass=0.5", "mass=0.6"])
    with pytest.raises(ConfigError, match="--set: key 'mass' is given twice"):
        export_from_args(args)
