"""``drone_follow_v1``: the quadcopter of the KH4VREP paper's Fig. 8 following a Khepera IV, as a
PettingZoo env with one agent, ``drone``, or two with ``driver="agent"``: ``drone`` and
``robot``, the Khepera driven by an agent along its route (Nav's observation and reward toward
its current waypoint). The task, its observations, rewards and keys are
:class:`khepera_gym.envs.DroneFollowEnv`'s (its manual); by default the Khepera drives its route
scripted.
Units are SI (m, s, rad); world frame x right, y up::

    from khepera_gym.pettingzoo import drone_follow_v1

    env = drone_follow_v1.parallel_env()
"""

from __future__ import annotations

from typing import Any, ClassVar

from pettingzoo import AECEnv
from pettingzoo.utils.conversions import parallel_to_aec

from khepera_gym.pettingzoo._parallel import AgentAction, AgentObs, KheperaParallelEnv


class DroneFollowParallelEnv(KheperaParallelEnv):
    """DroneFollow as a PettingZoo ``ParallelEnv``: agent ``drone`` (its action the normalised
    horizontal acceleration command; `agent_robot("drone")` is 1, the task's vehicle after the
    one robot: its position is ``targets()``), and with ``driver="agent"`` agent ``robot`` (the
    Khepera, robot 0: a wheel command). Arguments as :class:`KheperaParallelEnv`."""

    metadata: ClassVar[dict[str, Any]] = {
        **KheperaParallelEnv.metadata,
        "name": "drone_follow_v1",
    }
    TASK: ClassVar[str] = "dronefollow"
    VERSION: ClassVar[int | None] = 1


def parallel_env(**kwargs: Any) -> DroneFollowParallelEnv:
    """DroneFollow as a PettingZoo ``ParallelEnv``; see :class:`DroneFollowParallelEnv`."""
    return DroneFollowParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv[str, AgentObs, AgentAction]:
    """DroneFollow as a PettingZoo AEC env; takes the arguments of :func:`parallel_env`."""
    return parallel_to_aec(parallel_env(**kwargs))


__all__ = ["DroneFollowParallelEnv", "env", "parallel_env"]
