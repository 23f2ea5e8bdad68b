"""Every code block of the README and the docs pages runs, or says why it is not run.

A block is marked as not run by an HTML comment on the line before its fence,
``<!-- not run: the reason -->``. The others run, page by page, in a fresh folder:

* ``python`` blocks one after the other in one namespace (a page reads like a session);
* ``bash`` blocks line by line, each a ``khepera-gym ...`` command (run as ``python -m
  khepera_gym.cli``); any other command must be marked;
* ``toml`` blocks are parsed; one whose first line is a comment naming a ``.toml`` file
  (``# my_arena.toml``) is written to that file, for the blocks after it to load;
* a ``python`` block whose first line is a comment naming a ``.py`` file (``# mine.py``) is run
  and also written to that file, for the commands after it (``--policy mine.py:function``).

``text`` blocks (layouts, output) and MyST directives (```` ```{note} ````) are not code. The
generated pages' examples come from the env manuals and run as doctests (tests/test_docs.py).
"""

from __future__ import annotations

import dataclasses
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from khepera_gym.config import tomllib

ROOT = Path(__file__).resolve().parents[1]
#: The hand-written pages: the README and docs/*.md (not the generated ones).
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: Languages whose blocks are not code.
NOT_CODE = {"text", ""}
#: Languages the test runs.
RUNNABLE = {"python", "bash", "toml"}
_FENCE = re.compile(r"^(?P<indent> *)(?P<fence>`{3,})(?P<info>[^`]*)$")
_NOT_RUN = re.compile(r"^<!-- not run: (?P<reason>.+\S) -->$")


@dataclasses.dataclass
class Block:
    """A fenced code block of a page."""

    page: Path
    line: int
    language: str
    code: str
    not_run: str | None


def blocks(page: Path) -> list[Block]:
    """The page's fenced blocks, with the reason they are not run (if marked)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found: list[Block] = []
    index = 0
    while index < len(lines):
        match = _FENCE.match(lines[index])
        if match is None:
            index += 1
            continue
        indent, fence = match.group("indent"), match.group("fence")
        info = match.group("info").strip()
        start = index
        index += 1
        body = []
        while index < len(lines) and lines[index].rstrip() != indent + fence:
            body.append(lines[index].removeprefix(indent))
            index += 1
        index += 1
        previous = lines[start - 1].strip() if start > 0 else ""
        marker = _NOT_RUN.match(previous)
        language = info.split()[0] if info else ""
        found.append(
            Block(page, start + 1, language, "\n".join(body), marker and marker.group("reason"))
        )
    return found


def _is_directive(block: Block) -> bool:
    return block.language.startswith("{")


def _run_bash(block: Block, cwd: Path) -> None:
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), *sys.path]))
    command = ""
    for raw in block.code.splitlines():
        line = raw.split(" #", 1)[0].strip() if not raw.lstrip().startswith("#") else ""
        command += line.removesuffix("\\")
        if not line or line.endswith("\\"):
            continue
        argv = shlex.split(command)
        command = ""
        assert argv[0] == "khepera-gym", (
            f"{block.page.name}:{block.line}: `{argv[0]}` is not a khepera-gym command; mark "
            "the block <!-- not run: reason -->"
        )
        result = subprocess.run(
            [sys.executable, "-m", "khepera_gym.cli", *argv[1:]],
            cwd=cwd,
            env=environment,
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
        assert result.returncode == 0, f"{block.page.name}:{block.line}: {result.stderr[-2000:]}"


def _run_toml(block: Block, cwd: Path) -> None:
    tomllib.loads(block.code)
    first = block.code.splitlines()[0] if block.code else ""
    name = first.lstrip("# ").strip()
    if first.startswith("#") and name.endswith(".toml"):
        (cwd / name).write_text(block.code, encoding="utf-8")


def test_every_page_has_code_blocks_to_check() -> None:
    assert len(PAGES) >= 10
    assert sum(len(blocks(page)) for page in PAGES) >= 30


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_block_is_runnable_or_says_why_not(page: Path) -> None:
    for block in blocks(page):
        if block.not_run or _is_directive(block) or block.language in NOT_CODE:
            continue
        assert block.language in RUNNABLE, (
            f"{page.name}:{block.line}: a {block.language!r} block is not run; mark it "
            "<!-- not run: reason -->"
        )


def _runnable(page: Path) -> bool:
    return any(
        b.language in RUNNABLE and not b.not_run and not _is_directive(b) for b in blocks(page)
    )


#: The pages with at least one block to run (the others are checked by the test above).
RUN_PAGES = [page for page in PAGES if _runnable(page)]


@pytest.mark.parametrize("page", RUN_PAGES, ids=[p.name for p in RUN_PAGES])
def test_the_code_blocks_of_the_page_run(
    page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    ran = 0
    for block in blocks(page):
        if block.not_run or _is_directive(block) or block.language not in RUNNABLE:
            continue
        if block.language == "python":
            code = compile(block.code, f"{page.name}:{block.line}", "exec")
            exec(code, namespace)
            first = block.code.splitlines()[0] if block.code else ""
            if first.startswith("# ") and first.removeprefix("# ").strip().endswith(".py"):
                (tmp_path / first.removeprefix("# ").strip()).write_text(block.code)
        elif block.language == "bash":
            _run_bash(block, tmp_path)
        else:
            _run_toml(block, tmp_path)
        ran += 1
    for value in namespace.values():  # close what the page opened (not a class it imported)
        if isinstance(value, type):
            continue
        close = getattr(value, "close", None)
        if callable(close) and hasattr(value, "step"):
            close()
    assert ran
