"""khepera_gym: a fast, reproducible simulator of the K-Team Khepera IV robot as Gymnasium envs.

Importing the package registers the environments with Gymnasium::

    import gymnasium as gym
    import khepera_gym

    env = gym.make("KheperaIV-Nav")                      # one world, the latest version
    envs = gym.make_vec("KheperaIV-Nav", num_envs=1024)  # native Rust batch

An unversioned id picks the latest behaviour version, with Gymnasium's note that it did so; pin
one (``"KheperaIV-Nav-v<n>"``) in anything you publish. The registered ids are made from the
task list the Rust core exports (:mod:`khepera_gym.registration`):

``KheperaIV-<Task>-v<n>`` for every task the core exports with a Gymnasium id and every
behaviour version it exists in, each with its single env (:mod:`khepera_gym.envs`) and its native
vector env (:mod:`khepera_gym.vector`); ``khepera-gym list`` prints them, and
:func:`khepera_gym.registration.registered_ids` returns them. The multi-agent (PettingZoo) envs
are the ``*_vN`` modules of :mod:`khepera_gym.pettingzoo`.

Discovery: :func:`default_config` gives a task's scenario keys with their defaults and comments,
:func:`scenes` the built-in scenes that ``config=`` takes.

No ``max_episode_steps`` is registered: the Rust core truncates episodes itself at the scenario's
``max_steps``. ``gym.make(id, max_episode_steps=k)`` still adds Gymnasium's ``TimeLimit`` wrapper
on top; to change the episode length of the simulator itself pass ``max_steps=k``.
"""

from __future__ import annotations

import os

from khepera_gym import _core, _moved, errors
from khepera_gym.observations import obs_layout
from khepera_gym.registration import register_envs
from khepera_gym.registry import default_config, scenes

#: Real-robot speed units (``kh4_set_speed``, 0.678181 mm/s each) to and from m/s.
speed_to_units = _core.speed_to_units
units_to_speed = _core.units_to_speed

__version__: str = _core.__version__

#: The vector path of the hot kernels (``portable``, ``avx2``, ``avx512``): the widest this CPU
#: has, or the one named by the environment variable ``KHEPERA_GYM_SIMD`` (a ConfigError here if
#: the CPU lacks it). Every path gives the same results bit for bit; only the speed differs.
simd_path = _core.simd_path
if os.environ.get("KHEPERA_GYM_SIMD"):
    _core.force_simd(os.environ["KHEPERA_GYM_SIMD"])


def motor_presets() -> dict[str, dict[str, str]]:
    """The named drives of ``motors.preset`` (``gym.make(id, preset="kteam_default")``): name →
    the ``[motors]`` keys it sets (TOML) and who sets it on the real robot."""
    return {
        name: {"settings": settings, "source": " ".join(source.split())}
        for name, settings, source in _core.motor_presets()
    }


register_envs()
# The modules that moved to the layered folders in 0.2.0 keep their old paths (with a warning).
_moved.install()

__all__ = [
    "__version__",
    "default_config",
    "errors",
    "motor_presets",
    "obs_layout",
    "scenes",
    "simd_path",
    "speed_to_units",
    "units_to_speed",
]
