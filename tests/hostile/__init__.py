"""Hostile-input fuzzing of every public entry point, each case in a subprocess with a memory
limit (issue 36): scenario keys of every registered task from the domains the core declares
(floors and curves included), as keywords and as TOML files; the vector envs', PettingZoo
wrappers' and array envs' arguments; seeds, reset options, ``scene(i)``, saved states and
actions.

* :mod:`.schema` reads each task's keys and domains from ``default_config`` and draws values
  for them: inside, on and just beyond their bounds, NaN, infinities, huge numbers, wrong types
  and lengths;
* :mod:`.cases` draws one case (a JSON-able dict) from a seed and an index, reproducibly;
* :mod:`.execute` runs a case in this process and says what happened: an env that built,
  stepped with finite rewards and observations inside its space, or a typed error
  (``KheperaError`` subclasses, ``MemoryError``), or a failure (any other exception, a
  non-finite reward, an observation outside the space);
* :mod:`.campaign` runs many cases, each in a process forked from a worker that imported
  khepera_gym once, under an address-space limit and a timeout, so that an abort, a crash or a
  hang is caught and reported with the case that caused it.

One command runs a campaign and prints (and with ``--json``, writes) its counts::

    python -m tests.hostile --cases 100000 --json hostile-report.json

``tests/test_hostile.py`` runs a sample in CI; ``--replay SEED:INDEX`` reruns one case.
"""
