"""KheperaIV-LineFollow: follow a black line with the four ground sensors; and the heuristic that
solves it (K-Team's threshold line follower).

The manual is the class's docstring. Units are SI (m, s, rad); robot frame x forward, y left.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.baselines import LineThreshold
from khepera_gym.envs.base import KheperaEnv


class LineFollowEnv(KheperaEnv):
    r"""Follow a closed black line around one lap with the Khepera IV's ground sensors.

    ## Description

    Line following with the four ground IR sensors under the robot's front
    (docs/task-design.md §5.2), K-Team's classic demo. A black line `linefollow.width` = 2.7 cm
    wide (K-Team's demo needs at least that) is drawn on the white floor of the 2 m × 2 m
    arena along a closed curve (`linefollow.track`): `"circle"` (radius `linefollow.size` =
    0.6 m, a 3.77 m lap), `"lemniscate"` (a figure eight that crosses itself), `"spline"` (a
    random smooth closed curve per seed), `"square"` (sharp 90° corners: the hard case) or
    `"waypoints"` (a teacher's own line: the smooth closed curve through `linefollow.points`). The
    robot must lap it seeing only the floor under its sensors, its IR ring and its wheels.

    :func:`linefollow_heuristic` (K-Team's demo logic,
    :class:`khepera_gym.baselines.LineThreshold`) and
    :class:`khepera_gym.baselines.LineProportional` lap the circle, the figure eight and the
    splines; neither laps the square reliably.

    ## Action Space

    `Box(-1, 1, (2,), float32)`: normalised (left, right) wheel speeds, 1 = 0.813 m/s, as
    :class:`NavEnv`; `action_type="unicycle"` makes them a normalised (v, ω).

    ## Observation Space

    `Box(low, high, (14,), float32)`; `khepera_gym.obs_layout("linefollow")` names the slices.
    No pose, no goal, no offset from the line:

    | Index | Name         | Observation                                        | Min | Max |
    |-------|--------------|----------------------------------------------------|-----|-----|
    | 0-7   | ir           | IR proximity, K-Team order back-left ... back      | 0   | 1   |
    | 8-11  | ground       | ground sensors left, front-left, front-right,      | 0   | 1   |
    |       |              | right: raw / 1023 (white ≈ 0.93, black tape ≈ 0.29) |     |     |
    | 12-13 | wheel_speeds | left, right wheel speed / 0.813 m/s                | -1  | 1   |

    The ground sensors sit at (+20, ±58.5) and (+62, ±10) mm (docs/robot.md §4) and read
    black + (white − black) · g, g the floor's grey level (0 black .. 1 white) averaged over a
    3 mm spot, white `sensors.ground_white` = 954 (Webots at 4.5 mm), black
    `sensors.ground_black` = 300 [E], Gaussian noise of 4 counts; K-Team's demo takes < 800 as
    black. Raw counts: `env.unwrapped.sensor_readings()["ground_raw"]`.

    ## Rewards

    Every step: `linefollow.progress_weight` · Δs − `linefollow.error_weight` · |d|
    − `task.collision_penalty` · [contact], with Δs the progress (m) of the line's point closest
    to the robot's centre and d the centre's distance from the line (ground truth, used only
    here and in the statistics; docs/task-design.md §5.2).

    ## Starting State

    The line's direction of travel is drawn (`linefollow.direction`), a spline's shape too, and
    the start point uniformly along the line; the robot starts at rest on it, heading along
    it up to `linefollow.start_heading_offset` (10°) off, so that a front sensor starts over
    the line. All of it comes from the world's random stream: `reset(seed=s)` reproduces it.

    ## Episode End

    1. Termination (success): one lap along the line.
    2. Termination (lost, not a success): no ground sensor has read black for
       `linefollow.lost_time` (1 s) and the robot is more than `linefollow.lost_distance`
       (0.1 m) from the line.
    3. Truncation: `linefollow.truncation_factor` (2) × the lap time at
       `linefollow.reference_speed` (61 mm/s, the demo's speed; 124 s on the circle), or
       `task.max_steps` (4000) if sooner.

    `info["episode_stats"]` holds the common statistics (the lap time is `length` × 0.05 s of a
    successful episode) and `"line_offset_rms"` (m: RMS of d) and `"on_line_share"` (steps with
    a front ground sensor over black).

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-LineFollow", track="spline")
    >>> env.action_space.shape, env.observation_space.shape
    ((2,), (14,))
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.sensor_readings()["ground_raw"].shape
    (1, 4)
    >>> obs, reward, terminated, truncated, info = env.step(linefollow_heuristic(obs))

    ```

    The parameters are those of :class:`NavEnv`; the `[linefollow]` keys are overrides like
    any other. `env.unwrapped.goals()` is the line's point closest to the robot. Frames draw the
    floor (the line), the closest point and the ground sensors (red over black).

    ## Vectorized environment

    `gym.make_vec("KheperaIV-LineFollow", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.LineFollowVectorEnv` (world i reset with seed s ≡ this env reset
    with seed s + i).

    ```python
    >>> envs = gym.make_vec("KheperaIV-LineFollow", num_envs=4)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (4, 14)

    ```

    ## Robot model

    As :class:`NavEnv` (v1 dynamics).

    ## Sensors

    The robot carries the IR ring, the sonars, the gyroscope and the ground sensors; the
    observation holds the ring and the ground sensors. Any scenario may draw on its floor
    (`[floor]`: lines, arcs, polylines and a PNG image, :class:`NavEnv`'s Scenario file) and
    carry the ground sensors (`carry=[..., "ground"]`).

    ## Scenario file

    The keys of :class:`NavEnv` plus a `[linefollow]` table (the line's shape, size, width and grey,
    the start, when the robot is lost, the reward's weights, the reference speed); the robot carries
    the ground sensors and observes no pose. Every key, with its default in each version, its units,
    its comment and its source, is tabled on this env's page of the documentation (generated from
    the core's declarations by `make docs`); `khepera_gym.default_config("linefollow")` prints them
    as a TOML file.

    A size that leaves the arena, a width outside [5 mm, 20 cm], waypoints that are fewer than 4,
    not closed, closer than 1 mm or whose line leaves the arena, or a scenario that does not carry
    the ground sensors raise `khepera_gym.errors.ConfigError` naming the key.
    """

    TASK: ClassVar[str] = "linefollow"


#: The heuristic's controller, with its defaults (immutable and stateless: safe to share).
LINEFOLLOW_POLICY = LineThreshold()


def linefollow_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """K-Team's threshold line follower (the Khepera IV demo's logic) on a LineFollow observation.

    :class:`khepera_gym.baselines.LineThreshold` with its defaults (threshold 800, 61 mm/s on
    the line, ±34 mm/s toward it, 41 mm/s searching).

    Args:
        observation: One observation of shape (14,) or a batch (N, 14).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return LINEFOLLOW_POLICY(observation)


__all__ = ["LineFollowEnv", "linefollow_heuristic"]
