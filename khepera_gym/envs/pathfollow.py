"""KheperaIV-PathFollow: path following, a closed path with no clock; and the heuristic that
solves it (Samson's path follower).

The manual is the class's docstring. Units are SI (m, s, rad); robot frame x forward, y left.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.baselines import Samson
from khepera_gym.envs.base import KheperaEnv


class PathFollowEnv(KheperaEnv):
    r"""Drive one lap along a closed path with a Khepera IV (path following).

    ## Description

    Path following, one of the control problems the KH4VREP paper (Farias et al., IFAC 2017)
    names in its abstract; definitions from docs/task-design.md §4. The path is a closed curve
    centred in the 2 m × 2 m walled arena, given by its geometry only: unlike
    :class:`TrackEnv`, no point moves along it in time, so the controller chooses its own
    timing, and the task asks for one lap at about the desired speed `pathfollow.speed`
    (0.15 m/s) without leaving the path. Paths (`pathfollow.path`): `"circle"` (radius
    `pathfollow.size` = 0.6 m, a 3.77 m lap), `"lemniscate"` (Gerono's figure eight, half-width
    `pathfollow.size`; it crosses itself at the centre, where the closest point keeps to its
    branch), `"square"` (half-side `pathfollow.size`; curvature 0 on the sides and 90° corners:
    the limit of smooth controllers), `"spline"` (a random smooth star-shaped closed curve drawn
    from the world's random stream, as Track's) or `"waypoints"` (the scenario's own,
    `pathfollow.points = [[x, y], ...]`, a closed loop joined by a smooth periodic curve). Every
    path is checked to stay inside the arena and, at the desired speed, to ask the wheels for
    at most `pathfollow.max_wheel_fraction` of their speed (a spline is smoothed until it
    does). With `pathfollow.obstacle_count` > 0, cylinders stand on or near the path, so
    avoidance matters.

    :func:`pathfollow_heuristic` (Samson's path follower, :class:`khepera_gym.baselines.Samson`)
    laps every built-in path; the README's PathFollow section compares it with pure pursuit and
    waypoint switching.

    ## Action Space

    `Box(-1, 1, (2,), float32)`: normalised (left, right) wheel speeds, 1 = 0.813 m/s, as
    :class:`NavEnv`; `action_type="unicycle"` makes them a normalised (v, ω).

    ## Observation Space

    `Box(low, high, (31,), float32)`; `khepera_gym.obs_layout("pathfollow")` names the slices.
    The closest path point p_c to the robot is tracked along the path (a local search from the
    last one). Errors and points are from the pose the robot believes it has
    (`task.localization`, as :class:`NavEnv`), in the robot frame (x forward, y left):

    | Index | Name               | Observation                                   | Min    | Max   |
    |-------|--------------------|-----------------------------------------------|--------|-------|
    | 0-7   | ir                 | IR proximity, K-Team order back-left ... back | 0      | 1     |
    | 8-12  | us                 | ultrasonic left, front-left, front,           | 0      | 1     |
    |       |                    | front-right, right                            |        |       |
    | 13    | cross_track_error  | d: signed distance from the path (m),         | -2.83  | 2.83  |
    |       |                    | positive when the robot is left of it         |        |       |
    | 14-15 | path_heading_error | sin, cos of θ_p - θ, θ_p the path's direction | -1     | 1     |
    |       |                    | of travel at p_c                              |        |       |
    | 16-19 | curvature          | κ at p_c and at the 3 preview points (1/m,    | -18.98 | 18.98 |
    |       |                    | left turns positive)                          |        |       |
    | 20-25 | preview            | x, y of the path points 0.1, 0.2, 0.3 m of    | -2.83  | 2.83  |
    |       |                    | arc ahead of p_c (m)                          |        |       |
    | 26-27 | waypoint           | x, y of the current waypoint (m)              | -2.83  | 2.83  |
    | 28    | desired_speed      | v_d / 0.813 m/s                               | 0      | 1     |
    | 29-30 | wheel_speeds       | left, right wheel speed / 0.813 m/s           | -1     | 1     |

    IR and ultrasonic as in :class:`NavEnv`. Curvature is clipped to ±2 / axle (18.98 m⁻¹, a
    turn about one wheel); the square's is 0 (its corners show in the preview). At a corner,
    `cross_track_error` is the distance to the corner and `path_heading_error` the direction
    of the arc around it. Waypoints lie every `pathfollow.waypoint_spacing` (0.2 m) of arc from
    the start; the block moves on to the next one once the robot is within
    `pathfollow.waypoint_radius` (0.1 m) of it or p_c has passed it (the way the paper's
    scripts chain position-control targets; :class:`khepera_gym.baselines.WaypointSwitching`
    drives to it). `preview` has 2 · `pathfollow.preview_points` values (none when 0), and
    `curvature` 1 + `pathfollow.preview_points`.

    ## Rewards

    Every step: `progress_weight · Δs - error_weight · |d| - time_penalty - speed_weight ·
    max(0, Δs/dt - v_d) / v_d`, with Δs the arc length p_c moved along the direction of travel
    during the step (m; negative backwards), d the cross-track error after it and v_d the desired
    speed (`pathfollow.progress_weight` = 10, `pathfollow.error_weight` = 1,
    `pathfollow.time_penalty` = 0.01, docs/task-design.md §4; `pathfollow.speed_weight` = 0.02
    [E]), minus `task.collision_penalty` (0.1) on every step that ends in contact. A lap is
    worth 10 · 3.77 = 37.7 on the circle whatever the speed; the time penalty favours fast laps
    and the speed term slow ones: with any `speed_weight` above `time_penalty` a lap costs least
    at v_d. The speed term is this project's (docs/task-design.md's reward pays progress at any
    speed). It costs only speeding: costing slowness too made standing still expensive, and PPO
    learned to get lost within 3 s instead. PPO (500k steps) still laps at about twice v_d: the
    term makes that cost 2.5 of a lap's 37.7, a gradient it does not follow in 1M steps.

    ## Starting State

    The direction of travel is drawn (`pathfollow.direction = "random"`; `"ccw"`, `"cw"` fix
    it), and the start point uniformly over the path (`pathfollow.random_start`). The robot
    starts at rest up to `pathfollow.start_offset` (0.1 m) to either side of it, with a heading
    up to `pathfollow.start_heading_offset` (45°) from the path's. Obstacles are spread over
    the lap ahead, one in the middle half of each equal share of it (0.3 m clear of the start
    either way), up to `pathfollow.obstacle_offset` from the path; one that would touch the
    robot at its start is drawn again, and left out after 8 draws. All of it comes from the
    world's random stream: `reset(seed=s)` reproduces it.

    ## Episode End

    1. Termination (success): p_c has travelled one lap along the path.
    2. Termination (lost, not a success): |d| > `pathfollow.lost_distance` (0.3 m).
    3. Termination: any contact, only if `task.terminate_on_collision = true`.
    4. Truncation: `pathfollow.truncation_factor` (2) times the lap time at the desired speed
       (the circle: 1006 steps), or `task.max_steps` (4000) if sooner.

    `info["is_success"]` is True after a lap. At the last step `info["episode_stats"]` holds the
    common statistics (`"return"`, `"length"`, `"success"`, `"path_length"`, `"collisions"`)
    and `"path_error_rms"`, `"path_error_max"` (m: the RMS and largest |d| after the first
    `pathfollow.transient` = 5 s; over the whole episode if it ended sooner), `"path_iae"`
    (m·s: Σ |d| dt) and `"path_converge_time"` (s: when |d| fell below
    `pathfollow.converge_radius` = 2 cm for good; inf if it is above at the end). The lap
    time is `length` × 0.05 s of a successful episode; the mean speed `path_length` over it.

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-PathFollow", path="lemniscate")
    >>> env.action_space.shape, env.observation_space.shape
    ((2,), (31,))
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.goals().shape, env.unwrapped.targets().shape  # waypoint; p_c + preview
    ((1, 2), (4, 2))
    >>> obs, reward, terminated, truncated, info = env.step(pathfollow_heuristic(obs))

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `action_type`,
    `**overrides`); the `[pathfollow]` keys are overrides like any other (`path="square"`,
    `speed=0.1`, `pathfollow={"direction": "ccw"}`). `env.unwrapped.goals()` is the current
    waypoint, shape (1, 2); `env.unwrapped.targets()` the closest path point and the preview
    points, (1 + K, 2), in the world frame. Frames draw the path, p_c, the preview and the
    waypoint.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-PathFollow", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.PathFollowVectorEnv` (NEXT_STEP autoreset or DISABLED with
    resets by mask, episode statistics with masks, world i reset with seed s ≡ this env reset
    with seed s + i).

    ```python
    >>> envs = gym.make_vec("KheperaIV-PathFollow", num_envs=4)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (4, 31)

    ```

    ## Robot model

    As :class:`NavEnv` (v1 dynamics: tyre grip, K-Team's speed profile of 0.203 m/s²; the robot
    starts at rest and reaches 0.15 m/s after 0.74 s).

    ## Sensors

    As :class:`NavEnv`: 8 IR and 5 ultrasonic sensors observed; the arena is empty unless
    `pathfollow.obstacle_count` > 0, so they see the walls and the obstacles.

    ## Scenario file

    The keys of :class:`NavEnv` plus a `[pathfollow]` table (the path, its size, the desired speed,
    the start offsets, the preview, the waypoints, the reward's weights, the statistics' transient
    and radius, obstacles on the path). Every key, with its default in each version, its units, its
    comment and its source, is tabled on this env's page of the documentation (generated from the
    core's declarations by `make docs`); `khepera_gym.default_config("pathfollow")` prints them as a
    TOML file.

    A path outside the arena (with the start offset or obstacles, the robot's radius and
    `spawn.wall_margin`) raises `khepera_gym.errors.ConfigError` naming `pathfollow.size`; one
    too sharp for the wheels at the desired speed names `pathfollow.speed` (for a scenario's
    own path, `pathfollow.points` names both, and also an open loop, repeated points, fewer
    than 4 points, or points given with another path); too many obstacles for the lap names
    `pathfollow.obstacle_count`; a preview or waypoint spacing longer than the path names its
    key.
    """

    TASK: ClassVar[str] = "pathfollow"


# --- heuristic policy: Samson's path follower of khepera_gym.baselines ---------------------------

#: The heuristic's controller, with its defaults (immutable and stateless: safe to share).
PATHFOLLOW_POLICY = Samson()


def pathfollow_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Samson's path follower (ICARCV 1992) on a PathFollow observation.

    :class:`khepera_gym.baselines.Samson` with its defaults (k_d = 44.4 m⁻², k_θ = 9.33 m⁻¹:
    ω_n = 1 rad/s, ζ = 0.7 at 0.15 m/s), at the observed desired speed.

    Args:
        observation: One observation of shape (31,) or a batch (N, 31).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return PATHFOLLOW_POLICY(observation)


__all__ = ["PathFollowEnv", "pathfollow_heuristic"]
