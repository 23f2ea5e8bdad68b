"""PettingZoo environments: one agent per controlled Khepera IV robot, over the same Rust core.

* :mod:`khepera_gym.pettingzoo.formation_v0`: followers holding a formation around a leader
  (agents ``follower_0``.., plus ``leader`` with ``leader="agent"``);
* :mod:`khepera_gym.pettingzoo.multinav_v0`: robots driving to their own goals
  (agents ``robot_0``..).

Each module has ``parallel_env(**kwargs)`` (a ``pettingzoo.ParallelEnv``) and ``env(**kwargs)``
(its AEC version). Requires ``pettingzoo`` (a dependency of khepera_gym).
"""

from __future__ import annotations

from khepera_gym.pettingzoo import formation_v0, multinav_v0

__all__ = ["formation_v0", "multinav_v0"]
