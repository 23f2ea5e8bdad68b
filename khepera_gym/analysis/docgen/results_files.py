"""Reading the results files in docs/results/: every file of a folder (:func:`load`), what
kind of results it holds (:func:`kind`, read from its content), and where its figures come from
as a page says it (:func:`provenance_line`, with the recorded command as a user types it,
:func:`as_typed`). Every results section of the documentation reads its files through these.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from khepera_gym.analysis.docgen.markdown import code
from khepera_gym.tooling.provenance import portable_command


def load(results_dir: Path) -> list[tuple[Path, dict[str, Any]]]:
    """Every results file of the folder, by name."""
    if not results_dir.is_dir():
        return []
    return [
        (path, json.loads(path.read_text(encoding="utf-8")))
        for path in sorted(results_dir.glob("*.json"))
    ]


def kind(document: Any) -> str:
    """``"compare"``, ``"consensus"``, ``"train"``, ``"learning"`` (a learned formation, from
    ``examples/formation_shared_ppo.py --json``), ``"bench"``, ``"hostile"`` (a hostile-input
    campaign, ``python tests/hostile_campaign.py --json``) or ``"unknown"``."""
    if not isinstance(document, dict):
        return "unknown"
    if "summaries" in document:
        return "compare"
    if "algo" in document and "final" in document:
        return "train"
    if isinstance(document.get("formation_learning"), dict):
        return "learning"
    rows = document.get("rows")
    if isinstance(rows, list) and rows and "trigger" in rows[0]:
        return "consensus"
    if isinstance(rows, list) and "swarm" in document:
        return "bench"
    if isinstance(document.get("by_kind"), dict) and "failures" in document:
        return "hostile"
    return "unknown"


#: The package's command line run from a source tree (``python <tree>/khepera_gym/cli.py``, or
#: ``python -m khepera_gym.cli``): a user types it ``khepera-gym``.
_CLI = re.compile(r"^python3? (?:\S*/)?khepera_gym/cli\.py\b|^python3? -m khepera_gym\.cli\b")
#: A script of the repository run by its absolute path: a user types it from the checkout.
_SCRIPT = re.compile(r"^(python3?) \S*/((?:examples|tests)/\S+\.py)\b")
#: The checkout the documentation is built from.
_CHECKOUT = Path(__file__).resolve().parents[3]
#: A module of the package run by its file's path: a user types ``python -m`` and its name.
_MODULE = re.compile(r"^(python3?) \S*/khepera_gym/(\S+)\.py\b")


def as_typed(command: str) -> str:
    """A recorded command as a user types it in a checkout: ``khepera-gym train ...`` for the
    package's command line however it was started, ``python examples/x.py ...`` for a script,
    ``python -m khepera_gym.<module>`` for a module of the package; paths of the machine that
    ran it are made relative to the checkout or cut to their names
    (:func:`khepera_gym.tooling.provenance.portable_command`)."""
    command = _CLI.sub("khepera-gym", command)
    command = _SCRIPT.sub(r"\1 \2", command)
    command = _MODULE.sub(lambda m: f"{m[1]} -m khepera_gym.{m[2].replace('/', '.')}", command)
    return portable_command(command, _CHECKOUT / "docs")


def provenance_line(meta: dict[str, Any] | None) -> str:
    """Where a table's figures come from, in one sentence."""
    if not meta:
        return "*Provenance not recorded.*"
    commit = meta.get("commit")
    if commit:
        where = f"commit `{commit['id'][:10]}`" + (" with local changes" if commit["dirty"] else "")
    else:
        where = f"khepera_gym {meta.get('khepera_gym', '?')}"
    machine = meta.get("machine") or {}
    load_average = machine.get("load_average")
    load_text = f", load average {load_average[0]}" if load_average else ""
    return (
        f"Measured {meta.get('date', '?')[:10]} at {where} on {machine.get('cpu', '?')} "
        f"({machine.get('cpus', '?')} CPUs{load_text}): {code(as_typed(meta.get('command', '?')))}."
    )


__all__ = ["as_typed", "kind", "load", "provenance_line"]
