"""Saving and restoring an env's simulation state, and pickling envs.

Every env of khepera_gym (single, vector, SB3 VecEnv, PettingZoo) runs on a ``_core.Batch``. The
batch's state (robot poses and velocities, wheel encoders, the rapier contact state, each world's
ChaCha8 random stream, step counters, goals, formation and episode bookkeeping, the obstacles of
the episode) is saved as ``bytes`` by the Rust core: restoring it and replaying the same actions
reproduces the trajectory bit for bit. The batch pickles as its resolved scenario plus that state,
so the envs holding it pickle too (``copy.deepcopy``, ``multiprocessing``, SB3's and Gymnasium's
subprocess vector envs).
"""

from __future__ import annotations

from typing import Any


class StateMixin:
    """``get_state``/``set_state`` for an env that owns a ``_core.Batch`` in ``self._batch``."""

    _batch: Any
    _has_reset: bool

    def get_state(self) -> bytes:
        """The simulation state of every world, as bytes (picklable, writable to a file).

        It holds the robots' poses, velocities and encoders, the physics' contact state, each
        world's random stream, step counters, goals and task state, and the last observations.
        Restoring it with :meth:`set_state` and replaying the same actions reproduces the
        trajectory bit for bit.
        """
        return self._batch.get_state()

    def set_state(self, state: bytes) -> None:
        """Restores a state from :meth:`get_state` of an env of the same task, scenario and
        number of worlds (in this process or another).

        Raises:
            StateError: ``state`` is not a state, is corrupt, or was saved from another env
                (the message says which); the env is then unchanged.
        """
        self._batch.set_state(state)
        self._has_reset = True


__all__ = ["StateMixin"]
