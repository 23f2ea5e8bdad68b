"""The path-following baselines, on PathFollow observations (``cross_track_error``,
``path_heading_error``, ``curvature``, ``preview``, ``waypoint``, ``desired_speed``): Samson's
path follower, pure pursuit, and the paper's position control switching between waypoints."""

from __future__ import annotations

from typing import ClassVar

from khepera_gym.baselines.base import BaselinePolicy


class Samson(BaselinePolicy):
    r"""A Lyapunov path follower of Samson's type (C. Samson, ICARCV 1992; "rear-wheel feedback").

    At the desired speed :math:`v` (``desired_speed``), from the cross-track error :math:`d`
    (left of the path positive), the heading error :math:`\tilde\theta = \theta - \theta_p`
    (the observation's ``path_heading_error`` is :math:`\theta_p - \theta`) and the curvature
    :math:`\kappa` at the closest point:

    :math:`\omega = \frac{v \kappa \cos\tilde\theta}{1 - \kappa d} - k_\theta |v| \tilde\theta
    - k_d v d \frac{\sin\tilde\theta}{\tilde\theta}`.

    :math:`V = d^2 + \tilde\theta^2 / k_d` never grows (kinematic model); linearised,
    :math:`s^2 + k_\theta v s + k_d v^2 = 0`. The defaults (``kd`` = 44.4 m⁻², ``ktheta`` =
    9.33 m⁻¹) give :math:`\omega_n` = 1 rad/s, ζ = 0.7 at 0.15 m/s (docs/task-design.md §4).
    """

    CONTROLLER: ClassVar[str] = "samson"


class PurePursuit(BaselinePolicy):
    r"""Pure pursuit (R. C. Coulter, CMU-RI-TR-92-01, 1992).

    Steers on the arc through the robot and the goal point, the path point at distance
    :math:`L_d` (``lookahead``, 0.15 m [E]) from the robot, found on the polyline through the
    closest point and the ``preview`` points: with the goal at :math:`(x_g, y_g)` in the robot
    frame and :math:`l^2 = x_g^2 + y_g^2`, :math:`\omega = v \cdot 2 y_g / l^2` at the desired
    speed :math:`v`. On a circle it settles on the path; it cuts corners by about
    :math:`L_d`.
    """

    CONTROLLER: ClassVar[str] = "pure_pursuit"


class WaypointSwitching(BaselinePolicy):
    r"""The paper's position control (eqs. 1-4) driving to successive waypoints of the path.

    Its goal is the observation's ``waypoint``, which the task moves on to the next (every
    ``pathfollow.waypoint_spacing`` = 0.2 m of arc) once the robot is within
    ``pathfollow.waypoint_radius`` = 0.1 m of it, the way the paper's scripts chain targets:
    :math:`v = v_d` beyond :math:`k_r`, else :math:`d \, v_d / k_r`;
    :math:`\omega = \omega_{max} \sin(\alpha - \theta)`. It cuts inside the chords between
    waypoints (up to :math:`c^2 / 8R`, 1.9 cm on the 0.6 m circle) and slows near each one.
    """

    CONTROLLER: ClassVar[str] = "waypoint_switching"
