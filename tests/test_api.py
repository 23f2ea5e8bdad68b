"""The public Python API: registration, spaces, observation layout, Gymnasium conformance."""

from __future__ import annotations

import importlib
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import ALL_IDS, LATEST, random_actions
from gymnasium.utils.env_checker import check_env

import khepera_gym
from khepera_gym import _core
from khepera_gym.envs import NavEnv
from khepera_gym.errors import ConfigError
from khepera_gym.vector import KheperaVectorEnv

NAV_OBS_NAMES = [
    "ir",
    "us",
    "goal_distance",
    "goal_bearing_sin",
    "goal_bearing_cos",
    "wheel_speeds",
]
NAV_OBS_DIM = 18


def test_package_exports_version_errors_and_obs_layout() -> None:
    assert isinstance(khepera_gym.__version__, str) and khepera_gym.__version__
    assert khepera_gym.__version__ == _core.__version__
    assert khepera_gym.errors.ConfigError is ConfigError
    assert callable(khepera_gym.obs_layout)


def test_nav_is_registered_with_entry_point_and_vector_entry_point() -> None:
    spec = gym.spec(LATEST["nav"])
    assert spec.entry_point == "khepera_gym.envs:NavEnv"
    assert spec.vector_entry_point is not None
    assert spec.max_episode_steps is None  # the Rust core truncates by itself


def test_reimporting_the_package_registers_nothing_twice() -> None:
    before = dict(gym.registry)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        importlib.reload(khepera_gym)
    assert gym.registry.keys() == before.keys()
    assert gym.spec(LATEST["nav"]) == before[LATEST["nav"]]


def test_make_versioned_id_gives_nav_env(nav_env: gym.Env) -> None:
    assert isinstance(nav_env.unwrapped, NavEnv)
    observation, info = nav_env.reset(seed=0)
    assert observation.shape == (NAV_OBS_DIM,)
    assert info == {}


def test_make_unversioned_id_resolves_to_latest_version() -> None:
    with pytest.warns(UserWarning, match=f"latest versioned environment `{LATEST['nav']}`"):
        env = gym.make("KheperaIV-Nav")
    assert env.spec is not None and env.spec.id == LATEST["nav"]
    assert isinstance(env.unwrapped, NavEnv)
    env.close()


def test_action_space_is_normalised_wheel_speeds(nav_env: gym.Env) -> None:
    space = nav_env.action_space
    assert isinstance(space, gym.spaces.Box)
    assert space.shape == (2,) and space.dtype == np.float32
    np.testing.assert_array_equal(space.low, [-1.0, -1.0])
    np.testing.assert_array_equal(space.high, [1.0, 1.0])


def test_observation_space_is_finite_float32_box(nav_env: gym.Env) -> None:
    space = nav_env.observation_space
    assert isinstance(space, gym.spaces.Box)
    assert space.shape == (NAV_OBS_DIM,) and space.dtype == np.float32
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    assert np.all(space.low <= space.high)


def test_obs_layout_covers_observation_contiguously_in_order() -> None:
    layout = khepera_gym.obs_layout("nav")
    assert list(layout) == NAV_OBS_NAMES
    position = 0
    for name, block in layout.items():
        assert block.start == position, name
        assert block.stop > block.start, name
        assert block.step is None
        position = block.stop
    assert position == NAV_OBS_DIM
    assert layout["ir"] == slice(0, 8)
    assert layout["us"] == slice(8, 13)
    assert layout["wheel_speeds"] == slice(16, 18)


def test_obs_layout_returns_a_fresh_dict() -> None:
    layout = khepera_gym.obs_layout("nav")
    layout.clear()
    assert len(khepera_gym.obs_layout("nav")) == len(NAV_OBS_NAMES)


def test_observation_bounds_match_documented_ranges(nav_env: gym.Env) -> None:
    space = nav_env.observation_space
    layout = khepera_gym.obs_layout("nav")
    for name in ("ir", "us"):
        np.testing.assert_array_equal(space.low[layout[name]], 0.0)
        np.testing.assert_array_equal(space.high[layout[name]], 1.0)
    assert space.low[layout["goal_distance"]][0] == 0.0
    assert space.high[layout["goal_distance"]][0] == pytest.approx(np.hypot(2.0, 2.0), rel=1e-3)
    for name in ("goal_bearing_sin", "goal_bearing_cos", "wheel_speeds"):
        np.testing.assert_array_equal(space.low[layout[name]], -1.0)
        np.testing.assert_array_equal(space.high[layout[name]], 1.0)


def test_observations_stay_in_bounds_under_random_actions(nav_env: gym.Env) -> None:
    observation, _ = nav_env.reset(seed=3)
    assert observation in nav_env.observation_space
    for action in random_actions(3, 500, (2,)):
        observation, reward, terminated, truncated, _ = nav_env.step(action)
        assert observation.dtype == np.float32
        assert observation in nav_env.observation_space, observation
        assert isinstance(reward, float) and np.isfinite(reward)
        if terminated or truncated:
            observation, _ = nav_env.reset()
            assert observation in nav_env.observation_space


def test_step_returns_python_scalars_and_fresh_observations(nav_env: gym.Env) -> None:
    first, _ = nav_env.reset(seed=1)
    observation, reward, terminated, truncated, info = nav_env.step(np.array([0.5, 0.5]))
    assert type(reward) is float
    assert type(terminated) is bool and type(truncated) is bool
    assert info == {}
    assert not np.shares_memory(first, observation)
    kept = observation.copy()
    nav_env.step([0.5, 0.5])
    np.testing.assert_array_equal(observation, kept)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gymnasium_env_checker_passes_without_warnings(env_id: str) -> None:
    if env_id == LATEST["nav"]:  # the unversioned id warns that it takes the latest version
        with pytest.warns(UserWarning, match="latest versioned"):
            env = gym.make(env_id.rpartition("-v")[0])
    else:
        env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_make_vec_gives_native_rust_vector_env() -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=3)
    assert isinstance(envs, KheperaVectorEnv)
    assert not isinstance(envs, gym.vector.SyncVectorEnv)
    assert envs.num_envs == 3
    assert envs.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    assert envs.single_action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert envs.action_space.shape == (3, 2)
    assert envs.observation_space.shape == (3, NAV_OBS_DIM)
    assert envs.single_observation_space.shape == (NAV_OBS_DIM,)
    observations, infos = envs.reset(seed=0)
    assert observations.shape == (3, NAV_OBS_DIM) and observations.dtype == np.float32
    assert observations in envs.observation_space
    assert infos == {}
    envs.close()


def test_make_vec_with_unversioned_id_and_thread_count() -> None:
    with pytest.warns(UserWarning, match="latest versioned"):
        envs = gym.make_vec("KheperaIV-Nav", num_envs=2, num_threads=1)
    assert isinstance(envs, KheperaVectorEnv)
    assert envs.num_threads == 1
    envs.close()


def test_vector_env_step_shapes_dtypes_and_fresh_arrays() -> None:
    envs = gym.make_vec(LATEST["nav"], num_envs=4, num_threads=2)
    first, _ = envs.reset(seed=7)
    actions = random_actions(7, 1, (4, 2))[0]
    observations, rewards, terminations, truncations, infos = envs.step(actions)
    assert observations.shape == (4, NAV_OBS_DIM) and observations.dtype == np.float32
    assert rewards.shape == (4,) and np.issubdtype(rewards.dtype, np.floating)
    assert terminations.shape == (4,) and terminations.dtype == np.bool_
    assert truncations.shape == (4,) and truncations.dtype == np.bool_
    assert infos == {}
    assert not np.shares_memory(first, observations)
    kept = observations.copy()
    envs.step(actions)
    np.testing.assert_array_equal(observations, kept)
    envs.close()


def test_poses_and_goals_shapes_single_and_vector(nav_env: gym.Env) -> None:
    nav_env.reset(seed=0)
    poses = nav_env.unwrapped.poses()
    goals = nav_env.unwrapped.goals()
    assert poses.shape == (1, 3)
    assert goals.shape == (1, 2)
    assert -np.pi < poses[0, 2] <= np.pi
    assert np.all(np.abs(poses[:, :2]) < 1.0) and np.all(np.abs(goals) < 1.0)

    envs = gym.make_vec(LATEST["nav"], num_envs=5)
    envs.reset(seed=0)
    assert envs.poses().shape == (5, 1, 3)
    assert envs.goals().shape == (5, 1, 2)
    envs.close()


def test_sensor_readings_drop_the_world_axis_in_single_env(nav_env: gym.Env) -> None:
    nav_env.reset(seed=0)
    readings = nav_env.unwrapped.sensor_readings()
    assert readings["ir_raw"].shape == (1, 8)
    assert readings["us_cm"].shape == (1, 5)
    assert readings["wheel_speeds"].shape == (1, 2)
    assert readings["encoders"].shape == (1, 2)
    assert readings["gyro_z"].shape == (1,)
    assert np.all((readings["ir_raw"] >= 0) & (readings["ir_raw"] <= 1023))


def test_scene_and_resolved_config_describe_the_arena(nav_env: gym.Env) -> None:
    scene = nav_env.unwrapped.scene()
    assert tuple(scene["arena"]) == pytest.approx((2.0, 2.0))
    assert scene["robot_radius"] == pytest.approx(0.0704)
    assert scene["goal_radius"] == pytest.approx(0.05)
    assert scene["obstacles"] == []
    config = nav_env.unwrapped.config_toml()
    assert "max_steps = 400" in config


def test_keyword_overrides_reach_the_simulator() -> None:
    env = gym.make(LATEST["nav"], max_steps=25, task={"goal_radius": 0.1})
    assert env.unwrapped.max_episode_steps == 25
    assert env.unwrapped.scene()["goal_radius"] == pytest.approx(0.1)
    env.close()


def test_config_by_builtin_name_and_by_file(tmp_path) -> None:
    by_name = gym.make(LATEST["nav"], config="nav")
    assert by_name.unwrapped.max_episode_steps == 400
    by_name.close()

    scenario = tmp_path / "short.toml"
    scenario.write_text("[task]\nmax_steps = 33\n")
    for config in (scenario, str(scenario)):
        env = gym.make(LATEST["nav"], config=config)
        assert env.unwrapped.max_episode_steps == 33
        assert "max_steps = 33" in env.unwrapped.config_toml()
        env.close()


def test_time_limit_wrapper_still_applies_when_asked() -> None:
    env = gym.make(LATEST["nav"], max_episode_steps=5)
    env.reset(seed=0)
    for step in range(1, 6):
        _, _, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
        assert not terminated
        assert truncated == (step == 5)
    env.close()


def test_unknown_render_mode_is_a_config_error() -> None:
    assert NavEnv.metadata["render_modes"] == ["rgb_array", "human"]
    with pytest.raises(ConfigError, match="render_mode"):
        NavEnv(render_mode="ansi")


def test_unicycle_action_type_drives_forward_along_heading() -> None:
    env = gym.make(
        LATEST["nav"], action_type="unicycle", version=0
    )  # wheels at the command at once
    env.reset(seed=2)
    start = env.unwrapped.poses()[0].copy()
    for _ in range(5):
        env.step(np.array([0.5, 0.0], np.float32))
    end = env.unwrapped.poses()[0]
    displacement = end[:2] - start[:2]
    heading = np.array([np.cos(start[2]), np.sin(start[2])])
    assert displacement @ heading > 0.05  # about 5 * 0.05 s * 0.4 m/s = 0.1 m forward
    assert abs(end[2] - start[2]) < 1e-3
    env.close()


def test_close_is_idempotent(nav_env: gym.Env) -> None:
    nav_env.close()
    nav_env.close()
    envs = gym.make_vec(LATEST["nav"], num_envs=2)
    envs.close()
    envs.close()


def test_gymnasium_episode_statistics_wrappers_work_on_top():
    """Our stats live under "episode_stats", so Gymnasium's wrappers can add "episode"."""
    from gymnasium.wrappers import RecordEpisodeStatistics
    from gymnasium.wrappers.vector import RecordEpisodeStatistics as VectorRecordEpisodeStatistics

    envs = VectorRecordEpisodeStatistics(gym.make_vec(LATEST["nav"], num_envs=3, max_steps=5))
    envs.reset(seed=0)
    for _ in range(5):
        _, _, _, truncations, infos = envs.step(np.zeros((3, 2), np.float32))
    assert truncations.all()
    assert (infos["episode"]["l"] == 5).all() and (infos["episode_stats"]["length"] == 5).all()
    env = RecordEpisodeStatistics(gym.make(LATEST["nav"], max_steps=5))
    env.reset(seed=0)
    for _ in range(5):
        _, _, _, truncated, info = env.step(np.zeros(2, np.float32))
    assert truncated and info["episode"]["l"] == 5 and info["episode_stats"]["length"] == 5


def test_column_major_actions_are_read_in_the_right_order() -> None:
    """rust-numpy hands out Fortran-ordered buffers as slices too; the core must not misread."""
    results = []
    for order in ("C", "F"):
        batch = _core.Batch("nav", 3, num_threads=1, version=0)  # wheels at the command at once
        batch.reset(0)
        actions = np.zeros((3, 2), np.float32, order=order)
        actions[:, 0] = 1.0
        batch.step(actions)
        results.append(batch.sensor_readings()["wheel_speeds"])
    np.testing.assert_array_equal(results[0], results[1])
    np.testing.assert_allclose(results[0][:, 0], [[0.813, 0.0]] * 3)


def test_real_robot_speed_units_round_trip() -> None:
    assert khepera_gym.speed_to_units(0.813) == 1199  # about 1200 units: the manual's maximum
    assert khepera_gym.units_to_speed(1200) == pytest.approx(0.8138, abs=1e-4)
    assert round(_core.MAX_WHEEL_SPEED, 4) == 0.813
    assert round(_core.AXLE_LENGTH, 4) == 0.1054
    with pytest.raises(ValueError, match="finite"):
        khepera_gym.speed_to_units(float("nan"))


@pytest.mark.parametrize(
    ("keywords", "suggestion"),
    [
        ({"goal_radios": 0.1}, "did you mean `goal_radius`?"),
        ({"max_stesp": 3}, "did you mean `max_steps`?"),
        ({"task": {"goal_radios": 0.1}}, "did you mean `goal_radius`?"),
        ({"sensors": {"ir_rnage": 0.3}}, "did you mean `ir_range`?"),
    ],
)
def test_a_mistyped_keyword_is_a_config_error_naming_the_nearest_key(
    keywords: dict, suggestion: str
) -> None:
    with pytest.raises(ConfigError, match="unknown key") as caught:
        gym.make(LATEST["nav"], **keywords)
    assert suggestion in str(caught.value)


def test_a_keyword_far_from_every_key_gets_no_suggestion() -> None:
    with pytest.raises(ConfigError, match="unknown key") as caught:
        gym.make(LATEST["nav"], zzzzzzzz=1)
    assert "did you mean" not in str(caught.value)


@pytest.mark.parametrize("seed", [-1, 2**64, 1.5, np.int64(3), "7"])
def test_a_bad_seed_raises_our_config_error_in_the_single_and_vector_env(seed: object) -> None:
    with pytest.raises(ConfigError, match="seed"):
        gym.make(LATEST["nav"]).reset(seed=seed)
    if not isinstance(seed, np.integer):  # a vector env takes NumPy ints, as Gymnasium's does
        with pytest.raises(ConfigError, match="seed"):
            gym.make_vec(LATEST["nav"], num_envs=2).reset(seed=seed)
