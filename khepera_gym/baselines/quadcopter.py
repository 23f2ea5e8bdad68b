"""The quadcopter's baseline for DroneFollow (docs/task-design.md §7). Units: metres, seconds,
radians; world frame (the drone holds its yaw)."""

from __future__ import annotations

from typing import ClassVar

from khepera_gym.baselines.base import BaselinePolicy


class DronePursuit(BaselinePolicy):
    r"""PD pursuit of the robot the drone's downward camera sees.

    With :math:`e` the robot's offset in metres (the camera's image coordinates times the
    footprint's radius :math:`z \tan(\mathrm{fov}/2)`) and :math:`\dot e` the observed relative
    velocity, the commanded acceleration is
    :math:`a = k_p e + k_d \dot e + c\, v_{drone}`, the last term cancelling the drag
    :math:`c = a_{max} / v_{max}`, so that :math:`\ddot e + k_d \dot e + k_p e = a_{robot}`.
    The defaults (``kp`` = 4 s⁻², ``kd`` = 4 s⁻¹) are critically damped, ω_n = 2 rad/s [E]: a
    robot at constant velocity is tracked with no steady error, one accelerating by
    :math:`a_{robot}` lags by :math:`a_{robot}/k_p`. Out of view it brakes to a hover while the
    autopilot climbs to search. The action is :math:`a / a_{max}`,
    :math:`a_{max} = g \tan(\mathrm{tilt\_max})`; ``fov``, ``tilt_max`` and ``speed_max`` must
    match the scenario's ``[drone]`` keys.
    """

    CONTROLLER: ClassVar[str] = "drone_pursuit"
