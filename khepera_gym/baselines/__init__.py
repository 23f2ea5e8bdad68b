"""The KH4VREP paper's classical controllers as baseline policies on observations.

Farias et al., "A Khepera IV library for robotic control education using V-REP" (IFAC 2017),
§3.3-3.5: :class:`PositionControl` (eqs. 1-4), :class:`Braitenberg` avoidance after it (eqs. 5-7,
Fig. 5), :class:`VFH` (eqs. 8-11) and :class:`LeaderFollower` formation control (eq. 12); for
trajectory tracking, :class:`Kanayama` (Kanayama et al. 1990) and :class:`PositionChase` (eqs.
1-4 chasing the moving reference); for path following, :class:`Samson` (Samson 1992),
:class:`PurePursuit` (Coulter 1992) and :class:`WaypointSwitching` (eqs. 1-4 toward successive
waypoints); for the quadcopter of Fig. 8, :class:`DronePursuit` (PD pursuit); for line
following, :class:`LineThreshold` (K-Team's demo) and :class:`LineProportional`; for the camera,
:class:`BlobServo` and :class:`BlobVFH` (VFH on the pillar the camera sees); for consensus with
messages, :class:`ConsensusLaw`. Each is a drop-in
policy for the environments created with ``action_type="wheels"``::

    from khepera_gym.baselines import Braitenberg

    policy = Braitenberg(weights="kteam")
    action = policy(obs)                          # one (18,) observation or a batch (N, 18)
    action, state = policy.predict(obs)           # stable-baselines3's signature

All the maths lives in the Rust core (src/controllers/, the code the scripted formation leader
runs inside the simulator), and so do the controllers' parameters: their names (as in the
papers), defaults, units and checks are declared once in Rust, and each class here takes them as
keywords (see ``help(Braitenberg)`` or ``inspect.signature``; :func:`parameters` lists them).
A policy reads the observation of its task's default scenario; for another (other sensors
observed), give ``layout=env.unwrapped.obs_layout()`` and it finds its blocks by name. Units:
metres, seconds, radians; robot frame x forward, y left, angles counter-clockwise. Actions are
normalised (left, right) wheel speeds in [-1, 1]: wheel speeds ``v ∓ ω · axle_length / 2``
divided by ``max_wheel_speed`` and clipped. In a world whose agents also set their LEDs
(``task.led_action``), :func:`with_leds` appends a colour to each agent's wheel values.

Adding a controller: a Rust file in src/controllers/ and a short class in a module of this
package (by domain: navigation, formation) that names it
(``CONTROLLER = "..."``) and says in its docstring what it does.

Threading and copies: a call copies the observations into Rust, releases the GIL while acting
and returns a fresh float32 array. Policies are immutable and hold no state between calls, so one
instance may serve several environments (``predict`` returns ``state`` unchanged).
"""

import functools

from khepera_gym import _core, registry
from khepera_gym.baselines.base import (
    BRAITENBERG_WEIGHT_SETS,
    FORMATION_SHAPES,
    KHEPERA_AXLE_LENGTH,
    KHEPERA_MAX_WHEEL_SPEED,
    BaselinePolicy,
    parameters,
    with_leds,
)
from khepera_gym.baselines.consensus import ConsensusLaw
from khepera_gym.baselines.formation import LeaderFollower, formation_offsets
from khepera_gym.baselines.lines import LineProportional, LineThreshold
from khepera_gym.baselines.navigation import VFH, Braitenberg, PositionControl, braitenberg_weights
from khepera_gym.baselines.paths import PurePursuit, Samson, WaypointSwitching
from khepera_gym.baselines.quadcopter import DronePursuit
from khepera_gym.baselines.tracking import Kanayama, PositionChase
from khepera_gym.baselines.vision import BlobServo, BlobVFH
from khepera_gym.errors import ConfigError


@functools.cache
def for_task(task: str) -> tuple[type[BaselinePolicy], ...]:
    """The baselines that act on an agent of ``task``'s default scenario: those whose
    controller finds every observation block it reads in the first agent's layout (the core
    decides), in the core's controller order. A new task gets the baselines that fit it without
    a list to update.

    Raises:
        ConfigError: ``task`` is not a task of the core.
    """
    from khepera_gym.observations import layout_dict

    order = list(registry.controllers())
    layout = layout_dict(_core.Batch(task, 1, num_threads=1).agents()[0][4])
    classes: list[type[BaselinePolicy]] = []
    pending = list(BaselinePolicy.__subclasses__())
    while pending:
        cls = pending.pop(0)
        pending += cls.__subclasses__()
        if not cls.CONTROLLER or cls in classes:
            continue
        try:
            cls(layout=layout)
        except ConfigError:
            continue
        classes.append(cls)
    return tuple(sorted(classes, key=lambda cls: order.index(cls.CONTROLLER)))


__all__ = [
    "BRAITENBERG_WEIGHT_SETS",
    "FORMATION_SHAPES",
    "KHEPERA_AXLE_LENGTH",
    "KHEPERA_MAX_WHEEL_SPEED",
    "VFH",
    "BaselinePolicy",
    "BlobServo",
    "BlobVFH",
    "Braitenberg",
    "ConsensusLaw",
    "DronePursuit",
    "Kanayama",
    "LeaderFollower",
    "LineProportional",
    "LineThreshold",
    "PositionChase",
    "PositionControl",
    "PurePursuit",
    "Samson",
    "WaypointSwitching",
    "braitenberg_weights",
    "for_task",
    "formation_offsets",
    "parameters",
    "with_leds",
]
