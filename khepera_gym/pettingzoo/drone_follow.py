"""The ``drone_follow_vN`` modules (one a behaviour version, the same env on that version's
dynamics): the quadcopter of the KH4VREP paper's Fig. 8 following a Khepera IV, as a
PettingZoo env with one agent, ``drone``, or two with ``driver="agent"``: ``drone`` and
``robot``, the Khepera driven by an agent along its route (Nav's observation and reward toward
its current waypoint). The task, its observations, rewards and keys are
:class:`khepera_gym.envs.DroneFollowEnv`'s (its manual); by default the Khepera drives its route
scripted.
Units are SI (m, s, rad); world frame x right, y up::

    from khepera_gym.pettingzoo import drone_follow_v3

    env = drone_follow_v3.parallel_env()
"""

from __future__ import annotations

from typing import ClassVar

from khepera_gym.pettingzoo._parallel import KheperaParallelEnv


class DroneFollowParallelEnv(KheperaParallelEnv):
    """DroneFollow as a PettingZoo ``ParallelEnv``: agent ``drone`` (its action the normalised
    horizontal acceleration command; `agent_robot("drone")` is 1, the task's vehicle after the
    one robot: its position is ``targets()``), and with ``driver="agent"`` agent ``robot`` (the
    Khepera, robot 0: a wheel command). Arguments as :class:`KheperaParallelEnv`."""

    TASK: ClassVar[str] = "dronefollow"
    FAMILY: ClassVar[str] = "drone_follow"


__all__ = ["DroneFollowParallelEnv"]
