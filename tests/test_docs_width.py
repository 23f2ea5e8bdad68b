"""Every table of the documentation fits the page's content column: a width budget.

Every Markdown table of the pages (docs/*.md with their ``{include}`` fragments, the generated
results tables among them, and the generated env pages) is estimated by
:mod:`khepera_gym.analysis.docgen.width`: its min-content width from the fonts' metrics and
Furo's CSS, against Furo's 46em (736 px) content column less a 5 % margin for wider system
fonts. That module states how its constants were derived (Liberation Sans and Mono's advance
widths, Furo's paddings and borders) and their calibration against headless Chromium
(docs/tools/check_table_widths.py --estimate: 0.986 to 1.064 times the browser's width over the
345 tables measured). The browser check itself is docs tooling: CI has no Chromium.
"""

from __future__ import annotations

import shutil
from fnmatch import fnmatch
from pathlib import Path

import pytest

from khepera_gym.analysis.docgen.width import (
    BOLD,
    BUDGET_PX,
    CELL_PX,
    CONTENT_WIDTH_PX,
    MARGIN,
    Table,
    cell_min_width,
    page_tables,
    tables,
)

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


# --- the pages -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """docs/ with its generated pages written into a copy: the Markdown Sphinx reads."""
    from khepera_gym.analysis.docgen import write_all

    docs = tmp_path_factory.mktemp("docs")
    for path in DOCS.glob("*.md"):
        shutil.copy(path, docs / path.name)
    shutil.copytree(DOCS / "images", docs / "images")
    shutil.copytree(DOCS / "results", docs / "results")
    write_all(docs)
    return docs


def test_the_estimate_flags_a_table_too_wide_and_passes_a_narrow_one() -> None:
    # A path breaks at no hyphen or space: one piece of 84 characters of code at 7.8 px,
    # wider than the column on its own.
    command = "`sb3:runs/pathfollow_v3/seed_0/checkpoints/best_model_after_500000_steps_of_ppo.zip`"
    wide = tables(
        "| env | run |\n|---|---|\n| `KheperaIV-PathFollow-v3` | " + command + " |\n",
        "synthetic.md",
    )[0]
    assert wide.width > CONTENT_WIDTH_PX
    (message,) = _over([wide])
    assert message.startswith("synthetic.md: table [env | run]: ")
    assert f"against {BUDGET_PX:.0f} px" in message
    # Chromium breaks after a hyphen: a command's widest piece is its longest word.
    hyphens = cell_min_width("`khepera-gym benchmark --tasks pathfollow`")
    assert hyphens == pytest.approx(cell_min_width("`x pathfollow`"))
    narrow = tables(
        "| env | run |\n|---|---|\n| `KheperaIV-PathFollow-v3` | the run's command below |\n",
        "synthetic.md",
    )[0]
    assert narrow.width < BUDGET_PX / 2
    # Text breaks at spaces: a long sentence adds lines, not width.
    prose = tables("| a |\n|---|\n| " + "a few words " * 50 + "|\n", "s.md")[0]
    assert prose.width < 100
    # Twelve columns of "mean [low, high]" cells: each column is as wide as its widest piece.
    many = tables(
        "| "
        + " | ".join(f"metric {i}" for i in range(12))
        + " |\n|"
        + "---|" * 12
        + "\n| "
        + " | ".join(["100.0 [98.1, 100.0]"] * 12)
        + " |\n",
        "s.md",
    )[0]
    assert many.width == pytest.approx(
        12 * (max(cell_min_width("metric 10", BOLD), cell_min_width("[98.1,")) + CELL_PX) + 11
    )


def test_the_estimate_reads_code_links_roles_escapes_and_bold() -> None:
    assert cell_min_width("`abc`") == pytest.approx(3 * 7.8 + 2 * (2.6 + 1), rel=1e-3)
    assert cell_min_width("[`abc`](x.md#a-long-anchor)") == cell_min_width("`abc`")
    assert cell_min_width("{ref}`abc <a-long-label>`") == cell_min_width("abc")
    assert cell_min_width("x\\|y") == pytest.approx(cell_min_width("x|y"))
    assert cell_min_width("**mm**") == cell_min_width("mm", BOLD) > cell_min_width("mm")
    # A word glued to a code span is one piece.
    assert cell_min_width("(`swarm` scene)") > cell_min_width("`swarm`")


#: The results pages: their tables are made from data (docs/results/), and the width budget
#: holds for every one (issue 52: a 15,000 px table whose right columns were cut off).
RESULTS_PAGES = ("results.md", "history.md")

#: Pages (glob patterns) whose tables were over the budget before issue 52's change and are
#: outside it (it reshaped the results tables only), with where the table comes from. The test
#: below fails when one of them fits, so that the list only shrinks, and when any other page's
#: table is over.
KNOWN_OVER = {
    "dynamics.md": "the version-changes table (docgen/reference.py): long keys and values",
    "drive.md": "the hand-written table of the programs' modes",
    "robot.md": "the hand-written IR calibration table, 15 distances wide",
    "reliability.md": "the hand-written table of hostile inputs",
    "sim-to-real.md": "the hand-written identification table",
    "multi-agent.md": "the PettingZoo module table (docgen/envs.py)",
    "generated/envs/*.md": "every env page's scenario key tables (docgen/envs.py): long keys",
}


def _over(found: list[Table]) -> list[str]:
    return [
        f"{table.describe()}: {table.width:.0f} px against {BUDGET_PX:.0f} px "
        f"({CONTENT_WIDTH_PX:.0f} px column less {MARGIN:.0%})"
        for table in found
        if table.width > BUDGET_PX
    ]


def test_every_results_table_fits_the_content_column(built: Path) -> None:
    pages = page_tables(built)
    found = [table for page in RESULTS_PAGES for table in pages[page]]
    for fragment in sorted((built / "generated").glob("results-*.md")):
        found += tables(fragment.read_text(encoding="utf-8"), f"generated/{fragment.name}")
    assert len(found) > 50, "the results pages' tables were not found"
    over = _over(found)
    assert not over, "results tables wider than the page's content column:\n" + "\n".join(over)


def test_no_other_table_is_over_the_budget_but_the_known_ones(built: Path) -> None:
    pages = page_tables(built)
    over = {
        page: _over(found)
        for page, found in pages.items()
        if page not in RESULTS_PAGES and _over(found)
    }
    known = {page: next((p for p in KNOWN_OVER if fnmatch(page, p)), None) for page in pages}
    new = [line for page, lines in over.items() if known[page] is None for line in lines]
    assert not new, "tables wider than the page's content column:\n" + "\n".join(new)
    fixed = sorted(set(KNOWN_OVER) - {known[page] for page in over})
    assert not fixed, f"these pages' tables fit now: take them off KNOWN_OVER: {fixed}"
