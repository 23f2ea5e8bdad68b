"""Vision baselines for KheperaIV-Seek: steering by the camera's scanline
(docs/task-design.md §6.3). Units: m/s, rad/s; robot frame x forward, y left."""

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
