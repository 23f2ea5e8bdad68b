"""``python -m khepera_gym.analysis.docgen [DOCS_DIR]`` writes the generated pages without Sphinx;
``--readme`` rewrites the README's env table from the registries instead, and the generated
blocks of the README and docs/*.md (:mod:`khepera_gym.analysis.docgen.facts`), and ``--configs DIR``
writes every task's default scenario file (``configs/<task>.toml``) from the core (``make
configs``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from khepera_gym import _core, registry
from khepera_gym.analysis.docgen import facts, readme_env_table, write_all

#: The markers around the README's env table.
START, END = "<!-- env-table:start -->", "<!-- env-table:end -->"


def main() -> int:
    """Writes docs/generated/, or the README's env table with ``--readme``."""
    parser = argparse.ArgumentParser(prog="python -m khepera_gym.analysis.docgen")
    parser.add_argument("docs", nargs="?", type=Path, default=Path("docs"))
    parser.add_argument("--readme", type=Path, nargs="?", const=Path("README.md"), default=None)
    parser.add_argument("--configs", type=Path, default=None)
    args = parser.parse_args()
    if args.configs is not None:
        for task in registry.task_names():
            path = args.configs / f"{task}.toml"
            path.write_text(_core.default_config(task), encoding="utf-8")
            print(f"wrote {path}")
        return 0
    if args.readme is None:
        for path in write_all(args.docs):
            print(f"wrote {path}")
        return 0
    text = args.readme.read_text(encoding="utf-8")
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    args.readme.write_text(f"{head}{START}\n{readme_env_table()}\n{END}{tail}", encoding="utf-8")
    print(f"wrote the env table of {args.readme}")
    for path in facts.refresh(args.readme.resolve().parent):
        print(f"wrote the generated blocks of {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
