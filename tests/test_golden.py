"""Every registered env replays its recorded seeded trajectory bit for bit (tests/golden.py).

The cases come from the registries (every Gymnasium id, single and vector, every PettingZoo
module, the swarm scene split both ways), so a new env is covered without touching this file,
and a test fails until its digest is recorded. A digest changes only with an intended change of
behaviour, which comes with a new env version (the old versions' digests stay as they are).
"""

from __future__ import annotations

import pytest
from golden import cases, load

RECORDED = load()
CASES = dict(cases())


@pytest.mark.filterwarnings("ignore:.*is out of date:DeprecationWarning")
@pytest.mark.parametrize("name", sorted(CASES))
def test_seeded_trajectory_matches_its_golden_digest(name: str) -> None:
    assert name in RECORDED, (
        f"no golden digest for {name}: record it with `python tests/golden.py --write --only "
        f"'{name}'` once its behaviour is the intended one"
    )
    assert CASES[name]() == RECORDED[name], (
        f"{name} no longer replays its recorded trajectory bit for bit"
    )


def test_every_recorded_digest_still_has_its_env() -> None:
    # A digest whose env was unregistered would otherwise go unnoticed.
    assert sorted(set(RECORDED) - set(CASES)) == []
