"""Single-world Gymnasium environments over the Rust core, and heuristic policies that solve them.

:class:`NavEnv` (drive to a goal), :class:`AvoidEnv` (the same among random obstacles) and
:class:`FormationEnv` (followers holding a formation around a leader) share :class:`KheperaEnv`
(:mod:`khepera_gym.envs.base`); each task's module holds its manual (the class docstring) and its
heuristic: :func:`nav_heuristic`, :func:`avoid_heuristic` and :func:`formation_heuristic`, thin
wrappers of the paper's controllers in :mod:`khepera_gym.baselines` (computed in Rust).

A new task adds a module here with its env class (``TASK`` = the Rust task's name) and imports it
below; registration with Gymnasium comes from the task list the Rust core exports.
"""

from khepera_gym.config import ACTION_TYPES
from khepera_gym.envs.base import ENV_CLASSES, KheperaEnv
from khepera_gym.envs.drone import DroneFollowEnv, dronefollow_heuristic
from khepera_gym.envs.formation import (
    FormationEnv,
    formation_follower_heuristic,
    formation_heuristic,
)
from khepera_gym.envs.linefollow import LineFollowEnv, linefollow_heuristic
from khepera_gym.envs.nav import (
    BRAITENBERG_WEIGHTS,
    AvoidEnv,
    NavEnv,
    avoid_heuristic,
    nav_heuristic,
)
from khepera_gym.envs.pathfollow import PathFollowEnv, pathfollow_heuristic
from khepera_gym.envs.seek import SeekEnv, seek_heuristic
from khepera_gym.envs.track import TrackEnv, track_heuristic

# The manuals' examples live in the task modules: doctest.testmod(khepera_gym.envs) runs them.
__test__ = {
    "NavEnv": NavEnv,
    "AvoidEnv": AvoidEnv,
    "FormationEnv": FormationEnv,
    "TrackEnv": TrackEnv,
    "PathFollowEnv": PathFollowEnv,
    "DroneFollowEnv": DroneFollowEnv,
    "LineFollowEnv": LineFollowEnv,
    "SeekEnv": SeekEnv,
}

__all__ = [
    "ACTION_TYPES",
    "BRAITENBERG_WEIGHTS",
    "ENV_CLASSES",
    "AvoidEnv",
    "DroneFollowEnv",
    "FormationEnv",
    "KheperaEnv",
    "LineFollowEnv",
    "NavEnv",
    "PathFollowEnv",
    "SeekEnv",
    "TrackEnv",
    "avoid_heuristic",
    "dronefollow_heuristic",
    "formation_follower_heuristic",
    "formation_heuristic",
    "linefollow_heuristic",
    "nav_heuristic",
    "pathfollow_heuristic",
    "seek_heuristic",
    "track_heuristic",
]
