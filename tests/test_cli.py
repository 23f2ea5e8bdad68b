"""The ``khepera-gym`` command as a new user meets it: every subcommand checks its arguments, its
output's format and folder before simulating (a mistake costs no simulation), creates its
output folder, shows progress on long work, and ends a user error with one line and a non-zero
status, never a traceback; an unknown env id gets the nearest khepera_gym id suggested."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import pytest

from khepera_gym import cli, registry
from khepera_gym.analysis import record
from khepera_gym.analysis.compare import run as compare_run
from khepera_gym.registration import registered_ids

#: A path whose folder cannot be created (/proc takes no new entries, even for root).
UNWRITABLE = "/proc/khepera-gym-test/out"


@pytest.fixture
def no_simulation() -> Iterator[None]:
    """Fails a test that steps a world: the arguments must be refused before that."""

    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("simulated before the arguments were checked")

    with (
        mock.patch.object(record, "run_episodes", refuse),
        mock.patch.object(compare_run, "run_episodes", refuse),
    ):
        yield


def _user_error(argv: list[str]) -> str:
    """The one-line message ``khepera-gym argv`` exits with (a non-zero status)."""
    with pytest.raises(SystemExit) as caught:
        cli.main(argv)
    message = caught.value.code
    assert isinstance(message, str), f"exit status {message!r}, expected a message"
    assert "\n" not in message and "Traceback" not in message
    assert message.startswith(f"khepera-gym {argv[0]}"), message
    return message


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--env", "KheperaIV-Nv"], "did you mean 'KheperaIV-Nav'?"),
        (["--env", "kheperaiv-avoid-v9"], "did you mean"),
        (["--env", "Hopper"], "unknown environment 'Hopper'"),
        (["--out", "run.avi"], "use .gif or .mp4"),
        (["--out", "run"], "no suffix"),
        (["--out", f"{UNWRITABLE}/run.gif"], "cannot create the folder"),
        (["--policy", "nosuch"], "unknown policy 'nosuch'"),
        (["--env", "multinv"], "did you mean 'multinav'?"),
        (["--env", "multinav", "--policy", "kanayama"], "does not act on 'multinav'"),
        (["--env", "platoon_v3", "--size", "5", "5"], "frame_size width must be an int"),
        (["--size", "5", "5"], "frame_size width must be an int in 16..=4096, got 5"),
        (["--fps", "0"], "--fps must be >= 1"),
        (["--seed", "-1"], "--seed must be in [0, 2**64)"),
        (["--steps", "0"], "--steps must be >= 1"),
        (["--zoom", "0.5"], "--zoom must be >= 1"),
        (["--config", "no_such_scene"], "no_such_scene"),
    ],
)
def test_render_refuses_bad_arguments_in_one_line_before_simulating(
    argv: list[str], expected: str, tmp_path: Path, no_simulation: None
) -> None:
    argv = ["render", "--no-progress", *argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path / "run.gif")]
    message = _user_error(argv)
    assert expected in message, message
    assert "Hopper" not in message.replace("'Hopper'", "")  # no suggestion from Gymnasium's ids


def test_render_creates_the_output_folder_and_shows_progress(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new" / "folder" / "run.gif"
    assert cli.main(["render", "--steps", "3", "--out", str(out)]) == 0
    assert out.is_file() and out.stat().st_size > 0
    captured = capsys.readouterr()
    assert "wrote 4 frames" in captured.out
    assert "render KheperaIV-Nav" in captured.err and "step" in captured.err  # tqdm's bar


#: The tasks without a Gymnasium id (PettingZoo only), from the registries.
AGENTS_ONLY = [t for t in registry.task_names() if t not in registered_ids()]


@pytest.mark.parametrize("task", AGENTS_ONLY)
def test_render_plays_a_multi_agent_task_with_every_robot_acting(
    task: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # A task without a Gymnasium id: its PettingZoo module's world, each robot driven by the
    # policy on its own observation.
    out = tmp_path / f"{task}.gif"
    argv = ["render", "--env", task, "--policy", "random", "--steps", "3"]
    assert cli.main([*argv, "--out", str(out), "--no-progress"]) == 0
    assert out.is_file() and out.stat().st_size > 0
    assert f"wrote 4 frames of {task} (random, seed 0)" in capsys.readouterr().out


def test_a_policy_on_every_agent_is_the_baseline_on_each_agents_block() -> None:
    from khepera_gym.baselines import PositionControl
    from khepera_gym.config import make_batch
    from khepera_gym.learning.policies import make_agents_policy

    batch = make_batch("multinav", 3, None, {}, num_threads=1)
    observation = batch.reset(7)
    joint = make_agents_policy("position_control", batch)(observation)
    agents = batch.agents()
    assert joint.shape == (3, 2 * len(agents)) and len(agents) >= 2
    one = PositionControl()
    for index, (_, _, start, stop, _) in enumerate(agents):
        want = one(observation[:, start:stop])
        np.testing.assert_array_equal(joint[:, 2 * index : 2 * index + 2], want)
    # Distinct robots see distinct goals: the agents' actions are not one copy.
    assert not np.array_equal(joint[:, 0:2], joint[:, 2:4])


#: A user's controller in a file of their own: drive straight at half speed.
USER_CONTROLLER = """
import numpy as np

def straight(observations):
    return np.full((len(observations), 2), 0.5, dtype=np.float32)

def wrong_shape(observations):
    return np.zeros(3)
"""


def test_render_records_a_users_own_function(tmp_path: Path) -> None:
    """``--policy file.py:function`` drives the robot with the user's function: driving
    straight, the robot's heading does not change and it moves forward."""
    import gymnasium as gym

    import khepera_gym
    from khepera_gym.analysis.compare import make_policy
    from khepera_gym.registration import latest_ids

    controller = tmp_path / "mine.py"
    controller.write_text(USER_CONTROLLER)
    out = tmp_path / "mine.gif"
    argv = ["render", "--steps", "5", "--no-progress", "--out", str(out)]
    assert cli.main([*argv, "--policy", f"{controller}:straight"]) == 0
    assert out.is_file() and out.stat().st_size > 0
    envs = gym.make_vec(latest_ids()["nav"], num_envs=2, num_threads=1)
    act = make_policy(f"{controller}:straight", envs)
    observations, _ = envs.reset(seed=0)
    np.testing.assert_array_equal(act(observations), np.full((2, 2), 0.5, np.float32))
    with pytest.raises(khepera_gym.errors.ConfigError, match=r"returned actions of shape \(3,\)"):
        make_policy(f"{controller}:wrong_shape", envs)(observations)
    envs.close()
    for spec, message in [
        (f"{controller}:nothing", "has no 'nothing'"),
        (f"{tmp_path / 'none.py'}:f", "no file"),
        ("no_such_module_here:f", "cannot import 'no_such_module_here'"),
    ]:
        assert message in _user_error(["render", "--no-progress", "--policy", spec])


def test_render_zooms_and_sizes_the_frames(tmp_path: Path) -> None:
    from PIL import Image

    out = tmp_path / "zoomed.gif"
    argv = ["render", "--steps", "1", "--no-progress", "--out", str(out)]
    assert cli.main([*argv, "--size", "200", "120", "--zoom", "3", "--center", "0.2", "0"]) == 0
    with Image.open(out) as image:
        assert image.size == (200, 120)


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--env", "KheperaIV-Formaton"], "did you mean 'KheperaIV-Formation'?"),
        (["--task", "nav", "--episodes", "0"], "--episodes must be >= 1"),
        (["--task", "nav", "--seed", "-3"], "--seed must be in [0, 2**64)"),
        (["--task", "nav", "--num-threads", "0"], "--num-threads must be >= 1"),
        (["--task", "nav", "--plot-worlds", "-1"], "--plot-worlds must be >= 0"),
        (["--task", "nav", "--out", UNWRITABLE], "cannot create the folder"),
        (["--task", "consensus", "--out", UNWRITABLE], "cannot create the folder"),
    ],
)
def test_compare_refuses_bad_arguments_in_one_line_before_simulating(
    argv: list[str], expected: str, tmp_path: Path, no_simulation: None
) -> None:
    if "--out" not in argv:
        argv = [*argv, "--out", str(tmp_path)]
    message = _user_error(["compare", "--no-progress", "--episodes", "2", *argv])
    assert expected in message, message


def test_compare_creates_a_nested_output_folder_before_simulating(tmp_path: Path) -> None:
    out = tmp_path / "a" / "b"
    created = []

    def run_policy(*args: Any, **kwargs: Any) -> Any:
        created.append(out.is_dir())
        raise SystemExit("stopped")

    with mock.patch.object(compare_run, "run_policy", run_policy), pytest.raises(SystemExit):
        cli.main(
            ["compare", "--task", "nav", "--episodes", "2", "--no-progress", "--out", str(out)]
        )
    assert created == [True]


def test_demo_checks_its_folder_first(no_simulation: None) -> None:
    assert "cannot create the folder" in _user_error(["demo", "--out-dir", UNWRITABLE])
    assert "--episodes must be >= 1" in _user_error(["demo", "--episodes", "0"])


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--env", "KheperaIV-Nv"], "did you mean 'KheperaIV-Nav'?"),
        (["--env", "KheperaIV-Nav", "--timesteps", "0"], "--timesteps must be >= 1"),
        (["--env", "KheperaIV-Nav", "--n-envs", "0"], "--n-envs must be >= 1"),
        (["--env", "KheperaIV-Nav", "--seed", "-1"], "--seed must be in [0, 2**64)"),
        (["--env", "KheperaIV-Nav", "--eval-episodes", "0"], "--eval-episodes must be >= 1"),
        (["--env", "KheperaIV-Nav", "--hyperparams", "missing.toml"], "no such file"),
        (["--env", "KheperaIV-Nav", "--out", UNWRITABLE], "cannot create the folder"),
    ],
)
def test_train_refuses_bad_arguments_in_one_line_before_training(
    argv: list[str], expected: str
) -> None:
    pytest.importorskip("stable_baselines3")
    with mock.patch("khepera_gym.learning.train.train", side_effect=AssertionError("trained")):
        message = _user_error(["train", *argv])
    assert expected in message, message


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--num-envs", "0"], "--num-envs must be >= 1"),
        (["--threads", "1", "0"], "--threads must be >= 1"),
        (["--duration", "0"], "--duration must be > 0"),
        (["--json", "rows.txt"], "use .json"),
        (["--json", f"{UNWRITABLE}/rows.json"], "cannot create the folder"),
    ],
)
def test_bench_refuses_bad_arguments_in_one_line_before_measuring(
    argv: list[str], expected: str
) -> None:
    with mock.patch("khepera_gym.analysis.throughput.run", side_effect=AssertionError("measured")):
        message = _user_error(["bench", *argv])
    assert expected in message, message


def test_list_and_export_errors_are_one_line(tmp_path: Path) -> None:
    assert "unknown topic 'foo'" in _user_error(["list", "foo"])
    message = _user_error(["export", str(tmp_path / "missing.zip"), "--no-check"])
    assert "missing.zip" in message, message


def _guide_controller() -> str:
    """The single-observation controller of docs/getting-started.md, as the guide writes it."""
    page = (Path(__file__).resolve().parents[1] / "docs" / "getting-started.md").read_text()
    block = next(b for b in page.split("```python\n")[1:] if "def my_controller(obs)" in b)
    code = block.split("```")[0]
    return code[code.index("import numpy") : code.index("env = gym.make")]


def test_the_guides_single_observation_controller_is_a_policy_of_render_and_compare(
    tmp_path: Path,
) -> None:
    # docs/getting-started.md: "the same function" given to render and compare as
    # file.py:function. It takes one observation (18,) and returns one action (2,).
    import gymnasium as gym

    from khepera_gym.analysis.compare import make_policy
    from khepera_gym.registration import latest_ids

    controller = tmp_path / "mine.py"
    controller.write_text(_guide_controller())
    out = tmp_path / "mine.gif"
    argv = ["render", "--steps", "5", "--no-progress", "--out", str(out)]
    assert cli.main([*argv, "--policy", f"{controller}:my_controller"]) == 0
    assert out.stat().st_size > 0
    namespace: dict[str, object] = {}
    exec(_guide_controller(), namespace)
    one = namespace["my_controller"]
    envs = gym.make_vec(latest_ids()["nav"], num_envs=3, num_threads=1)
    observations, _ = envs.reset(seed=0)
    act = make_policy(f"{controller}:my_controller", envs)
    # Each row gets what the function gives that observation on its own, on every call.
    for _ in range(2):
        expected = np.stack([one(row) for row in observations])  # type: ignore[operator]
        np.testing.assert_array_equal(act(observations), expected)
        observations = envs.step(expected)[0]
    envs.close()


def test_a_function_that_takes_neither_batches_nor_observations_is_named(tmp_path: Path) -> None:
    import gymnasium as gym

    import khepera_gym.errors
    from khepera_gym.analysis.compare import make_policy
    from khepera_gym.registration import latest_ids

    controller = tmp_path / "bad.py"
    controller.write_text("def bad(obs):\n    return obs[100]\n")
    envs = gym.make_vec(latest_ids()["nav"], num_envs=2, num_threads=1)
    observations, _ = envs.reset(seed=0)
    with pytest.raises(
        khepera_gym.errors.ConfigError, match=r"takes neither a batch.*IndexError.*nor one"
    ):
        make_policy(f"{controller}:bad", envs)(observations)
    envs.close()


def test_train_refuses_worlds_that_break_the_recipes_minibatches(tmp_path: Path) -> None:
    # Issue 53, item 6: --n-envs 16 on a recipe of 256 worlds x 32 steps in minibatches of
    # 1,024 made 512-step rollouts that SB3 cut into a truncated minibatch, with a warning.
    pytest.importorskip("stable_baselines3")
    from khepera_gym.learning.recipes import load_hyperparams
    from khepera_gym.registration import latest_ids

    env_id = latest_ids()["nav"]
    table = load_hyperparams("ppo", env_id)
    worlds = next(n for n in range(1, 4096) if n * table["n_steps"] % table["batch_size"] and n > 8)
    out = tmp_path / "run"
    message = _user_error(["train", "--env", env_id, "--n-envs", str(worlds), "--out", str(out)])
    assert f"batch_size {table['batch_size']} does not divide" in message, message
    assert f"the table's {table['n_envs']} worlds" in message and "--hp n_steps=" in message
    assert not (out / "run.json").exists()


def test_a_controller_that_raises_is_named_in_one_line(tmp_path: Path) -> None:
    controller = tmp_path / "broken.py"
    controller.write_text("def drive(obs):\n    raise RuntimeError('the motors are off')\n")
    out = tmp_path / "broken.gif"
    argv = ["render", "--steps", "3", "--no-progress", "--out", str(out)]
    message = _user_error([*argv, "--policy", f"{controller}:drive"])
    assert "drive" in message and "RuntimeError" in message, message
    assert "the motors are off" in message, message
