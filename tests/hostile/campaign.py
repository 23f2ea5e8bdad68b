"""A fuzzing campaign: many hostile cases, each in a process of its own with a memory limit.

Workers (``python -m tests.hostile --worker``, one per core by default) import khepera_gym once
and then, for each case the campaign sends them (a seed and an index: the worker draws the case
itself, :func:`.cases.draw_case`), fork a child that limits its address space
(``RLIMIT_AS``: the worker's own size plus ``--memory``), runs the case (:func:`.execute.run_case`)
and writes its outcome to a pipe. The worker reports the outcome, or what killed the child (an
abort, a segfault: its signal and the last lines it printed) or that it ran past ``--timeout``
(killed). A worker never builds an env itself, so the children it forks inherit no threads.

The campaign counts outcomes by case kind and lists every failure with its seed and index
(``python -m tests.hostile --replay SEED:INDEX`` reruns one, in this process, with a traceback).
"""

from __future__ import annotations

import collections
import dataclasses
import json
import os
import resource
import select
import signal
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import Any, TextIO

#: The repository (``python -m tests.hostile`` runs from here).
ROOT = Path(__file__).resolve().parents[2]
#: Default memory a case may use beyond the worker's own address space.
DEFAULT_MEMORY = 2 << 30
#: Default time a case may take (s).
DEFAULT_TIMEOUT = 60.0


def _address_space() -> int:
    """This process's virtual size (bytes), from /proc (0 where there is none)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _run_child(seed: int, index: int, memory: int, result_fd: int) -> None:
    """In the forked child: limit memory, run the case, write its outcome, exit."""
    from .cases import draw_case
    from .execute import run_case

    limit = _address_space() + memory
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        outcome, detail = run_case(draw_case(seed, index))
    except BaseException as error:
        outcome, detail = f"FAIL: harness {type(error).__name__}", traceback.format_exc()[-600:]
    with os.fdopen(result_fd, "w") as out:
        json.dump({"outcome": outcome, "detail": detail}, out)
    os._exit(0)


def run_forked(seed: int, index: int, memory: int, timeout: float) -> dict[str, Any]:
    """Runs case (seed, index) in a forked child; its outcome, or how it died."""
    result_r, result_w = os.pipe()
    err_r, err_w = os.pipe()
    started = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the child
        os.close(result_r)
        os.close(err_r)
        os.dup2(err_w, 2)
        try:
            _run_child(seed, index, memory, result_w)
        finally:
            os._exit(70)
    os.close(result_w)
    os.close(err_w)
    chunks: dict[int, list[bytes]] = {result_r: [], err_r: []}
    open_fds = {result_r, err_r}
    timed_out = False
    while open_fds:
        remaining = timeout - (time.monotonic() - started)
        if remaining <= 0:
            timed_out = True
            os.kill(pid, signal.SIGKILL)
            break
        ready, _, _ = select.select(list(open_fds), [], [], remaining)
        for fd in ready:
            data = os.read(fd, 65536)
            if data:
                chunks[fd].append(data)
            else:
                open_fds.discard(fd)
    _, status = os.waitpid(pid, 0)
    os.close(result_r)
    os.close(err_r)
    seconds = time.monotonic() - started
    stderr = b"".join(chunks[err_r]).decode("utf-8", "replace")[-800:]
    if timed_out:
        return {"outcome": "FAIL: timeout", "detail": f"over {timeout} s; {stderr}", "s": seconds}
    if os.WIFSIGNALED(status):
        name = signal.Signals(os.WTERMSIG(status)).name
        return {"outcome": f"FAIL: killed by {name}", "detail": stderr, "s": seconds}
    try:
        result = json.loads(b"".join(chunks[result_r]).decode())
    except ValueError:
        code = os.WEXITSTATUS(status)
        return {"outcome": f"FAIL: exit {code}", "detail": stderr, "s": seconds}
    return {**result, "s": seconds}


def worker(memory: int, timeout: float, requests: TextIO, replies: TextIO) -> None:
    """Serves ``{"seed", "index"}`` lines with outcome lines until its input ends."""
    import gymnasium  # noqa: F401 - imported once, before any fork

    import khepera_gym  # noqa: F401

    from .cases import draw_case, gym_ids, pettingzoo

    gym_ids()
    pettingzoo()
    draw_case(0, 0)  # reads every task's schema once, before any fork
    for line in requests:
        request = json.loads(line)
        reply = run_forked(request["seed"], request["index"], memory, timeout)
        reply["index"] = request["index"]
        replies.write(json.dumps(reply) + "\n")
        replies.flush()


@dataclasses.dataclass
class Report:
    """What a campaign found."""

    seed: int
    cases: int = 0
    seconds: float = 0.0
    #: kind -> outcome -> count.
    outcomes: dict[str, collections.Counter[str]] = dataclasses.field(
        default_factory=lambda: collections.defaultdict(collections.Counter)
    )
    failures: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    def add(self, kind: str, reply: dict[str, Any]) -> None:
        self.cases += 1
        outcome = reply["outcome"]
        self.outcomes[kind][outcome] += 1
        if outcome.startswith("FAIL"):
            self.failures.append(
                {
                    "replay": f"{self.seed}:{reply['index']}",
                    "kind": kind,
                    "outcome": outcome,
                    "detail": reply.get("detail", "")[:800],
                }
            )

    def summary(self) -> dict[str, Any]:
        totals: collections.Counter[str] = collections.Counter()
        for counter in self.outcomes.values():
            for outcome, count in counter.items():
                totals[outcome.split(":")[0]] += count
        return {
            "cases": self.cases,
            "seed": self.seed,
            "seconds": round(self.seconds, 1),
            "cases_per_second": round(self.cases / self.seconds, 1) if self.seconds else None,
            "accepted": totals["built"]
            + sum(totals[k] for k in ("reset", "scene", "restored", "stepped")),
            "refused": totals["refused"],
            "failures": len(self.failures),
            "by_kind": {kind: dict(counter) for kind, counter in sorted(self.outcomes.items())},
            "failure_list": self.failures[:200],
        }


def campaign(
    cases: int,
    seed: int = 0,
    workers: int | None = None,
    memory: int = DEFAULT_MEMORY,
    timeout: float = DEFAULT_TIMEOUT,
    progress: TextIO | None = None,
) -> Report:
    """Runs cases 0..cases-1 of ``seed`` over ``workers`` worker processes."""
    from .cases import draw_case

    workers = workers or os.cpu_count() or 1
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    command = [
        sys.executable,
        "-m",
        "tests.hostile",
        "--worker",
        "--memory",
        str(memory),
        "--timeout",
        str(timeout),
    ]
    procs = [
        subprocess.Popen(
            command, cwd=ROOT, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        for _ in range(min(workers, max(cases, 1)))
    ]
    report = Report(seed)
    started = time.monotonic()
    kinds = {}
    pending = {proc.stdout.fileno(): proc for proc in procs if proc.stdout}
    next_index = 0
    busy: dict[int, int] = {}

    def send(proc: subprocess.Popen[str]) -> None:
        nonlocal next_index
        if next_index >= cases:
            assert proc.stdin is not None
            proc.stdin.close()
            return
        kinds[next_index] = draw_case(seed, next_index)["kind"]
        assert proc.stdin is not None
        proc.stdin.write(json.dumps({"seed": seed, "index": next_index}) + "\n")
        proc.stdin.flush()
        busy[proc.pid] = next_index
        next_index += 1

    for proc in procs:
        send(proc)
    while pending:
        ready, _, _ = select.select(list(pending), [], [])
        for fd in ready:
            proc = pending[fd]
            assert proc.stdout is not None
            line = proc.stdout.readline()
            if not line:
                del pending[fd]
                proc.wait()
                if proc.pid in busy:  # a worker died: its case is a failure
                    index = busy.pop(proc.pid)
                    report.add(kinds[index], {"index": index, "outcome": "FAIL: worker died"})
                continue
            reply = json.loads(line)
            busy.pop(proc.pid, None)
            report.add(kinds.pop(reply["index"]), reply)
            if progress is not None and report.cases % 1000 == 0:
                rate = report.cases / (time.monotonic() - started)
                progress.write(
                    f"{report.cases}/{cases} cases, {len(report.failures)} failures, "
                    f"{rate:.1f} cases/s\n"
                )
                progress.flush()
            send(proc)
    report.seconds = time.monotonic() - started
    return report


def replay(seed: int, index: int) -> int:
    """Reruns one case in this process and prints it, its outcome and any traceback."""
    from .cases import draw_case
    from .execute import run_case

    case = draw_case(seed, index)
    print(repr(case))
    outcome, detail = run_case(case)
    print(outcome)
    print(detail)
    return 1 if outcome.startswith("FAIL") else 0


__all__ = [
    "DEFAULT_MEMORY",
    "DEFAULT_TIMEOUT",
    "Report",
    "campaign",
    "replay",
    "run_forked",
    "worker",
]
