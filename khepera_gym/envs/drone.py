"""KheperaIV-DroneFollow: a quadcopter follows a Khepera IV (the KH4VREP paper's Fig. 8); and
the heuristic that solves it (PD pursuit).

The manual is the class's docstring. Units are SI (m, s, rad); world frame x right, y up.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.baselines import DronePursuit
from khepera_gym.envs.base import KheperaEnv


class DroneFollowEnv(KheperaEnv):
    r"""Fly a quadcopter that keeps a driving Khepera IV in its downward camera's view.

    ## Description

    The last experiment of the KH4VREP paper (Farias et al., IFAC 2017, §4.2, Fig. 8): a
    quadcopter follows a Khepera IV. Definitions from docs/task-design.md §7. The Khepera
    (robot 0) drives a closed route of `drone.route_points` (6) random waypoints in the 2 m ×
    2 m walled arena, scripted with the paper's position control (eqs. 1-4, 0.15 m/s) and
    Braitenberg avoidance (eqs. 5-7), heading for the next waypoint once within
    `drone.waypoint_radius` (0.1 m) of the current one. The agent is the drone, a 2.5-D vehicle
    above the arena (no contacts): its horizontal motion is v̇ = a_max · u − c · v, with u the
    action (its length clamped to 1), a_max = g · tan(`drone.tilt_max`) = 2.63 m/s² (15° of
    tilt [E]) and drag c = a_max / `drone.speed_max` (1 m/s, the terminal speed [E]); its
    autopilot holds the altitude, ż = (z_ref − z) / τ with τ = `drone.altitude_tau` (0.3 s
    [E]), at `drone.track_altitude` (0.5 m) while it sees the robot and at
    `drone.search_altitude` (1.5 m) once it has lost it for `drone.search_delay` (0.5 s): the
    UNED course's quadcopter on the KH4VREP model descends once it sees the Khepera and climbs to
    search. Its camera points down with a cone of `drone.fov` (60° [E]): the robot is seen
    within z · tan(fov / 2) of the drone (0.29 m at 0.5 m, 0.87 m at 1.5 m).

    :func:`dronefollow_heuristic` (PD pursuit, :class:`khepera_gym.baselines.DronePursuit`)
    keeps the robot in view on every route (tests/drone.rs).

    With `drone.driver = "agent"` the Khepera is a second agent, `robot`, instead of the script (the
    paper's "or an agent"; the key came within v1, its default keeping v1's behaviour): its action
    is a wheel command as in :class:`NavEnv` (`action_type` applies to it), its observation Nav's
    blocks toward its current waypoint (its observed sensors, `goal_distance`, `goal_bearing_sin`,
    `goal_bearing_cos`, `wheel_speeds`, after the drone's 8 numbers), its reward Nav's toward that
    waypoint (progress, time cost, collision penalty) plus `task.success_bonus` at each waypoint
    reached. Its episode ends with the drone's. The joint env then takes (4,) actions (the drone's,
    then the robot's) and returns the mean of the two rewards; the PettingZoo form
    (`drone_follow_vN.parallel_env(driver="agent")`) keeps them apart. An agent applying the
    script's own law (:class:`khepera_gym.baselines.Braitenberg` with `vmax=0.15, wmax=1.0, kr=0.15,
    stop_radius=0`) reaches the same waypoints as the script (tests).

    ## Action Space

    `Box(-1, 1, (2,), float32)`: the drone's normalised horizontal acceleration command (x, y
    in the world frame; the drone holds its yaw). `action_type` does not apply (the drone has
    no wheels). With `drone.driver = "agent"`, `Box(-1, 1, (4,), float32)`: the drone's two
    numbers, then the robot's wheel command.

    ## Observation Space

    `Box(low, high, (8,), float32)`; `khepera_gym.obs_layout("dronefollow")` names the slices.
    What the drone's camera and its own sensors give, no ground truth:

    | Index | Name              | Observation                                      | Min | Max |
    |-------|-------------------|--------------------------------------------------|-----|-----|
    | 0-1   | camera_offset     | the robot's offset in image coordinates, (p_robot | -1  | 1   |
    |       |                   | - p_drone) / (z tan(fov/2)); 0 when unseen       |     |     |
    | 2     | seen              | 1 when the robot is in view, else 0              | 0   | 1   |
    | 3-4   | relative_velocity | change of the robot's offset (m) since the last  | -4  | 4   |
    |       |                   | frame / dt (m/s); 0 unless seen on both frames   |     |     |
    | 5-6   | drone_velocity    | the drone's horizontal velocity (m/s)            | -1  | 1   |
    | 7     | altitude          | the drone's altitude (m)                         | 0   | 1.5 |

    ## Rewards

    Every step: −‖p_drone − p_robot‖ (horizontal distance, m) − `drone.unseen_penalty` (0.5)
    while the robot is out of view (docs/task-design.md §7).

    ## Starting State

    The Khepera starts at rest at a random pose (as Nav's robot); the route's waypoints are drawn
    uniformly in the arena, 0.2 m from the walls; the drone hovers at the tracking altitude, at
    rest, up to `drone.start_offset` (0.1 m) from above the robot, so it sees it. All of it
    comes from the world's random stream: `reset(seed=s)` reproduces it.

    ## Episode End

    1. Termination (lost): the robot has been out of view for `drone.lost_time` (3 s).
    2. Truncation: `task.max_steps` (800 steps, 40 s).

    At the last step `info["episode_stats"]` holds the common statistics and
    `"horizontal_error_rms"` (m), `"in_view_share"` (steps with the robot in view) and
    `"altitude_error_rms"` (m, against the tracking altitude). `success` is always False (the
    task has no goal to reach).

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-DroneFollow")
    >>> env.action_space.shape, env.observation_space.shape
    ((2,), (8,))
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.targets().shape, env.unwrapped.goals().shape  # drone; robot's waypoint
    ((1, 2), (1, 2))
    >>> obs, reward, terminated, truncated, info = env.step(dronefollow_heuristic(obs))

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `**overrides`); the
    `[drone]` keys are overrides like any other (`fov=0.8`, `drone={"tilt_max": 0.35}`).
    `env.unwrapped.poses()` is the Khepera's pose, (1, 3); `env.unwrapped.targets()` the
    drone's horizontal position, (1, 2); `env.unwrapped.goals()` the robot's current waypoint.
    Frames draw the route, the drone (a cross) and its camera's footprint (green while it sees
    the robot, red otherwise).

    ## Vectorized environment

    `gym.make_vec("KheperaIV-DroneFollow", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.DroneFollowVectorEnv` (world i reset with seed s ≡ this env
    reset with seed s + i).

    ```python
    >>> envs = gym.make_vec("KheperaIV-DroneFollow", num_envs=4)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (4, 8)

    ```

    ## Robot model

    The Khepera as in :class:`NavEnv` (v1 dynamics). The drone: the 2.5-D model above (no
    contacts, no rotor dynamics; docs/task-design.md §7), integrated exactly over 4 substeps of
    the 0.05 s control step.

    ## Sensors

    The Khepera carries its IR ring and sonars (its Braitenberg avoidance reads the ring); the
    drone observes only its camera, its velocity and its altitude.

    ## Scenario file

    The keys of :class:`NavEnv` plus a `[drone]` table (the drone's tilt, speed and altitudes, its
    camera, when it is lost, the robot's route and who drives it). Every key, with its default in
    each version, its units, its comment and its source, is tabled on this env's page of the
    documentation (generated from the core's declarations by `make docs`);
    `khepera_gym.default_config("dronefollow")` prints them as a TOML file.

    A tilt outside (0, 1.2) rad, a camera cone outside (0, 3) rad, a non-positive speed, time or
    altitude, a search altitude below the tracking one, a start offset that would leave the robot
    out of view, or fewer than 2 or more than 32 route points raise
    `khepera_gym.errors.ConfigError` naming the key.
    """

    TASK: ClassVar[str] = "dronefollow"


# --- heuristic policy: the PD pursuit of khepera_gym.baselines -----------------------------------

#: The heuristic's controller, with its defaults (immutable and stateless: safe to share).
DRONEFOLLOW_POLICY = DronePursuit()


def dronefollow_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """PD pursuit of the robot seen by the drone's camera (docs/task-design.md §7).

    :class:`khepera_gym.baselines.DronePursuit` with its defaults (k_p = 4 s⁻², k_d = 4 s⁻¹:
    critically damped, ω_n = 2 rad/s; drag compensated; brakes when the robot is out of view
    while the autopilot climbs to search).

    Args:
        observation: One observation of shape (8,) or a batch (N, 8).

    Returns:
        Normalised acceleration commands of shape (2,) or (N, 2), float32.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return DRONEFOLLOW_POLICY(observation)


__all__ = ["DroneFollowEnv", "dronefollow_heuristic"]
