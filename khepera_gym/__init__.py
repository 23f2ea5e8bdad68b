"""khepera_gym: a fast, reproducible simulator of the K-Team Khepera IV robot as Gymnasium envs.

Importing the package registers the environments with Gymnasium::

    import gymnasium as gym
    import khepera_gym

    env = gym.make("KheperaIV-Nav-v1")                      # one world
    envs = gym.make_vec("KheperaIV-Nav-v1", num_envs=1024)  # native Rust batch

Registered ids (``gym.make("KheperaIV-Nav")`` picks the latest version, with Gymnasium's warning
that it did so), made from the task list the Rust core exports (:mod:`khepera_gym.registration`):

* ``KheperaIV-Nav-v1``: :class:`khepera_gym.envs.NavEnv`, vector env
  :class:`khepera_gym.vector.NavVectorEnv`;
* ``KheperaIV-Avoid-v1``: :class:`khepera_gym.envs.AvoidEnv`, vector env
  :class:`khepera_gym.vector.AvoidVectorEnv`;
* ``KheperaIV-Formation-v1``: :class:`khepera_gym.envs.FormationEnv`, vector env
  :class:`khepera_gym.vector.FormationVectorEnv`.

Multi-agent versions (PettingZoo) live in :mod:`khepera_gym.pettingzoo`: ``formation_v1`` (one
agent per follower), ``multinav_v1`` (several robots, each with its own goal) and ``platoon_v1``
(several robots tracking time-shifted copies of one reference trajectory).

No ``max_episode_steps`` is registered: the Rust core truncates episodes itself at the scenario's
``max_steps``. ``gym.make(id, max_episode_steps=k)`` still adds Gymnasium's ``TimeLimit`` wrapper
on top; to change the episode length of the simulator itself pass ``max_steps=k``.
"""

from __future__ import annotations

from khepera_gym import _core, errors
from khepera_gym.layout import obs_layout
from khepera_gym.registration import register_envs

#: Real-robot speed units (``kh4_set_speed``, 0.678181 mm/s each) to and from m/s.
speed_to_units = _core.speed_to_units
units_to_speed = _core.units_to_speed

__version__: str = _core.__version__


def motor_presets() -> dict[str, dict[str, str]]:
    """The named drives of ``motors.preset`` (``gym.make(id, preset="kteam_default")``): name →
    the ``[motors]`` keys it sets (TOML) and who sets it on the real robot."""
    return {
        name: {"settings": settings, "source": " ".join(source.split())}
        for name, settings, source in _core.motor_presets()
    }


register_envs()

__all__ = [
    "__version__",
    "errors",
    "motor_presets",
    "obs_layout",
    "speed_to_units",
    "units_to_speed",
]
