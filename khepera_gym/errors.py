"""Exceptions raised by khepera_gym, in Python and from the Rust core.

The Rust binding (src/python/) raises exactly these classes, so ``except ValueError`` catches every
input error and ``except KheperaError`` catches everything the simulator raises.
"""


class KheperaError(Exception):
    """Base class of every error raised by khepera_gym (including a caught Rust panic)."""


class ConfigError(KheperaError, ValueError):
    """A scenario file or keyword override is malformed (unknown key, wrong type, impossible
    value), or another argument of an env is (``num_envs``, ``action_type``, a seed).

    The message names the file (or "<built-in>"/"<override>") and the key, e.g.
    ``nav.toml: robot.radius: must be > 0, got -1``.
    """


class ActionError(KheperaError, ValueError):
    """An action is NaN/inf or has the wrong shape or dtype."""


class StateError(KheperaError, ValueError):
    """A saved state cannot be restored: it is not one, it is corrupt, or it was saved from
    another env (task, scenario or number of worlds); the message says which."""


__all__ = ["ActionError", "ConfigError", "KheperaError", "StateError"]
