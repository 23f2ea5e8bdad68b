"""KheperaIV-Track: trajectory tracking, a reference point moving on a closed curve in time; and
the heuristic that solves it (Kanayama's tracking controller).

The manual is the class's docstring. Units are SI (m, s, rad); robot frame x forward, y left.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.baselines import Kanayama
from khepera_gym.envs.base import KheperaEnv


class TrackEnv(KheperaEnv):
    r"""Track a reference point moving on a closed curve with a Khepera IV (trajectory tracking).

    ## Description

    Trajectory tracking, one of the control problems the KH4VREP paper (Farias et al., IFAC
    2017) names in its abstract; definitions from docs/task-design.md §3. A reference point moves
    on a closed curve centred in the 2 m × 2 m walled arena, once per period
    T = length / `track.speed`; the robot must be at the reference point p_r(t) at time t,
    heading along the curve (θ_r(t)). Curves (`track.reference`): `"circle"` (radius
    `track.size` = 0.6 m: v_r = 0.15 m/s, ω_r = 0.25 rad/s, T = 25.1 s), `"lemniscate"`
    (Gerono's figure eight, x = A sin φ, y = A sin φ cos φ, A = `track.size`), `"square"`
    (half-side `track.size`; at the corners the reference heading jumps by 90°, which no smooth
    controller follows: the limit of smooth controllers) and `"spline"` (a random smooth
    star-shaped closed curve, r(φ) = r₀ (1 + Σ_k a_k cos(kφ + ψ_k)), k = 2, 3, 4, drawn from the
    world's random stream, never beyond `track.size` from the centre), or `"waypoints"` (a
    scenario's own reference, `track.waypoints = [[t, x, y], ...]`: times strictly rising from
    0, the last point repeating the first at the period; joined by a periodic cubic Hermite
    curve in time with Catmull-Rom tangents, so v_r is continuous). Every reference is checked
    to stay inside the arena and to ask the wheels for at most `track.max_wheel_fraction` of
    their speed and `track.max_accel_fraction` of their acceleration limit (a spline is smoothed
    until it does). :func:`track_heuristic` (Kanayama's controller,
    :class:`khepera_gym.baselines.Kanayama`) converges below 2 cm within about 5 s.

    ## Action Space

    `Box(-1, 1, (2,), float32)`: normalised (left, right) wheel speeds, 1 = 0.813 m/s, as
    :class:`NavEnv`; `action_type="unicycle"` makes them a normalised (v, ω).

    ## Observation Space

    `Box(low, high, (29,), float32)`; `khepera_gym.obs_layout("track")` names the slices.
    Errors and points are in the robot frame (x forward, y left), from the pose the robot
    believes it has (`task.localization`, as :class:`NavEnv`):

    | Index | Name            | Observation                                        | Min   | Max  |
    |-------|-----------------|----------------------------------------------------|-------|------|
    | 0-7   | ir              | IR proximity, K-Team order back-left ... back      | 0     | 1    |
    | 8-12  | us              | ultrasonic left, front-left, front, front-right,   | 0     | 1    |
    |       |                 | right                                              |       |      |
    | 13-14 | tracking_error  | e_x, e_y: the reference point in the robot frame   | -2.83 | 2.83 |
    |       |                 | (m)                                                |       |      |
    | 15-16 | heading_error   | sin e_θ, cos e_θ with e_θ = θ_r - θ                | -1    | 1    |
    | 17-18 | reference_rates | feed-forward v_r / 0.813 m/s, ω_r / 15.4 rad/s     | -1    | 1    |
    | 19-26 | preview         | x, y of the next 4 reference points, every 0.25 s  | -2.83 | 2.83 |
    |       |                 | ahead, in the robot frame (m)                      |       |      |
    | 27-28 | wheel_speeds    | left, right wheel speed / 0.813 m/s                | -1    | 1    |

    IR and ultrasonic as in :class:`NavEnv`. Distances are clipped to the arena diagonal
    (2.83 m). `preview` has 2 · `track.preview_points` values (none when 0), spaced
    `track.preview_step` s apart.

    ## Rewards

    Every step: `-error_weight · ‖e‖ - heading_weight · (1 - cos e_θ)`, with ‖e‖ the distance
    from the robot's centre to the reference point after the step (m) and e_θ the heading error
    (`track.error_weight` = 1, `track.heading_weight` = 0.1, docs/task-design.md §3), minus
    `task.collision_penalty` (0.1) on every step that ends in contact.

    ## Starting State

    The reference's starting phase is uniform over the curve (`track.random_phase`) and its
    direction of travel is drawn (`track.direction = "random"`; `"ccw"`, `"cw"` fix it). The
    robot starts at rest up to `track.start_offset` (0.2 m) from the reference point, in a
    uniform direction, with a heading up to `track.start_heading_offset` (45°) from the
    reference's. All of it comes from the world's random stream: `reset(seed=s)` reproduces it.

    ## Episode End

    1. Termination (lost, not a success): the robot is more than `track.lost_distance` (0.5 m)
       from the reference point.
    2. Termination: any contact, only if `task.terminate_on_collision = true`.
    3. Truncation: one period plus `track.truncation_margin` (2 s) has passed (the circle: 543
       steps), or `task.max_steps` (4000) steps if sooner.

    The task has no success: `info["is_success"]` is always False. At the last step
    `info["episode_stats"]` holds the common statistics (`"return"`, `"length"`, `"success"`,
    `"path_length"`, `"collisions"`) and `"track_error_rms"`, `"track_error_max"` (m: the RMS and
    largest position error after the first `track.transient` = 5 s; over the whole episode if it
    ended sooner, i.e. was lost), `"track_iae"` (m·s: Σ ‖e‖ dt over the episode) and
    `"track_converge_time"` (s: when the error fell below `track.converge_radius` = 2 cm for
    good; inf if it is above at the end).

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-Track", reference="lemniscate")
    >>> env.action_space.shape, env.observation_space.shape
    ((2,), (29,))
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.goals().shape   # the reference point now
    (1, 2)
    >>> obs, reward, terminated, truncated, info = env.step(track_heuristic(obs))

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `action_type`,
    `**overrides`); the `[track]` keys are overrides like any other (`reference="square"`,
    `speed=0.1`, `track={"direction": "ccw"}`). `env.unwrapped.goals()` is the reference point
    now, shape (1, 2); `env.unwrapped.targets()` the preview points, (K, 2), in the world frame.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Track", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.TrackVectorEnv` (NEXT_STEP autoreset or DISABLED with resets by
    mask, episode statistics with masks, world i reset with seed s ≡ this env reset with seed
    s + i).

    ```python
    >>> envs = gym.make_vec("KheperaIV-Track", num_envs=4)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape, envs.goals().shape
    ((4, 29), (4, 1, 2))

    ```

    ## Robot model

    As :class:`NavEnv` (v1 dynamics: tyre grip, K-Team's speed profile of 0.203 m/s²; the robot
    starts at rest, so it lags v_r² / (2 · 0.203) ≈ 5.5 cm behind a 0.15 m/s reference before
    any feedback acts).

    ## Sensors

    As :class:`NavEnv`: 8 IR and 5 ultrasonic sensors observed; the arena is empty by default,
    so they only see the walls.

    ## Scenario file

    The keys of :class:`NavEnv` plus a `[track]` table (the reference, its size and speed, the start
    offsets, the speed and acceleration fractions a reference may ask of the wheels, the preview,
    the reward's weights, the statistics' transient and radius). Every key, with its default in each
    version, its units, its comment and its source, is tabled on this env's page of the
    documentation (generated from the core's declarations by `make docs`);
    `khepera_gym.default_config("track")` prints them as a TOML file.

    A reference outside the arena (with the start offset, the robot's radius and
    `spawn.wall_margin`) raises `khepera_gym.errors.ConfigError` naming `track.size`; one that
    asks the wheels for more than their fractions (too fast or too sharp) names `track.speed`
    (for waypoints, `track.waypoints` names both, and also times that do not rise, an open loop,
    fewer than 4 points, or waypoints given with another reference).
    """

    TASK: ClassVar[str] = "track"


# --- heuristic policy: Kanayama's tracking controller of khepera_gym.baselines ------------------

#: The heuristic's controller, with its defaults (immutable and stateless: safe to share).
TRACK_POLICY = Kanayama()


def track_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Kanayama's tracking controller (ICRA 1990) on a Track observation.

    :class:`khepera_gym.baselines.Kanayama` with its defaults (K_x = 1 s⁻¹, K_y = 44.4 m⁻²,
    K_θ = 13.3 m⁻¹: critically damped at ω_n = 1 rad/s for v_r = 0.15 m/s).

    Args:
        observation: One observation of shape (29,) or a batch (N, 29).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return TRACK_POLICY(observation)


__all__ = ["TrackEnv", "track_heuristic"]
