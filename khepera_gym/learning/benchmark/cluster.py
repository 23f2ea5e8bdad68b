"""The benchmark's runs as Ray tasks: ``khepera-gym benchmark --ray [ADDRESS]``, on a Ray this
machine starts (no ADDRESS) or on the cluster whose head is at ADDRESS (``host:port`` as
``ray start --head`` prints it, or a Ray Client ``ray://host:port``).

A cluster shares no folder. Each (task, learner, seed) runs as one Ray task
(:func:`train_on_worker`): the worker trains and evaluates into a temporary folder with
:func:`~khepera_gym.learning.benchmark.runner.run_one` and hands back the run's record and its
model files as bytes; the driver writes them where a local run writes them (``runs/``,
``models/<run>/``; :meth:`RayRuns.store`), where the record's ``files`` (relative to the
results folder) name them. So the results folder, its resumption (runs done there are not
submitted) and its tables are those of a local benchmark. The baselines play their held-out
episodes on the driver: no training, and their file is needed before any run is judged.

Provenance: a record's ``meta`` is the worker's (date, commit, machine; and ``ray_node``, the
Ray node id it ran on) with the driver's command. Every node must run the driver's commit (the
folder would refuse a record of other code on resumption): :func:`check_code` asks each node
before any work, and a record of other code (from a node that joined later) is not written.

Same results as a local run: a run computes with torch on
:data:`~khepera_gym.learning.benchmark.runner.TORCH_THREADS` threads wherever it runs, the
Rust batches' results do not depend on their thread count, and every generator is seeded from
the run's seed; so a run's held-out results, history and parameters equal the local run's of
the same seed on the same device, bit for bit (``tests/test_benchmark_ray.py`` checks it).

Resources: a run asks Ray for ``--num-threads`` CPUs (1 without it; its Rust batches then use as
many threads) and, with ``--device cuda``, one GPU (Ray makes it the worker's ``cuda``; a device
index is the driver's and means nothing on a worker). A run whose worker or node is lost is run
again (:data:`MAX_RETRIES` times); one that still fails, or fails in its own code, is reported
and not written, and the other runs go on.

Threading: the driver waits on Ray in its own thread; the work is in the workers' processes.
"""

from __future__ import annotations

import dataclasses
import logging
import socket
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark.marl_eval import write_marl_eval
from khepera_gym.learning.benchmark.runner import (
    Settings,
    load_records,
    run_one,
    run_path,
    write_record,
)
from khepera_gym.tooling.provenance import commit

#: How long the driver tries to reach the head's address before saying it cannot (s).
CONNECT_SECONDS = 10.0
#: How long every node has to say which code it runs, before any work (s).
PROBE_SECONDS = 120.0
#: Times Ray runs a run again whose worker died (a lost node, a killed process).
MAX_RETRIES = 3
#: The folder, under a worker's temporary folder, that the driver's ``--out`` stands for.
_OUT = "out"

#: One run: (suite entry, learner, behaviour version, seed).
Run = tuple[Any, Any, int, int]


def _host_port(address: str) -> tuple[str, int] | None:
    """The host and port of ``host:port`` or ``ray://host:port``; None for another form
    (``auto``), which Ray resolves itself."""
    text = address.split("://", 1)[1] if "://" in address else address
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def connect(address: str | None) -> None:
    """Starts a Ray on this machine (``address`` None) or joins the cluster at ``address``.

    Raises:
        ConfigError: Nothing answers at ``address`` within :data:`CONNECT_SECONDS`, or Ray
            cannot join it; the message names the address.
    """
    if address:
        host_port = _host_port(address)
        if host_port is not None:
            # Ray itself retries an address where nothing answers for minutes: ask first.
            try:
                socket.create_connection(host_port, timeout=CONNECT_SECONDS).close()
            except OSError as error:
                reason = error.strerror or type(error).__name__
                raise ConfigError(
                    f"--ray {address}: no Ray cluster answers there ({reason} within "
                    f"{CONNECT_SECONDS:.0f} s); give the head's host:port as `ray start --head` "
                    "printed it, or no address for a Ray on this machine"
                ) from None
    import ray

    try:
        # Without an address, a Ray of its own: Ray's default joins any cluster it finds listed
        # (RAY_ADDRESS, /tmp/ray/ray_current_cluster), and a stale entry there hangs it.
        ray.init(address=address or "local", logging_level=logging.WARNING)
    except (ConnectionError, RuntimeError, ValueError) as error:
        where = f"the Ray cluster at {address}" if address else "a Ray on this machine"
        raise ConfigError(
            f"--ray {address or ''}: cannot join {where}: {error}; where Ray's token "
            "authentication is on, set RAY_AUTH_MODE=token and give this machine the head's "
            "token (RAY_AUTH_TOKEN or ~/.ray/auth_token)"
        ) from None


def check_gpus(device: str, address: str | None) -> None:
    """Whether the cluster has a GPU for ``--device cuda``.

    Raises:
        ConfigError: A CUDA device asked for on a cluster without a GPU.
    """
    import ray

    if device.startswith("cuda") and ray.cluster_resources().get("GPU", 0) < 1:
        where = f"the Ray cluster at {address}" if address else "the Ray on this machine"
        raise ConfigError(f"--device {device}: {where} has no GPU")


def _code_here() -> dict[str, Any] | None:
    """On a node: the commit of the khepera_gym it imports (None: an installed wheel)."""
    return commit()


def _short(code: dict[str, Any] | None) -> str:
    if code is None:
        return "no git commit (an installed package)"
    return f"commit {code['id'][:12]}{' (dirty)' if code.get('dirty') else ''}"


def check_code(address: str | None) -> None:
    """Whether every node of the cluster imports khepera_gym from the driver's commit (a run of
    other code could not be written to the folder): one small task a node, before any work.

    Raises:
        ConfigError: A node that cannot import khepera_gym, runs other code, or does not
            answer within :data:`PROBE_SECONDS`; the message names the node.
    """
    import ray
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    here = commit()
    probe = ray.remote(_code_here)
    asked = {
        probe.options(
            num_cpus=0, scheduling_strategy=NodeAffinitySchedulingStrategy(node["NodeID"], False)
        ).remote(): node
        for node in ray.nodes()
        if node["Alive"]
    }
    where = f"the Ray cluster at {address}" if address else "the Ray on this machine"
    ready, late = ray.wait(list(asked), num_returns=len(asked), timeout=PROBE_SECONDS)
    if late:
        node = asked[late[0]]
        raise ConfigError(
            f"--ray: node {node['NodeID']} ({node['NodeManagerAddress']}) of {where} did not "
            f"answer within {PROBE_SECONDS:.0f} s"
        )
    for ref in ready:
        node = asked[ref]
        name = f"node {node['NodeID']} ({node['NodeManagerAddress']}) of {where}"
        try:
            there = ray.get(ref)
        except ray.exceptions.RayError as error:
            raise ConfigError(
                f"--ray: {name} cannot run khepera_gym ({_why(error)}); install the driver's "
                "khepera_gym on every node"
            ) from None
        if there != here:
            raise ConfigError(
                f"--ray: {name} runs khepera_gym of {_short(there)}, this driver {_short(here)}; "
                "install the same code on every node (results of different code are not mixed)"
            )


def start(address: str | None, settings: Settings) -> RayRuns:
    """Joins the cluster at ``address`` (None: starts a Ray here) and checks it can run the
    runs of ``settings``; leave the :class:`RayRuns` (a context manager) to disconnect.

    Raises:
        ConfigError: As :func:`connect` and :func:`check_gpus` (then disconnected).
    """
    connect(address)
    try:
        check_gpus(settings.device, address)
        check_code(address)
        return RayRuns(settings)
    except BaseException:
        import ray

        ray.shutdown()
        raise


def train_on_worker(
    entry: Any,
    learner: Any,
    version: int,
    seed: int,
    settings: Settings,
    baselines: Mapping[str, Any],
) -> dict[str, Any]:
    """One run, on a Ray worker: trains and evaluates it into a temporary folder (``settings.out``
    stands for the driver's folder) and returns ``{"record": ..., "files": {path relative to
    the results folder: bytes}}`` (the record's ``files`` are relative to it too)."""
    import ray

    with tempfile.TemporaryDirectory(prefix="khepera-gym-benchmark-") as folder:
        out = Path(folder) / _OUT
        here = dataclasses.replace(settings, out=out)
        record = run_one(entry, learner, version, seed, here, baselines, restart=True)
        record["meta"]["ray_node"] = ray.get_runtime_context().get_node_id()
        files = {
            path.relative_to(out).as_posix(): path.read_bytes()
            for path in sorted((out / "models").rglob("*"))
            if path.is_file()
        }
    return {"record": record, "files": files}


class RayRuns:
    """Runs submitted to Ray, and their results written to the driver's folder as they end.

    Used as a context manager: leaving it cancels the runs still going and disconnects.
    """

    def __init__(self, settings: Settings) -> None:
        import ray

        self.settings = settings
        self._pending: dict[Any, tuple[int, Run]] = {}  # Ray object ref → its run
        self._commit = commit()
        cpus = settings.num_threads or 1
        gpu = settings.device.startswith("cuda")
        # No learner's own progress bar: a worker's output is forwarded to the driver's.
        self._worker_settings = dataclasses.replace(
            settings, num_threads=cpus, device="cuda" if gpu else settings.device, progress=False
        )
        self._remote = ray.remote(train_on_worker).options(
            num_cpus=cpus, num_gpus=1 if gpu else 0, max_retries=MAX_RETRIES
        )

    def __enter__(self) -> RayRuns:
        return self

    def __exit__(self, *exc: object) -> None:
        import ray

        for ref in self._pending:
            ray.cancel(ref, force=True)
        self._pending.clear()
        ray.shutdown()

    def submit(self, index: int, run: Run, baselines: Mapping[str, Any]) -> None:
        """Starts one run (``index``: the caller's name for it) on the cluster, where it waits
        for free resources."""
        entry, learner, version, seed = run
        ref = self._remote.remote(
            entry, learner, version, seed, self._worker_settings, dict(baselines)
        )
        self._pending[ref] = (index, run)

    @property
    def running(self) -> int:
        """Runs submitted and not yet ended."""
        return len(self._pending)

    def ended(self) -> Iterator[tuple[int, dict[str, Any] | None, str | None]]:
        """Each run as it ends: (its index, its record as written, None) or (its index, None,
        why it failed; nothing written)."""
        import ray

        while self._pending:
            ready, _ = ray.wait(list(self._pending), num_returns=1)
            ref = ready[0]
            index, run = self._pending.pop(ref)
            try:
                result = ray.get(ref)
            except ray.exceptions.RayError as error:
                yield index, None, _why(error)
                continue
            try:
                record = self.store(run, result)
            except ConfigError as error:
                yield index, None, str(error)
                continue
            yield index, record, None

    def store(self, run: Run, result: Mapping[str, Any]) -> dict[str, Any]:
        """Writes a run's files and then its record (whose file says the run is done) under the
        driver's folder; returns the record.

        Raises:
            ConfigError: The worker runs other code than the driver (nothing written).
        """
        entry, learner, version, seed = run
        record = result["record"]
        meta = record["meta"]
        if meta.get("commit") != self._commit:  # a node that joined after check_code
            raise ConfigError(
                f"the worker on Ray node {meta.get('ray_node')} runs khepera_gym of "
                f"{_short(meta.get('commit'))}, this driver {_short(self._commit)}: install the "
                "same code on every node (results of different code are not mixed)"
            )
        for relative, data in result["files"].items():
            path = self.settings.out / relative
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.name + ".tmp")
            tmp.write_bytes(data)
            tmp.replace(path)
        write_record(run_path(self.settings, entry.task, version, learner.name, seed), record)
        write_marl_eval(self.settings.out, load_records(self.settings.out)[1])  # as run_one
        return record


def _why(error: Exception) -> str:
    """One line saying why a Ray task failed: its own exception's, else Ray's."""
    cause = getattr(error, "cause", None)
    if isinstance(cause, BaseException):
        return f"{type(cause).__name__}: {cause}".splitlines()[0]
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}"


__all__ = [
    "CONNECT_SECONDS",
    "MAX_RETRIES",
    "PROBE_SECONDS",
    "RayRuns",
    "check_code",
    "check_gpus",
    "connect",
    "start",
    "train_on_worker",
]
