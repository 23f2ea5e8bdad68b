"""Runs the hostile-input campaign of ``tests/hostile`` (see that package's docstring):

    python tests/hostile_campaign.py --cases 100000 --json hostile-report.json
    python tests/hostile_campaign.py --replay 0:1234

A script rather than ``python -m tests.hostile``: some packages install a top-level ``tests``
package into site-packages (moviepy 1.0, a dependency at the declared floors, does), and a
package of that name anywhere on the path shadows this folder, which has no ``__init__.py``.
Run as a script, ``tests/`` is first on the path and ``hostile`` is found there; the
repository comes next, so ``khepera_gym`` is the source tree's, as under pytest.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(1, str(Path(__file__).resolve().parent.parent))

from hostile.__main__ import main  # after the path is set

if __name__ == "__main__":
    sys.exit(main())
