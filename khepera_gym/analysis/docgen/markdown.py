"""Markdown (MyST) helpers of the documentation generator: tables, escaping, links to the pages
that code comments cite, and docstrings turned into page text.

Docstrings are written for ``help()`` and for these pages at once: Markdown tables and fenced
examples, Sphinx roles (``:class:`NavEnv```) and reStructuredText literals (``x``, ``::``
blocks). :func:`docstring_markdown` makes them MyST: roles become code (or links to an env's
page), ``::`` blocks become fenced Python.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable, Iterable, Sequence

#: Citations of the research notes in comments, and the page label each points to. The notes
#: became pages: the robot's spec (docs/robot.md), the task definitions (docs/task-design.md),
#: the fidelity review (docs/fidelity.md); their section numbers are kept.
_CITATIONS: tuple[tuple[re.Pattern[str], str], ...] = (
    (
        re.compile(
            r"(?:shared/|docs/)?(?:khepera4_spec\.md|robot\.md|spec) §(?P<section>\d+)"
            r"(?P<rest>[\d.–-]*)"
        ),
        "spec",
    ),
    (
        re.compile(
            r"(?:research/|docs/)?(?:tasks|task-design)\.md §(?P<section>\d+)(?P<rest>[\d.–-]*)"
        ),
        "tasks",
    ),
    (
        re.compile(r"(?:research/|docs/)?fidelity\.md §(?P<section>\d+)(?P<rest>[\d.–-]*)"),
        "fidelity",
    ),
)


def link_citations(text: str) -> str:
    """``spec §6``, ``research/tasks.md §6.3`` and ``fidelity.md §3.2`` as links to the section
    of the page that holds that note now (a MyST ``{ref}`` to its label, e.g. ``spec-6``)."""
    for pattern, prefix in _CITATIONS:

        def link(match: re.Match[str], prefix: str = prefix) -> str:
            return f"{{ref}}`{match.group(0)} <{prefix}-{match.group('section')}>`"

        text = pattern.sub(link, text)
    return text


def escape_cell(text: str) -> str:
    """Text safe in a Markdown table cell: pipes and angle brackets escaped, one line."""
    return " ".join(text.replace("|", "\\|").replace("<", "\\<").split())


def code(text: str) -> str:
    """An inline code span that may itself hold backquotes."""
    fence = "``" if "`" in text else "`"
    padding = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{fence}{padding}{text}{padding}{fence}"


def missing_results(command: str, what: str = "the JSON file it writes") -> str:
    """A note for a results table with no file yet: the command that writes it."""
    return f"```{{note}}\nNo data yet. Run {code(command)} and copy {what} into docs/results/.\n```"


def table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    """A Markdown pipe table; cells are used as given (escape them with :func:`escape_cell`)."""
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---" for _ in header) + "|",
    ]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


_ROLE = re.compile(r":(?:py:)?(?:class|func|mod|meth|data|attr|obj):`~?(?P<target>[^`]+)`")
_LITERAL_INTRO = re.compile(r"::\s*$")


def _literal_blocks(lines: list[str]) -> list[str]:
    """reStructuredText ``::`` literal blocks as fenced Python blocks."""
    out: list[str] = []
    index = 0
    while index < len(lines):
        line = lines[index]
        out.append(line)
        index += 1
        if not _LITERAL_INTRO.search(line) or line.lstrip().startswith(("|", "```")):
            continue
        out[-1] = _LITERAL_INTRO.sub(":", line.rstrip()) if line.strip() != "::" else ""
        while index < len(lines) and not lines[index].strip():
            index += 1
        block: list[str] = []
        while index < len(lines) and (not lines[index].strip() or lines[index].startswith(" ")):
            block.append(lines[index])
            index += 1
        while block and not block[-1].strip():
            block.pop()
        out += ["", "```python", *inspect.cleandoc("\n".join(block)).splitlines(), "```", ""]
    return out


def docstring_markdown(doc: str, link: Callable[[str], str | None] = lambda _: None) -> str:
    """A docstring as MyST Markdown.

    Args:
        doc: The docstring.
        link: Maps a role's target (``"NavEnv"``, ``"khepera_gym.envs.TrackEnv"``) to a page
            path to link it to, or None to show it as code.
    """

    def role(match: re.Match[str]) -> str:
        target = match.group("target")
        name = target.rsplit(".", 1)[-1]
        page = link(target)
        return f"[`{name}`]({page})" if page else code(target)

    text = _ROLE.sub(role, inspect.cleandoc(doc))
    return link_citations("\n".join(_literal_blocks(text.splitlines())))


def sections(markdown: str) -> tuple[str, dict[str, str]]:
    """A manual split at its ``## `` headings: (the text before the first, {heading: body})."""
    parts = re.split(r"^## (.+)$", markdown, flags=re.M)
    return parts[0].strip(), {
        parts[i].strip(): parts[i + 1].strip() for i in range(1, len(parts) - 1, 2)
    }


__all__ = [
    "code",
    "docstring_markdown",
    "escape_cell",
    "link_citations",
    "sections",
    "table",
]
