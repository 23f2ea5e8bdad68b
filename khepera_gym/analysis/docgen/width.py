"""The documentation's width budget: how wide a Markdown table lays out on a Furo page.

A browser lays a table out no narrower than its min-content width: the sum of its columns'
widest unbreakable pieces. :func:`table_min_width` estimates it from the Markdown, with the
fonts' metrics and Furo's CSS, and :func:`column_groups` splits a table too wide for the page's
content column (:data:`BUDGET_PX`) into a few narrower ones. tests/test_docs_width.py checks
every table of the pages against the budget; docs/tools/check_table_widths.py measures the built
pages in headless Chromium, which the constants are calibrated against.

Furo's content column is ``.content { width: 46em }`` with ``box-sizing: content-box`` (its
``padding: 0 3em`` is outside the 46em): tables get 46em = 736 px at the 16 px root font from a
window 800 px wide up (from 1,552 px Furo sets the root to 110 %, and text and column grow
together). Below 48em the column is the window less 1em a side, and a wide table scrolls in its
``.table-wrapper`` by design. Measured in headless Chromium: the article is 736 px wide at
1,400, 1,000 and 800 px windows, 568 px at 600.

Text breaks at spaces (``overflow-wrap: break-word`` does not lower a table cell's min-content
width), and Chromium also breaks after a hyphen or a dash and after a question mark before a
letter (:data:`BREAK_AFTER`, measured with a probe page); a slash, an underscore, a dot or a
bracket does not break. Inline code breaks the same way (Furo does not load Sphinx's basic.css,
whose ``span.pre`` would forbid it). So a column needs at least its longest word, code span,
number range or path without a space. The estimate:

- Text: the advance widths of Liberation Sans Regular and Bold 2.1 (metric-compatible with Arial
  and Helvetica, which Furo's font stack names after the Apple and Segoe system fonts; what
  Chromium on Linux draws it with), read from the font files' ``hmtx`` tables with fontTools, in
  1/2048 em at 16 px. Table headers are bold.
- Code: Furo sets it at 81.25 % (13 px) in its monospace stack, whose Linux face is Liberation
  Mono: 0.6 em (7.8 px) every character, plus ``code.literal``'s 0.2em padding and 1 px border
  at each end.
- A cell: Furo's ``padding: 0 .25rem`` and its paragraph's ``margin: .25rem`` (16 px in all), and
  a collapsed 1 px border between columns.

Calibrated against Chromium 156 (``check_table_widths.py --estimate``): over the 345 tables of
the build before issue 52's changes, the estimate was 0.986 to 1.064 times the browser's
min-content width, median 1.000 (kerning, left out, makes the browser's a little narrower; the
widest over-estimates are rows of dotted numbers). A reader whose system font is wider than Arial
(San Francisco on a Mac) needs room: the budget keeps :data:`MARGIN` of the column free.

This is a tool of the repository, not part of the package's API.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

#: Furo's content column at the 16 px root font (46em), in CSS px.
CONTENT_WIDTH_PX = 736.0
#: The share of the column a table may not use: room for system fonts wider than Arial.
MARGIN = 0.05
#: The widest table's min-content width, in CSS px.
BUDGET_PX = CONTENT_WIDTH_PX * (1 - MARGIN)

#: Body text in CSS px (Furo: 100 % of the 16 px root).
TEXT_PX = 16.0
#: Inline code in CSS px (Furo: ``--font-size--small--2``, 81.25 %).
CODE_PX = 13.0
#: Liberation Mono's advance width, in em: every character.
CODE_EM = 1229 / 2048
#: ``code.literal``'s horizontal padding at each end, in em of the code font.
CODE_PADDING_EM = 0.2
#: ``p code.literal``'s border at each end, in CSS px.
CODE_BORDER_PX = 1.0
#: A cell's horizontal padding (0.25rem a side) and its paragraph's margin (0.25rem a side).
CELL_PX = 16.0
#: The collapsed border between two columns.
BORDER_PX = 1.0
#: Units per em of Liberation Sans's advance widths below.
UNITS_PER_EM = 2048

#: Liberation Sans Regular 2.1's advance widths (fontTools, ``hmtx``): width -> characters.
_REGULAR = {
    391: "'",
    455: "ijl’",
    532: "|",
    569: " !,./:;I[\\]ft·",
    682: "()-`r“”²³",
    684: "{}",
    727: '"',
    797: "*",
    809: "τ",
    819: "°",
    961: "^",
    1024: "Jcksvxyz",
    1124: "≤≥±≈√",
    1139: "#$0123456789?L_abdeghnopqu–θ",
    1180: "µ",
    1196: "+<=>~×",
    1251: "FTZ",
    1264: "σ",
    1366: "&ABEKPSVXY",
    1413: "π",
    1460: "∞",
    1479: "CDHNRUw",
    1593: "GOQ",
    1599: "ω",
    1706: "Mm",
    1708: "½",
    1821: "%",
    1933: "W",
    2048: "—→…",
    2079: "@",
}
#: Liberation Sans Bold 2.1's advance widths, as above (table headers).
_BOLD = {
    487: "'",
    569: " ,./I\\ijl·’",
    573: "|",
    682: "!()-:;[]`ft²³",
    797: "*r{}",
    819: "°",
    914: "τ",
    971: '"',
    1024: "z“”",
    1107: "θ",
    1124: "≤≥±≈√",
    1139: "#$0123456789J_aceksvxy–",
    1180: "µ",
    1196: "+<=>^~×",
    1251: "?FLTZbdghnopqu",
    1366: "EPSVXY",
    1401: "σ",
    1460: "∞",
    1479: "&ABCDHKNRU",
    1568: "π",
    1593: "GOQw",
    1706: "M",
    1708: "½",
    1730: "ω",
    1821: "%m",
    1933: "W",
    1997: "@",
    2048: "—→…",
}
#: A character neither table has: as wide as the widest capital, to err on the wide side.
_OTHER = 1706


def _per_character(groups: dict[int, str]) -> dict[str, float]:
    return {c: width / UNITS_PER_EM for width, chars in groups.items() for c in chars}


REGULAR_EM = _per_character(_REGULAR)
BOLD_EM = _per_character(_BOLD)

TEXT, BOLD, CODE = "text", "bold", "code"


def char_px(char: str, style: str) -> float:
    """One character's advance width in CSS px, in a style (text, bold or code)."""
    if style == CODE:
        return CODE_EM * CODE_PX
    table = BOLD_EM if style == BOLD else REGULAR_EM
    return table.get(char, _OTHER / UNITS_PER_EM) * TEXT_PX


# --- Markdown: the tables of a page and what a cell shows ----------------------------------------

#: Characters after which Chromium breaks a line (measured with a probe page): hyphens and
#: dashes, and a question mark before a letter. A slash, an underscore, a dot or a bracket does
#: not break: a path or a dotted key is one piece.
BREAK_AFTER = frozenset("-–—?")
#: Characters before which it breaks too (an em dash).
BREAK_BEFORE = frozenset("—")

_FENCE = re.compile(r"^(`{3,}|:{3,})")
_INCLUDE = re.compile(r"^```\{include\}\s+(\S+)\s*$")
_DELIMITER = re.compile(r"^\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?\s*$")


@dataclass
class Table:
    """One Markdown table of a page."""

    page: str
    header: list[str]
    rows: list[list[str]]

    @property
    def width(self) -> float:
        """The estimated min-content width in CSS px."""
        return table_min_width(self.header, self.rows)

    def describe(self) -> str:
        """The page and the table's header, for a message."""
        return f"{self.page}: table [{' | '.join(self.header)[:80]}]"


def split_cells(line: str) -> list[str]:
    """A table row's cells: split at pipes that are not escaped (``\\|``)."""
    line = line.strip()
    line = line.removeprefix("|")
    if line.endswith("|") and not line.endswith("\\|"):
        line = line[:-1]
    return [cell.strip() for cell in re.split(r"(?<!\\)\|", line)]


def expand_includes(markdown: str, folder: Path) -> str:
    """A page's source with its ``{include}`` fragments in their place."""
    lines = markdown.splitlines()
    out: list[str] = []
    index = 0
    while index < len(lines):
        match = _INCLUDE.match(lines[index])
        if match:
            included = folder / match.group(1)
            out += expand_includes(included.read_text(encoding="utf-8"), included.parent).split(
                "\n"
            )
            index += 1
            while index < len(lines) and lines[index].strip() != "```":
                index += 1
            index += 1
            continue
        out.append(lines[index])
        index += 1
    return "\n".join(out)


def tables(markdown: str, page: str = "") -> list[Table]:
    """Every pipe table of a page's Markdown (outside fenced blocks)."""
    found: list[Table] = []
    lines = markdown.splitlines()
    fence: str | None = None
    index = 0
    while index < len(lines):
        line = lines[index]
        opening = _FENCE.match(line.strip())
        if fence is not None:
            if opening and line.strip().startswith(fence) and line.strip() == fence:
                fence = None
            index += 1
            continue
        if opening:
            fence = opening.group(1)
            index += 1
            continue
        if (
            line.lstrip().startswith("|")
            and index + 1 < len(lines)
            and _DELIMITER.match(lines[index + 1].strip())
        ):
            header = split_cells(line)
            rows = []
            index += 2
            while index < len(lines) and lines[index].lstrip().startswith("|"):
                rows.append(split_cells(lines[index]))
                index += 1
            found.append(Table(page, header, rows))
            continue
        index += 1
    return found


def runs(cell: str, style: str = TEXT) -> Iterator[tuple[str, str]]:
    """What a cell shows, as (text, style) runs: code spans as code, ``**`` as bold, links
    and roles as their text, escapes as the character they escape."""
    index = 0
    bold = style == BOLD
    while index < len(cell):
        rest = cell[index:]
        role = re.match(r"\{[\w:-]+\}(`+)", rest)
        if role:
            fence = role.group(1)
            end = rest.find(fence, role.end())
            content = rest[role.end() : end]
            shown = re.match(r"^(.*?)\s*<[^>]+>$", content)
            yield (shown.group(1) if shown else content, BOLD if bold else TEXT)
            index += end + len(fence)
            continue
        ticks = re.match(r"`+", rest)
        if ticks:
            fence = ticks.group(0)
            end = rest.find(fence, len(fence))
            if end < 0:
                yield (fence, BOLD if bold else TEXT)
                index += len(fence)
                continue
            content = rest[len(fence) : end]
            if content.startswith(" ") and content.endswith(" ") and content.strip():
                content = content[1:-1]
            yield ("\0", CODE)  # a code element's start: its padding
            yield (content, CODE)
            yield ("\0", CODE)
            index += end + len(fence)
            continue
        link = re.match(r"!?\[((?:[^\[\]]|\[[^\]]*\])*)\]\(([^)]*)\)", rest)
        if link:
            if not rest.startswith("!"):
                yield from runs(link.group(1), BOLD if bold else TEXT)
            index += link.end()
            continue
        if rest.startswith("**"):
            bold = not bold
            index += 2
            continue
        if rest.startswith("\\") and len(rest) > 1:
            yield (rest[1], BOLD if bold else TEXT)
            index += 2
            continue
        if rest[0] in "*_" and (index == 0 or not cell[index - 1].isalnum()):
            index += 1  # emphasis: italic is about as wide as regular
            continue
        yield (rest[0], BOLD if bold else TEXT)
        index += 1


def cell_min_width(cell: str, style: str = TEXT) -> float:
    """The widest piece of a cell that cannot be broken (no space in it), in CSS px."""
    widest = 0.0
    word = 0.0
    for text, run_style in runs(cell, style):
        for char in text:
            if char == "\0":
                word += CODE_PADDING_EM * CODE_PX + CODE_BORDER_PX
            elif char.isspace() and char != "\u00a0":
                widest = max(widest, word)
                word = 0.0
            else:
                if char in BREAK_BEFORE:
                    widest, word = max(widest, word), 0.0
                word += char_px(char, run_style)
                if char in BREAK_AFTER:
                    widest, word = max(widest, word), 0.0
    return max(widest, word)


def table_min_width(header: list[str], rows: list[list[str]]) -> float:
    """A table's min-content width in CSS px: its columns' widest unbreakable pieces, with
    each cell's padding and the borders between the columns."""
    columns = max(len(header), *(len(row) for row in rows)) if rows else len(header)
    widths = [0.0] * columns
    for row, style in [(header, BOLD), *((row, TEXT) for row in rows)]:
        for index, cell in enumerate(row[:columns]):
            widths[index] = max(widths[index], cell_min_width(cell, style))
    return sum(w + CELL_PX for w in widths) + BORDER_PX * (columns - 1)


def column_groups(
    header: Sequence[str], rows: Sequence[Sequence[str]], keep: int = 1, budget: float | None = None
) -> list[list[int]]:
    """The columns of a table too wide for ``budget`` (default :data:`BUDGET_PX`) as the fewest
    even groups that fit: each group the first ``keep`` columns (the policy, say, repeated in
    each part) and a run of the others. A table that fits is one group; a column too wide on its
    own still gets a group of its own."""
    limit = BUDGET_PX if budget is None else budget
    columns = len(header)
    widths = [0.0] * columns
    for row, style in [(header, BOLD), *((row, TEXT) for row in rows)]:
        for index, cell in enumerate(row[:columns]):
            widths[index] = max(widths[index], cell_min_width(cell, style))
    kept = sum(w + CELL_PX + BORDER_PX for w in widths[:keep])
    rest = list(range(keep, columns))
    for parts in range(1, len(rest) + 1):
        size = -(-len(rest) // parts)
        groups = [rest[i : i + size] for i in range(0, len(rest), size)]
        if all(kept + sum(widths[i] + CELL_PX + BORDER_PX for i in g) <= limit for g in groups):
            break
    return [[*range(keep), *group] for group in groups]


def split_table(header: Sequence[str], rows: Sequence[Sequence[str]], keep: int = 1) -> list[str]:
    """A table as the fewest Markdown tables that fit the page (:func:`column_groups`), each
    repeating the first ``keep`` columns."""
    from khepera_gym.analysis.docgen.markdown import table

    return [
        table([header[i] for i in group], ([row[i] for i in group] for row in rows))
        for group in column_groups(header, rows, keep)
    ]


def page_tables(docs: Path) -> dict[str, list[Table]]:
    """Every page's tables, by the page's path under docs/ (fragments under their page)."""
    pages = sorted(docs.glob("*.md")) + sorted((docs / "generated" / "envs").glob("*.md"))
    found = {}
    for path in pages:
        name = str(path.relative_to(docs))
        text = expand_includes(path.read_text(encoding="utf-8"), path.parent)
        found[name] = tables(text, name)
    return found


__all__ = [
    "BUDGET_PX",
    "CONTENT_WIDTH_PX",
    "MARGIN",
    "Table",
    "cell_min_width",
    "column_groups",
    "page_tables",
    "split_table",
    "table_min_width",
    "tables",
]
