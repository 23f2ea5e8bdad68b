"""The learning benchmark's wiring (``khepera-gym benchmark``), on tiny budgets: training runs are
benchmarks, not tests. Checked here: the shipped suite covers every task and is valid, a wrong
suite or argument is an error naming the valid choices, the criterion is judged against the
baselines' held-out means, a run writes its results file with provenance and the table, an
interrupted benchmark resumes without training again, and results of other code are refused.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shlex
import warnings
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip(
    "stable_baselines3", reason="needs the sb3 extra: pip install 'khepera-gym[sb3]'"
)

from khepera_gym import _core, cli
from khepera_gym.config import parse_key_values
from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark import command, learners, load_suite
from khepera_gym.learning.benchmark.command import add_arguments, reproduce
from khepera_gym.learning.benchmark.jobs import gym_id
from khepera_gym.learning.benchmark.runner import FORMAT, judge, means
from khepera_gym.learning.benchmark.suite import Condition
from khepera_gym.learning.benchmark.tables import load_records, markdown, task_rows
from khepera_gym.learning.sb3.policy import frame_stack_of

#: The smallest benchmark that runs every step: one seed, a few updates, a few episodes.
TINY = [
    "--seeds",
    "1",
    "--timesteps",
    "2048",
    "--episodes",
    "6",
    "--eval-episodes",
    "4",
    "--no-progress",
    "--hp",
    "n_envs=8",
    "--hp",
    "n_steps=128",
    "--hp",
    "frame_stack=2",
]


def _run(argv: list[str]) -> None:
    assert cli.main(["benchmark", *argv]) == 0


def test_the_shipped_suite_has_a_valid_entry_for_every_task() -> None:
    suite = load_suite()
    assert list(suite) == [name for name, _, _ in _core.tasks()]
    for entry in suite.values():
        assert entry.criterion and entry.learners and entry.why, entry.task
        for name in entry.learners:
            # Every learner of the suite applies to its task and has a recipe for it.
            learner = learners.learner(name)
            version = _core.task_versions(entry.task)[-1]
            learner.env_name(entry.task, version)
            if name != "mappo" and name != "ippo":
                assert learner.recipe(entry.task, version, {})["n_timesteps"] > 0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[walk]\nlearners = ['ppo']\ncriterion = [{metric = 'success', at_least = 0.9}]",
            r"\[walk\] is not a task of the core",
        ),
        (
            "[nav]\nlearners = ['ppo0']\ncriterion = [{metric = 'success', at_least = 0.9}]",
            "unknown learner 'ppo0'; did you mean 'ppo'",
        ),
        (
            "[nav]\nlearners = ['ppo']\ncriterion = [{metric = 'sucess', at_least = 0.9}]",
            "nav has no statistic 'sucess'; did you mean 'success'",
        ),
        (
            "[track]\nlearners = ['ppo']\nbaselines = ['kanayama']\n"
            "criterion = [{metric = 'track_error_rms', at_most = 'samson'}]",
            "'samson' is not a baseline of the entry",
        ),
        (
            "[nav]\nlearners = ['ppo']\ncriterion = [{metric = 'success'}]",
            "exactly one of at_least and at_most",
        ),
        (
            "[nav]\nlearners = ['ppo']\ncriterion = [{metric = 'success', at_least = nan}]",
            "finite number",
        ),
        (
            "[nav]\nlearners = ['ppo']\nbaselines = ['vhf']\n"
            "criterion = [{metric = 'success', at_least = 0.9}]",
            "unknown baseline 'vhf'; did you mean 'vfh'",
        ),
        ("[nav]\nlearner = ['ppo']", "unknown key 'learner'; did you mean 'learners'"),
        (
            "[nav]\nlearners = ['ppo']\ncriterion = [{metric = 'success', at_least = 0.9}]\n"
            "tried = ['a longer run']",
            "tried must be a string",
        ),
    ],
)
def test_a_wrong_suite_is_an_error_naming_the_choices(
    text: str, message: str, tmp_path: Path
) -> None:
    path = tmp_path / "suite.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_suite(path)


def test_a_condition_holds_against_a_number_or_a_baselines_held_out_mean() -> None:
    at_least = Condition("success", "at_least", reference="vfh")
    at_most = Condition("track_error_rms", "at_most", value=0.02)
    baselines = {"vfh": {"success": 0.86}}
    assert at_least.threshold(baselines) == pytest.approx(0.86)
    assert at_least.holds(0.9, 0.86) and not at_least.holds(0.85, 0.86)
    assert at_most.holds(0.01, 0.02) and not at_most.holds(0.03, 0.02)
    assert not at_least.holds(math.nan, 0.0)  # no data is not a success
    assert at_least.describe() == "success ≥ vfh" and at_most.describe() == "track_error_rms ≤ 0.02"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--tasks", "walk"], "unknown task 'walk'"),
        (["--tasks", "nav", "--learners", "dqn"], "unknown learner 'dqn'; known: ppo"),
        (["--tasks", "nav", "--learners", "mappo"], "learner 'mappo' is in no chosen task"),
        (["--tasks", "nav", "--device", "cuda"], "no CUDA device"),
        (["--tasks", "nav", "--device", "abacus"], "not a torch device"),
        (["--tasks", "nav", "--version", "9"], "nav has no behaviour version 9"),
        (["--tasks", "nav", "--episodes", "0"], "--episodes must be >= 1"),
        (["--tasks", "nva"], "unknown task 'nva'; did you mean 'nav'? known: nav, "),
        (["--tasks", "nav", "--learners", "ppo0"], "unknown learner 'ppo0'; did you mean 'ppo'?"),
        (["--tasks", "nav", "--learners", "PPO"], "unknown learner 'PPO'; did you mean 'ppo'?"),
        (
            ["--tasks", "nav", "--hp", "n_step=64"],
            "--hp n_step: learner 'ppo' (PPO) has no hyperparameter 'n_step'; did you mean "
            "'n_steps'? known: n_envs, n_timesteps, ",
        ),
        (
            ["--tasks", "formation", "--learners", "mappo", "--hp", "minibatch=256"],
            "--hp minibatch: learner 'mappo' has no recipe key 'minibatch'; did you mean "
            "'minibatch_size'?",
        ),
    ],
)
def test_bad_arguments_are_refused_before_anything_runs(
    argv: list[str], message: str, tmp_path: Path
) -> None:
    if "cuda" in argv:
        import torch

        if torch.cuda.is_available():
            pytest.skip("this machine has CUDA")
    with pytest.raises(SystemExit) as caught:
        cli.main(["benchmark", "--out", str(tmp_path), *argv])
    assert message in str(caught.value)
    assert not (tmp_path / "runs").exists()
    # One line, as every command's errors, and before the baselines ran too.
    assert "\n" not in str(caught.value) and not (tmp_path / "baselines").exists()


def _no_work(
    monkeypatch: pytest.MonkeyPatch, value: float | None = 0.5
) -> list[tuple[str, str, int]]:
    """Replaces the baselines and the runs of the command with records made up on the spot
    (each criterion statistic's held-out mean ``value``); returns the (task, learner, seed) of
    every run asked for."""
    asked: list[tuple[str, str, int]] = []

    def baselines(entry: Any, version: int, settings: Any, restart: bool) -> dict[str, Any]:
        return {"summaries": {}}

    def run(entry: Any, learner: Any, version: int, seed: int, *args: Any) -> dict[str, Any]:
        asked.append((entry.task, learner.name, seed))
        final = {c.metric: {"value": value} for c in entry.criterion}
        return {"final": final, "reached": None, "solved": False, "train_seconds": 1.0}

    monkeypatch.setattr(command, "run_baselines", baselines)
    monkeypatch.setattr(command, "run_one", run)
    return asked


def test_task_names_are_taken_in_any_case(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    asked = _no_work(monkeypatch)
    _run(
        [
            "--tasks",
            "Nav",
            "NAV",
            "--learners",
            "ppo",
            "--seeds",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
        ]
    )
    assert asked == [("nav", "ppo", 0)]


def test_ctrl_c_stops_with_one_line_saying_the_same_command_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    asked = _no_work(monkeypatch)
    run = command.run_one

    def interrupted_at_the_second(*args: Any) -> dict[str, Any]:
        if asked:
            raise KeyboardInterrupt
        return run(*args)

    monkeypatch.setattr(command, "run_one", interrupted_at_the_second)
    argv = [
        "benchmark",
        "--tasks",
        "nav",
        "--learners",
        "ppo",
        "--seeds",
        "3",
        "--out",
        str(tmp_path),
    ]
    # Caught here too, so that a KeyboardInterrupt escaping fails this test, not the session.
    with pytest.raises((SystemExit, KeyboardInterrupt)) as caught:
        cli.main(argv)
    assert isinstance(caught.value, SystemExit), "Ctrl-C escaped as a KeyboardInterrupt"
    assert caught.value.code == command.INTERRUPTED == 130
    errors = capsys.readouterr().err
    # The last line (the progress bar is on: its lines come first), and no traceback.
    last = errors.rstrip("\n").split("\n")[-1]
    assert last == (
        f"khepera-gym benchmark: interrupted with 1 of 3 runs done in {tmp_path}; the same "
        "command resumes (the runs done there are skipped)"
    ), errors
    assert "Traceback" not in errors and "KeyboardInterrupt" not in errors
    # With --no-progress, that line is all of stderr.
    asked.clear()
    with pytest.raises((SystemExit, KeyboardInterrupt)):
        cli.main([*argv, "--no-progress"])
    assert capsys.readouterr().err == last + "\n"
    # A run further on that was done before counts as done.
    asked.clear()
    monkeypatch.setattr(command, "finished", lambda *run: {} if run[3] == 2 else None)
    with pytest.raises((SystemExit, KeyboardInterrupt)):
        cli.main([*argv, "--no-progress"])
    assert "interrupted with 2 of 3 runs done" in capsys.readouterr().err


def test_a_run_whose_held_out_episodes_gave_no_value_prints_no_nan(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _no_work(monkeypatch, value=None)  # how a NaN mean is written (strict JSON)
    _run(["--tasks", "track", "--seeds", "1", "--out", str(tmp_path), "--no-progress"])
    line = next(x for x in capsys.readouterr().out.splitlines() if "track ppo seed 0:" in x)
    assert "track_error_rms none (no held-out episode gave a value)" in line, line
    assert "nan" not in line.lower()


def test_a_misspelt_hp_key_fails_before_the_baselines_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    asked = _no_work(monkeypatch)

    def no_baselines(*args: Any) -> None:
        raise AssertionError("the baselines ran before the --hp keys were checked")

    monkeypatch.setattr(command, "run_baselines", no_baselines)
    argv = ["--tasks", "avoid", "--out", str(tmp_path), "--no-progress"]
    misspelt = {"n_step=64": "n_steps", "gama=0.9": "gamma", "batchsize=8": "batch_size"}
    for hp, near in misspelt.items():
        with pytest.raises(SystemExit, match=f"did you mean '{near}'"):
            cli.main(["benchmark", *argv, "--hp", hp])
    assert not asked


def test_a_learner_that_does_not_fit_the_task_says_why() -> None:
    with pytest.raises(ConfigError, match="'multinav' is a PettingZoo task"):
        learners.learner("ppo").env_name("multinav", 3)
    with pytest.raises(ConfigError, match="'nav' is not one"):
        learners.learner("shared_ppo").env_name("nav", 3)


def test_a_benchmark_writes_its_results_resumes_and_refuses_other_code(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "bench"
    _run(["--tasks", "nav", "--learners", "ppo", "--out", str(out), *TINY])
    captured = capsys.readouterr()
    printed = captured.out
    assert captured.err == ""  # --no-progress: no bar, and SB3 prints nothing of its own
    run_file = out / "runs" / f"nav-v{_core.LATEST_VERSION}_ppo_seed0.json"
    record = json.loads(run_file.read_text())
    assert record["format"] == FORMAT and record["meta"]["commit"] is not None
    assert record["key"]["episodes"] == 6 and record["timesteps"] >= 2048
    assert record["history"] and record["history"][-1]["steps"] == record["timesteps"]
    assert set(record["final"]) >= {"success", "return", "collisions"}
    assert record["final"]["success"]["n"] == 6
    baselines = json.loads((out / "baselines" / f"nav-v{_core.LATEST_VERSION}.json").read_text())
    # The suite's baselines, and the random policy: the 0 of the normalised scores.
    assert set(baselines["summaries"]) == {"position_control", "braitenberg", "vfh", "random"}
    assert baselines["summaries"]["random"]["success"]["n"] == 6
    # The runs in marl-eval's format as well: this run, its evaluations and its final policy's.
    marl = json.loads((out / "marl_eval.json").read_text())
    mine = marl["khepera_gym"][f"nav-v{_core.LATEST_VERSION}"]["ppo"]["seed_0"]
    assert len(mine) == len(record["history"]) + 1
    assert mine["absolute_metrics"]["success"] == [record["final"]["success"]["value"]]
    # The criterion is judged on the held-out means against the baselines.
    assert record["solved"] == judge(load_suite()["nav"], means(record["final"]), baselines)
    assert "| ppo (KheperaIV-Nav-v" in printed and "braitenberg (baseline)" in printed
    assert (
        "reproduce ppo: khepera-gym benchmark --tasks nav --learners ppo --seed-list 0" in printed
    )
    summary = json.loads((out / "benchmark.json").read_text())
    assert summary["tables"][0]["learners"][0]["seeds"] == [0]
    # The printed command is the command that ran: parsed again, it asks for the same work.
    again = _parsed(summary["tables"][0]["learners"][0]["reproduce"])
    ran = _parsed(" ".join(["khepera-gym benchmark", "--tasks nav --learners ppo", *TINY]))
    for option in ("tasks", "timesteps", "episodes", "heldout_seed", "eval_episodes"):
        assert getattr(again, option) == getattr(ran, option), option
    # The same version: the one the run resolved (none given: the latest), now pinned.
    assert again.version == (ran.version or _core.LATEST_VERSION) == _core.LATEST_VERSION
    assert again.seed_list == [0]
    assert parse_key_values(again.hp, "--hp") == parse_key_values(ran.hp, "--hp")
    # The model has its run.json beside it, as `khepera-gym train` leaves one: load_policy
    # (compare, render) stacks its frames and export finds its env.
    # (Its files are named relative to the results folder, which may move to another machine.)
    run = json.loads((out / record["files"]["run"]).read_text())
    assert run["env_id"] == record["key"]["env"] and run["hyperparams"] == record["recipe"]
    assert frame_stack_of(out / record["files"]["model"]) == 2
    # Nothing written carries this machine's paths: the files, the command (--out relative).
    assert record["files"]["model"] == f"models/nav-v{_core.LATEST_VERSION}_ppo_seed0/model.zip"
    for path in [*out.rglob("*.json")]:
        assert str(tmp_path) not in path.read_text(), path
    assert record["meta"]["command"].startswith(
        "khepera-gym benchmark --tasks nav --learners ppo --out bench "
    )

    # Resumed: a finished run is not trained again.
    def no_training(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a finished run was trained again")

    monkeypatch.setattr(learners.SB3Learner, "train", no_training)
    _run(["--tasks", "nav", "--learners", "ppo", "--out", str(out), *TINY])
    assert json.loads(run_file.read_text())["meta"] == record["meta"]
    # ... and it says so, before it starts and on the run's line.
    printed = capsys.readouterr().out
    assert printed.startswith(
        f"resuming in {out}: 1 run done already, not run again: "
        f"nav ppo v{_core.LATEST_VERSION} seed 0\n"
    ), printed
    assert "nav ppo seed 0: " in printed and "(done before: read from its file" in printed

    # A file written by other code is refused, never mixed in.
    record["meta"]["commit"] = {"id": "0" * 40, "dirty": False}
    run_file.write_text(json.dumps(record))
    with pytest.raises(SystemExit, match="comes from commit 000000000000"):
        cli.main(["benchmark", "--tasks", "nav", "--learners", "ppo", "--out", str(out), *TINY])


def _parsed(command: str) -> argparse.Namespace:
    """``command`` (``khepera-gym benchmark ...``) as the CLI parses it."""
    words = shlex.split(command)
    assert words[:2] == ["khepera-gym", "benchmark"], command
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(words[2:])


def _single_agent_task() -> str:
    """The registry's first task with a Gymnasium id: a tiny PPO run, the suite's cheapest."""
    return next(name for name, _, _ in _core.tasks() if gym_id(name, _latest(name)) is not None)


def _latest(task: str) -> int:
    return _core.task_versions(task)[-1]


@pytest.mark.parametrize(
    ("task", "learner"),
    [(entry.task, name) for entry in load_suite().values() for name in entry.learners],
)
def test_the_printed_command_asks_for_the_rows_work_again(task: str, learner: str) -> None:
    # Every task and learner of the suite, on its oldest and its latest version.
    overrides = {"gamma": 0.9, "policy_kwargs": {"net_arch": [8, 8]}, "schedule": "lin_1e-3"}
    for version in dict.fromkeys((_core.task_versions(task)[0], _latest(task))):
        row = {
            "learner": learner,
            "seeds": [3, 1],
            "version": version,
            "settings": {
                "timesteps": 4096,
                "overrides": overrides,
                "eval_episodes": 7,
                "episodes": 9,
                "heldout_seed": 5,
            },
        }
        args = _parsed(reproduce(task, row))
        assert (args.tasks, args.learners, args.seed_list) == ([task], [learner], [3, 1])
        assert (_latest(task) if args.version is None else args.version) == version
        # Pinned on the latest version too: the command must not run a later one some day.
        assert args.version == version
        assert (args.timesteps, args.eval_episodes, args.episodes, args.heldout_seed) == (
            4096,
            7,
            9,
            5,
        )
        assert parse_key_values(args.hp, "--hp") == overrides


def test_runs_of_another_recipe_in_the_folder_get_their_own_row(tmp_path: Path) -> None:
    out = tmp_path / "bench"
    task = _single_agent_task()
    ppo = ["--tasks", task, "--learners", "ppo", "--out", str(out), *TINY]
    _run(ppo)
    _run(
        [
            *ppo,
            "--seed-list",
            "1",
            "--hp",
            "gamma=0.9",
        ]
    )
    baselines, runs = load_records(out)
    rows = task_rows(task, baselines, runs)["learners"]
    # Two recipes, two rows: seed 1's gamma is never averaged with seed 0's.
    assert [row["seeds"] for row in rows] == [[0], [1]]
    assert [row["recipe"]["gamma"] for row in rows][1] == 0.9 != rows[0]["recipe"]["gamma"]
    assert rows[0]["variant"].startswith("recipe ") and rows[0]["variant"] != rows[1]["variant"]
    assert all(
        f"({row['env']}, {row['variant']})"
        in markdown({"task": task, "baselines": [], "learners": [row]})
        for row in rows
    )
    assert parse_key_values(_parsed(reproduce(task, rows[1])).hp, "--hp")["gamma"] == 0.9
    # Other held-out episodes, the same recipe: a row of its own too, labelled by them.
    _run(
        [
            *ppo,
            "--seed-list",
            "2",
            "--episodes",
            "4",
        ]
    )
    rows = task_rows(task, *load_records(out))["learners"]
    assert [row["seeds"] for row in rows] == [[0], [1], [2]]
    recipe_of = [row["variant"].split(", ")[0] for row in rows]
    assert recipe_of[2] == recipe_of[0] != recipe_of[1]
    assert rows[2]["variant"].endswith(", 4 episodes from seed 0")
    assert rows[0]["variant"].endswith(", 6 episodes from seed 0")
    assert _parsed(reproduce(task, rows[2])).episodes == 4


def test_a_shared_policy_trains_on_the_agents_of_a_multi_agent_task(tmp_path: Path) -> None:
    out = tmp_path / "bench"
    tiny = ["--seeds", "1", "--timesteps", "1024", "--episodes", "4", "--eval-episodes", "2"]
    recipe = ["--hp", "n_envs=2", "--hp", "n_steps=64", "--hp", "batch_size=64"]
    _run(
        [
            "--tasks",
            "consensus",
            "--learners",
            "shared_ppo",
            "--out",
            str(out),
            "--no-progress",
            *tiny,
            *recipe,
        ]
    )
    record = json.loads(next((out / "runs").glob("consensus-*_shared_ppo_seed0.json")).read_text())
    assert record["key"]["env"].startswith("consensus_v")
    assert "consensus_error_final" in record["final"]
    # The results page renders the row, and names the suite's other learner of the task as not
    # run rather than leaving its row out; every other task says it has no run.
    from khepera_gym.analysis.docgen.benchmark_results import benchmark_fragment

    page = benchmark_fragment(out)
    consensus = next(p for p in page.split("\n\n") if "--tasks consensus" in p)
    assert "Not run yet: mappo" in consensus, consensus
    # What was tried follows the task's table, before any other task's.
    after = page[page.index("--tasks consensus") :]
    tried = after.index(f"\n\nTried: {load_suite()['consensus'].tried}")
    assert "--tasks " not in after[len("--tasks consensus") : tried].replace(
        "--tasks consensus", ""
    )
    assert "**nav**: no learned run recorded yet. Not run yet: ppo" in page
    # The suite's wall-clock on one machine: the records' training and evaluation times.
    hours = (record["train_seconds"] + record["eval_seconds"]) / 3600
    assert f"The 1 run above took {hours:.1f} h of training and evaluation" in page


def test_a_recurrent_policy_trains_and_plays_the_held_out_episodes_with_its_state(
    tmp_path: Path,
) -> None:
    """recurrent_ppo (sb3-contrib's RecurrentPPO): its memory is the LSTM's state, so it trains
    without a frame stack, is judged on the held-out episodes carrying that state, and the
    model it leaves reloads as a recurrent policy (compare, render and export use that)."""
    from khepera_gym.learning.sb3.policy import RecurrentPolicy, load_policy

    out = tmp_path / "bench"
    tiny = ["--seeds", "1", "--timesteps", "1024", "--episodes", "4", "--eval-episodes", "2"]
    recipe = ["--hp", "n_envs=4", "--hp", "n_steps=64", "--hp", "batch_size=128"]
    argv = ["--tasks", "avoid", "--learners", "recurrent_ppo", "--out", str(out), "--no-progress"]
    _run([*argv, *tiny, *recipe])
    path = next((out / "runs").glob("avoid-*_recurrent_ppo_seed0.json"))
    record = json.loads(path.read_text())
    assert record["timesteps"] >= 1024 and "success" in record["final"]
    assert "frame_stack" not in record["recipe"] or record["recipe"]["frame_stack"] == 1
    model = next((out / "models").rglob("model.zip"))
    assert isinstance(load_policy(model), RecurrentPolicy)
    # A frame stack on top of the LSTM is refused before anything trains.
    with pytest.raises(SystemExit, match="frame_stack"):
        cli.main(["benchmark", *argv, "--restart", *tiny, *recipe, "--hp", "frame_stack=2"])


# torchrl's own deprecation notices inside BenchMARL, and its notice of an iteration where no
# episode ended (a few frames of a long episode), are theirs.
@pytest.mark.filterwarnings("ignore::DeprecationWarning:torchrl")
@pytest.mark.filterwarnings("ignore:No episode terminated this iteration:UserWarning")
def test_mappo_trains_through_benchmarl(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("benchmarl", reason="needs the benchmarl extra")
    import torch
    from benchmarl.experiment import Experiment
    from tensordict import TensorDict

    experiments: list[Any] = []
    build = Experiment.__init__

    def keep(self: Any, *args: Any, **kwargs: Any) -> None:
        build(self, *args, **kwargs)
        experiments.append(self)

    monkeypatch.setattr(Experiment, "__init__", keep)
    out = tmp_path / "bench"
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("always")
        _run(
            [
                "--tasks",
                "formation",
                "--learners",
                "mappo",
                "--out",
                str(out),
                "--seeds",
                "1",
                "--timesteps",
                "1280",
                "--episodes",
                "4",
                "--eval-episodes",
                "2",
                "--no-progress",
                "--hp",
                "frames_per_batch=512",
                "--hp",
                "minibatch_size=256",
                "--hp",
                "n_envs=4",
                "--hp",
                "sigma_min=0.25",
            ]
        )
    # --no-progress: neither BenchMARL's bar nor torchrl's log lines, only the command's lines;
    # nor their warnings that a batch ended no episode or that 1,280 steps are not whole batches.
    noise = ("No episode terminated", "is not exactly divisible")
    assert not [w for w in shown if any(n in str(w.message) for n in noise)], [
        str(w.message) for w in shown
    ]
    captured = capsys.readouterr()
    assert captured.err == "", captured.err
    assert "torchrl" not in captured.out and "mean return" not in captured.out, captured.out
    record = json.loads(next((out / "runs").glob("formation-*_mappo_seed0.json")).read_text())
    assert record["timesteps"] >= 1024 and "formation_error_mean" in record["final"]
    assert (out / record["files"]["policy"]).is_file()
    # The recipe's floor holds under the actor's σ, however far its outputs push it down.
    (experiment,) = experiments
    group = next(iter(experiment.group_map))
    actor = experiment.policy
    for parameter in actor.parameters():
        torch.nn.init.constant_(parameter, -100.0)
    observation = torch.rand(8, 4, experiment.observation_spec[group, "observation"].shape[-1])
    with torch.no_grad():
        scale = actor(TensorDict({group: {"observation": observation}}, batch_size=[8]))[
            group, "scale"
        ]
    assert record["recipe"]["sigma_min"] == 0.25
    assert scale.min().item() == pytest.approx(0.25)


@pytest.mark.filterwarnings("ignore::DeprecationWarning:torchrl")
@pytest.mark.filterwarnings("ignore:No episode terminated this iteration:UserWarning")
def test_mappos_progress_bar_never_shows_nan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Formation's episodes outlast a batch of 128 steps a world: in BenchMARL's own bar, both
    batches read ``mean return = nan``."""
    pytest.importorskip("benchmarl", reason="needs the benchmarl extra")
    import logging

    argv = ["--tasks", "formation", "--learners", "mappo", "--out", str(tmp_path), "--seeds", "1"]
    recipe = ["--hp", "frames_per_batch=512", "--hp", "minibatch_size=512", "--hp", "n_envs=4"]
    # torchrl's log handler keeps the stdout of the test that imported torchrl, closed since.
    torchrl_log = logging.getLogger("torchrl")
    level = torchrl_log.level
    torchrl_log.setLevel(logging.WARNING)
    try:
        _run([*argv, "--timesteps", "1024", "--episodes", "2", "--eval-episodes", "2", *recipe])
    finally:
        torchrl_log.setLevel(level)
    shown = capsys.readouterr().err
    assert "mean return: no episode ended yet" in shown, shown
    assert re.search(r"\bnan\b", shown, re.IGNORECASE) is None, shown


def test_the_progress_bar_says_the_last_known_return_when_no_episode_ended() -> None:
    pytest.importorskip("benchmarl", reason="needs the benchmarl extra")
    from khepera_gym.learning.benchmark.marl import return_description

    assert return_description(-12.5, -12.5) == "mean return = -12.5"
    assert return_description(math.nan, -12.5) == (
        "mean return = -12.5 (no episode ended in the last batch)"
    )
    assert return_description(math.nan, math.nan) == "mean return: no episode ended yet"


@pytest.mark.parametrize("floor", [0.0, 1.0, "high", True])
def test_a_wrong_sigma_floor_is_refused_before_training(floor: Any) -> None:
    pytest.importorskip("benchmarl", reason="needs the benchmarl extra")
    with pytest.raises(ConfigError, match="sigma_min must be"):
        learners.learner("mappo").recipe("formation", _core.LATEST_VERSION, {"sigma_min": floor})


def test_a_command_written_to_results_carries_no_absolute_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from khepera_gym.tooling.provenance import portable_command

    monkeypatch.chdir(tmp_path / "..")
    here = tmp_path.name
    command = (
        f"khepera-gym benchmark --out /home/someone/bench/final --suite {tmp_path}/suite.toml "
        "--hp 'policy_kwargs={net_arch = [8, 8]}' --out=/tmp/elsewhere/x "
        "--policy sb3:/home/someone/bench/final/models/a/model.zip"
    )
    assert portable_command(command, "/home/someone/bench/final") == (
        f"khepera-gym benchmark --out final --suite {here}/suite.toml "
        "--hp 'policy_kwargs={net_arch = [8, 8]}' --out=x "
        "--policy sb3:final/models/a/model.zip"
    )


def _with_absolute_paths(source: Path, target: Path) -> Path:
    """A copy of the results folder ``source`` whose every file's command and model files name
    absolute paths of three machines (as the committed files may)."""
    for path in source.rglob("*.json"):
        record = json.loads(path.read_text())
        if "meta" not in record:  # marl_eval.json: runs in marl-eval's format, no command
            continue
        record["meta"]["command"] = (
            "khepera-gym benchmark --tasks nav --out /work/bench/final --suite "
            "/home/someone/suite.toml --seed-list 0 --hp n_epochs=10"
        )
        if "files" in record:
            record["files"] = {"model": "/tmp/bench/final/models/x/model.zip"}
        copy = target / path.relative_to(source)
        copy.parent.mkdir(parents=True, exist_ok=True)
        copy.write_text(json.dumps(record))
    return target


def test_the_results_page_shows_no_absolute_path(tmp_path: Path) -> None:
    from khepera_gym.analysis.docgen.benchmark_results import (
        BENCHMARK_DIR,
        RECIPE_BEFORE_DIR,
        benchmark_fragment,
        recipe_speed_fragment,
    )

    results = Path(__file__).resolve().parents[1] / "docs" / "results"
    after = _with_absolute_paths(results / BENCHMARK_DIR, tmp_path / "after")
    before = _with_absolute_paths(results / RECIPE_BEFORE_DIR, tmp_path / "before")
    page = benchmark_fragment(after) + recipe_speed_fragment(before, after)
    assert "| ppo (KheperaIV-Nav-v" in page and "--suite suite.toml --hp n_epochs=10" in page
    for machine in ("/work/", "/home/", "/tmp/", str(tmp_path)):
        assert machine not in page, machine
    # The page of the committed files too.
    page = benchmark_fragment(results / BENCHMARK_DIR) + recipe_speed_fragment(
        results / RECIPE_BEFORE_DIR, results / BENCHMARK_DIR
    )
    assert re.search(r"(/work/|/home/|/tmp/|/Users/)", page) is None


def test_the_recipe_speed_table_pairs_each_earlier_run_with_the_shipped_run_of_its_seed(
    tmp_path: Path,
) -> None:
    """The ratio on the results page is earlier training time over shipped training time, seed
    by seed, over the runs both folders hold (a seed the shipped folder lacks is left out)."""
    from khepera_gym.analysis.docgen.benchmark_results import recipe_speed_fragment

    def write(folder: Path, seed: int, seconds: float, success: float) -> None:
        (folder / "runs").mkdir(parents=True, exist_ok=True)
        record = {
            "format": FORMAT,
            "key": {"task": "avoid", "learner": "ppo", "version": 3, "seed": seed},
            "meta": {
                "date": "2026-11-28T20:00:00+00:00",
                "commit": {"id": "0123456789abcdef", "dirty": False},
                "machine": {"cpu": "a CPU", "cpus": 2},
                "command": f"khepera-gym benchmark --tasks avoid --out {folder} --seed-list {seed}"
                " --hp n_epochs=10",
            },
            "train_seconds": seconds,
            "final": {"success": {"value": success}},
        }
        (folder / "runs" / f"avoid-v3_ppo_seed{seed}.json").write_text(json.dumps(record))

    before, after = tmp_path / "before", tmp_path / "after"
    for seed, (slow, fast) in enumerate([(60.0, 10.0), (90.0, 20.0), (50.0, 5.0)]):
        write(before, seed, slow, 0.9)
        if seed < 2:
            write(after, seed, fast, 0.97)
    page = recipe_speed_fragment(before, after)
    # Training seconds earlier and shipped, their ratio, success % earlier and shipped.
    assert "| avoid ppo v3 | 0 | 60 | 10 | 6.0 | 90.0 | 97.0 |" in page
    assert "| avoid ppo v3 | 1 | 90 | 20 | 4.5 | 90.0 | 97.0 |" in page
    assert "| 2 |" not in page
    assert "150 s against 30 s" in page and "(5.0x; median ratio 5.2)" in page
    assert str(tmp_path) not in page and "--hp n_epochs=10 --seed-list S" in page


def test_every_shipped_recipe_says_how_it_was_chosen(tmp_path: Path) -> None:
    # Issue 52: each recipe names the search that chose it, or says it was not searched.
    for task, entry in load_suite().items():
        assert set(entry.searched) == set(entry.learners), task
        for name in entry.learners:
            how = entry.search_of(name)
            assert how.startswith("not searched") or "tune" in how, (task, name, how)
    suite = tmp_path / "suite.toml"
    suite.write_text(
        '[nav]\nlearners = ["ppo"]\nbaselines = ["vfh"]\n'
        'criterion = [{ metric = "success", at_least = 0.9 }]\nsearched = { pppo = "x" }\n'
    )
    with pytest.raises(ConfigError, match=r"searched names 'pppo'.*did you mean 'ppo'"):
        load_suite(suite)
