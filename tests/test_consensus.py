"""consensus_v1 from Python (issue 16, item 3): the law converges through the PettingZoo env for
any number of robots, the array env and the parallel env agree, a lossy delayed run is saved and
restored bit for bit, bad keys raise ConfigError naming them, and ``khepera-gym compare --task
consensus`` prints and saves the error-against-messages sweep. The Rust core's tests
(tests/consensus.rs) hold the theory: convergence per graph, none across components, the event
trigger's economy, delay and drop statistics."""

from __future__ import annotations

import doctest
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from khepera_gym import cli, registry
from khepera_gym.analysis.compare import consensus as sweep
from khepera_gym.baselines import ConsensusLaw
from khepera_gym.errors import ActionError, ConfigError
from khepera_gym.pettingzoo import consensus, consensus_v1
from khepera_gym.pettingzoo.arrays import MultiAgentArrayEnv

#: The default tolerance (m): converged below it.
TOLERANCE = 0.03


def _run(env, policy, seed: int) -> dict:
    observations, _ = env.reset(seed=seed)
    infos: dict = {}
    while env.agents:
        observations, _, _, _, infos = env.step(policy(observations))
    return infos["robot_0"]["world_episode_stats"]  # the world's, with the consensus errors


@pytest.mark.parametrize("graph", ["ring", "line"])
def test_the_law_converges_through_the_pettingzoo_env(graph: str) -> None:
    # Three robots on a connected graph: the law drives the disagreement to zero; in 30 s below
    # the tolerance (tests/consensus.rs derives it; here the binding, for N other than the
    # default 4, read through ConsensusLaw.for_env).
    env = consensus_v1.parallel_env(n_robots=3, graph=graph, trigger="event", threshold=0.01)
    policy = ConsensusLaw.for_env(env)
    for seed in range(3):
        stats = _run(env, policy, seed)
        assert stats["consensus_error_final"] < TOLERANCE, (seed, stats)
        assert stats["messages_per_robot_s"] < 20.0


def test_the_default_law_reads_four_robots_and_names_a_wrong_length() -> None:
    env = consensus_v1.parallel_env(n_robots=5)
    observations, _ = env.reset(seed=0)
    with pytest.raises(ActionError, match="29"):
        ConsensusLaw()(observations)


def test_the_array_env_and_the_parallel_env_agree() -> None:
    keys = {"n_robots": 5, "graph": "complete", "drop": 0.3, "delay_steps": 2}
    parallel = consensus_v1.parallel_env(**keys)
    arrays = MultiAgentArrayEnv("consensus", 1, version=1, num_threads=1, consensus=keys)
    policy = ConsensusLaw.for_env(parallel)
    observations, _ = parallel.reset(seed=11)
    stacked, _ = arrays.reset(seed=11)
    for _ in range(50):
        assert np.array_equal(np.stack([observations[a] for a in arrays.agents]), stacked[0])
        observations, *_ = parallel.step(policy(observations))
        stacked, *_ = arrays.step(policy(stacked))


def test_a_lossy_delayed_run_restores_bit_for_bit() -> None:
    # Messages in flight and the loss stream are part of the saved state.
    env = consensus_v1.parallel_env(drop=0.4, delay_steps=5, trigger="event", threshold=0.005)
    policy = ConsensusLaw.for_env(env)
    observations, _ = env.reset(seed=3)
    for _ in range(40):
        observations, *_ = env.step(policy(observations))
    state = env.get_state()
    saved = dict(observations)

    def go_on(obs: dict) -> list:
        trace = []
        for _ in range(60):
            obs, *_ = env.step(policy(obs))
            trace.append(np.stack([obs[a] for a in sorted(obs)]))
        return trace

    first = go_on(observations)
    env.set_state(state)
    second = go_on(saved)
    assert all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"n_robots": 40}, "consensus.n_robots"),
        ({"graph": "edges", "consensus": {"edges": [[0, 9]]}}, "consensus.edges"),
        ({"graph": "star"}, "consensus.graph"),
        ({"drop": 1.5}, "consensus.drop"),
        ({"n_robots": 8, "formation_radius": 0.12}, "consensus.formation_radius"),
    ],
)
def test_bad_keys_raise_config_error_naming_them(kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        consensus_v1.parallel_env(**kwargs)


def test_compare_task_consensus_prints_and_saves_the_sweep(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [
        "khepera-gym",
        "compare",
        "--task",
        "consensus",
        "--episodes",
        "4",
        "--out",
        str(tmp_path),
        "--no-progress",
        "--num-threads",
        "1",
    ]
    monkeypatch.setattr(sys, "argv", argv)
    assert cli.main() == 0
    table = capsys.readouterr().out
    document = json.loads((tmp_path / "consensus_sweep.json").read_text())
    assert document["meta"]["command"].startswith("khepera-gym compare --task consensus")
    # Without --version, the latest, named in the JSON and above the table (it was pinned to v1).
    latest = registry.latest_version("consensus")
    assert document["version"] == latest and document["env"] == f"consensus_v{latest}"
    assert {r["version"] for r in document["rows"]} == {latest}
    assert table.startswith(f"consensus_v{latest}: ")
    rows = document["rows"]
    assert len(rows) == len(sweep.PERIODS) + len(sweep.THRESHOLDS)
    assert "| event 0.01 m |" in table
    assert (tmp_path / "consensus_tradeoff.png").stat().st_size > 10_000
    by_setting = {(r["trigger"], r["value"]): r for r in rows}
    # Periodic every period p sends 1/p messages per second, plus the reset's over 30 s.
    for period in sweep.PERIODS:
        sent = by_setting[("periodic", period)]["messages"]["value"]
        assert sent == pytest.approx(1 / period + 1 / 30, rel=1e-3)
    # Messages are about the path driven over the threshold: the thresholds are 2 to 2.5x apart
    # while the paths differ far less, so a larger threshold sends fewer.
    sent = [by_setting[("event", t)]["messages"]["value"] for t in sweep.THRESHOLDS]
    assert sent == sorted(sent, reverse=True)


@pytest.mark.parametrize(
    "target", [["--task", "consensus", "--version", "1"], ["--env", "consensus_v1"]]
)
def test_compare_runs_the_consensus_version_asked_for(
    target: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    argv = ["khepera-gym", "compare", *target, "--episodes", "2", "--out", str(tmp_path)]
    monkeypatch.setattr(sys, "argv", [*argv, "--no-progress", "--no-plot"])
    assert cli.main() == 0
    document = json.loads((tmp_path / "consensus_sweep.json").read_text())
    assert document["version"] == 1 and document["env"] == "consensus_v1"
    # The same worlds as the sweep's own v1 run: the version reached the env.
    first = sweep.run_setting("periodic", sweep.PERIODS[0], 2, version=1)
    assert document["rows"][0]["error_final"] == first.error_final.to_json()


@pytest.mark.parametrize(
    ("target", "message"),
    [
        (["--task", "consensus", "--version", "0"], "no behaviour version 0; it has 1, 2"),
        (["--env", "consensus_v0"], "no behaviour version 0"),
        (["--env", "consensus_v1", "--version", "1"], "names its version"),
        (["--env", "consensus_vx"], "write consensus_vN"),
    ],
)
def test_compare_refuses_a_consensus_version_it_does_not_have(
    target: list[str], message: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "argv", ["khepera-gym", "compare", *target, "--episodes", "2"])
    with pytest.raises(SystemExit, match=message):
        cli.main()


def test_compare_task_consensus_rejects_policies_and_trigger_keys(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    for extra in (["--policy", "random"], ["--set", "trigger=event"]):
        argv = ["khepera-gym", "compare", "--task", "consensus", "--episodes", "2", *extra]
        monkeypatch.setattr(sys, "argv", argv)
        with pytest.raises(SystemExit, match="consensus"):
            cli.main()


def test_the_manual_has_its_sections_its_layout_and_running_examples() -> None:
    # The manual is the family's class (every consensus_vN module's env subclasses it).
    manual = consensus.ConsensusParallelEnv.__doc__ or ""
    sections = [
        "Description",
        "Agents",
        "Action Space",
        "Observation Space",
        "Rewards",
        "Starting State",
        "Episode End",
        "Arguments",
        "Scenario file",
        "Version History",
    ]
    positions = [manual.index(f"## {section}\n") for section in sections]
    assert positions == sorted(positions)
    # The table's rows name the blocks of an agent's layout, in order.
    rows = re.findall(r"^\s*\| [\d…last][^|]*\| (\w+)\s*\|", manual, re.M)
    layout = consensus_v1.parallel_env().agent_obs_layout("robot_0")
    assert rows == list(layout)
    assert layout["neighbours"] == slice(13, 25) and len(range(29)[layout["wheel_speeds"]]) == 2
    assert "v1: Initial version" in manual
    results = doctest.testmod(consensus, optionflags=doctest.ELLIPSIS)
    assert results.attempted >= 4 and results.failed == 0
