"""KheperaIV-Nav and KheperaIV-Avoid: drive to a goal, in an empty arena or among obstacles; and
the heuristics that solve them (the paper's controllers of :mod:`khepera_gym.baselines`).

The manuals are the classes' docstrings (Gymnasium's sections, plus Robot model, Sensors and
Scenario file). Units are SI (m, s, rad); robot frame x forward, y left.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym import _core
from khepera_gym.baselines import Braitenberg, PositionControl
from khepera_gym.envs.base import KheperaEnv


class NavEnv(KheperaEnv):
    r"""Drive a Khepera IV robot to a goal point in a walled arena.

    ## Description

    A simulated K-Team Khepera IV (a 14 cm differential-drive disc robot) starts at a random pose
    in an empty 2 m × 2 m walled arena and must bring its centre within 5 cm of a random goal
    point at least 0.5 m away, as in the position-control exercise of the KH4VREP paper (Farias
    et al., IFAC 2017, §3.3). The goal's distance and bearing are observed directly (as from
    odometry with a known goal); the infrared and ultrasonic readings show the walls. The walls
    stop the robot: from v1 on the shell rubs on them with friction, so a robot pushing into a
    wall turns toward it and stalls (in v0 it slid along it).
    :func:`nav_heuristic`, the paper's position controller (eqs. 1-4), solves most episodes.

    ## Action Space

    `Box(-1, 1, (2,), float32)`. With `action_type="wheels"` (default) the normalised wheel speed
    commands (left, right), 1 = 0.813 m/s forward. With `action_type="unicycle"`: (v, ω)
    normalised by 0.813 m/s and by the largest yaw rate 2 · 0.813 / 0.1054 ≈ 15.4 rad/s (wheel
    speeds beyond the limit are scaled down keeping the turn radius). With `led_action=True`,
    `Box(-1, 1, (5,), float32)`: those two, then the top LEDs' red, green, blue (-1 off, 1 full,
    to the real LEDs' 64 levels). Finite values outside [-1, 1] are clipped; NaN/inf or a wrong
    shape raise `khepera_gym.errors.ActionError`.

    ## Observation Space

    `Box(low, high, (18,), float32)`; `khepera_gym.obs_layout("nav")` gives the slices by name.
    Robot frame: x forward, y left, angles counter-clockwise.

    | Index | Name             | Observation                                    | Min | Max  |
    |-------|------------------|------------------------------------------------|-----|------|
    | 0     | ir               | IR proximity back-left (135°)                  | 0   | 1    |
    | 1     | ir               | IR proximity left (90°)                        | 0   | 1    |
    | 2     | ir               | IR proximity front-left (45°)                  | 0   | 1    |
    | 3     | ir               | IR proximity front (0°)                        | 0   | 1    |
    | 4     | ir               | IR proximity front-right (-45°)                | 0   | 1    |
    | 5     | ir               | IR proximity right (-90°)                      | 0   | 1    |
    | 6     | ir               | IR proximity back-right (-135°)                | 0   | 1    |
    | 7     | ir               | IR proximity back (180°)                       | 0   | 1    |
    | 8     | us               | ultrasonic left (90°)                          | 0   | 1    |
    | 9     | us               | ultrasonic front-left (45°)                    | 0   | 1    |
    | 10    | us               | ultrasonic front (0°)                          | 0   | 1    |
    | 11    | us               | ultrasonic front-right (-45°)                  | 0   | 1    |
    | 12    | us               | ultrasonic right (-90°)                        | 0   | 1    |
    | 13    | goal_distance    | distance from the robot centre to the goal (m) | 0   | 2.83 |
    | 14    | goal_bearing_sin | sine of the goal bearing in the robot frame    | -1  | 1    |
    | 15    | goal_bearing_cos | cosine of the goal bearing in the robot frame  | -1  | 1    |
    | 16    | wheel_speeds     | left wheel speed / 0.813 m/s                   | -1  | 1    |
    | 17    | wheel_speeds     | right wheel speed / 0.813 m/s                  | -1  | 1    |

    IR: `(raw - floor) / (1023 - floor)` clipped to [0, 1], with `raw` the 0..1023 reading and
    `floor` = `sensors.ir_floor_value`: 0 = nothing within 25 cm, 1 = touching. Ultrasonic:
    distance / 2 m, 0 when closer than 0.25 m ("too close"), 1 when nothing within 2 m (or the
    sensor is disabled). The max of `goal_distance` is the arena diagonal (2.83 m by default).
    The goal bearing is (0, 1) when the robot is exactly on the goal.

    ## Rewards

    Every step: `progress_weight · (d_prev - d) - time_cost`, with d the goal distance before and
    after the step (10 per metre of progress, 0.01 per step); plus `success_bonus` (10) on the
    step that reaches the goal; minus `collision_penalty` (0.1) on every step that ends in contact
    with a wall or obstacle. The defaults are in the `[task]` table of the scenario.

    ## Starting State

    The start position and the goal are uniform in the arena shrunk by the robot radius and
    `spawn.wall_margin` (5 cm); the heading is uniform in [-π, π). The goal is redrawn until it is
    at least `spawn.min_goal_distance` (0.5 m) from the start. `spawn.start` and `spawn.goal` fix
    them instead. Both come from the world's own random stream: `reset(seed=s)` reproduces them
    exactly; `reset()` continues the stream.

    ## Episode End

    1. Termination: the robot centre is within `task.goal_radius` (0.05 m) of the goal (success).
    2. Termination: contact with a wall or obstacle, only if
       `task.terminate_on_collision = true`.
    3. Truncation: `task.max_steps` (400) steps have passed, i.e. 20 s at dt = 0.05 s. The Rust core
       truncates by itself: no `TimeLimit` wrapper is registered, though
       `gym.make(..., max_episode_steps=k)` still adds one.

    At the last step `info` holds `"episode_stats"`: `{"return", "length", "success", "path_length"
    (m), "collisions" (steps in contact)}` as Python scalars, and `"is_success"` (as
    stable-baselines3 expects). Stepping after the end without `reset()` raises `KheperaError`.
    The key is not `"episode"`, so Gymnasium's `RecordEpisodeStatistics` and SB3's `Monitor`
    (which write `info["episode"]`) work unchanged on top.

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> import khepera_gym
    >>> env = gym.make("KheperaIV-Nav", max_steps=200, goal_radius=0.1)
    >>> env
    <OrderEnforcing<PassiveEnvChecker<NavEnv<KheperaIV-Nav-v...>>>>
    >>> obs, info = env.reset(seed=0)

    ```

    | Parameter     | Type                    | Default    | Description                          |
    |---------------|-------------------------|------------|--------------------------------------|
    | `render_mode` | str \| None             | `None`     | `"rgb_array"` or `"human"` (pygame)  |
    | `config`      | str \| PathLike \| None | `None`     | built-in scenario name or TOML path  |
    | `action_type` | str                     | `"wheels"` | `"wheels"` or `"unicycle"`           |
    | `**overrides` | scenario keys           |            | e.g. `goal_radius=0.1`, `task={...}` |

    Overrides name scenario keys (table below) by leaf (`goal_radius=0.1`), by section
    (`task={"max_steps": 100}`) or dotted (`**{"robot.radius": 0.07}`). Unknown keys and
    impossible values raise `khepera_gym.errors.ConfigError` naming the key.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Nav", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.NavVectorEnv`: N worlds stepped in one Rust call on a thread pool
    (None = all cores), autoreset mode NEXT_STEP, episode statistics in
    `infos["episode_stats"]` with `_`-prefixed masks at steps where some world ended. World i
    reset with seed s behaves bit for bit like this env reset with seed s + i, whatever the
    thread count. `autoreset_mode=gym.vector.AutoresetMode.DISABLED` turns autoreset off: the
    caller resets the worlds that ended with `envs.reset(options={"reset_mask": mask})`, which
    (in either mode) resets only the masked worlds, seeded as a full reset would seed them.

    ```python
    >>> envs = gym.make_vec("KheperaIV-Nav", num_envs=1024, num_threads=2)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (1024, 18)

    ```

    ## Robot model

    Khepera IV: a disc of radius 0.0704 m, wheels of radius 0.021 m, 0.1054 m apart; each wheel
    speed limited to ±0.813 m/s; commands below 3 mm/s give 0 (the real controller's floor). The
    wheels follow K-Team's speed profile as the firmware computes it, at Acc_Inc 40 (2.71 m/s²,
    `[motors]`; v1: a plain 0.203 m/s² ramp; v0: the command within a step), which the program
    `khepera-gym export` writes sets on the robot. A rigid disc driven by its tyres' bounded grip
    (`physics.drive = "traction"`; v0: its velocity imposed); contacts stop, turn or stall it:
    with walls and obstacles solved as a disc's with Coulomb friction (`physics.scene_solver =
    "disc"`; v2 and earlier: rapier2d's step), with other robots by rapier2d.
    Control step `physics.dt` = 0.05 s (V-REP's default) with `physics.substeps` = 2 physics
    substeps (v0: 4). Ground truth: `env.unwrapped.poses()` (n_robots, 3) x, y, θ in the world
    frame (x right, y up, arena centred at the origin); `env.unwrapped.goals()` (n_goals, 2).

    ## Sensors

    Exact ray casts against the arena's shapes. 8 IR proximity sensors 45° apart on the rim, in
    K-Team order, range 2-250 mm, raw 0..1023 from K-Team's measured response curve, reading
    `sensors.ir_floor_value` (≈100) with nothing in range, Gaussian noise of
    `sensors.ir_noise_sigma` counts. 5 ultrasonic sensors (left, front-left, front, front-right,
    right) from 0.25 m to 2 m in whole centimetres, noise `sensors.us_noise_sigma` m, with the
    K-Team codes 0 (too close), 1000 (nothing), 2000 (disabled). Raw values in the real robot's
    units: `env.unwrapped.sensor_readings()` ("ir_raw", "us_cm", "wheel_speeds" m/s, "encoders",
    "gyro_z" rad/s). Carried on request (`carry`, `observe`): the IMU (`imu`, the LSM330DLC:
    accelerometer ±2 g in 1 mg counts, z negative with gravity, from the body's real acceleration
    with contacts; gyroscope on three axes), readings "accel_raw", "accel_g", "imu_gyro_raw",
    "imu_gyro", observation block `imu` of 6 values in [-1, 1].

    ## Scenario file

    `config="path.toml"` overlays a TOML file on the built-in defaults; a file may change any key
    and add none. Every key, with its default in each version, its units, its comment and its
    source, is tabled on this env's page of the documentation (generated from the core's
    declarations by `make docs`); `khepera_gym.default_config("nav")` prints them as a TOML file.
    `robot.axle_length`, `robot.max_wheel_speed`, `robot.wheel_accel_limit`, `robot.mass`,
    `sensors.ir_floor_value`, `sensors.ir_noise_sigma` and `sensors.us_noise_sigma` may be given as
    `[low, high]` ranges, drawn anew at every reset (domain randomisation). Built-in scenes
    (`khepera_gym.scenes()`, e.g. `config="paper_fig6"`) overlay their keys the same way.
    `env.unwrapped.config_toml()` returns the resolved scenario.
    """

    TASK: ClassVar[str] = "nav"


class AvoidEnv(KheperaEnv):
    r"""Drive a Khepera IV robot to a goal among random obstacles (the Nav task plus obstacles).

    ## Description

    The obstacle-avoidance exercise of the KH4VREP paper (Farias et al., IFAC 2017, §3.4, Fig. 6):
    the robot of :class:`NavEnv` must bring its centre within 5 cm of a goal at least 1 m away,
    in the same 2 m × 2 m walled arena, now with 10 random obstacles (circles, boxes and thin wall
    segments) drawn anew at every reset, some of them between the start and the goal. Only the
    sensors show the obstacles: the 8 infrared sensors up to 25 cm, the 5 ultrasonic ones from
    0.25 m to 2 m. The layout is always feasible: obstacles keep a free gap of
    `obstacles.min_gap` (0.16 m, more than the robot's diameter) from the walls and from one
    another, and stay clear of the start and the goal, so the goal can always be reached.
    :func:`avoid_heuristic`, the paper's position controller followed by its Braitenberg block
    (eqs. 1-7), solves most episodes. `config="paper_fig6"` loads the paper's Fig. 6 scene (a wall
    and a box between fixed start and goal).

    ## Action Space

    As :class:`NavEnv`: `Box(-1, 1, (2,), float32)`, normalised (left, right) wheel speeds, or
    normalised (v, ω) with `action_type="unicycle"`; out-of-range values are clipped, NaN/inf or a
    wrong shape raise `khepera_gym.errors.ActionError`.

    ## Observation Space

    `Box(low, high, (18,), float32)`, the same layout as :class:`NavEnv` (whose manual has one row
    per index); `khepera_gym.obs_layout("avoid")` gives the slices by name. Robot frame: x
    forward, y left, angles counter-clockwise.

    | Index | Name             | Observation                                       | Min | Max  |
    |-------|------------------|---------------------------------------------------|-----|------|
    | 0-7   | ir               | IR proximity, K-Team order back-left ... back     | 0   | 1    |
    | 8-12  | us               | ultrasonic left, front-left, front, front-right,  | 0   | 1    |
    |       |                  | right                                             |     |      |
    | 13    | goal_distance    | distance from the robot centre to the goal (m)    | 0   | 2.83 |
    | 14    | goal_bearing_sin | sine of the goal bearing in the robot frame       | -1  | 1    |
    | 15    | goal_bearing_cos | cosine of the goal bearing in the robot frame     | -1  | 1    |
    | 16-17 | wheel_speeds     | left, right wheel speed / 0.813 m/s               | -1  | 1    |

    IR proximity is 0 with nothing within 25 cm and 1 touching; ultrasonic is distance / 2 m, 0
    closer than 0.25 m, 1 with nothing within 2 m (see :class:`NavEnv` for the exact formulas).
    Obstacles block the rays of both.

    ## Rewards

    As :class:`NavEnv`: `progress_weight · (d_prev - d) - time_cost` every step (10 per metre of
    progress, 0.01 per step), `success_bonus` (10) on reaching the goal, minus
    `collision_penalty` on every step that ends in contact with a wall or obstacle, 0.5 here
    (0.1 in Nav): brushing an obstacle costs more than the time it saves.

    ## Starting State

    The start pose and the goal are drawn as in :class:`NavEnv` but at least
    `spawn.min_goal_distance` (1 m) apart; then `obstacles.count` (10) obstacles are drawn, each
    of a random kind from `obstacles.kinds`, size and orientation, placed uniformly in the arena
    (`obstacles.placement = "anywhere"`; `"between"` confines them to a band of
    `obstacles.corridor_width` around the start-goal line) where it keeps `obstacles.min_gap`
    from walls, fixed obstacles and the other obstacles, and `obstacles.spawn_clearance` (5 cm)
    from the robot and the goal. When an obstacle finds no place in 40 tries, the whole layout is
    redrawn (up to 16 times, keeping the fullest); the scenario is checked at load time to fit.
    `env.unwrapped.scene()` lists this episode's obstacles. All of it comes from the world's
    random stream: `reset(seed=s)` reproduces the layout exactly; `reset()` continues the stream,
    giving a new layout.

    ## Episode End

    1. Termination: the robot centre is within `task.goal_radius` (0.05 m) of the goal (success).
    2. Termination: contact with a wall or obstacle, only if `task.terminate_on_collision = true`.
    3. Truncation: `task.max_steps` (600) steps have passed, i.e. 30 s at dt = 0.05 s (detours
       take longer than in Nav). The Rust core truncates by itself.

    At the last step `info` holds `"episode_stats"` (`"return"`, `"length"`, `"success"`,
    `"path_length"` (m), `"collisions"` (steps in contact)) and `"is_success"`, as in
    :class:`NavEnv`.

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-Avoid", config="paper_fig6", max_steps=300)
    >>> obs, info = env.reset(seed=0)
    >>> [obstacle["kind"] for obstacle in env.unwrapped.scene()["obstacles"]]
    ['box', 'box']
    >>> env.unwrapped.poses()[0].round(2).tolist(), env.unwrapped.goals()[0].round(2).tolist()
    ([-0.75, 0.05, 0.0], [0.75, 0.05])

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `action_type`,
    `**overrides`); `config` is None (the Avoid defaults), a built-in scenario name such as
    `"paper_fig6"`, or a path to a TOML file, and keyword overrides are merged on top, e.g.
    `gym.make("KheperaIV-Avoid", count=20, kinds=["circle"])`.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Avoid", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.AvoidVectorEnv` (same semantics as Nav's: NEXT_STEP autoreset or
    DISABLED with resets by mask, `infos["episode_stats"]` with masks, world i reset with seed
    s ≡ this env reset with seed s + i, bit for bit). `envs.scene(i)` is the geometry of world i.

    ```python
    >>> envs = gym.make_vec("KheperaIV-Avoid", num_envs=16, num_threads=2)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (16, 18)

    ```

    ## Robot model

    As :class:`NavEnv`: a Khepera IV disc (radius 0.0704 m, wheels 0.1054 m apart, ±0.813 m/s),
    a rigid disc that obstacles stop or deflect. From v1 on, `physics.friction` = 0.7
    holds it against what it touches (it turns toward a wall it pushes and stalls); in v0
    (`physics.friction` = 0) it slid along walls and obstacles.

    ## Sensors

    As :class:`NavEnv`: 8 IR proximity sensors (2-250 mm) and 5 ultrasonic sensors (0.25-2 m),
    exact ray casts against the walls and every obstacle, with noise;
    `env.unwrapped.sensor_readings()` gives them in the real robot's units.

    ## Scenario file

    The keys of :class:`NavEnv`, with Avoid's defaults: 10 random obstacles placed anywhere, a goal
    at least 1 m away, 600 steps, 0.5 per step in contact. Every key, with its default in each
    version, its units, its comment and its source, is tabled on this env's page of the
    documentation (generated from the core's declarations by `make docs`);
    `khepera_gym.default_config("avoid")` prints them as a TOML file.

    Fixed obstacles go in `obstacles.fixed`, e.g.
    `fixed = [{kind = "box", center = [0.0, 0.2], half_extents = [0.025, 0.4], angle = 0.0}]`.
    A scenario that cannot work raises `khepera_gym.errors.ConfigError` naming the file and the
    key: an obstacle with a size ≤ 0 or outside the arena (`obstacles.fixed[i]`), random
    obstacles that cannot fit (`obstacles.count`), a gap too small to pass
    (`obstacles.min_gap`, at least the robot's diameter + 1 cm).
    """

    TASK: ClassVar[str] = "avoid"


# --- heuristic policies: the paper's controllers of khepera_gym.baselines ------------------------

#: Default Braitenberg weights (m/s per unit of IR proximity; paper eqs. 5-7), as the Rust core
#: defines them: rows left, right wheel; columns the IR sensors in K-Team order.
BRAITENBERG_WEIGHTS = np.array(_core.braitenberg_weights("default"), dtype=np.float32)

#: The heuristics' controllers, with their defaults (immutable and stateless: safe to share).
NAV_POLICY = PositionControl()
AVOID_POLICY = Braitenberg()


def nav_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Position control of the KH4VREP paper (eqs. 1-4) on Nav observations.

    :class:`khepera_gym.baselines.PositionControl` with its defaults: ``v = v_max`` beyond
    ``k_r`` of the goal, else ``d · v_max / k_r``; ``ω = ω_max · sin(α)`` with α the goal
    bearing in the robot frame; ``v_max`` = 0.3 m/s, ``ω_max`` = 4 rad/s, ``k_r`` = 0.15 m,
    stop within 0.02 m. Ignores obstacles.

    Args:
        observation: One Nav observation of shape (18,) or a batch (N, 18).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return NAV_POLICY(observation)


def avoid_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Position control followed by Braitenberg avoidance (paper eqs. 1-7, Fig. 5).

    :class:`khepera_gym.baselines.Braitenberg` with its defaults: the wheel speeds of
    :func:`nav_heuristic` pass unchanged while every IR proximity is below 0.05; otherwise
    ``W · p`` is added to them (``p`` the 8 IR proximities, ``W`` = :data:`BRAITENBERG_WEIGHTS`).
    Works on Nav and Avoid observations (same layout); it reaches the goal in most Avoid
    episodes and in the paper's Fig. 6 scene, but like any reactive controller it can be
    trapped in a dead end.

    Args:
        observation: One Avoid observation of shape (18,) or a batch (N, 18).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return AVOID_POLICY(observation)


__all__ = ["BRAITENBERG_WEIGHTS", "AvoidEnv", "NavEnv", "avoid_heuristic", "nav_heuristic"]
