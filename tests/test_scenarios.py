"""Scenario files: every built-in scene loads and runs, files and overrides merge, bad files fail.

Malformed files are written to ``tmp_path`` and passed by path, as users do; the error must name
the file and the key.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym import _core
from khepera_gym.analysis.plots import plot_trajectories
from khepera_gym.config import builtin_config_names
from khepera_gym.envs import avoid_heuristic
from khepera_gym.errors import ConfigError
from khepera_gym.pettingzoo import multinav_v1

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: The paper's Fig. 6 scene, as configs/paper_fig6.toml gives it.
FIG6 = tomllib.loads(_core.default_config("paper_fig6"))


def test_builtin_scenarios_are_listed() -> None:
    names = set(builtin_config_names())
    assert {"nav", "avoid", "formation", "multinav", "paper_fig6", "paper_fig7"} <= names


@pytest.mark.parametrize(
    ("env_id", "config"),
    [
        (LATEST["nav"], None),
        (LATEST["nav"], "nav"),
        (LATEST["avoid"], None),
        (LATEST["avoid"], "avoid"),
        (LATEST["formation"], None),
        (LATEST["formation"], "formation"),
        (LATEST["avoid"], "paper_fig6"),
        (LATEST["nav"], "paper_fig6"),
        (LATEST["formation"], "paper_fig7"),
    ],
)
def test_builtin_scenario_loads_and_steps_100_steps(env_id: str, config: str | None) -> None:
    env = gym.make(env_id, config=config)
    observation, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(100):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        observation, reward, terminated, truncated, _ = env.step(action)
        assert observation in env.observation_space and np.isfinite(reward)
        if terminated or truncated:
            observation, _ = env.reset()
    env.close()


def test_multinav_default_scenario_loads_and_steps_100_steps() -> None:
    env = multinav_v1.parallel_env()
    env.reset(seed=0)
    for _ in range(100):
        if not env.agents:
            env.reset()
        actions = {agent: env.action_space(agent).sample() for agent in env.agents}
        _, rewards, *_ = env.step(actions)
        assert all(np.isfinite(reward) for reward in rewards.values())
    env.close()


def test_task_defaults_by_name_equal_no_config() -> None:
    for env_id, name in ((LATEST["avoid"], "avoid"), (LATEST["formation"], "formation")):
        by_name = gym.make(env_id, config=name)
        default = gym.make(env_id)
        assert by_name.unwrapped.config_toml() == default.unwrapped.config_toml()
        np.testing.assert_array_equal(by_name.reset(seed=4)[0], default.reset(seed=4)[0])
        by_name.close()
        default.close()


@pytest.mark.parametrize("task", [name for name, *_ in _core.tasks()])
def test_the_config_files_list_each_tasks_defaults(task: str) -> None:
    """configs/<task>.toml is what the docs point users to for every key and its default: it
    must be the scenario the core builds, comments included."""
    path = Path(__file__).resolve().parent.parent / "configs" / f"{task}.toml"
    assert path.read_text(encoding="utf-8") == _core.default_config(task), (
        f"{path.name} is stale: `make configs` writes it from the core"
    )


def test_builtin_scene_by_name_by_path_and_with_overrides(tmp_path: Path) -> None:
    fig6_file = tmp_path / "fig6.toml"
    fig6_file.write_text(_core.default_config("paper_fig6"))
    by_name = gym.make(LATEST["avoid"], config="paper_fig6")
    by_path = gym.make(LATEST["avoid"], config=fig6_file)
    assert by_name.unwrapped.config_toml() == by_path.unwrapped.config_toml()
    np.testing.assert_array_equal(by_name.reset(seed=1)[0], by_path.reset(seed=1)[0])
    assert by_name.unwrapped.max_episode_steps == FIG6["task"]["max_steps"]

    overridden = gym.make(LATEST["avoid"], config="paper_fig6", max_steps=123, goal_radius=0.1)
    overridden.reset(seed=1)
    assert overridden.unwrapped.max_episode_steps == 123
    assert overridden.unwrapped.scene()["goal_radius"] == pytest.approx(0.1)
    # The file's keys that were not overridden stay: fixed start, goal and obstacles.
    np.testing.assert_allclose(overridden.unwrapped.poses()[0], FIG6["spawn"]["start"], atol=1e-6)
    np.testing.assert_allclose(overridden.unwrapped.goals()[0], FIG6["spawn"]["goal"], atol=1e-6)
    assert len(overridden.unwrapped.scene()["obstacles"]) == 2
    for env in (by_name, by_path, overridden):
        env.close()


def test_paper_fig6_has_the_wall_the_obstacle_the_start_and_the_goal() -> None:
    env = gym.make(LATEST["avoid"], config="paper_fig6")
    for seed in (0, 1):
        env.reset(seed=seed)
        scene = env.unwrapped.scene()
        assert len(scene["obstacles"]) == 2
        for obstacle, spec in zip(scene["obstacles"], FIG6["obstacles"]["fixed"], strict=True):
            assert obstacle["kind"] == spec["kind"] == "box"
            np.testing.assert_allclose(obstacle["center"], spec["center"], atol=1e-6)
            np.testing.assert_allclose(obstacle["half_extents"], spec["half_extents"], atol=1e-6)
        wall, _ = scene["obstacles"]
        assert wall["half_extents"][1] > 5 * wall["half_extents"][0]  # long and thin
        np.testing.assert_allclose(env.unwrapped.poses()[0], FIG6["spawn"]["start"], atol=1e-6)
        np.testing.assert_allclose(env.unwrapped.goals()[0], FIG6["spawn"]["goal"], atol=1e-6)
    env.close()


def test_paper_fig6_plot_is_rendered(tmp_path: Path) -> None:
    env = gym.make(LATEST["avoid"], config="paper_fig6", version=0)  # the paper's Fig. 6 dynamics
    observation, _ = env.reset(seed=0)
    path = [env.unwrapped.poses()[0]]
    while True:
        observation, _, terminated, truncated, info = env.step(avoid_heuristic(observation))
        path.append(env.unwrapped.poses()[0])
        if terminated or truncated:
            break
    assert info["is_success"]  # around the wall and past the obstacle
    figure = plot_trajectories(
        [np.array(path)], env.unwrapped.scene(), goals=[env.unwrapped.goals()[0]]
    )
    output = tmp_path / "fig6.png"
    figure.savefig(output)
    assert output.is_file() and output.stat().st_size > 0
    env.close()


# --- malformed scenario files ---------------------------------------------------------------

MALFORMED = {
    "unknown_key": ("[obstacles]\ncount = 3\nradiuss = 0.1\n", r"obstacles\.radiuss"),
    "wrong_type": ('[obstacles]\ncount = "ten"\n', r"obstacles\.count"),
    "negative_radius": (
        '[obstacles]\nfixed = [{kind = "circle", center = [0.3, 0.0], radius = -0.1}]\n',
        r"obstacles\.fixed\[0\]",
    ),
    "negative_half_extent": (
        '[obstacles]\nfixed = [{kind = "circle", center = [0.3, 0.3], radius = 0.1},\n'
        '  {kind = "box", center = [0.0, 0.0], half_extents = [-0.1, 0.1], angle = 0.0}]\n',
        r"obstacles\.fixed\[1\]",
    ),
    "outside_arena": (
        '[obstacles]\nfixed = [{kind = "circle", center = [1.5, 0.0], radius = 0.1}]\n',
        r"obstacles\.fixed\[0\]",
    ),
    "cannot_fit": (
        '[obstacles]\ncount = 60\nkinds = ["circle"]\ncircle_radius = [0.2, 0.3]\n',
        r"obstacles\.count",
    ),
    "min_gap_too_small": ("[obstacles]\nmin_gap = 0.05\n", r"obstacles\.min_gap"),
    "negative_arena": ("[arena]\nwidth = -2.0\n", r"arena\.width"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_avoid_file_names_the_file_and_the_key(tmp_path: Path, case: str) -> None:
    text, key = MALFORMED[case]
    scenario = tmp_path / f"{case}.toml"
    scenario.write_text(text)
    with pytest.raises(ConfigError, match=key) as raised:
        gym.make(LATEST["avoid"], config=scenario)
    assert f"{case}.toml" in str(raised.value)
    with pytest.raises(ConfigError, match=key):
        gym.make_vec(LATEST["avoid"], num_envs=2, config=str(scenario))


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('[formation]\nshape = "blob"\n', r"formation\.shape"),
        ("[formation]\nn_followers = 0\n", r"formation\.n_followers"),
        ("[formation]\nspacing = 0.1\n", r"formation\.spacing"),
        ('[formation]\nshape = "custom"\noffsets = []\n', r"formation\.offsets"),
        ('[formation]\nleader = "nobody"\n', r"formation\.leader"),
        ("[formation]\ncolour = 1\n", r"formation\.colour"),
    ],
)
def test_malformed_formation_file_names_the_file_and_the_key(
    tmp_path: Path, text: str, key: str
) -> None:
    scenario = tmp_path / "team.toml"
    scenario.write_text(text)
    with pytest.raises(ConfigError, match=key) as raised:
        gym.make(LATEST["formation"], config=scenario)
    assert "team.toml" in str(raised.value)


def test_formation_table_is_an_error_outside_the_formation_task(tmp_path: Path) -> None:
    scenario = tmp_path / "nav_team.toml"
    scenario.write_text("[formation]\nn_followers = 2\n")
    with pytest.raises(ConfigError, match="formation") as raised:
        gym.make(LATEST["avoid"], config=scenario)
    assert "nav_team.toml" in str(raised.value)
    with pytest.raises(ConfigError, match="formation"):
        gym.make(LATEST["avoid"], config="paper_fig7")


def test_bad_keyword_overrides_on_top_of_a_file_name_the_key() -> None:
    with pytest.raises(ConfigError, match=r"obstacles\.count|count"):
        gym.make(LATEST["avoid"], config="paper_fig6", count=-1)
    with pytest.raises(ConfigError, match="n_followerz"):
        gym.make(LATEST["formation"], config="paper_fig7", n_followerz=3)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[task]\nmax_steps = 10\ngoal_radus = 0.1\n",
            r"task\.goal_radus: unknown key \(line 3\); did you mean `goal_radius`\?",
        ),
        (
            "# two letters swapped\n\n[taks]\ngoal_radius = 0.1\n",
            r"taks: unknown key \(line 3\); did you mean `task`\?",
        ),
    ],
)
def test_a_misspelt_key_in_a_file_gets_its_line_and_a_suggestion(
    text: str, message: str, tmp_path: Path
) -> None:
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"mine\.toml: {message}"):
        gym.make(LATEST["nav"], config=path)
