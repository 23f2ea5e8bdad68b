"""Line followers for KheperaIV-LineFollow, on the four ground sensors (docs/task-design.md §5.2).
Units: raw ground counts (0..1023), m/s; robot frame x forward, y left."""

from __future__ import annotations

from typing import ClassVar

from khepera_gym.baselines.base import BaselinePolicy


class LineThreshold(BaselinePolicy):
    r"""K-Team's line follower: the logic of the Khepera IV's line-following demo.

    The two front ground sensors are read against ``threshold`` (800 raw counts: darker is
    black). Both over black: straight on at ``speed`` (90 units = 61 mm/s); one: turn toward it,
    the wheels at ``speed`` ∓ ``turn`` (50 units); neither: turn in place at ``search`` (60
    units) toward the side the line was last seen (the side the wheels last turned to).
    """

    CONTROLLER: ClassVar[str] = "line_threshold"


class LineProportional(BaselinePolicy):
    r"""A proportional follower on the front sensors' difference (Webots' e-puck example).

    :math:`v_{L,R} = \mathrm{speed} \mp \mathrm{gain}\,(g_R - g_L)`, with :math:`g` the raw
    counts of the front-right and front-left ground sensors; the default gain (2 · speed / 654
    per count) keeps the e-puck example's ratio of full differential to base speed.
    """

    CONTROLLER: ClassVar[str] = "line_proportional"
