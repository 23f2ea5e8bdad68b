"""``khepera-gym benchmark --ray ADDRESS`` on a Ray cluster of a head and a worker on this
machine: its run equals the local run of the same seed bit for bit (held-out results, training
history, the model's parameters), ran on the worker (the head has no CPU), and its files are
where a local run writes them; a second command resumes; a bad address fails at once.

The cluster lives in namespaces of its own (``unshare --net --pid --fork --mount-proc``): a
network with only loopback up, so nothing leaves the machine and no other Ray is seen, and a
PID namespace, so every process of the cluster ends when the test's part does (the nodes are
also stopped by killing their process groups; ``ray stop`` would end every Ray on the machine).
Ray's token authentication is off there (``RAY_AUTH_MODE=disabled``), loopback only. Running as
root (as CI does) or with unprivileged user namespaces (``--map-root-user``).

Run as a script (``python tests/test_benchmark_ray.py cluster OUT``), this file is that part.
"""

from __future__ import annotations

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
from pathlib import Path
from typing import Any

import numpy as np
import pytest

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
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    temp = tempfile.mkdtemp(prefix="kgray")  # short: Ray's socket paths must fit in 107 bytes
    env = {
        **os.environ,
        "RAY_AUTH_MODE": "disabled",
        "RAY_TMPDIR": temp,  # Ray's sessions and its ray_current_cluster file, ours alone
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
    }
    ray = shutil.which("ray", path=str(Path(sys.executable).parent)) or "ray"
    port = _free_port()
    address = f"127.0.0.1:{port}"
    nodes: list[subprocess.Popen[bytes]] = []

    def start(name: str, *flags: str) -> None:
        log = (out.parent / f"{name}.log").open("wb")
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
        start("head", "--head", "--num-cpus=0", f"--port={port}", "--disable-usage-stats")
        _wait_for_port(port, nodes[0])
        start("worker", f"--address={address}", "--num-cpus=1")
        driver = (
            "import json, sys, time\n"
            "import ray\n"
            "from khepera_gym import cli\n"
            f"argv = ['benchmark', '--ray', {address!r}, '--out', {str(out)!r}, *{RUN!r}]\n"
            "ray.init(address=sys.argv[1])  # wait for the worker to join\n"
            "while ray.cluster_resources().get('CPU', 0) < 1:\n"
            "    time.sleep(0.2)\n"
            "nodes = [{'id': n['NodeID'], 'cpus': n['Resources'].get('CPU', 0)}\n"
            "         for n in ray.nodes() if n['Alive']]\n"
            "ray.shutdown()\n"
            "for _ in range(2):\n"
            "    assert cli.main(argv) == 0\n"
            f"open({str(out.parent / 'nodes.json')!r}, 'w').write(json.dumps(nodes))\n"
        )
        with (out.parent / "driver.log").open("wb") as log:
            subprocess.run(
                [sys.executable, "-c", driver, address],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                check=True,
                timeout=CLUSTER_SECONDS - 30,
            )
    finally:
        for node in nodes:
            os.killpg(node.pid, signal.SIGKILL)
            node.wait()
        shutil.rmtree(temp, ignore_errors=True)


def _namespaces() -> list[str]:
    prefix = ["unshare", "--net", "--pid", "--fork", "--mount-proc"]
    return prefix if os.geteuid() == 0 else [*prefix, "--map-root-user"]


def _normalizer(path: str) -> list[Any]:
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
    pytest.importorskip("ray", reason="needs Ray: pip install 'khepera-gym[rllib]'")
    pytest.importorskip("stable_baselines3", reason="needs the sb3 extra")
    import torch
    from stable_baselines3 import PPO

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
        assert cli.main(["benchmark", "--out", str(here), *RUN]) == 0  # meanwhile, locally
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

    (run_file,) = (here / "runs").glob("*.json")
    local = json.loads(run_file.read_text())
    remote_text = (on_ray / "runs" / run_file.name).read_text()
    remote = json.loads(remote_text)
    assert "khepera-gym-benchmark-" not in remote_text  # no path of the worker's folder
    assert _only_results(remote) == _only_results(local)
    # The files are where a local run writes them, named by the driver's paths.
    assert remote["files"].keys() == local["files"].keys()
    for name, path in remote["files"].items():
        assert path == str(on_ray / Path(local["files"][name]).relative_to(here)), name
        assert Path(path).is_file(), name
    models = [PPO.load(r["files"]["model"], device="cpu") for r in (local, remote)]
    ours, theirs = (m.policy.state_dict() for m in models)
    assert ours.keys() == theirs.keys()
    for key in ours:
        assert torch.equal(ours[key], theirs[key]), key
    if "vecnormalize" in local["files"]:  # the observation normaliser's statistics too
        stats = [_normalizer(r["files"]["vecnormalize"]) for r in (local, remote)]
        for ours_stats, theirs_stats in zip(*stats, strict=True):
            assert np.array_equal(ours_stats, theirs_stats)
    # Made on the worker: the head has no CPU, and the record names the worker's node.
    nodes = json.loads((on_ray.parent / "nodes.json").read_text())
    assert sorted(node["cpus"] for node in nodes) == [0, 1]
    (worker,) = (node["id"] for node in nodes if node["cpus"] == 1)
    assert remote["meta"]["ray_node"] == worker
    assert remote["meta"]["commit"] == local["meta"]["commit"]
    assert "--ray 127.0.0.1:" in remote["meta"]["command"]
    assert (on_ray / "baselines").is_dir() and (on_ray / "benchmark.json").is_file()
    # The second command found the run done and did not submit it again.
    driver_log = (on_ray.parent / "driver.log").read_text()
    assert "done before: read from its file, not run again" in driver_log, driver_log


def test_a_bad_ray_address_fails_at_once_naming_it(tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="needs Ray: pip install 'khepera-gym[rllib]'")
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


if __name__ == "__main__":
    if sys.argv[1:2] != ["cluster"]:
        raise SystemExit("usage: python tests/test_benchmark_ray.py cluster OUT")
    _cluster_part(Path(sys.argv[2]))
