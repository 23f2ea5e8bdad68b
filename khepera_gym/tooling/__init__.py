"""What every tool of khepera_gym stands on, below the tool families and above the env library.

* :mod:`~khepera_gym.tooling.arguments`: the checks of a command's arguments and the one-line
  errors of ``khepera-gym`` (never a traceback for a user's mistake);
* :mod:`~khepera_gym.tooling.provenance`: the date, commit, machine and command that every
  results file carries;
* :mod:`~khepera_gym.tooling.stats`: the intervals of the tables (bootstrap, Wilson).

It imports the env library only; the tool families (:mod:`khepera_gym.learning`,
:mod:`khepera_gym.analysis`, :mod:`khepera_gym.robot`) import it.
"""
