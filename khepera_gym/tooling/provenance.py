"""Where a measurement comes from: the date, commit, machine and command that produced it.

The tools that write results (``khepera-gym compare``, ``train``, ``bench`` and the consensus
sweep) put :func:`provenance` under the key ``"meta"`` of every JSON file they write, so that a
table made from those files (the documentation's results pages, ``docs/results/``) can say when,
on what and how each figure was measured. Nothing here affects a result.

The commit is read with ``git`` from the folder the package was imported from, when that folder
is a git work tree (a source checkout); an installed wheel has none, and the package version
stands in for it. Threading: none; reading the machine's description takes a few milliseconds.
"""

from __future__ import annotations

import contextlib
import contextvars
import datetime
import os
import platform
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import khepera_gym

#: The repository root of a source checkout (the folder holding ``khepera_gym/``).
_SOURCE_ROOT = Path(__file__).resolve().parents[2]
#: The command being run, when a caller knows it better than ``sys.argv`` (``cli.main(argv)``).
_COMMAND: contextvars.ContextVar[str | None] = contextvars.ContextVar("command", default=None)


def _git(*args: str) -> str | None:
    """The stripped output of ``git args`` in the source folder, or None without git or a repo."""
    try:
        result = subprocess.run(
            ["git", *args],
            cwd=_SOURCE_ROOT,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return result.stdout.strip() if result.returncode == 0 else None


def commit() -> dict[str, Any] | None:
    """The source checkout's commit: ``{"id": full hash, "dirty": bool}`` (dirty: tracked files
    changed since that commit), or None when the package does not run from a git work tree."""
    if _git("rev-parse", "--is-inside-work-tree") != "true":
        return None
    head = _git("rev-parse", "HEAD")
    if head is None:
        return None
    status = _git("status", "--porcelain", "--untracked-files=no")
    return {"id": head, "dirty": bool(status)}


def _cpu_model() -> str:
    """The CPU's model name (Linux ``/proc/cpuinfo``), else what ``platform`` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_bytes() -> int | None:
    """Total memory (Linux ``/proc/meminfo``), or None."""
    try:
        for line in Path("/proc/meminfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


#: The CPU flags recorded beside speed figures (/proc/cpuinfo), the vector extensions first.
CPU_FLAGS = (
    "sse4_2",
    "avx",
    "avx2",
    "fma",
    "avx512f",
    "avx512dq",
    "avx512cd",
    "avx512bw",
    "avx512vl",
    "avx512_vnni",
    "avx512_bf16",
    "avx512_fp16",
    "amx_tile",
)


def cpu_flags() -> dict[str, bool]:
    """Which of :data:`CPU_FLAGS` the CPU has (Linux /proc/cpuinfo; empty elsewhere)."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8")
    except OSError:
        return {}
    line = next((line for line in text.splitlines() if line.startswith("flags")), "")
    present = set(line.split(":", 1)[-1].split())
    return {flag: flag in present for flag in CPU_FLAGS}


def machine() -> dict[str, Any]:
    """What the figures were measured on: CPU model, its vector extensions and the path the
    kernels ran on (:func:`khepera_gym.simd_path`), logical CPUs, memory, OS and the load
    average when asked (a shared machine's figures are low; the load says how shared)."""
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover - not on Linux or macOS
        load = None
    return {
        "cpu": _cpu_model(),
        "cpu_flags": cpu_flags(),
        "simd_path": khepera_gym.simd_path(),
        "cpus": os.cpu_count(),
        "memory_bytes": _memory_bytes(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "load_average": load,
    }


def command_line(argv: Sequence[str] | None = None) -> str:
    """The command as typed: ``sys.argv`` with the program named by its file name
    (``khepera-gym compare ...``, ``python examples/benchmark.py ...``)."""
    argv = list(sys.argv if argv is None else argv)
    if not argv:
        return ""
    program = [Path(argv[0]).name]
    if Path(argv[0]).as_posix().endswith("khepera_gym/cli.py"):
        program = ["khepera-gym"]  # the package's command line, run from a source tree
    elif program[0].endswith(".py"):
        program = ["python", argv[0]]
    elif program[0] in {"-c", ""}:
        program = ["python", "-c"]
    return shlex.join([*program, *argv[1:]])


@contextlib.contextmanager
def running_command(argv: Sequence[str]) -> Iterator[None]:
    """Within the block, :func:`provenance` records ``argv`` as the command (``cli.main`` called
    with its arguments, e.g. from a script or a test, rather than from the shell)."""
    token = _COMMAND.set(command_line(argv))
    try:
        yield
    finally:
        _COMMAND.reset(token)


def current_command() -> str:
    """The command being run: the one of the enclosing :func:`running_command`, else this
    process's command line (:func:`command_line`)."""
    return _COMMAND.get() or command_line()


#: An absolute path in a command's word, after an optional ``--option=``, ``KEY=`` or
#: ``sb3:`` (``--out=/a/b``, ``sb3:/a/model.zip``).
_PATH_WORD = re.compile(r"^(?P<prefix>(?:[\w.-]+[:=])?)(?P<path>/.*)$")


def portable_command(command: str, folder: str | os.PathLike[str]) -> str:
    """``command`` without this machine's absolute paths, for a results file written under
    ``folder``: a path below the current directory becomes relative to it, one below
    ``folder``'s parent relative to that parent (``--out /work/bench/final`` from elsewhere is
    ``--out final``, its models ``final/models/...``), and any other keeps its name only."""
    here = Path.cwd()
    anchor = Path(os.path.abspath(folder)).parent

    def portable(word: str) -> str:
        match = _PATH_WORD.match(word)
        if match is None:
            return word
        path = Path(os.path.normpath(match["path"]))
        for base in (here, anchor):
            if path.is_relative_to(base) and path != base:
                return match["prefix"] + path.relative_to(base).as_posix()
        return match["prefix"] + (path.name or ".")

    try:
        words = shlex.split(command)
    except ValueError:  # unbalanced quotes: not a command shlex.join wrote
        return command
    return shlex.join(portable(word) for word in words)


def provenance(command: str | None = None) -> dict[str, Any]:
    """The ``"meta"`` record of a results file.

    Args:
        command: The command that produced the results; None: the one of the enclosing
            :func:`running_command`, else this process's command line.

    Returns:
        ``{"date": ISO 8601 UTC, "commit": {"id", "dirty"} or None, "khepera_gym": version,
        "machine": {...}, "command": str}``.
    """
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    return {
        "date": now.isoformat(),
        "commit": commit(),
        "khepera_gym": khepera_gym.__version__,
        "machine": machine(),
        "command": command or _COMMAND.get() or command_line(),
    }


__all__ = [
    "command_line",
    "commit",
    "current_command",
    "machine",
    "portable_command",
    "provenance",
    "running_command",
]
