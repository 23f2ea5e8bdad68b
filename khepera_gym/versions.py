"""The behaviour versions, as the Rust core declares them: the one list of them.

Each version is an entry of the core (``src/scenario/versions.rs``): its number, a title, one line
of what changed and why, and the previous version's values of the keys it changed. The
registered ids, the PettingZoo modules, every manual's Version History (:func:`with_history`), the
documentation's tables and the tests' version lists are derived from it, so a new version is a
change in the core.
"""

from __future__ import annotations

import dataclasses
import functools
import textwrap

from khepera_gym import _core


@dataclasses.dataclass(frozen=True)
class Version:
    """A behaviour version (the ``-vN`` of an id).

    Attributes:
        number: N.
        title: A few words on what it is.
        summary: What changed from the version before, and why.
        before: The previous version's values of the keys it changed (TOML; empty for v0).
    """

    number: int
    title: str
    summary: str
    before: str


@functools.cache
def versions() -> tuple[Version, ...]:
    """Every behaviour version, oldest first."""
    return tuple(Version(*entry) for entry in _core.versions())


#: The behaviour version of the current defaults (what an id without ``-vN`` takes).
LATEST_VERSION: int = _core.LATEST_VERSION


def history_lines(task: str) -> list[str]:
    """A task's Version History, one Markdown bullet a version it exists in."""
    numbers = _core.task_versions(task)
    lines = []
    for version in versions():
        if version.number not in numbers:
            continue
        if version.number != numbers[0]:
            text = f"{version.title}. {version.summary}"
        elif version.number == 0:
            text = f"Initial version. {version.title}: {version.summary}"
        else:
            older = ", ".join(f"v{n}" for n in range(version.number))
            text = (
                f"Initial version, on behaviour version {version.number}'s dynamics "
                f"({_lower_first(version.title)}). There is no {older}: the task is newer."
            )
        lines.append(f"* v{version.number}: {text}")
    return lines


def _lower_first(text: str) -> str:
    return text[:1].lower() + text[1:]


def with_history(doc: str | None, task: str, indent: str = "    ") -> str:
    """A manual (a class docstring, its lines after the first indented by ``indent``; a module
    docstring: ``indent=""``) with its ``## Version History`` section appended: one line a
    version of ``task``, from the core, and where the full story is."""
    body = (doc or "").rstrip()
    bullets = "\n".join(
        textwrap.fill(line, 96, initial_indent=indent, subsequent_indent=indent + "  ")
        for line in history_lines(task)
    )
    note = textwrap.fill(
        "Older versions stay registered with their behaviour, so published numbers reproduce; "
        "the documentation's dynamics page tells each version's story, with the keys it "
        "changed.",
        96,
        initial_indent=indent,
        subsequent_indent=indent,
    )
    return f"{body}\n\n{indent}## Version History\n\n{bullets}\n\n{note}\n"


__all__ = ["LATEST_VERSION", "Version", "history_lines", "versions", "with_history"]
