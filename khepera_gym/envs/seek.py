"""KheperaIV-Seek: find and reach a coloured pillar seen only through the camera; and the
heuristic for it (VFH on the pillar the camera sees).

The manual is the class's docstring. Units are SI (m, s, rad); robot frame x forward, y left.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.baselines import BlobVFH
from khepera_gym.envs.base import KheperaEnv


class SeekEnv(KheperaEnv):
    r"""Find a red pillar with the Khepera IV's colour camera and drive up to it.

    ## Description

    A camera task (docs/task-design.md §6.3): Avoid's 2 m × 2 m arena with 10 random
    grey obstacles, and one red pillar (radius `seek.pillar_radius` = 5 cm) standing on the goal,
    optionally with `seek.distractors` pillars of other colours. The goal's distance and bearing
    are not observed: only the IR ring, the camera's scanline and the wheel speeds.

    The camera (`sensors.camera_*`) is the Khepera IV's front colour camera as a scanline: 32
    pixels across its 131° field of view, from 60 mm ahead of the centre (Webots' mounting), each
    showing the colour (RGB in [0, 1]) and depth of the nearest surface its 4 rays meet within
    2 m: walls light grey (`arena.wall_color`), obstacles grey or their `color`, robots their
    LEDs' colour (`robot.led_color`), nothing black. :func:`seek_heuristic` (the Vector Field
    Histogram on the pillar the camera sees, :class:`khepera_gym.baselines.BlobVFH`) reaches the
    pillar in every episode of an empty arena and in about 80% of the cluttered ones on v2;
    colour-blob servoing (:class:`khepera_gym.baselines.BlobServo`) in about a third of those.

    ## Action Space

    `Box(-1, 1, (2,), float32)`: normalised (left, right) wheel speeds, as :class:`NavEnv`.

    ## Observation Space

    `Box(low, high, (138,), float32)`; `khepera_gym.obs_layout("seek")` names the slices:

    | Index   | Name         | Observation                                           | Min | Max |
    |---------|--------------|-------------------------------------------------------|-----|-----|
    | 0-7     | ir           | IR proximity, K-Team order back-left ... back         | 0   | 1   |
    | 8-135   | camera       | per pixel, left to right: r, g, b, depth / 2 m        | 0   | 1   |
    | 136-137 | wheel_speeds | left, right wheel speed / 0.813 m/s                   | -1  | 1   |

    `sensors.camera_pixels`, `sensors.camera_depth = false` (3 values per pixel) and the other
    camera keys change the block. Raw scanline: `env.unwrapped.sensor_readings()["camera_rgb"]`
    and `["camera_depth"]` (m).

    ## Rewards

    As :class:`NavEnv`'s, toward the pillar's centre: 10 · progress (m) − 0.01 per step + 10 on
    success − `task.collision_penalty` (0.5, as Avoid) per step in contact.

    ## Starting State

    As :class:`AvoidEnv`: a random start and goal at least 1 m apart, 10 random obstacles; the
    pillar stands on the goal, distractors where they clear the start, the goal and the
    obstacles. All of it comes from the world's random stream.

    ## Episode End

    1. Termination (success): the robot's centre within `task.goal_radius` = 0.1704 m of the
       pillar's, its rim 5 cm from the pillar's surface.
    2. Truncation: `task.max_steps` (600 steps, 30 s).

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-Seek", distractors=2)
    >>> env.observation_space.shape
    (138,)
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.sensor_readings()["camera_rgb"].shape
    (1, 96)
    >>> obs, reward, terminated, truncated, info = env.step(seek_heuristic(obs))

    ```

    The parameters are those of :class:`NavEnv`; the `[seek]` keys are overrides like any other.
    `env.unwrapped.goals()` is the pillar's centre. Frames draw the pillars in their colours and
    the camera's field of view (two orange lines).

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Seek", num_envs=N)` returns the native
    :class:`khepera_gym.vector.SeekVectorEnv`.

    ```python
    >>> envs = gym.make_vec("KheperaIV-Seek", num_envs=4)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (4, 138)

    ```

    ## Robot model

    As :class:`NavEnv` (v1 dynamics).

    ## Sensors

    The robot carries the IR ring, the sonars, the gyroscope and the camera; the observation
    holds the ring and the camera. Any scenario may carry the camera (`carry=[..., "camera"]`).

    ## Scenario file

    The keys of :class:`NavEnv` with Avoid's obstacles, the camera carried and observed (no goal
    bearing), plus a `[seek]` table (the pillar's radius and colour, distractors). Every key, with
    its default in each version, its units, its comment and its source, is tabled on this env's page
    of the documentation (generated from the core's declarations by `make docs`);
    `khepera_gym.default_config("seek")` prints them as a TOML file.

    A colour outside [0, 1] (`seek.pillar_color`, `arena.wall_color`, `robot.led_color`, an
    obstacle's `color`), a goal radius the robot could never reach, or a scenario that does not
    carry the camera raise `khepera_gym.errors.ConfigError` naming the key.
    """

    TASK: ClassVar[str] = "seek"


#: The heuristic's controller, with its defaults (immutable and stateless: safe to share).
SEEK_POLICY = BlobVFH()


def seek_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """The Vector Field Histogram toward the red pillar the camera sees.

    :class:`khepera_gym.baselines.BlobVFH` with its defaults: the pillar's bearing and distance
    from the red pixels and their depth, a polar histogram of obstacles from the IR ring and the
    other pixels' depth (enlarged by the robot's radius and a safety distance), the free
    direction nearest the pillar; with no red pixel in view, toward the farthest surface the
    camera shows. It replaces colour-blob servoing (:class:`khepera_gym.baselines.BlobServo`),
    which has no view of the thin walls its IR ring misses: about 80% of the targets among
    obstacles on v2 against its 31%.

    Args:
        observation: One observation of shape (138,) or a batch (N, 138).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return SEEK_POLICY(observation)


__all__ = ["SeekEnv", "seek_heuristic"]
