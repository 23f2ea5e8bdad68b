"""The plot helper, the ``khepera-gym`` command and the benchmark, end to end (no timing checks)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any
from unittest import mock

import gymnasium as gym
import numpy as np
import pytest
from conftest import LATEST
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from khepera_gym import _core, cli, registry
from khepera_gym.analysis import throughput
from khepera_gym.analysis.compare.command import DEMO_RUNS, demo_runs
from khepera_gym.analysis.plots import plot_trajectories
from khepera_gym.envs import formation_heuristic
from khepera_gym.registration import latest_ids, registered_ids
from khepera_gym.registration import task_of as registration_task


def test_plot_trajectories_draws_paths_and_saves_png(tmp_path: Path) -> None:
    env = gym.make(LATEST["nav"])
    env.reset(seed=0)
    path = [env.unwrapped.poses()[0]]
    for _ in range(20):
        env.step(np.array([0.5, 0.3], np.float32))
        path.append(env.unwrapped.poses()[0])
    scene = env.unwrapped.scene()
    goal = env.unwrapped.goals()[0]
    env.close()

    figure = plot_trajectories([np.array(path)], scene, goals=[goal], title="one episode")
    assert isinstance(figure, Figure)
    ax = figure.axes[0]
    assert ax.get_title() == "one episode"
    drawn = ax.lines[0].get_xydata()
    np.testing.assert_allclose(drawn, np.array(path)[:, :2])
    output = tmp_path / "paths.png"
    figure.savefig(output)
    assert output.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_trajectories_draws_obstacles_of_every_kind() -> None:
    scene = {
        "arena": (2.0, 2.0),
        "robot_radius": 0.07,
        "goal_radius": 0.05,
        "obstacles": [
            {"kind": "circle", "center": (0.3, 0.2), "radius": 0.1},
            {"kind": "box", "center": (-0.4, 0.1), "half_extents": (0.1, 0.2), "angle": 0.3},
            {"kind": "segment", "start": (0.0, -0.5), "end": (0.5, -0.5)},
        ],
    }
    trajectory = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    figure = plot_trajectories([trajectory, trajectory[:, :2]], scene)
    assert len(figure.axes) == 1
    ax = figure.axes[0]
    assert len(ax.lines) == 2  # only the paths are lines; obstacles are patches and collections
    segments = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert any(np.allclose(c.get_segments()[0], [(0.0, -0.5), (0.5, -0.5)]) for c in segments)
    with pytest.raises(ValueError, match="trajectory 0"):
        plot_trajectories([np.zeros((3, 4))], scene)


def test_plot_trajectories_accepts_scene_segments_with_a_and_b_and_open_floors() -> None:
    scene = {
        "arena": (2.0, 2.0),
        "walls": False,
        "wall_thickness": 0.05,
        "obstacles": [{"kind": "segment", "a": (0.0, -0.5), "b": (0.5, -0.5)}],
    }
    figure = plot_trajectories([np.zeros((2, 2))], scene, goals=[None])
    assert figure.axes[0].patches[0].get_linestyle() == "--"  # open floor: dashed border


def test_plot_trajectories_draws_a_formation_with_its_leader_and_targets(tmp_path: Path) -> None:
    env = gym.make(LATEST["formation"], config="paper_fig7")
    observation, _ = env.reset(seed=0)
    poses, targets = [env.unwrapped.poses()], [env.unwrapped.formation_targets()]
    for _ in range(60):
        observation, *_ = env.step(formation_heuristic(observation))
        poses.append(env.unwrapped.poses())
        targets.append(env.unwrapped.formation_targets())
    scene, goals = env.unwrapped.scene(), env.unwrapped.goals()
    env.close()
    names = ["leader", "follower_0", "follower_1", "follower_2", "follower_3"]
    figure = plot_trajectories(
        [np.array(poses)],
        scene,
        goals=[goals],
        targets=[np.array(targets)],
        leader=0,
        robot_names=names,
        snapshots=2,
    )
    ax = figure.axes[0]
    assert len(ax.lines) == 5  # one trace per robot
    np.testing.assert_allclose(ax.lines[0].get_xydata(), np.array(poses)[:, 0, :2])
    assert ax.lines[0].get_color() == "black"
    assert ax.lines[0].get_linewidth() > ax.lines[1].get_linewidth()  # the leader stands out
    assert [text.get_text() for text in ax.get_legend().get_texts()] == names
    assert len(scene["obstacles"]) == 4  # circle, box, circle, segment: all drawn
    output = tmp_path / "formation.png"
    figure.savefig(output)
    assert output.stat().st_size > 0
    with pytest.raises(ValueError, match="targets"):
        plot_trajectories([np.array(poses)], scene, targets=[np.zeros((3,))])
    with pytest.raises(ValueError, match="2 targets for 1 trajectories"):
        plot_trajectories([np.array(poses)], scene, targets=[None, None])


def test_cli_demo_prints_the_comparison_tables_and_saves_the_plots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["demo", "--episodes", "2", "--out-dir", str(tmp_path)]) == 0
    output = capsys.readouterr().out
    # The paper's Fig. 6 and Fig. 7 scenes, then every registered task on its latest id.
    assert output.count("2 episodes per policy") == len(DEMO_RUNS) == 2 + len(latest_ids())
    assert {run[1] for run in DEMO_RUNS} == set(latest_ids().values())
    for env_id in LATEST.values():
        assert env_id in output
    for policy in ("position_control", "braitenberg", "vfh", "leader_follower", "random"):
        assert policy in output
    assert "kanayama" in output and "position_chase" in output
    for policy in ("samson", "pure_pursuit", "waypoint_switching"):
        assert policy in output
    assert "formation err cm" in output and "RMS error mm" in output
    for name in ("paper_fig6", "paper_fig7", "nav", "avoid", "formation"):
        plot = tmp_path / f"{name}_trajectories.png"
        assert plot.is_file() and plot.stat().st_size > 0
        assert str(plot.resolve()) in output
        assert (tmp_path / f"{name}_episodes.csv").is_file()
    for figure in ("track_references.png", "track_errors.png"):  # reference vs robot, error
        assert str((tmp_path / figure).resolve()) in output
    assert str((tmp_path / "pathfollow_trajectories.png").resolve()) in output
    assert "line_threshold" in output and "line_proportional" in output
    assert "drone_pursuit" in output and "blob_servo" in output
    # The consensus sweep: one row per trigger setting, and its figure.
    assert "| periodic 0.05 s |" in output and "| event 0.01 m |" in output
    assert str((tmp_path / "consensus_tradeoff.png").resolve()) in output


def test_benchmark_runs_and_reports_steps_per_second(capsys: pytest.CaptureFixture[str]) -> None:
    measurements = throughput.run(
        num_envs=(2,), num_threads=(1, 2), duration=0.02, memory=False, task_envs=3
    )
    # Nav at n = 2 on 1 and 2 threads, then every other task of the registry and the camera
    # rows at n = 3 on 1 and 2 threads, then the single env.
    labels = [env_id.removeprefix("KheperaIV-") for env_id in throughput.OTHER_TASKS]
    labels += [label for label, _ in throughput.CAMERA_ROWS]
    assert {"Avoid", "Formation", "Track", "PathFollow", "LineFollow", "Seek"} <= set(labels)
    every_task = {ids[-1].rsplit("-v", 1)[0] for ids in registered_ids().values()}
    assert {LATEST["nav"].rsplit("-v", 1)[0], *throughput.OTHER_TASKS} == every_task
    assert [m.num_envs for m in measurements] == [2, 2] + [3] * (2 * len(labels)) + [1]
    assert [m.label for m in measurements][2:-1] == [
        f"{label} make_vec n=3" for label in labels for _ in range(2)
    ]
    assert all(m.steps > 0 and m.env_steps_per_second > 0 for m in measurements)
    assert "env-steps/s" in capsys.readouterr().out


def test_bench_writes_its_rows_with_date_commit_machine_and_command(tmp_path: Path) -> None:
    path = tmp_path / "bench.json"
    argv = ["bench", "--num-envs", "2", "--threads", "1", "--duration", "0.02", "--no-single"]
    argv += ["--no-memory", "--json", str(path)]
    with (
        mock.patch.object(throughput, "OTHER_TASKS", ()),
        mock.patch.object(throughput, "CAMERA_ROWS", ()),
        mock.patch.object(throughput, "swarm_rows", lambda *args: [{"robots": 4}]),
    ):
        assert cli.main(argv) == 0
    document = json.loads(path.read_text())
    assert document["meta"]["command"] == "khepera-gym " + " ".join(argv)
    assert document["meta"]["machine"]["cpus"] >= 1 and "date" in document["meta"]
    assert [row["label"] for row in document["rows"]] == ["make_vec n=2"]
    assert document["rows"][0]["env_steps_per_second"] > 0
    assert document["swarm"] == [{"robots": 4}] and document["memory_per_world_bytes"] is None


def test_the_swarm_rows_run_the_benchmarks_version_on_both_splits() -> None:
    # Until 2026-12-07 the rows timed multinav v1 whatever --version said.
    from khepera_gym.analysis import swarm_throughput

    made: list[tuple[int | None, str]] = []
    real = swarm_throughput.MultiAgentArrayEnv

    def spy(task: str, num_envs: int, **kwargs: Any) -> Any:
        made.append((kwargs["version"], kwargs["physics"]["split"]))
        return real(task, num_envs, **kwargs)

    with mock.patch.object(swarm_throughput, "MultiAgentArrayEnv", spy):
        rows = swarm_throughput.swarm_rows((4,), (1,), 0.01, version=2)
    # 4-robot worlds and the swarm scene, each split both ways.
    assert made == [(2, "world"), (2, "robot")] * 2
    assert [(r["robots"], r["split"], r["version"]) for r in rows] == [
        (4, "world", 2),
        (4, "robot", 2),
        (1000, "world", 2),
        (1000, "robot", 2),
    ]


def test_memory_per_world_is_measured_on_linux() -> None:
    # A larger batch made and freed first leaves memory this process would reuse: measured here,
    # the next batch's growth would read as 0. A world holds at least its robot, its rapier
    # world and its sensors' state: well over a kilobyte.
    freed = _core.Batch("nav", 2048, num_threads=1)
    freed.reset(0)
    del freed
    per_world = throughput.memory_per_world(num_worlds=256)
    if per_world is None:
        pytest.skip("no /proc/self/statm on this platform")
    assert isinstance(per_world, float) and per_world > 1024


def test_cli_demo_runs_the_behaviour_version_asked_for(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["demo", "--episodes", "1", "--version", "0", "--out-dir", str(tmp_path)]) == 0
    output = capsys.readouterr().out
    v0 = [t for t in registry.task_names() if 0 in registry.task_versions(t)]
    later = [t for t in registry.task_names() if t not in v0]
    # The tasks that did not exist at v0 are named as left out, and none of them runs.
    assert f"behaviour version 0: {', '.join(later)} did not exist yet, left out" in output
    ran = [run[1] for run in demo_runs(0)]
    assert ran and all(env_id.endswith("-v0") for env_id in ran)
    assert {registration_task(env_id) for env_id in ran} <= set(v0)
    for env_id in ran:
        assert env_id in output
    assert "consensus_v" not in output  # consensus came with v1
    with pytest.raises(SystemExit, match="--version"):
        cli.main(
            ["demo", "--version", str(registry.LATEST_VERSION + 1), "--out-dir", str(tmp_path)]
        )
