"""Measures every table of the built documentation in a real headless browser: does it fit the
page's content column, with nothing cut off and no horizontal scroll?

Docs tooling, not a test: CI has no browser. It needs Debian's ``chromium`` and
``chromium-driver`` and Selenium (``pip install selenium`` in a throwaway venv; ``playwright
install`` cannot download browsers here). Run it on a build (``make docs`` or ``sphinx -b html
docs OUT``)::

    python docs/tools/check_table_widths.py OUT [--widths 1400 1000 800] [--json widths.json]

For each page with a table and each window width (CSS px), it prints the content column's
width (the article's), and for each table its wrapper's ``clientWidth`` and ``scrollWidth``
(Furo wraps a table in a ``.table-wrapper`` with ``overflow-x: auto``: ``scrollWidth >
clientWidth`` is a table the reader must scroll, or that is cut off), the table's laid-out width,
and its min-content and max-content widths (the table set to ``width: min-content`` /
``max-content`` for the measurement, then restored). The min-content widths are what
khepera_gym.analysis.docgen.width estimates from the Markdown (tests/test_docs_width.py's budget);
``--json`` writes them, and ``--estimate docs`` prints the estimate of every table against them
(its calibration).
Exits 1 if a table overflows at a width of at least ``--fit-from`` px (default 800: below 48em
Furo's content column is the window less its margins, and a wide table scrolls in its wrapper by
design).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import sys
from pathlib import Path
from typing import Any

from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service

#: Reads, for every table of the page, what the report prints (all in CSS px).
MEASURE = """
const article = document.querySelector('article[role=main]') || document.body;
const content = article.getBoundingClientRect().width;
const tables = [];
for (const table of article.querySelectorAll('table')) {
  const wrapper = table.closest('.table-wrapper') || table.parentElement;
  const header = Array.from(table.querySelectorAll('thead th')).map(th => th.innerText.trim());
  const first = table.querySelector('tbody tr');
  const saved = table.style.width;
  table.style.width = 'min-content';
  const minContent = table.getBoundingClientRect().width;
  table.style.width = 'max-content';
  const maxContent = table.getBoundingClientRect().width;
  table.style.width = saved;
  let heading = '';
  for (let node = table; node && !heading; node = node.parentElement) {
    const section = node.closest('section');
    if (!section) break;
    const h = section.querySelector(':scope > h1, :scope > h2, :scope > h3, :scope > h4');
    heading = h ? h.innerText.replace('#', '').trim() : '';
  }
  tables.push({
    heading: heading,
    header: header.join(' | '),
    first_row: first ? first.innerText.replace(/\\s+/g, ' ').slice(0, 60) : '',
    client: wrapper.clientWidth,
    scroll: wrapper.scrollWidth,
    wrapper_content: wrapper.clientWidth
      - parseFloat(getComputedStyle(wrapper).paddingLeft)
      - parseFloat(getComputedStyle(wrapper).paddingRight),
    width: table.getBoundingClientRect().width,
    min_content: minContent,
    max_content: maxContent,
    height: table.getBoundingClientRect().height,
  });
}
const root = getComputedStyle(document.documentElement);
return {content: content, root_font: parseFloat(root.fontSize),
        text_font: getComputedStyle(article).fontFamily, tables: tables};
"""


def driver(binary: str, chromedriver: str) -> webdriver.Chrome:
    """A headless Chromium."""
    options = Options()
    options.binary_location = binary
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"):
        options.add_argument(argument)
    return webdriver.Chrome(options=options, service=Service(chromedriver))


def set_viewport(browser: webdriver.Chrome, width: int) -> None:
    """The window's layout viewport ``width`` CSS px wide (what a media query sees)."""
    browser.execute_cdp_cmd(
        "Emulation.setDeviceMetricsOverride",
        {"width": width, "height": 900, "deviceScaleFactor": 1, "mobile": False},
    )


def main() -> int:
    """Measures the build's tables; prints a report, exits 1 on an overflow."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("html", type=Path, help="the built site (sphinx -b html's output)")
    parser.add_argument("--widths", type=int, nargs="+", default=[1400, 1000, 800, 600])
    parser.add_argument("--fit-from", type=int, default=800)
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument(
        "--estimate",
        type=Path,
        default=None,
        metavar="DOCS",
        help="compare the width budget's estimates (of the Sphinx source DOCS) with the "
        "browser's min-content widths at the first window width",
    )
    args = parser.parse_args()
    pages = sorted(
        path
        for path in args.html.rglob("*.html")
        if "<table" in path.read_text(encoding="utf-8")
        and not path.name.startswith(("genindex", "search"))
    )
    browser = driver(args.chromium, args.chromedriver)
    report: dict[str, dict[str, object]] = {}
    overflowing = 0
    try:
        for width in args.widths:
            set_viewport(browser, width)
            for page in pages:
                browser.get(page.resolve().as_uri())
                found = browser.execute_script(MEASURE)
                name = str(page.relative_to(args.html))
                report.setdefault(name, {})[str(width)] = found
                for table in found["tables"]:
                    over = table["scroll"] > table["client"]
                    if over and width >= args.fit_from:
                        overflowing += 1
                    if over or width == args.widths[0]:
                        print(
                            f"{'OVER' if over else 'ok  '} {width:>5} px {name} "
                            f"(column {found['content']:.0f}): "
                            f"[{table['header'][:50]}] scroll {table['scroll']} / client "
                            f"{table['client']}, min-content {table['min_content']:.0f}, "
                            f"height {table['height']:.0f}"
                        )
            measured = [t for r in report.values() for t in r[str(width)]["tables"]]
            print(
                f"-- {width} px: {len(measured)} tables on {len(pages)} pages, "
                f"{sum(t['scroll'] > t['client'] for t in measured)} overflow, the widest "
                f"min-content {max(t['min_content'] for t in measured):.0f} px"
            )
    finally:
        browser.quit()
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    if args.estimate is not None:
        calibrate(report, args.estimate, str(args.widths[0]))
    return 1 if overflowing else 0


def calibrate(report: dict[str, dict[str, Any]], docs: Path, width: str) -> None:
    """Prints the width budget's estimate of every table against the browser's min-content
    width (``docs``: the Sphinx source the build read, its generated/ included)."""
    # The module alone (standard library only), so that this venv needs no khepera_gym.
    path = Path(__file__).resolve().parents[2] / "khepera_gym" / "analysis" / "docgen" / "width.py"
    spec = importlib.util.spec_from_file_location("width", path)
    assert spec is not None and spec.loader is not None
    width_module = importlib.util.module_from_spec(spec)
    sys.modules["width"] = width_module  # dataclasses look their module up
    spec.loader.exec_module(width_module)
    page_tables = width_module.page_tables

    ratios = []
    for page, found in page_tables(docs).items():
        measured = report.get(page[: -len(".md")] + ".html", {}).get(width, {}).get("tables")
        if not found:
            continue
        if measured is None or len(measured) != len(found):
            print(f"not compared: {page} ({len(found)} tables in the Markdown)")
            continue
        for table, browser in zip(found, measured, strict=True):
            ratios.append((table.width / browser["min_content"], table.describe()))
    ratios.sort()
    print(
        f"estimate / browser over {len(ratios)} tables: median "
        f"{statistics.median(r for r, _ in ratios):.3f}, from {ratios[0][0]:.3f} "
        f"({ratios[0][1]}) to {ratios[-1][0]:.3f} ({ratios[-1][1]})"
    )


if __name__ == "__main__":
    sys.exit(main())
