"""The comparison tool (khepera_gym.analysis.compare, ``khepera-gym compare``) and the rollout
plots."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import sys
import types
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST

from khepera_gym import cli
from khepera_gym.analysis import compare
from khepera_gym.analysis.plots import plot_rollouts, record_rollout
from khepera_gym.baselines import Braitenberg, LeaderFollower, PositionControl
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import DEFAULT_POLICIES


def test_wilson_interval_matches_the_textbook_values() -> None:
    # 8 successes in 10 trials at 95%: the Wilson score interval is (0.4902, 0.9433).
    estimate = compare.wilson_interval(8, 10)
    assert estimate.value == 0.8 and estimate.n == 10
    assert estimate.low == pytest.approx(0.4902, abs=1e-4)
    assert estimate.high == pytest.approx(0.9433, abs=1e-4)
    # All or nothing still gives a non-empty interval: 0/20 -> (0, 0.1611), 20/20 -> (0.8389, 1).
    none, every = compare.wilson_interval(0, 20), compare.wilson_interval(20, 20)
    assert (none.low, every.high) == (0.0, 1.0)
    assert none.high == pytest.approx(0.1611, abs=1e-4)
    assert every.low == pytest.approx(0.8389, abs=1e-4)
    assert math.isnan(compare.wilson_interval(0, 0).value)
    with pytest.raises(ValueError, match="successes"):
        compare.wilson_interval(3, 2)


def test_bootstrap_interval_is_seeded_and_close_to_the_t_interval() -> None:
    rng = np.random.default_rng(7)
    sample = rng.normal(10.0, 2.0, size=400)
    estimate = compare.bootstrap_interval(sample, "mean")
    assert estimate == compare.bootstrap_interval(sample, "mean")  # deterministic
    assert estimate.value == pytest.approx(sample.mean())
    # For 400 normal values the t interval's half width is 1.966 s / sqrt(n).
    half_width = 1.966 * sample.std(ddof=1) / math.sqrt(sample.size)
    assert (estimate.high - estimate.low) / 2 == pytest.approx(half_width, rel=0.1)
    assert estimate.low < sample.mean() < estimate.high
    p95 = compare.bootstrap_interval(sample, "p95")
    assert p95.value == pytest.approx(np.percentile(sample, 95))
    assert p95.low <= p95.value <= p95.high
    constant = compare.bootstrap_interval([2.5, 2.5, 2.5], "mean")
    assert (constant.value, constant.low, constant.high) == (2.5, 2.5, 2.5)
    assert compare.bootstrap_interval([], "mean").n == 0
    assert compare.bootstrap_interval([1.0, float("nan"), 3.0], "mean").value == 2.0
    with pytest.raises(ValueError, match="statistic"):
        compare.bootstrap_interval(sample, "mode")


def test_compare_runs_every_policy_on_the_same_seeded_episodes() -> None:
    result = compare.compare(
        LATEST["avoid"],
        ["braitenberg", "random"],
        episodes=6,
        seed=40,
        record_worlds=2,
        progress=False,
    )
    assert [s.policy for s in result.summaries] == ["braitenberg", "random"]
    for name, episodes in result.results.items():
        assert [e.seed for e in episodes] == list(range(40, 46)), name
        assert all(e.policy == name for e in episodes)
    # The same episode (start, goal, obstacles) for every policy: the recorded worlds agree.
    braitenberg, random = result.rollouts["braitenberg"], result.rollouts["random"]
    for mine, theirs in zip(braitenberg, random, strict=True):
        np.testing.assert_array_equal(mine.poses[0], theirs.poses[0])
        np.testing.assert_array_equal(mine.goals, theirs.goals)
        assert mine.scene == theirs.scene
    # World i of the batch is the single env reset with seed + i, step for step.
    single = record_rollout(LATEST["avoid"], Braitenberg(), seed=41)
    np.testing.assert_array_equal(braitenberg[1].poses, single.poses)
    assert braitenberg[1].stats == single.stats
    # Time to goal is the episode length times dt, for successes only.
    for episode in result.results["braitenberg"]:
        if episode.success:
            assert episode.time_to_goal == pytest.approx(episode.length * 0.05)
        else:
            assert episode.time_to_goal is None
    assert (
        compare.compare(
            LATEST["avoid"], ["braitenberg"], episodes=6, seed=40, progress=False
        ).results["braitenberg"]
        == result.results["braitenberg"]
    )


def test_cli_compare_writes_table_csv_json_and_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["compare", "--env", "KheperaIV-Avoid-v0", "--config", "paper_fig6", "--episodes", "3"]
    argv += ["--policy", "braitenberg", "vfh", "--seed", "5", "--out", str(tmp_path)]
    argv += ["--num-threads", "2", "--no-progress"]
    assert cli.main(argv) == 0
    output = capsys.readouterr().out
    assert 'KheperaIV-Avoid-v0, config="paper_fig6": 3 episodes per policy, seeds 5..7' in output
    for column in ("success %", "time to goal s", "p95 time s", "path m", "contact steps"):
        assert column in output
    assert "speed m/s" in output and "RMS error" not in output  # Avoid has no reference
    rows = {line.split()[0]: line for line in output.splitlines() if line[:3] in ("bra", "vfh")}
    assert set(rows) == {"braitenberg", "vfh"}
    assert "100.0 [43.9, 100.0]" in rows["braitenberg"]  # 3/3 with its Wilson interval

    with (tmp_path / "paper_fig6_episodes.csv").open() as file:
        episodes = list(csv.DictReader(file))
    assert [(e["policy"], e["seed"]) for e in episodes] == [
        (policy, str(seed)) for policy in ("braitenberg", "vfh") for seed in (5, 6, 7)
    ]
    document = json.loads((tmp_path / "paper_fig6_results.json").read_text())
    assert document["env_id"] == "KheperaIV-Avoid-v0" and document["config"] == "paper_fig6"
    assert document["meta"]["command"].startswith("khepera-gym compare --env KheperaIV-Avoid-v0")
    assert {"date", "commit", "machine"} <= document["meta"].keys()
    assert [s["policy"] for s in document["summaries"]] == ["braitenberg", "vfh"]
    success = document["summaries"][0]["success_rate"]
    assert success["value"] == 1.0 and success["n"] == 3
    assert len(document["episodes"]) == 6
    plot = tmp_path / "paper_fig6_trajectories.png"
    assert plot.is_file() and plot.stat().st_size > 10_000
    assert f"saved {plot}" in output


def test_cli_compare_formation_reports_the_formation_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["compare", "--env", "KheperaIV-Formation", "--episodes", "2", "--no-progress"]
    assert cli.main([*argv, "--out", str(tmp_path), "--no-plot"]) == 0
    output = capsys.readouterr().out
    assert "formation err cm" in output
    assert "leader_follower" in output and "random" in output  # the task's default policies
    assert not list(tmp_path.glob("*.png"))  # --no-plot
    document = json.loads((tmp_path / "formation_results.json").read_text())
    assert document["summaries"][0]["formation_error_mean"]["value"] < 0.1


def test_an_older_version_compares_its_tasks_default_policies(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["compare", "--env", "KheperaIV-Formation-v0", "--episodes", "1", "--no-progress"]
    assert cli.main([*argv, "--out", str(tmp_path), "--no-plot"]) == 0
    document = json.loads((tmp_path / "formation_results.json").read_text())
    assert [s["policy"] for s in document["summaries"]] == list(DEFAULT_POLICIES["formation"])


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--task", "avoid", "--policy", "bogus"], "unknown policy 'bogus'; known: position_cont"),
        (["--task", "avoid", "--policy", "braitenbreg"], "did you mean 'braitenberg'"),
        (["--task", "formation", "--policy", "vfh"], "'vfh' does not act on 'formation'"),
        (["--task", "nav", "--policy", "leader_follower"], "'leader_follower' does not act on"),
        (["--env", "KheperaIV-Fly"], "'KheperaIV-Fly' is not registered"),
        (["--task", "nav", "--policy", "random", "random"], "listed twice"),
        (["--task", "nav", "--episodes", "0"], "episodes must be >= 1"),
        (["--task", "nav", "--config", "no_such_scene"], "no_such_scene"),
        (["--task", "track", "--policy", "vfh"], "use kanayama, position_chase, random or sb3:"),
        (["--task", "track", "--set", "refrence=square"], "refrence: unknown key"),
        (["--task", "track", "--set", "reference"], "expected KEY=VALUE"),
        (["--task", "track", "--set", "reference=bogus"], "bogus"),
    ],
)
def test_cli_compare_errors_name_the_problem(argv: list[str], message: str) -> None:
    with pytest.raises(SystemExit, match="khepera-gym compare: ") as error:
        cli.main(["compare", *argv, "--no-progress", "--no-plot", "--out", "/nonexistent"])
    assert message in str(error.value)


def test_sb3_policy_without_stable_baselines3_names_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # import fails as if missing
    model = tmp_path / "ppo_nav.zip"
    model.write_bytes(b"")
    with pytest.raises(SystemExit, match=r"pip install khepera-gym\[sb3\]") as error:
        cli.main(["compare", "--task", "nav", "--policy", f"sb3:{model}", "--no-progress"])
    assert "needs stable-baselines3" in str(error.value)
    with pytest.raises(ImportError, match="stable-baselines3"):
        compare.load_sb3_policy(model)


def test_record_rollout_and_plot_rollouts_side_by_side(tmp_path: Path) -> None:
    formation = record_rollout(
        LATEST["formation"], LeaderFollower(), seed=0, config="paper_fig7", max_steps=50, label="lf"
    )
    assert formation.poses.shape == (51, 5, 3) and formation.targets.shape == (51, 4, 2)
    assert formation.stats["length"] == 50 and not formation.stats["success"]  # truncated
    nav = record_rollout(LATEST["nav"], Braitenberg(), seed=3, label="braitenberg")
    assert nav.poses.shape[1:] == (1, 3) and nav.stats["success"]
    assert nav.duration == pytest.approx(nav.stats["length"] * 0.05)
    figure = plot_rollouts([nav, formation], titles=["Nav", "Formation"])
    assert [ax.get_title() for ax in figure.axes[:2]] == ["Nav", "Formation"]
    assert len(figure.axes[1].lines) == 5  # one trace per robot of the formation
    figure.savefig(tmp_path / "rollouts.png")
    assert (tmp_path / "rollouts.png").stat().st_size > 0
    with pytest.raises(ValueError, match="1 titles for 2 rollouts"):
        plot_rollouts([nav, formation], titles=["one"])
    with pytest.raises(ValueError, match="at least one"):
        plot_rollouts([])


class _FakeModel:
    """Stands in for a stable-baselines3 model: SB3's ``predict`` and ``observation_space``."""

    def __init__(self, policy, obs_dim: int) -> None:
        self.policy = policy
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic=False):
        assert deterministic
        assert observation.shape[-1] == self.observation_space.shape[0]
        return self.policy(observation), state


def _fake_stable_baselines3(model: _FakeModel) -> types.ModuleType:
    """A module with SB3's loader classes: PPO loads ``model``, the others refuse the file."""
    module = types.ModuleType("stable_baselines3")

    def refuse(path: str, device: str = "cpu") -> None:
        raise ValueError("not saved by this algorithm")

    for name in compare.SB3_ALGORITHMS:
        setattr(module, name, type(name, (), {"load": staticmethod(refuse)}))
    module.PPO.load = staticmethod(lambda path, device="cpu": model)
    return module


@pytest.mark.parametrize("algo", [None, "PPO"])
def test_sb3_models_are_loaded_by_algorithm_and_act_on_the_episodes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, algo: str | None
) -> None:
    fake = _fake_stable_baselines3(_FakeModel(PositionControl(), 18))
    monkeypatch.setitem(sys.modules, "stable_baselines3", fake)
    monkeypatch.setitem(
        sys.modules, "khepera_gym.learning.sb3", None
    )  # fall back to trying loaders
    model = tmp_path / "model.zip"
    model.write_bytes(b"")
    result = compare.compare(
        LATEST["nav"], ["position_control", f"sb3:{model}"], episodes=4, progress=False, algo=algo
    )
    # The stand-in model is position control: the same episodes give the same results.
    sb3_results = result.results[f"sb3:{model}"]
    assert [dataclasses.replace(r, policy="") for r in sb3_results] == [
        dataclasses.replace(r, policy="") for r in result.results["position_control"]
    ]
    with pytest.raises(ValueError, match="unknown stable-baselines3 algorithm 'XYZ'"):
        compare.load_sb3_policy(model, "XYZ")
    with pytest.raises(ValueError, match=r"SAC: ValueError: not saved by this algorithm"):
        compare.load_sb3_policy(model, "SAC")
    with pytest.raises(FileNotFoundError, match="no such model file"):
        compare.load_sb3_policy(tmp_path / "missing.zip")


def test_sb3_follower_model_drives_every_follower_of_a_formation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    follower = _FakeModel(LeaderFollower(shape=None), 23)  # one follower's block in, 2 out
    monkeypatch.setitem(sys.modules, "stable_baselines3", _fake_stable_baselines3(follower))
    monkeypatch.setitem(sys.modules, "khepera_gym.learning.sb3", None)
    model = tmp_path / "followers.zip"
    model.write_bytes(b"")
    result = compare.compare(LATEST["formation"], [f"sb3:{model}"], episodes=3, progress=False)
    assert result.summaries[0].formation_error_mean.value < 0.1


# --- Track: a task scored by its tracking error -------------------------------------------------


def test_event_time_median_counts_never_as_inf_without_interpolating() -> None:
    inf = math.inf
    # The smallest time by which half of the episodes converged: 2 of [1, 2, never, never].
    assert compare.event_time_median([1.0, 2.0, inf, inf]).value == 2.0
    # Fewer than half converged: the median is "never", not a number between the times.
    never = compare.event_time_median([1.0, inf, inf])
    assert never.value == inf and never.high == inf
    assert compare.event_time_median([inf] * 5).format() == "inf [inf, inf]"
    assert compare.event_time_median([inf] * 5).to_json()["value"] == "inf"
    assert compare.event_time_median([3.0] * 10).value == 3.0
    assert compare.event_time_median([]).n == 0
    with pytest.raises(ValueError, match="-inf"):
        compare.event_time_median([1.0, -inf])


def test_compare_track_tables_the_tracking_error_of_its_three_policies(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["compare", "--task", "track", "--episodes", "6", "--plot-worlds", "2"]
    assert cli.main([*argv, "--no-progress", "--out", str(tmp_path)]) == 0
    output = capsys.readouterr().out
    header = next(line for line in output.splitlines() if line.startswith("policy"))
    for column in ("RMS error mm", "max error mm", "IAE m·s", "converged %", "converge s"):
        assert column in header
    assert "lost %" in header and "speed m/s" in header
    assert "success %" not in header and "time to goal" not in header  # Track has no success
    rows = {line.split()[0] for line in output.splitlines()[4:7]}
    assert rows == {"kanayama", "position_chase", "random"}  # the task's default policies
    assert "nan" not in output.lower()
    # Strict JSON (no NaN or Infinity literals); a converge time that never came is "inf".
    text = (tmp_path / "track_results.json").read_text()
    document = json.loads(text, parse_constant=lambda name: pytest.fail(f"{name} in JSON"))
    random = document["summaries"][2]
    assert random["policy"] == "random" and random["errors"]["converge_time"]["value"] == "inf"
    with (tmp_path / "track_episodes.csv").open() as file:
        episodes = list(csv.DictReader(file))
    assert len(episodes) == 18 and "track_converge_time" in episodes[0]
    assert {e["track_converge_time"] for e in episodes if e["policy"] == "random"} == {"inf"}
    for figure in ("track_references.png", "track_errors.png"):
        assert (tmp_path / figure).stat().st_size > 10_000
        assert f"saved {tmp_path / figure}" in output


def test_kanayama_tracks_the_circle_far_below_random() -> None:
    result = compare.compare(
        LATEST["track"],
        ["kanayama", "random"],
        episodes=12,
        record_worlds=1,
        progress=False,
        overrides={"reference": "circle"},
    )
    kanayama, random = (s.errors for s in result.summaries)
    # Linearised, Kanayama's error decays as (1 + ω_n t) e^(-ω_n t) with ω_n = 1 rad/s from a
    # 0.2 m offset: below 0.2 · 6 · e^-5 = 8 mm by the end of the 5 s transient, so its RMS
    # after it is below the 2 cm convergence radius and every episode converges.
    assert kanayama["error_rms"].high < 0.02
    assert kanayama["converged"].value == 1.0
    # Random wheel speeds have zero mean: the reference leaves at v_r until the robot is lost
    # at 0.5 m, an error ramping up from at most 0.2 m: RMS >= 0.5 / sqrt(3) = 0.29 m if it
    # started on the reference; 0.2 m leaves room for where it ends.
    assert random["error_rms"].low > 0.2
    assert random["error_rms"].value > 10 * kanayama["error_rms"].value
    assert result.summaries[1].terminated_rate.value > 0.5  # lost
    assert result.summaries[0].terminated_rate.value == 0.0
    # Both followed the same reference, recorded step by step on the 0.6 m circle.
    reference = result.rollouts["kanayama"][0].goal_trace[:, 0]
    np.testing.assert_allclose(np.hypot(*reference.T), 0.6, atol=1e-3)
    np.testing.assert_array_equal(
        result.rollouts["random"][0].goal_trace[:, 0],
        reference[: len(result.rollouts["random"][0].goal_trace)],
    )
    # The error traces: every world at reset and after every step, NaN once it ended.
    trace = result.error_traces["kanayama"]
    assert trace.shape[1] == 12 and np.all(trace[0] <= 0.2 + 1e-6)
    assert np.nanmax(trace[-1]) < 0.02


def test_a_policy_that_never_converges_reports_zero_converged_and_no_nan() -> None:
    result = compare.compare(
        LATEST["track"], ["random"], episodes=5, record_worlds=0, progress=False
    )
    summary = result.summaries[0]
    assert summary.errors["converged"].value == 0.0
    assert summary.errors["converge_time"].value == math.inf
    table = compare.format_table(result)
    assert "0.0 [0.0, 43.4]" in table  # 0 of 5: Wilson z²/(n + z²) = 3.84 / 8.84
    assert "inf [inf, inf]" in table and "nan" not in table.lower()


def test_set_chooses_the_reference_and_names_the_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert compare.parse_overrides(["reference=square", "track.speed=0.1", 'direction="ccw"']) == {
        "reference": "square",
        "track.speed": 0.1,
        "direction": "ccw",
    }
    with pytest.raises(ConfigError, match="given twice"):
        compare.parse_overrides(["speed=0.1", "speed=0.2"])
    argv = ["compare", "--task", "track", "--set", "reference=square", "--episodes", "2"]
    assert cli.main([*argv, "--no-progress", "--out", str(tmp_path)]) == 0
    assert f'{LATEST["track"]}, reference="square": 2 episodes' in capsys.readouterr().out
    document = json.loads((tmp_path / "track_reference-square_results.json").read_text())
    assert document["overrides"] == {"reference": "square"}
    assert (tmp_path / "track_reference-square_references.png").is_file()
    # The reference ran on the square of half-side 0.6 m: the larger coordinate is 0.6 m.
    result = compare.compare(
        LATEST["track"], ["kanayama"], episodes=1, progress=False, overrides={"reference": "square"}
    )
    corners = np.abs(result.rollouts["kanayama"][0].goal_trace[:, 0]).max(axis=1)
    np.testing.assert_allclose(corners, 0.6, atol=1e-3)


def test_a_policy_that_cannot_read_track_observations_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="'position_control' does not act on 'track'"):
        compare.compare(LATEST["track"], ["position_control"], episodes=1, progress=False)
    with pytest.raises(ConfigError, match="unknown policy"):
        compare.compare(LATEST["track"], ["kanayma"], episodes=1, progress=False)


def test_a_task_scored_by_laps_and_cross_track_error_needs_one_metrics_entry(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    entry = compare.TaskMetrics(
        success="lap", time="lap time", error_prefix="path", error="cross-track error"
    )
    monkeypatch.setitem(compare.TASK_METRICS, "pathfollow", entry)

    def lap(world: int, success: bool, converge: float) -> compare.EpisodeResult:
        length = 400 + 100 * world  # 20 s, 25 s, 30 s at dt = 0.05 s
        return compare.EpisodeResult(
            policy="follower",
            world=world,
            seed=world,
            success=success,
            length=length,
            time_to_goal=length * 0.05 if success else None,
            episode_return=0.0,
            path_length=3.0,
            collisions=0,
            terminated=success,
            mean_speed=3.0 / (length * 0.05),
            task_stats={
                "path_error_rms": 0.01,
                "path_error_max": 0.03,
                "path_iae": 0.2,
                "path_converge_time": converge,
            },
        )

    results = [lap(0, True, 2.0), lap(1, True, 3.0), lap(2, False, math.inf)]
    summary = compare.summarize("follower", results, entry)
    # Lap time and mean speed over the two laps: (20 + 25) / 2 s, (0.15 + 0.12) / 2 m/s.
    assert summary.time_to_goal_mean.value == pytest.approx(22.5)
    assert summary.mean_speed.value == pytest.approx(0.135)
    assert summary.errors["converged"].value == pytest.approx(2 / 3)
    assert summary.errors["converge_time"].value == 3.0  # the median of 2, 3 and never
    # Both terminations were laps: none counts as lost.
    assert summary.terminated_rate.value == 0.0
    comparison = compare.Comparison(
        env_id="KheperaIV-PathFollow-v1",
        config=None,
        label="pathfollow",
        seed=0,
        episodes=3,
        dt=0.05,
        results={"follower": results},
        summaries=[summary],
        rollouts={"follower": []},
        task="pathfollow",
    )
    header = compare.format_table(comparison).splitlines()[2]
    for column in ("lap %", "lap time s", "RMS error mm", "converged %", "speed m/s"):
        assert column in header
    assert "lost %" not in header  # no termination entry: not reported


def test_a_tasks_own_statistics_are_columns_of_its_table() -> None:
    # DroneFollow: the PD pursuit keeps the robot in view (its footprint is 0.29 m wide at
    # 0.5 m, the PD's lag in the robot's turns is a/k_p = 4 cm); random does not.
    result = compare.compare(
        LATEST["dronefollow"],
        ["drone_pursuit", "random"],
        episodes=4,
        record_worlds=0,
        progress=False,
    )
    pursuit, random = (s.errors for s in result.summaries)
    assert pursuit["in_view_share"].value == 1.0 and random["in_view_share"].value < 1.0
    assert pursuit["horizontal_error_rms"].high < 0.04
    episodes = result.results["drone_pursuit"]
    expected = np.mean([r.task_stats["horizontal_error_rms"] for r in episodes])
    assert pursuit["horizontal_error_rms"].value == pytest.approx(expected)
    table = compare.format_table(result)
    assert "in view %" in table and "horizontal RMS cm" in table
    # LineFollow: the demo's follower stays over its line on the circle.
    lines = compare.compare(
        LATEST["linefollow"], ["line_threshold"], episodes=2, record_worlds=0, progress=False
    )
    (summary,) = lines.summaries
    assert summary.errors["on_line_share"].value == 1.0
    assert summary.errors["line_offset_rms"].value < 0.0135  # within the tape's half-width
    assert "on line %" in compare.format_table(lines)
