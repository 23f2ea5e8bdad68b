"""Single-world Gymnasium environments over the Rust core, and heuristic policies that solve them.

Each env owns a ``_core.Batch`` of one world without autoreset: the Rust core simulates, observes,
rewards and ends episodes; this layer only validates actions, converts outputs to Python scalars
and builds ``info``. Units are SI (m, s, rad); the world frame has x right, y up, angles
counter-clockwise; the robot frame has x forward, y left.

Threading and copies: ``step`` and ``reset`` release the GIL inside the Rust core while simulating;
every returned array is freshly allocated, so callers may keep or mutate observations.
"""

from __future__ import annotations

from typing import Any, ClassVar, SupportsFloat

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from khepera_gym import _core
from khepera_gym.config import ConfigArg, resolve_config
from khepera_gym.errors import ActionError, ConfigError
from khepera_gym.layout import obs_layout

#: Action types understood by the Rust core: normalised (left, right) wheel speeds, or (v, ω).
ACTION_TYPES = ("wheels", "unicycle")
#: Largest seed drawn from ``np_random`` on a first ``reset()`` without a seed (exclusive).
_SEED_BOUND = 2**62


def _check_render_mode(render_mode: str | None, render_modes: list[str]) -> None:
    if render_mode is not None and render_mode not in render_modes:
        raise ConfigError(
            f"render_mode={render_mode!r} is not supported by this version of khepera_gym "
            f"(supported: {[None, *render_modes]}); rendering comes in a later release, "
            "use env.unwrapped.poses() and khepera_gym.plot.plot_trajectories meanwhile"
        )


def _check_action_type(action_type: str) -> None:
    if action_type not in ACTION_TYPES:
        raise ConfigError(f"action_type must be one of {ACTION_TYPES}, got {action_type!r}")


class KheperaEnv(gym.Env[npt.NDArray[np.float32], npt.NDArray[np.float32]]):
    """Base of the single-world Khepera IV environments; subclasses set :attr:`TASK`.

    Args:
        render_mode: Must be None for now (rendering comes in a later release).
        config: None (built-in defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        **overrides: Scenario keys overriding the file, e.g. ``goal_radius=0.1`` or
            ``task={"max_steps": 100}`` (see the task's docstring, section Scenario file).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": [], "render_fps": 20}
    #: Task name in the Rust core.
    TASK: ClassVar[str] = ""

    def __init__(
        self,
        render_mode: str | None = None,
        config: ConfigArg = None,
        action_type: str = "wheels",
        **overrides: Any,
    ) -> None:
        _check_render_mode(render_mode, self.metadata["render_modes"])
        _check_action_type(action_type)
        config_text, config_name = resolve_config(config, self.TASK)
        self.render_mode = render_mode
        self.action_type = action_type
        self._batch = _core.Batch(
            self.TASK,
            1,
            config_text=config_text,
            config_name=config_name,
            overrides=dict(overrides) or None,
            action_type=action_type,
            num_threads=1,
            autoreset=False,
        )
        low, high = self._batch.obs_bounds()
        self.observation_space = gym.spaces.Box(
            low.astype(np.float32), high.astype(np.float32), dtype=np.float32
        )
        self.action_space = gym.spaces.Box(
            -1.0, 1.0, shape=(self._batch.act_dim,), dtype=np.float32
        )
        self._action_shape = (self._batch.act_dim,)
        # Reused input buffer of shape (1, act_dim): the Rust core copies actions on entry.
        self._action_buffer = np.zeros((1, self._batch.act_dim), dtype=np.float32)
        self._has_reset = False

    @property
    def max_episode_steps(self) -> int:
        """Steps after which the Rust core truncates an episode (the scenario's ``max_steps``)."""
        return self._batch.max_episode_steps

    @property
    def n_robots(self) -> int:
        """Number of robots in the world."""
        return self._batch.n_robots

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Start a new episode.

        Args:
            seed: Seeds the world's random stream; None continues it (the very first reset without
                a seed draws one from ``self.np_random``).
            options: Unused; accepted for API compatibility.

        Returns:
            The first observation and an empty info dict.
        """
        super().reset(seed=seed)
        if seed is None and not self._has_reset:
            seed = int(self.np_random.integers(_SEED_BOUND))
        observations = self._batch.reset(seed)
        self._has_reset = True
        return observations[0], {}

    def step(
        self, action: npt.ArrayLike
    ) -> tuple[npt.NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply one control step (0.05 s by default) of wheel commands.

        Args:
            action: Shape ``(2,)``, normalised to [-1, 1]; finite values outside are clipped.

        Returns:
            ``(observation, reward, terminated, truncated, info)``; ``info`` is empty during an
            episode and holds ``"episode_stats"`` statistics and ``"is_success"`` at its last step.

        Raises:
            ActionError: The action is not numeric, has the wrong shape, or is NaN/inf.
            KheperaError: ``step`` after the episode ended without ``reset``.
        """
        try:
            action_array = np.asarray(action, dtype=np.float32)
        except (TypeError, ValueError) as error:
            raise ActionError(
                f"action must be numeric of shape {self._action_shape}, got {action!r}"
            ) from error
        if action_array.shape != self._action_shape:
            raise ActionError(
                f"action must have shape {self._action_shape}, got shape {action_array.shape}"
            )
        buffer = self._action_buffer
        buffer[0] = action_array
        observations, rewards, terminations, truncations = self._batch.step(buffer)
        terminated = bool(terminations[0])
        truncated = bool(truncations[0])
        info = self._episode_info() if terminated or truncated else {}
        return observations[0], float(rewards[0]), terminated, truncated, info

    def _episode_info(self) -> dict[str, Any]:
        stats = self._batch.episode_stats()
        success = bool(stats["success"][0])
        return {
            "episode_stats": {
                "return": float(stats["return"][0]),
                "length": int(stats["length"][0]),
                "success": success,
                "path_length": float(stats["path_length"][0]),
                "collisions": int(stats["collisions"][0]),
            },
            "is_success": success,
        }

    def poses(self) -> npt.NDArray[np.float64]:
        """Ground-truth robot poses, shape (n_robots, 3): x, y (m), θ (rad, (-π, π])."""
        return self._batch.poses()[0]

    def goals(self) -> npt.NDArray[np.float64]:
        """Goal positions, shape (n_goals, 2), in metres."""
        return self._batch.goals()[0]

    def sensor_readings(self) -> dict[str, npt.NDArray[Any]]:
        """Raw sensor values of the last observation in the real robot's units.

        Keys as ``_core.Batch.sensor_readings`` without the world axis: "ir_raw" (n_robots, 8)
        0..1023, "us_cm" (n_robots, 5), "wheel_speeds" (n_robots, 2) m/s, "encoders"
        (n_robots, 2) pulses, "gyro_z" (n_robots,) rad/s.
        """
        return {name: values[0] for name, values in self._batch.sensor_readings().items()}

    def scene(self) -> dict[str, Any]:
        """Geometry of the world for plots: arena size, robot radius, obstacles, goal radius."""
        return self._batch.scene(0)

    def config_toml(self) -> str:
        """The fully resolved scenario (defaults + file + overrides) as TOML text."""
        return self._batch.config_toml()

    def close(self) -> None:
        """Release nothing yet (the Rust world is freed with the env); safe to call twice."""
        super().close()


class NavEnv(KheperaEnv):
    r"""Drive a Khepera IV robot to a goal point in a walled arena.

    ## Description

    A simulated K-Team Khepera IV (a 14 cm differential-drive disc robot) starts at a random pose
    in an empty 2 m × 2 m walled arena and must bring its centre within 5 cm of a random goal
    point at least 0.5 m away, as in the position-control exercise of the KH4VREP paper (Farias
    et al., IFAC 2017, §3.3). The goal's distance and bearing are observed directly (as from
    odometry with a known goal); the infrared and ultrasonic readings show the walls. Physics
    (rapier2d) stops the robot at the walls; a robot in contact slides along them.
    :func:`nav_heuristic`, the paper's position controller (eqs. 1-4), solves it in about 90 steps.

    ## Action Space

    `Box(-1, 1, (2,), float32)`. With `action_type="wheels"` (default) the normalised wheel speed
    commands (left, right), 1 = 0.813 m/s forward. With `action_type="unicycle"`: (v, ω)
    normalised by 0.813 m/s and by the largest yaw rate 2 · 0.813 / 0.1054 ≈ 15.4 rad/s (wheel
    speeds beyond the limit are scaled down keeping the turn radius). Finite values outside
    [-1, 1] are clipped; NaN/inf or a wrong shape raise `khepera_gym.errors.ActionError`.

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
    `task.spawn_margin` (5 cm); the heading is uniform in [-π, π). The goal is redrawn until it is
    at least `task.min_goal_distance` (0.5 m) from the start. Both come from the world's own
    random stream: `reset(seed=s)` reproduces them exactly; `reset()` continues the stream.

    ## Episode End

    1. Termination: the robot centre is within `task.goal_radius` (0.05 m) of the goal (success).
    2. Termination: contact with a wall, only if `task.terminate_on_collision = true`.
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
    >>> env = gym.make("KheperaIV-Nav-v0", max_steps=200, goal_radius=0.1)
    >>> env
    <OrderEnforcing<PassiveEnvChecker<NavEnv<KheperaIV-Nav-v0>>>>
    >>> obs, info = env.reset(seed=0)

    ```

    | Parameter     | Type                    | Default    | Description                          |
    |---------------|-------------------------|------------|--------------------------------------|
    | `render_mode` | str \| None             | `None`     | must be None (rendering comes later) |
    | `config`      | str \| PathLike \| None | `None`     | built-in scenario name or TOML path  |
    | `action_type` | str                     | `"wheels"` | `"wheels"` or `"unicycle"`           |
    | `**overrides` | scenario keys           |            | e.g. `goal_radius=0.1`, `task={...}` |

    Overrides name scenario keys (table below) by leaf (`goal_radius=0.1`), by section
    (`task={"max_steps": 100}`) or dotted (`**{"robot.radius": 0.07}`). Unknown keys and
    impossible values raise `khepera_gym.errors.ConfigError` naming the key.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Nav-v0", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.NavVectorEnv`: N worlds stepped in one Rust call on a thread pool
    (None = all cores), autoreset mode NEXT_STEP, episode statistics in
    `infos["episode_stats"]` with `_`-prefixed masks at steps where some world ended. World i
    reset with seed s behaves bit for bit like this env reset with seed s + i, whatever the
    thread count.

    ```python
    >>> envs = gym.make_vec("KheperaIV-Nav-v0", num_envs=1024, num_threads=2)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (1024, 18)

    ```

    ## Robot model

    Khepera IV: a disc of radius 0.0704 m, wheels of radius 0.021 m, 0.1054 m apart; each wheel
    speed limited to ±0.813 m/s; commands below 3 mm/s give 0 (the real controller's floor); an
    optional wheel acceleration limit (`robot.wheel_accel_limit`, none by default). A dynamic
    rapier2d body whose planar velocity follows the wheels; contacts stop or deflect it. Control
    step `physics.dt` = 0.05 s (V-REP's default) with `physics.substeps` = 4 physics substeps.
    Ground truth: `env.unwrapped.poses()` (n_robots, 3) x, y, θ in the world frame (x right, y up,
    arena centred at the origin); `env.unwrapped.goals()` (n_goals, 2).

    ## Sensors

    Exact ray casts against the arena's shapes. 8 IR proximity sensors 45° apart on the rim, in
    K-Team order, range 2-250 mm, raw 0..1023 from K-Team's measured response curve, reading
    `sensors.ir_floor_value` (≈100) with nothing in range, Gaussian noise of
    `sensors.ir_noise_sigma` counts. 5 ultrasonic sensors (left, front-left, front, front-right,
    right) from 0.25 m to 2 m in whole centimetres, noise `sensors.us_noise_sigma` m, with the
    K-Team codes 0 (too close), 1000 (nothing), 2000 (disabled). Raw values in the real robot's
    units: `env.unwrapped.sensor_readings()` ("ir_raw", "us_cm", "wheel_speeds" m/s, "encoders",
    "gyro_z" rad/s).

    ## Scenario file

    `config="path.toml"` overlays a TOML file on the built-in defaults below
    (`khepera_gym._core.default_config("nav")`); a file may change any key and add none.
    `robot.axle_length`, `robot.max_wheel_speed`, `robot.wheel_accel_limit`, `robot.mass`,
    `sensors.ir_floor_value`, `sensors.ir_noise_sigma` and `sensors.us_noise_sigma` may be given
    as `[low, high]` ranges, drawn anew at every reset (domain randomisation). Built-in scenes
    such as `config="paper_fig6"` overlay their keys the same way.
    `env.unwrapped.config_toml()` returns the resolved scenario.

    | Key                           | Default | Meaning                                      |
    |-------------------------------|---------|----------------------------------------------|
    | `robot.radius`                | 0.0704  | body radius (m)                              |
    | `robot.wheel_radius`          | 0.021   | wheel radius (m)                             |
    | `robot.axle_length`           | 0.1054  | distance between the wheels (m)              |
    | `robot.max_wheel_speed`       | 0.813   | wheel speed limit (m/s); action 1 maps to it |
    | `robot.min_wheel_speed`       | 0.003   | smaller commands give 0 (m/s)                |
    | `robot.wheel_accel_limit`     | inf     | wheel acceleration limit (m/s²); inf = none  |
    | `robot.mass`                  | 0.54    | kg                                           |
    | `arena.width`, `arena.height` | 2.0     | inner arena size (m), centred at the origin  |
    | `arena.wall_thickness`        | 0.05    | m, outside the inner rectangle               |
    | `arena.walls`                 | true    | false: open floor (size bounds spawning only) |
    | `obstacles.fixed`             | []      | fixed obstacles: inline tables `{kind =      |
    |                               |         | "circle", center, radius}`, `{kind = "box",  |
    |                               |         | center, half_extents, angle}`, `{kind =      |
    |                               |         | "segment", a, b}`                            |
    | `obstacles.count`             | 0       | random obstacles drawn at every reset        |
    | `obstacles.kinds`             | all 3   | shapes of the random obstacles               |
    | `obstacles.circle_radius`     | [0.04, 0.10] | range of random circle radii (m)        |
    | `obstacles.box_half_extent`   | [0.03, 0.10] | range of random box half sides (m)      |
    | `obstacles.segment_length`    | [0.20, 0.45] | range of random segment lengths (m)     |
    | `obstacles.placement`         | between | "between" start and goal, or "anywhere"      |
    | `obstacles.corridor_width`    | 0.8     | band around start→goal for "between" (m)     |
    | `obstacles.min_gap`           | 0.16    | free gap around random obstacles (m); ≥ the  |
    |                               |         | robot's diameter + 1 cm keeps goals reachable |
    | `obstacles.spawn_clearance`   | 0.05    | gap between obstacles and start/goal (m)     |
    | `spawn.wall_margin`           | 0.05    | clearance from the walls at reset (m)        |
    | `spawn.min_goal_distance`     | 0.5     | least start-goal distance at reset (m)       |
    | `spawn.start`                 | []      | [] random, or fixed [x, y, heading]          |
    | `spawn.goal`                  | []      | [] random, or fixed [x, y]                   |
    | `sensors.ir_range`            | 0.25    | m; beyond it the IR reads the floor value    |
    | `sensors.ir_floor_value`      | 100.0   | raw IR count with nothing in range           |
    | `sensors.ir_noise_sigma`      | 10.0    | raw counts, Gaussian                         |
    | `sensors.us_min_range`        | 0.25    | m; closer reads code 0                       |
    | `sensors.us_max_range`        | 2.0     | m; farther reads code 1000                   |
    | `sensors.us_noise_sigma`      | 0.01    | m, Gaussian                                  |
    | `sensors.us_enabled`          | 5×true  | per sensor; a disabled one reads code 2000   |
    | `task.goal_radius`            | 0.05    | success distance (m)                         |
    | `task.max_steps`              | 400     | steps before truncation                      |
    | `task.progress_weight`        | 10.0    | reward per metre of progress                 |
    | `task.time_cost`              | 0.01    | reward subtracted per step                   |
    | `task.success_bonus`          | 10.0    | reward on success                            |
    | `task.collision_penalty`      | 0.1     | reward subtracted per step in contact        |
    | `task.terminate_on_collision` | false   | end the episode on contact                   |
    | `physics.dt`                  | 0.05    | control step (s)                             |
    | `physics.substeps`            | 4       | physics substeps per control step            |
    | `physics.solver_iterations`   | 4       | rapier solver iterations for contact steps   |
    | `physics.friction`            | 0.0     | robot-wall friction (0: slide along walls)   |

    ## Version History

    * v0: Initial version.
    """

    TASK: ClassVar[str] = "nav"


# --- heuristic policy of the Nav task (paper eqs. 1-4) --------------------------------------------

#: Cruise speed of the position controller (m/s).
NAV_HEURISTIC_V_MAX = 0.3
#: Largest turn rate of the position controller (rad/s).
NAV_HEURISTIC_W_MAX = 4.0
#: Distance to the goal below which the controller slows down proportionally (m).
NAV_HEURISTIC_K_R = 0.15
#: Distance between the wheels of the Khepera IV (m).
KHEPERA_AXLE_LENGTH = 0.1054
#: Largest wheel speed of the Khepera IV (m/s); normalised wheel commands are divided by it.
KHEPERA_MAX_WHEEL_SPEED = 0.813


def nav_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Position controller of the KH4VREP paper (eqs. 1-4) acting on Nav observations.

    ``v = v_max`` beyond ``k_r`` of the goal, else ``d · v_max / k_r``; ``ω = ω_max · sin(α)``
    with α the goal bearing in the robot frame; converted to normalised wheel speeds
    ``(v ∓ ω · axle / 2) / 0.813`` clipped to [-1, 1]. ``v_max`` = 0.3 m/s, ``ω_max`` = 4 rad/s,
    ``k_r`` = 0.15 m. Ignores obstacles.

    Args:
        observation: One Nav observation of shape (obs_dim,) or a batch (N, obs_dim).

    Returns:
        Wheel actions of shape (2,) or (N, 2), float32, for ``action_type="wheels"``.
    """
    observation = np.asarray(observation, dtype=np.float32)
    layout = obs_layout("nav")
    goal_distance = observation[..., layout["goal_distance"]][..., 0]
    bearing_sin = observation[..., layout["goal_bearing_sin"]][..., 0]
    bearing_cos = observation[..., layout["goal_bearing_cos"]][..., 0]
    bearing = np.arctan2(bearing_sin, bearing_cos)
    speed = np.where(
        goal_distance > NAV_HEURISTIC_K_R,
        NAV_HEURISTIC_V_MAX,
        goal_distance * (NAV_HEURISTIC_V_MAX / NAV_HEURISTIC_K_R),
    )
    turn_rate = NAV_HEURISTIC_W_MAX * np.sin(bearing)
    half_axle = 0.5 * KHEPERA_AXLE_LENGTH
    wheel_speeds = np.stack((speed - turn_rate * half_axle, speed + turn_rate * half_axle), axis=-1)
    return np.clip(wheel_speeds / KHEPERA_MAX_WHEEL_SPEED, -1.0, 1.0).astype(np.float32)


__all__ = ["ACTION_TYPES", "KheperaEnv", "NavEnv", "nav_heuristic"]
