"""The trajectory-tracking baselines, on Track observations (``tracking_error``,
``heading_error``, ``reference_rates``): Kanayama's tracking controller, and the paper's
position control (eqs. 1-4) chasing the moving reference point."""

from __future__ import annotations

from typing import ClassVar

from khepera_gym.baselines.base import BaselinePolicy


class Kanayama(BaselinePolicy):
    r"""Kanayama's tracking controller (Kanayama, Kimura, Miyazaki & Noguchi, ICRA 1990).

    From the error posture in the robot frame (``tracking_error`` = :math:`(e_x, e_y)`,
    ``heading_error`` = :math:`(\sin e_\theta, \cos e_\theta)`) and the reference's
    feed-forward (``reference_rates`` = :math:`(v_r, \omega_r)`, normalised):

    * :math:`v = v_r \cos e_\theta + K_x e_x`;
    * :math:`\omega = \omega_r + v_r (K_y e_y + K_\theta \sin e_\theta)`.

    Linearised, the along-track error decays at rate :math:`K_x` and the cross-track loop is
    :math:`s^2 + v_r K_\theta s + v_r^2 K_y = 0`: :math:`\omega_n = v_r \sqrt{K_y}`, critically
    damped when :math:`K_y = K_\theta^2 / 4`. The defaults (``kx`` = 1 s⁻¹, ``ky`` = 44.4 m⁻²,
    ``ktheta`` = 13.3 m⁻¹) give :math:`\omega_n` = 1 rad/s, ζ = 1 at :math:`v_r` = 0.15 m/s
    (docs/task-design.md §3).
    """

    CONTROLLER: ClassVar[str] = "kanayama"


class PositionChase(BaselinePolicy):
    r"""The paper's position control (eqs. 1-4) chasing the moving reference point.

    :class:`khepera_gym.baselines.PositionControl`'s law with the reference point of a Track
    observation (``tracking_error``) as its goal: :math:`v = v_{max}` beyond :math:`k_r`, else
    :math:`d \, v_{max} / k_r`; :math:`\omega = \omega_{max} \sin(\alpha - \theta)`. It has no
    feed-forward, so it lags: holding the reference's speed :math:`v_r` inside :math:`k_r`
    needs a steady distance :math:`d = v_r k_r / v_{max}` (7.5 cm at 0.15 m/s with the defaults).
    """

    CONTROLLER: ClassVar[str] = "position_chase"
