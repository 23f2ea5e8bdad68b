"""``khepera-gym benchmark --ray ADDRESS`` on a Ray cluster of a head and a worker on this
machine: its runs equal the local runs of the same seeds bit for bit (held-out results,
training history, the model's parameters), ran on the worker (the head has no CPU), and their
files are where a local run writes them; a second command resumes; a run whose worker process
is killed is run again, to the same bits; ``--ray`` alone (a Ray started here) gives the same
bits too; a bad address fails at once.

The cluster lives in namespaces of its own (``unshare --net --pid --fork --mount-proc``): a
network with only loopback up, so nothing leaves the machine and no other Ray is seen, and a
PID namespace, so every process of the cluster ends when the test's part does (the nodes are
also stopped by killing their process groups; ``ray stop`` would end every Ray on the machine).
Ray's token authentication is off there (``RAY_AUTH_MODE=disabled``), loopback only. Running as
root (as CI does) or with unprivileged user namespaces (``--map-root-user``).

Run as a script (``python tests/test_benchmark_ray.py cluster OUT``), this file is that part.
"""

from __future__ import annotations

import contextlib
import json
import os
import pickle
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("ray", reason="needs Ray: pip install 'khepera-gym[rllib]'")
pytest.importorskip(
    "stable_baselines3", reason="needs the sb3 extra: pip install 'khepera-gym[sb3]'"
)

ROOT = Path(__file__).resolve().parents[1]
#: One tiny run (as tests/test_benchmark.py's TINY): nav, ppo, seed 0, a few updates.
RUN = [
    "--tasks",
    "nav",
    "--learners",
    "ppo",
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
#: The cluster's part may take this long (s) before the test gives up on it.
CLUSTER_SECONDS = 240


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _wait_for_port(port: int, head: subprocess.Popen[bytes]) -> None:
    """Until the head answers on ``port`` (Ray would retry a silent address for minutes)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and head.poll() is None:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"the Ray head did not answer on port {port} (exit status {head.poll()})")


def _cluster_part(out: Path) -> None:
    """Inside the namespaces: a head (no CPU) and a worker (1 CPU); the benchmark run on them
    twice into ``out`` (the second resumes); the nodes in ``out/nodes.json``."""
    if os.getpid() != 1:
        raise SystemExit("run in a PID namespace of its own: unshare --pid --fork --mount-proc")
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    temp = tempfile.mkdtemp(prefix="kgray")  # short: Ray's socket paths must fit in 107 bytes
    env = {
        **os.environ,
        "RAY_AUTH_MODE": "disabled",
        "RAY_USAGE_STATS_ENABLED": "0",
        "RAY_TMPDIR": temp,  # Ray's sessions and its ray_current_cluster file, ours alone
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
    }
    ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or "ray"
    port = _free_port()
    address = f"127.0.0.1:{port}"
    nodes: list[subprocess.Popen[bytes]] = []
    logs: list[Any] = []

    def start(name: str, *flags: str) -> None:
        log = (out.parent / f"{name}.log").open("wb")
        logs.append(log)
        nodes.append(
            subprocess.Popen(
                [ray, "start", *flags, "--node-ip-address=127.0.0.1", "--block"],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,  # its own process group, killed whole below
            )
        )

    try:
        # First without an address, before the cluster exists: a Ray of its own here.
        with (out.parent / "driver_here.log").open("wb") as log:
            here = ["benchmark", "--ray", "--out", str(out.parent / "here"), *RUN]
            subprocess.run(
                [sys.executable, "-m", "khepera_gym.cli", *here],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                check=True,
                timeout=CLUSTER_SECONDS // 2,
            )
        start("head", "--head", "--num-cpus=0", f"--port={port}", "--disable-usage-stats")
        _wait_for_port(port, nodes[0])
        start("worker", f"--address={address}", "--num-cpus=1")
        with (out.parent / "driver.log").open("wb") as log:
            subprocess.run(
                [sys.executable, __file__, "driver", address, str(out)],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                check=True,
                timeout=CLUSTER_SECONDS - 30,
            )
    finally:
        for node in nodes:
            with contextlib.suppress(ProcessLookupError):  # ended already
                os.killpg(node.pid, signal.SIGKILL)
            node.wait()
        for log in logs:
            log.close()
        shutil.rmtree(temp, ignore_errors=True)


def _driver_part(address: str, out: Path) -> None:
    """The driver, in the namespaces: waits for the worker, notes the nodes, runs seed 0 twice
    (the second finds it done) and seed 1 with its first worker process killed mid-run."""
    import threading

    import ray

    from khepera_gym import cli

    ray.init(address=address)
    while ray.cluster_resources().get("CPU", 0) < 1:  # the worker has not joined yet
        time.sleep(0.2)
    nodes = [
        {"id": node["NodeID"], "cpus": node["Resources"].get("CPU", 0)}
        for node in ray.nodes()
        if node["Alive"]
    ]
    (out.parent / "nodes.json").write_text(json.dumps(nodes))
    ray.shutdown()
    argv = ["benchmark", "--ray", address, "--out", str(out), *RUN]
    for _ in range(2):
        assert cli.main(argv) == 0
    killer = threading.Thread(target=_kill_first_run, args=(out.parent / "killed.txt",))
    killer.start()
    assert cli.main([*argv, "--seed-list", "1"]) == 0
    killer.join()


def _kill_first_run(note: Path) -> None:
    """SIGKILLs the first worker process seen running a run, as a lost worker; notes its pid.
    Only in the PID namespace, whose ``/proc`` shows the cluster's processes alone."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        for process in Path("/proc").iterdir():
            try:
                title = (process / "cmdline").read_bytes() if process.name.isdigit() else b""
            except OSError:
                continue
            if title.startswith(b"ray::train_on_worker"):
                os.kill(int(process.name), signal.SIGKILL)
                note.write_text(process.name)
                return
        time.sleep(0.05)


def _namespaces() -> list[str]:
    prefix = ["unshare", "--net", "--pid", "--fork", "--mount-proc"]
    return prefix if os.geteuid() == 0 else [*prefix, "--map-root-user"]


def _normalizer(path: Path) -> list[Any]:
    """The running statistics of a saved VecNormalize (observations and returns)."""
    with open(path, "rb") as file:
        normalizer = pickle.load(file)
    return [
        normalizer.obs_rms.mean,
        normalizer.obs_rms.var,
        normalizer.ret_rms.mean,
        normalizer.ret_rms.var,
    ]


def _only_results(record: dict[str, Any]) -> dict[str, Any]:
    """What must be the same bits: held-out results, the history's steps and means, the
    criterion's verdicts (timings and the machine are exempt)."""
    return {
        "key": record["key"],
        "recipe": record["recipe"],
        "timesteps": record["timesteps"],
        "history": [(h["steps"], h["means"]) for h in record["history"]],
        "reached": None if record["reached"] is None else record["reached"]["steps"],
        "final": record["final"],
        "final_sampled": record["final_sampled"],
        "solved": (record["solved"], record["solved_sampled"]),
    }


def test_a_run_on_a_ray_cluster_equals_the_local_run_and_ran_on_the_worker(
    tmp_path: Path,
) -> None:
    from khepera_gym import cli

    on_ray, here = tmp_path / "ray" / "out", tmp_path / "local"
    on_ray.parent.mkdir()
    started = time.perf_counter()
    cluster = subprocess.Popen(
        [*_namespaces(), sys.executable, __file__, "cluster", str(on_ray)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        assert cli.main(["benchmark", "--out", str(here), *RUN, "--seed-list", "0", "1"]) == 0
        output, _ = cluster.communicate(timeout=CLUSTER_SECONDS)
    finally:
        if cluster.poll() is None:
            cluster.kill()  # the namespace's first process: the kernel ends the rest
            cluster.wait()
    logs = "".join(
        f"\n--- {log.name}\n{log.read_text(errors='replace')[-3000:]}"
        for log in sorted(on_ray.parent.glob("*.log"))
    )
    assert cluster.returncode == 0, output.decode(errors="replace") + logs
    print(f"cluster part and local run: {time.perf_counter() - started:.1f} s")

    nodes = json.loads((on_ray.parent / "nodes.json").read_text())
    assert sorted(node["cpus"] for node in nodes) == [0, 1]  # the head has no CPU
    (worker,) = (node["id"] for node in nodes if node["cpus"] == 1)
    run_files = sorted((here / "runs").glob("*.json"))
    assert [f.name for f in run_files] == [f.name for f in sorted((on_ray / "runs").glob("*"))]
    for run_file in run_files:  # seed 0, and seed 1 whose first worker was killed
        local = json.loads(run_file.read_text())
        remote_text = (on_ray / "runs" / run_file.name).read_text()
        remote = json.loads(remote_text)
        assert "khepera-gym-benchmark-" not in remote_text  # no path of the worker's folder
        assert _only_results(remote) == _only_results(local), run_file.name
        _assert_same_model(local, here, remote, on_ray)
        # Made on the worker, by the same code, with the driver's command.
        assert remote["meta"]["ray_node"] == worker
        assert remote["meta"]["commit"] == local["meta"]["commit"]
        assert "--ray 127.0.0.1:" in remote["meta"]["command"]
    assert (on_ray / "baselines").is_dir() and (on_ray / "benchmark.json").is_file()
    # `--ray` without an address: a Ray started here, the same bits again.
    on_local_ray = on_ray.parent / "here"
    local = json.loads(run_files[0].read_text())
    remote = json.loads((on_local_ray / "runs" / run_files[0].name).read_text())
    assert _only_results(remote) == _only_results(local)
    _assert_same_model(local, here, remote, on_local_ray)
    driver_log = (on_ray.parent / "driver.log").read_text()
    # The second command found seed 0 done and did not submit it again; seed 1's run was
    # retried after its worker was killed, and nothing was reported lost.
    assert "done before: read from its file, not run again" in driver_log, driver_log
    assert (on_ray.parent / "killed.txt").is_file(), driver_log
    assert "failed on the cluster" not in driver_log, driver_log


def _assert_same_model(
    local: dict[str, Any], here: Path, remote: dict[str, Any], on_ray: Path
) -> None:
    """The files are where a local run writes them (the records name them alike, relative to
    the results folder) and hold the same parameters and normaliser statistics."""
    import torch
    from stable_baselines3 import PPO

    assert remote["files"] == local["files"]
    assert all((on_ray / path).is_file() for path in remote["files"].values())
    models = [PPO.load(folder / local["files"]["model"], device="cpu") for folder in (here, on_ray)]
    ours, theirs = (m.policy.state_dict() for m in models)
    assert ours.keys() == theirs.keys()
    for key in ours:
        assert torch.equal(ours[key], theirs[key]), key
    if "vecnormalize" in local["files"]:
        stats = [_normalizer(folder / local["files"]["vecnormalize"]) for folder in (here, on_ray)]
        for ours_stats, theirs_stats in zip(*stats, strict=True):
            assert np.array_equal(ours_stats, theirs_stats)


def test_a_bad_ray_address_fails_at_once_naming_it(tmp_path: Path) -> None:
    from khepera_gym import cli
    from khepera_gym.learning.benchmark.cluster import CONNECT_SECONDS

    address = f"127.0.0.1:{_free_port()}"  # nothing listens there
    started = time.perf_counter()
    with pytest.raises(SystemExit) as caught:
        cli.main(["benchmark", "--ray", address, "--out", str(tmp_path), *RUN])
    assert time.perf_counter() - started < CONNECT_SECONDS
    message = str(caught.value)
    assert f"--ray {address}: no Ray cluster answers there" in message
    assert "\n" not in message and not (tmp_path / "baselines").exists()


#: A run's record as far as the command's lines read it.
_RECORD = {
    "final": {"success": {"value": 0.5}},
    "reached": None,
    "solved": False,
    "train_seconds": 1.0,
}


class _StandInCluster:
    """Stands in for :class:`~khepera_gym.learning.benchmark.cluster.RayRuns`: the first run
    ends with a record, every other is lost (as when Ray's retries are spent), or with
    ``interrupt`` Ctrl-C comes after the first."""

    def __init__(self, interrupt: bool = False) -> None:
        self.runs: list[int] = []
        self.interrupt = interrupt
        self.left = False  # whether the command left it (cancelling what runs, disconnecting)

    def __enter__(self) -> _StandInCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.left = True

    @property
    def running(self) -> int:
        return len(self.runs)

    def submit(self, index: int, run: Any, baselines: Any) -> None:
        self.runs.append(index)

    def ended(self) -> Iterator[tuple[int, dict[str, Any] | None, str | None]]:
        yield self.runs.pop(0), _RECORD, None
        while self.runs:
            if self.interrupt:
                raise KeyboardInterrupt
            yield self.runs.pop(0), None, "WorkerCrashedError: the worker died"


def _stand_in(monkeypatch: pytest.MonkeyPatch, interrupt: bool = False) -> _StandInCluster:
    from khepera_gym.learning.benchmark import cluster, command

    stand_in = _StandInCluster(interrupt)
    monkeypatch.setattr(cluster, "start", lambda address, settings: stand_in)
    monkeypatch.setattr(command, "run_baselines", lambda *args: {"summaries": {}})
    monkeypatch.setattr(command, "_write_summary", lambda *args: None)
    return stand_in


def test_a_run_lost_on_the_cluster_is_named_and_the_command_fails(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from khepera_gym import cli

    stand_in = _stand_in(monkeypatch)
    seeds = ["--seed-list", "0", "1", "2"]
    with pytest.raises(SystemExit) as caught:
        cli.main(["benchmark", "--ray", "--out", str(tmp_path), *RUN, *seeds])
    assert str(caught.value) == (
        f"khepera-gym benchmark: 2 of 3 runs failed on the cluster and are not in {tmp_path}: "
        "nav ppo seed 1 (WorkerCrashedError: the worker died); nav ppo seed 2 "
        "(WorkerCrashedError: the worker died); the same command runs them again"
    )
    out = capsys.readouterr().out
    assert "nav ppo seed 0: success 0.5" in out
    assert "nav ppo seed 2 (WorkerCrashedError: the worker died): failed on the cluster" in out
    assert stand_in.left


def test_ctrl_c_on_the_cluster_cancels_its_runs_and_says_the_command_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from khepera_gym import cli
    from khepera_gym.learning.benchmark import command

    stand_in = _stand_in(monkeypatch, interrupt=True)
    # Seed 3 was done before: it counts as done, though the cluster ends runs in any order.
    monkeypatch.setattr(command, "finished", lambda *run: {} if run[3] == 3 else None)
    monkeypatch.setattr(command, "run_one", lambda *args: _RECORD)  # seed 3's, from its file
    seeds = ["--seed-list", "0", "1", "2", "3"]
    with pytest.raises((SystemExit, KeyboardInterrupt)) as caught:
        cli.main(["benchmark", "--ray", "--out", str(tmp_path), *RUN, *seeds])
    assert isinstance(caught.value, SystemExit), "Ctrl-C escaped as a KeyboardInterrupt"
    assert caught.value.code == command.INTERRUPTED
    assert capsys.readouterr().err == (
        f"khepera-gym benchmark: interrupted with 2 of 4 runs done in {tmp_path}; the same "
        "command resumes (the runs done there are skipped)\n"
    )
    assert stand_in.left


if __name__ == "__main__":
    if sys.argv[1:2] == ["cluster"]:
        _cluster_part(Path(sys.argv[2]))
    elif sys.argv[1:2] == ["driver"]:
        _driver_part(sys.argv[2], Path(sys.argv[3]))
    else:
        raise SystemExit("usage: python tests/test_benchmark_ray.py cluster OUT")
