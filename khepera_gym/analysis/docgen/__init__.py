"""The documentation's generated reference: pages and tables written from the registries and
from the results data at docs build time (``make docs``; docs/conf.py calls :func:`write_all`).

Everything a reader needs to list is generated here rather than copied by hand: the env table
and one page per env (:mod:`khepera_gym.analysis.docgen.envs`), the scenes, sensors, baselines and
policies (:mod:`khepera_gym.analysis.docgen.reference`), and the results tables from the JSON files
in docs/results/ (:mod:`khepera_gym.analysis.docgen.results`; the side-by-side run beside
VMAS and NumPy: :mod:`khepera_gym.analysis.docgen.peers`). The output goes to docs/generated/,
which is not kept in git. ``python -m khepera_gym.analysis.docgen [DOCS_DIR]`` writes it without
Sphinx, and
``python -m khepera_gym.analysis.docgen --readme`` refreshes the README's env table.

This is a tool of the repository, not part of the package's API.
"""

from __future__ import annotations

import shutil
from pathlib import Path

#: The folder under docs/ that the generator owns (emptied and rewritten on every build).
GENERATED = "generated"


def write_all(docs_dir: str | Path) -> list[Path]:
    """Writes every generated page and fragment under ``docs_dir/generated``; returns the files.

    Args:
        docs_dir: The Sphinx source folder (docs/), whose images/ and results/ are read.
    """
    from khepera_gym.analysis.docgen import envs, reference, results

    docs = Path(docs_dir)
    out = docs / GENERATED
    if out.exists():
        shutil.rmtree(out)
    (out / "envs").mkdir(parents=True)
    written: list[Path] = []

    def write(relative: str, text: str) -> None:
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        written.append(path)

    pages = envs.env_pages()
    for page in pages:
        write(f"envs/{page.slug}.md", envs.env_page(page, pages, docs))
    write("env-table.md", envs.env_table(pages, prefix=f"{GENERATED}/envs/") + "\n")
    for name, text in reference.fragments().items():
        write(f"{name}.md", text)
    for name, text in results.fragments(docs / "results").items():
        write(f"results-{name}.md", text)
    from khepera_gym.analysis.docgen.benchmark_reliable import reliable_fragment, tune_fragment

    benchmark = reliable_fragment(
        docs / "results" / "benchmark", out / "benchmark", f"{GENERATED}/benchmark"
    )
    write("results-benchmark-reliable.md", benchmark + "\n")
    write("results-tune.md", tune_fragment(docs / "results" / "tune") + "\n")
    from khepera_gym.analysis.docgen.peers import PEERS_DIR, peers_fragment

    write("results-peers.md", peers_fragment(docs / "results" / PEERS_DIR) + "\n")
    from khepera_gym.analysis.docgen.simd import SIMD_DIR, simd_fragment

    write("results-simd.md", simd_fragment(docs / "results" / SIMD_DIR) + "\n")
    return written


def readme_env_table() -> str:
    """The README's table of every env: its id and PettingZoo modules (from which version),
    what it is, and a link to its docs page (``docs/generated/envs/<task>.md``, which
    :func:`write_all` writes at every docs build)."""
    from khepera_gym.analysis.docgen.envs import baselines, env_pages
    from khepera_gym.analysis.docgen.markdown import code, escape_cell, table

    rows = []
    for page in env_pages():
        source = f"docs/{GENERATED}/envs/{page.slug}.md"
        # Version-free, so that a new version leaves the README as it is: the id without its
        # version (the latest) and the module family, with the task's first version.
        names = [code(page.ids[0].rsplit("-v", 1)[0])] if page.ids else []
        names += [code(f"{family}_vN") for family in dict.fromkeys(m.family for m in page.modules)]
        first = (page.ids or [m.name for m in page.modules])[0].rsplit("v", 1)[1]
        rows.append(
            [
                f"[{page.title}]({source})",
                ", ".join(names) + f" (v{first} to the latest)",
                escape_cell(page.summary),
                ", ".join(code(cls.__name__) for cls in baselines(page.task)) or "–",
            ]
        )
    return table(["Env (its page)", "Id and PettingZoo modules", "What", "Baselines"], rows)


__all__ = ["GENERATED", "readme_env_table", "write_all"]
