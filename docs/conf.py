"""Sphinx configuration of the khepera_gym documentation (``make docs``).

The site is MyST Markdown with the Furo theme, as Gymnasium's and PettingZoo's. Reference pages
and results tables are generated from the code and from docs/results/ at every build
(:func:`khepera_gym.analysis.docgen.write_all`, into docs/generated/, which git ignores), so they cannot
drift from what the package does. The package is imported from the source tree, with the
extension `make develop` compiled into it.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import khepera_gym  # noqa: E402
from khepera_gym.analysis.docgen import write_all  # noqa: E402

project = "khepera_gym"
author = "the khepera_gym developers"
copyright = "the khepera_gym developers"  # noqa: A001
release = khepera_gym.__version__

extensions = ["myst_parser"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
# Headings get anchors (page.md#a-heading) down to ###.
myst_heading_anchors = 4
source_suffix = {".md": "markdown"}
root_doc = "index"
# Fragments under generated/ are included into pages, not pages of their own; results/ holds
# data (JSON) and its README.
exclude_patterns = ["_build", "generated/*.md", "results/*.md"]
# Every cross-reference must resolve (warnings are errors in `make docs`).
nitpicky = True

html_theme = "furo"
html_title = f"khepera_gym {release}"
html_static_path: list[str] = []


def _generate(app: object) -> None:
    """Writes docs/generated/ before Sphinx reads the sources."""
    write_all(Path(__file__).resolve().parent)


def setup(app: object) -> dict[str, bool]:
    """Generates the reference at the start of every build."""
    app.connect("builder-inited", _generate)  # type: ignore[attr-defined]
    return {"parallel_read_safe": True}
