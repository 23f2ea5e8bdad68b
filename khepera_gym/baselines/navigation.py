"""The navigation baselines of the paper: position control (eqs. 1-4), Braitenberg avoidance after
it (eqs. 5-7, Fig. 5) and the Vector Field Histogram (eqs. 8-11), on Nav-like observations."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym import _core
from khepera_gym.baselines.base import BaselinePolicy
from khepera_gym.errors import ConfigError


class PositionControl(BaselinePolicy):
    r"""Position control (paper §3.3, eqs. 1-4, after Vilella et al. 2004): drive to the goal.

    From the goal distance and bearing of a Nav/Avoid observation (``goal_distance``,
    ``goal_bearing_sin``, ``goal_bearing_cos``):

    * eq. 1: :math:`d = \sqrt{(x_p - x_r)^2 + (y_p - y_r)^2}`, the observed ``goal_distance``;
    * eq. 2: :math:`\alpha - \theta`, the goal bearing in the robot frame;
    * eq. 3: :math:`v = v_{max}` if :math:`d > k_r`, else :math:`d \, v_{max} / k_r`;
    * eq. 4: :math:`\omega = \omega_{max} \sin(\alpha - \theta)`;

    and :math:`v = \omega = 0` once :math:`d` < ``stop_radius`` (the library stops at 0.05 m;
    the task succeeds within 0.05 m, so the default stops closer). Obstacles are ignored.
    """

    CONTROLLER: ClassVar[str] = "position_control"


def braitenberg_weights(
    weights: str | npt.ArrayLike = "default", smax: float = 1.0
) -> npt.NDArray[np.float64]:
    """The 2 × 8 weight matrix W of eq. 5 (m/s per unit proximity), divided by ``smax``.

    Args:
        weights: "default" (tuned on KheperaIV-Avoid), "kteam" (K-Team's
            ``braitenbergAvoidance`` demo converted to m/s) or a 2 × 8 array: row 0 the left
            wheel, row 1 the right; columns the IR sensors in K-Team order (back-left, left,
            front-left, front, front-right, right, back-right, back).
        smax: Full scale of the proximity (see :class:`Braitenberg`), > 0.

    Returns:
        A new float64 array of shape (2, 8).

    Raises:
        ValueError: Unknown name, not a finite 2 × 8 matrix, or ``smax`` not > 0.
    """
    if isinstance(weights, str):
        matrix = np.array(_core.braitenberg_weights(weights), dtype=np.float64)
    else:
        try:
            matrix = np.array(weights, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise ConfigError(f"weights must be a 2 x 8 numeric matrix, got {weights!r}") from error
        if matrix.shape != (2, 8) or not np.all(np.isfinite(matrix)):
            raise ConfigError(
                "weights must be a finite 2 x 8 matrix (rows left, right wheel; columns the IR "
                f"sensors in K-Team order), got shape {matrix.shape}"
            )
    smax = float(smax)
    if not (math.isfinite(smax) and smax > 0):
        raise ConfigError(f"smax must be a finite number > 0, got {smax}")
    return matrix / smax


class Braitenberg(BaselinePolicy):
    r"""Position control followed by Braitenberg avoidance (paper §3.4, eqs. 5-7, Fig. 5).

    The weight matrix W (eq. 5, 2 × 8) maps the IR ring S (eq. 6) to wheel speeds,
    :math:`v_{L,R} = W (1 - S / S_{max})` (eq. 7). Our IR observation already is that term:
    ``ir`` = :math:`p = 1 - S/S_{max}` in [0, 1] (0 nothing within 25 cm, 1 touching), the
    reading normalised by its full scale :math:`S_{max} = 1`. As in Fig. 5 the block sits after
    the control law: while every :math:`p_i` is below ``threshold`` the wheel speeds of
    :class:`PositionControl` pass unchanged; otherwise :math:`W p / s_{max}` is added to them,
    and :math:`(v', \omega')` follow from the differential drive. Within ``stop_radius`` of the
    goal the robot stops.

    ``smax`` rescales the proximity, :math:`p / s_{max}`: the sensors then count as saturated
    at :math:`p = s_{max}` instead of 1 (``smax`` = 1 is eq. 7 as written). It is implemented
    exactly by dividing the weights by ``smax``; ``threshold`` still applies to :math:`p`.
    ``weights="default"`` reaches about 97% of KheperaIV-Avoid goals; ``"kteam"`` (K-Team's
    ``braitenbergAvoidance`` demo converted to m/s per unit proximity) about 70%.
    """

    CONTROLLER: ClassVar[str] = "braitenberg"

    @property
    def effective_weights(self) -> npt.NDArray[np.float64]:
        """The weights of the Rust block: W / smax (m/s per unit proximity), shape (2, 8)."""
        return braitenberg_weights(self.params["weights"], self.params["smax"])


class VFH(BaselinePolicy):
    r"""Vector Field Histogram obstacle avoidance (paper §3.4, eqs. 8-11, after Ulrich and
    Borenstein 2000), with the obstacle enlargement and direction choice of VFH+ (Ulrich and
    Borenstein 1998).

    A polar histogram of ``sectors`` sectors is rebuilt at every step from the 8 IR proximities
    and the 5 ultrasonic readings. Each reading is an obstacle at its sensor's bearing and a
    distance :math:`d` from the rim (IR: K-Team's response curve inverted, with the observation's
    floor ``ir_floor_value``; ultrasonic: its range, a "too close" reading counting as an echo at
    the sensor's 25 cm minimum range, the IR ring covering what is nearer). It adds its magnitude
    (IR: its proximity; ultrasonic: :math:`1 - d / \text{us\_range}` for echoes closer than
    ``us_range``) to every sector within half its beam (``beam_width`` for the IR ring,
    ``us_beam_width`` for the sonars) plus VFH+'s enlargement
    :math:`\gamma = \arcsin\big(\min(1, (r_r + d_s) / (r_r + d))\big)` of its bearing, with
    :math:`r_r` = ``robot_radius`` and :math:`d_s` = ``safety_distance``: every direction whose
    straight path would pass within :math:`r_r + d_s` of the obstacle is blocked. The histogram
    is smoothed over neighbouring sectors; sectors under ``threshold`` are free.

    Each free valley at least ``min_valley`` wide offers VFH+'s candidate directions: a narrow
    valley's centre; in a wide one each edge ``min_valley / 2`` inside, and the goal bearing when
    it lies between them. The robot takes the candidate of least cost: angle to the goal +
    ``heading_weight`` × angle to straight ahead + ``previous_weight`` × angle to the previous
    direction (VFH+'s :math:`\mu_1 : \mu_2 : \mu_3` = 5 : 2 : 2), + ``switch_penalty`` rad for
    a candidate on the other side of its current turn. The controller is stateless: it reads the
    previous direction from its turn rate (the observation's wheel speeds), eq. 9 inverted. Boxed
    in, it turns in place. With :math:`\theta_e` the chosen direction and :math:`h'_c` the
    density in the sector straight ahead:

    * eq. 9: :math:`\omega = \omega_{max} \sin(\theta_e)` (full rate once the direction is
      behind);
    * eq. 11: :math:`h'_c = \min(h'_c, h_m)`;
    * eq. 10: :math:`v' = v_{max} (1 - h'_c / h_m)`;
    * eq. 8: :math:`v = v' (1 - |\omega| / \omega_{max})`;

    within ``kr`` of the goal :math:`v` is also capped by eq. 3's docking law, and the robot stops
    within ``stop_radius``. The histogram has no memory, so an obstacle that leaves every beam
    leaves the histogram and the robot turns back toward it: it zigzags, as the paper observed,
    and a thin wall whose end lies between two IR rays is not seen at all. IR beams narrower than
    the sensors' 45° spacing leave blind zones between them (the paper's explanation);
    ``beam_width = math.radians(10)`` shows that at its worst.

    The ultrasonic observation is read as distance / ``us_max_range`` (the scenario's
    ``sensors.us_max_range``, 2 m by default). docs/notes/controllers-v2.md gives the reasons
    for the enlargement and the measurements on v0, v1 and v2.
    """

    CONTROLLER: ClassVar[str] = "vfh"


__all__ = ["VFH", "Braitenberg", "PositionControl", "braitenberg_weights"]
