"""Vision baselines for KheperaIV-Seek: steering by the camera's scanline
(docs/task-design.md §6.3), and VFH on the pillar the camera sees. Units: m, m/s, rad/s; robot
frame x forward, y left."""

from __future__ import annotations

from typing import ClassVar

from khepera_gym.baselines.base import BaselinePolicy


class BlobServo(BaselinePolicy):
    r"""Colour-blob servoing: turn toward the target-coloured pixels, slow as they fill the view.

    With the blob's centroid :math:`\bar x \in [-1, 1]` (positive to the right) and its width
    :math:`w` (share of the scanline): :math:`\omega = -k\,\omega_{max}\,\bar x`,
    :math:`v = v_{max}(1 - |\bar x|)(1 - w/w^*)`; with nothing in view it turns in place at
    ``search`` · ω_max. Braitenberg avoidance (eqs. 5-7) is added while the blob is narrower
    than w*/2. A pixel matches when each channel is within ``tolerance`` of ``target``.
    """

    CONTROLLER: ClassVar[str] = "blob_servo"


class BlobVFH(BaselinePolicy):
    r"""The Vector Field Histogram (paper eqs. 8-11, with VFH+'s enlargement and direction choice,
    as :class:`khepera_gym.baselines.VFH`) driving to the pillar the camera sees, its histogram
    built from the IR ring and the camera's depth.

    The target pixels (each channel within ``tolerance`` of ``target``) give the pillar's
    bearing (the middle of the blob) and its distance (the nearest target pixel's depth, from the
    camera ``camera_ahead`` in front of the centre, plus ``pillar_radius``); the robot drives to
    the point ``standoff`` short of its centre. Every other pixel is a range reading (a sector
    keeps the nearest surface its pixels show, within ``range_window`` of the rim), the IR ring
    adds its proximities (but for the sensors within ``target_cone`` of a pillar in IR range),
    and both are enlarged by ``robot_radius`` + ``safety_distance``. The camera sees the thin
    walls the IR ring's eight rays miss. With no target pixel in view it explores toward the
    farthest surface the camera shows. Needs the camera's depth (``sensors.camera_depth =
    true``, Seek's default). Reaches about 80% of Seek's targets among 10 obstacles (200 seeds,
    measured on v2), every one in an empty arena.
    """

    CONTROLLER: ClassVar[str] = "blob_vfh"
