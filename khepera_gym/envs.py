"""Single-world Gymnasium environments over the Rust core, and heuristic policies that solve them.

:class:`NavEnv` (drive to a goal), :class:`AvoidEnv` (the same among random obstacles) and
:class:`FormationEnv` (followers holding a formation around a leader) share :class:`KheperaEnv`;
their heuristics are :func:`nav_heuristic`, :func:`avoid_heuristic` and :func:`formation_heuristic`,
thin wrappers of the paper's controllers in :mod:`khepera_gym.baselines` (computed in Rust).

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
from khepera_gym._inputs import SEED_LIMIT, as_action_array, check_seed
from khepera_gym.baselines import Braitenberg, LeaderFollower, PositionControl
from khepera_gym.config import ACTION_TYPES, ConfigArg, make_batch
from khepera_gym.errors import ConfigError
from khepera_gym.layout import layout_dict
from khepera_gym.render import DEFAULT_FRAME_SIZE, Renderer
from khepera_gym.state import StateMixin

#: Largest seed drawn from ``np_random`` on a first ``reset()`` without a seed (exclusive).
_SEED_BOUND = 2**62


def _check_render_mode(render_mode: str | None, render_modes: list[str]) -> None:
    if render_mode is not None and render_mode not in render_modes:
        raise ConfigError(
            f"render_mode={render_mode!r} is not supported (supported: {[None, *render_modes]})"
        )


class KheperaEnv(StateMixin, gym.Env[npt.NDArray[np.float32], npt.NDArray[np.float32]]):
    """Base of the single-world Khepera IV environments; subclasses set :attr:`TASK`.

    Args:
        render_mode: None, "rgb_array" (``render()`` returns the frame) or "human" (a pygame
            window refreshed after every step; ``pip install khepera-gym[render]``).
        config: None (built-in defaults), a built-in scenario name, or a path to a TOML file.
        action_type: "wheels" (normalised left/right wheel speeds) or "unicycle" (normalised v, ω).
        frame_size: (width, height) of rendered frames in pixels.
        **overrides: Scenario keys overriding the file, e.g. ``goal_radius=0.1`` or
            ``task={"max_steps": 100}`` (see the task's docstring, section Scenario file).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "human"], "render_fps": 20}
    #: Task name in the Rust core.
    TASK: ClassVar[str] = ""

    def __init__(
        self,
        render_mode: str | None = None,
        config: ConfigArg = None,
        action_type: str = "wheels",
        frame_size: tuple[int, int] = DEFAULT_FRAME_SIZE,
        **overrides: Any,
    ) -> None:
        _check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.action_type = action_type
        self._batch = make_batch(
            self.TASK,
            1,
            config,
            overrides,
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
        self._renderer = Renderer(
            self._batch,
            render_mode,
            frame_size,
            fps=self.metadata["render_fps"],
            title=f"khepera_gym {self.TASK}",
        )

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The current frame, drawn in software without a display: (height, width, 3) uint8 for
        ``render_mode="rgb_array"``; for ``"human"`` it is shown in a pygame window (also after
        every step) and None is returned; None without a render mode.

        The frame shows the arena, obstacles, goal(s), formation targets, the robots' fading
        trails, IR rays (green, turning red as an obstacle nears) and ultrasonic rays (blue, to
        the echo), and each robot with its heading (red rim while in contact).
        """
        return self._renderer.render()

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
        if isinstance(seed, int) and seed >= SEED_LIMIT:  # Gymnasium checks the rest
            check_seed(seed)
        super().reset(seed=seed)
        if seed is None and not self._has_reset:
            seed = int(self.np_random.integers(_SEED_BOUND))
        observations = self._batch.reset(seed)
        self._has_reset = True
        if self.render_mode == "human":
            self.render()
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
        buffer = self._action_buffer
        buffer[0] = as_action_array(action, self._action_shape, "action")
        observations, rewards, terminations, truncations = self._batch.step(buffer)
        terminated = bool(terminations[0])
        truncated = bool(truncations[0])
        info = self._episode_info() if terminated or truncated else {}
        if self.render_mode == "human":
            self.render()
        return observations[0], float(rewards[0]), terminated, truncated, info

    def _episode_info(self) -> dict[str, Any]:
        # .item() gives Python float/int/bool of the same value for every statistic the task has.
        stats = {name: values[0].item() for name, values in self._batch.episode_stats().items()}
        return {"episode_stats": stats, "is_success": stats["success"]}

    def obs_layout(self) -> dict[str, slice]:
        """Observation layout of this env's scenario, name → slice (with agent prefixes such as
        "follower_0/ir" when there are several robots)."""
        return layout_dict(self._batch.obs_layout())

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
        """Closes the render window, if any (the Rust world is freed with the env); safe to call
        twice."""
        self._renderer.close()
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
    >>> env = gym.make("KheperaIV-Nav-v0", max_steps=200, goal_radius=0.1)
    >>> env
    <OrderEnforcing<PassiveEnvChecker<NavEnv<KheperaIV-Nav-v0>>>>
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
    >>> env = gym.make("KheperaIV-Avoid-v0", config="paper_fig6", max_steps=300)
    >>> obs, info = env.reset(seed=0)
    >>> [obstacle["kind"] for obstacle in env.unwrapped.scene()["obstacles"]]
    ['box', 'box']
    >>> env.unwrapped.poses()[0].round(2).tolist(), env.unwrapped.goals()[0].round(2).tolist()
    ([-0.75, 0.05, 0.0], [0.75, 0.05])

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `action_type`,
    `**overrides`); `config` is None (the Avoid defaults), a built-in scenario name such as
    `"paper_fig6"`, or a path to a TOML file, and keyword overrides are merged on top, e.g.
    `gym.make("KheperaIV-Avoid-v0", count=20, kinds=["circle"])`.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Avoid-v0", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.AvoidVectorEnv` (same semantics as Nav's: NEXT_STEP autoreset,
    `infos["episode_stats"]` with masks, world i reset with seed s ≡ this env reset with seed
    s + i, bit for bit). `envs.scene(i)` is the geometry of world i.

    ```python
    >>> envs = gym.make_vec("KheperaIV-Avoid-v0", num_envs=16, num_threads=2)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape
    (16, 18)

    ```

    ## Robot model

    As :class:`NavEnv`: a Khepera IV disc (radius 0.0704 m, wheels 0.1054 m apart, ±0.813 m/s),
    a dynamic rapier2d body that obstacles stop or deflect. `physics.friction` (0) lets it slide
    along walls and obstacles.

    ## Sensors

    As :class:`NavEnv`: 8 IR proximity sensors (2-250 mm) and 5 ultrasonic sensors (0.25-2 m),
    exact ray casts against the walls and every obstacle, with noise;
    `env.unwrapped.sensor_readings()` gives them in the real robot's units.

    ## Scenario file

    The keys are those of :class:`NavEnv` (its Scenario file section tables them all; the
    resolved defaults are `khepera_gym._core.default_config("avoid")`). Defaults that differ from
    Nav:

    | Key                         | Default    | Meaning                                      |
    |-----------------------------|------------|----------------------------------------------|
    | `obstacles.count`           | 10         | random obstacles drawn at every reset        |
    | `obstacles.placement`       | anywhere   | uniform in the arena ("between": start-goal) |
    | `spawn.min_goal_distance`   | 1.0        | least start-goal distance (m)                |
    | `task.max_steps`            | 600        | steps before truncation (30 s)               |
    | `task.collision_penalty`    | 0.5        | reward subtracted per step in contact        |

    Fixed obstacles go in `obstacles.fixed`, e.g.
    `fixed = [{kind = "box", center = [0.0, 0.2], half_extents = [0.025, 0.4], angle = 0.0}]`.
    A scenario that cannot work raises `khepera_gym.errors.ConfigError` naming the file and the
    key: an obstacle with a size ≤ 0 or outside the arena (`obstacles.fixed[i]`), random
    obstacles that cannot fit (`obstacles.count`), a gap too small to pass
    (`obstacles.min_gap`, at least the robot's diameter + 1 cm).

    ## Version History

    * v0: Initial version.
    """

    TASK: ClassVar[str] = "avoid"


class FormationEnv(KheperaEnv):
    r"""Keep K Khepera IV followers in formation around a leader driving to a goal.

    ## Description

    The leader-follower exercise of the KH4VREP paper (Farias et al., IFAC 2017, §3.5, Fig. 7).
    Robot 0, the leader, drives to a goal; by default it is scripted in Rust: the paper's position
    controller (eqs. 1-4, on its true pose, at `formation.leader_vmax` = 0.15 m/s) followed by its
    Braitenberg avoidance block (eqs. 5-7) on its own IR ring. The K followers (4 by default),
    robots 1..K, are driven jointly by this env's action; follower k must hold the point at
    offset (r_k, β_k) from the leader's pose (paper eq. 12):
    `x_k = x_L + r_k cos(β_k + θ_L)`, `y_k = y_L + r_k sin(β_k + θ_L)`. Shapes: `"cross"`
    (Fig. 7: ahead, left, behind, right at `formation.spacing` = 0.5 m), `"line"` (abreast),
    `"wedge"` (a V behind), `"circle"` and `"custom"` (`formation.offsets`). The arena is
    3 m × 3 m with walls and, by default, no obstacles; robots are obstacles to one another
    (contacts and sensor rays). `config="paper_fig7"` loads the paper's scene (the cross past four
    obstacles). With `leader="agent"` the leader is driven by the action too, with the Nav
    observation and reward. :func:`formation_heuristic` (the paper's leader-follower control,
    :class:`khepera_gym.baselines.LeaderFollower`, toward each follower's `target_offset`)
    keeps the default formation within a centimetre on average.

    ## Action Space

    `Box(-1, 1, (2K,), float32)` (8 for the default K = 4): follower k's normalised (left, right)
    wheel speeds, 1 = 0.813 m/s, at indices 2k and 2k + 1. With `leader="agent"` the leader's
    pair comes first: shape (2 + 2K,). `action_type="unicycle"` makes every pair a normalised
    (v, ω), as in :class:`NavEnv`. Out-of-range values are clipped; NaN/inf or a wrong shape raise
    `khepera_gym.errors.ActionError`.

    ## Observation Space

    `Box(low, high, (23K,), float32)` (92 for K = 4): one block of 23 values per follower, in
    follower order; with `leader="agent"` the leader's Nav block (18 values, the table of
    :class:`NavEnv`) comes first, shape (18 + 23K,). `khepera_gym.obs_layout("formation")` names
    the slices of the default scenario ("follower_0/ir", "follower_0/us", ...). Every follower's
    block has the same bounds, so one policy can serve them all (parameter sharing). Block of
    follower k, in its own robot frame (x forward, y left):

    | Index | Name            | Observation                                        | Min   | Max  |
    |-------|-----------------|----------------------------------------------------|-------|------|
    | 0-7   | ir              | IR proximity, K-Team order back-left ... back      | 0     | 1    |
    | 8-12  | us              | ultrasonic left, front-left, front, front-right,   | 0     | 1    |
    |       |                 | right                                              |       |      |
    | 13-14 | target_offset   | x, y of its target point (eq. 12) in its robot     | -4.24 | 4.24 |
    |       |                 | frame (m)                                          |       |      |
    | 15-16 | leader_offset   | x, y of the leader in its robot frame (m)          | -4.24 | 4.24 |
    | 17-18 | leader_heading  | sin, cos of the leader's heading minus its own     | -1    | 1    |
    | 19-20 | leader_velocity | the leader's v / 0.813 m/s and ω / 15.4 rad/s      | -1    | 1    |
    | 21-22 | wheel_speeds    | its left, right wheel speed / 0.813 m/s            | -1    | 1    |

    IR and ultrasonic as in :class:`NavEnv` (other robots are seen too). `target_offset` and
    `leader_offset` are clipped to the arena diagonal (4.24 m by default); a target offset of
    (0, 0) means the follower is on its target. With `leader_offset` and `leader_heading` a
    controller can compute eq. 12 targets of its own (`khepera_gym.baselines.LeaderFollower`).
    `leader_velocity` is the leader's forward speed and yaw rate, normalised by the largest wheel
    speed and the largest yaw rate 2 · 0.813 / 0.1054 ≈ 15.4 rad/s. Follower k's block starts at
    index 23k (18 + 23k with an agent leader).

    ## Rewards

    Each follower k earns `-error_weight · e_k - collision_penalty · [k in contact]
    - team_weight · mean_j e_j` per step, with e_k its distance to its target after the step (m),
    `formation.error_weight` = 1, `task.collision_penalty` = 0.1 and `formation.team_weight` = 0.
    An agent leader earns the Nav reward. The reward returned by `step` is the mean over the
    agents (followers, plus the leader when it is an agent); `env.unwrapped.agent_rewards()` gives
    each agent's.

    ## Starting State

    The leader's start position is uniform in the arena shrunk by the robot radius and
    `spawn.wall_margin`, its goal uniform at least `spawn.min_goal_distance` (1.5 m) away and
    reachable, and the leader faces its goal (so the formation does not swing round at the
    start); both are redrawn until the whole formation fits at the start and at the goal (every
    follower on its target, clear of walls and obstacles). The robots start at rest, in
    formation, with the leader's heading. `spawn.start` ([x, y, heading]) and `spawn.goal` fix the
    leader's. `reset(seed=s)` reproduces all of it; `reset()` continues the stream.

    ## Episode End

    1. Termination: the leader's centre is within `task.goal_radius` (0.05 m) of its goal
       (success; the scripted leader stops there).
    2. Termination: any robot in contact with something, only if
       `task.terminate_on_collision = true`.
    3. Truncation: `task.max_steps` (800) steps have passed, i.e. 40 s at dt = 0.05 s.

    At the last step `info["episode_stats"]` holds `"return"`, `"length"`, `"success"` (the
    leader arrived), `"path_length"` (m, summed over the robots), `"collisions"` (steps in which
    some robot was in contact), and `"formation_error_mean"` and `"formation_error_max"` (m: the
    followers' distance to their targets, averaged over followers and steps, and its maximum);
    `info["is_success"]` as in :class:`NavEnv`.

    ## Arguments

    ```python
    >>> env = gym.make("KheperaIV-Formation-v0", config="paper_fig7")
    >>> env.action_space.shape, env.observation_space.shape
    ((8,), (92,))
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.poses().shape, env.unwrapped.formation_targets().shape
    ((5, 3), (4, 2))
    >>> gym.make("KheperaIV-Formation-v0", leader="agent", n_followers=2).action_space.shape
    (6,)

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `action_type`,
    `**overrides`). The `[formation]` keys are overrides like any other, by leaf
    (`shape="wedge"`, `n_followers=3`, `leader="agent"`) or by section
    (`formation={"leader": "agent"}`). `env.unwrapped.formation_targets()` gives the followers'
    target points, shape (K, 2); `poses()` is (K + 1, 3) with the leader first; `goals()` (1, 2)
    is the leader's goal.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Formation-v0", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.FormationVectorEnv` (NEXT_STEP autoreset, episode statistics with
    masks, world i reset with seed s ≡ this env reset with seed s + i); its
    `formation_targets()` has shape (N, K, 2).

    ```python
    >>> envs = gym.make_vec("KheperaIV-Formation-v0", num_envs=8)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape, envs.formation_targets().shape
    ((8, 92), (8, 4, 2))

    ```

    For one agent per follower use the PettingZoo environment
    :mod:`khepera_gym.pettingzoo.formation_v0`.

    ## Robot model

    As :class:`NavEnv`, for each of the K + 1 robots: Khepera IV discs (radius 0.0704 m, wheels
    0.1054 m apart, ±0.813 m/s) as dynamic rapier2d bodies; contacts between robots are resolved
    like any other.

    ## Sensors

    As :class:`NavEnv`, per robot: 8 IR and 5 ultrasonic sensors; the other robots block their
    rays. `env.unwrapped.sensor_readings()` gives raw values with a robot axis (K + 1, ...).

    ## Scenario file

    The keys of :class:`NavEnv` (its Scenario file section tables them) plus a `[formation]`
    table; `khepera_gym._core.default_config("formation")` is the resolved default file.
    `spawn.start` and `spawn.goal` are the leader's. Defaults that differ from Nav, and the
    `[formation]` keys:

    | Key                      | Default  | Meaning                                           |
    |--------------------------|----------|---------------------------------------------------|
    | `arena.width`            | 3.0      | m, room for a formation to travel                 |
    | `arena.height`           | 3.0      | m                                                 |
    | `spawn.min_goal_distance`| 1.5      | least leader start-goal distance (m)              |
    | `task.max_steps`         | 800      | steps before truncation (40 s)                    |
    | `formation.shape`        | cross    | cross, line, wedge, circle or custom              |
    | `formation.n_followers`  | 4        | K followers, 1..16 (ignored by "custom")          |
    | `formation.spacing`      | 0.5      | r (m) of the nearest followers; further ones at   |
    |                          |          | 2r, 3r, ... along the same directions             |
    | `formation.offsets`      | []       | custom shape: [[r, beta], ...] (m, rad CCW from   |
    |                          |          | the leader's heading), 1 to 16 of them            |
    | `formation.leader`       | scripted | "scripted" (position control + Braitenberg in     |
    |                          |          | Rust) or "agent" (driven by the action)           |
    | `formation.leader_vmax`  | 0.15     | m/s, scripted leader's speed (eq. 3)              |
    | `formation.leader_wmax`  | 1.0      | rad/s, scripted leader's turn-rate limit (eq. 4)  |
    | `formation.leader_kr`    | 0.15     | m, scripted leader's slow-down radius (eq. 3)     |
    | `formation.error_weight` | 1.0      | reward per metre of a follower's own error        |
    | `formation.team_weight`  | 0.0      | reward per metre of the followers' mean error     |

    Shapes: "cross" puts follower i at β = i · 90° (ahead, left, behind, right); "line" at
    ±90° (left, right alternately); "wedge" at ±135°; "circle" evenly at r. Robots in formation
    closer than a diameter + 1 cm raise `khepera_gym.errors.ConfigError` (`formation.spacing`
    or `formation.offsets`).

    ## Version History

    * v0: Initial version.
    """

    TASK: ClassVar[str] = "formation"

    def formation_targets(self) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12) for the current leader pose, shape (K, 2), m."""
        return self._batch.formation_targets()[0]

    def agent_rewards(self) -> npt.NDArray[np.float32]:
        """Each agent's reward on the last step, shape (n_agents,): followers in order, after
        the leader when it is an agent; ``step`` returns their mean."""
        return self._batch.agent_rewards()[0]


# --- heuristic policies: the paper's controllers of khepera_gym.baselines ------------------------

#: Default Braitenberg weights (m/s per unit of IR proximity; paper eqs. 5-7), as the Rust core
#: defines them: rows left, right wheel; columns the IR sensors in K-Team order.
BRAITENBERG_WEIGHTS = np.array(_core.braitenberg_weights("default"), dtype=np.float32)

#: The heuristics' controllers, with their defaults (immutable and stateless: safe to share).
_NAV_POLICY = PositionControl()
_AVOID_POLICY = Braitenberg()
_FORMATION_POLICY = LeaderFollower(shape=None, leader=_AVOID_POLICY)


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
    return _NAV_POLICY(observation)


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
    return _AVOID_POLICY(observation)


def formation_follower_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Leader-follower control (paper eq. 12) of follower blocks, toward their own targets.

    :class:`khepera_gym.baselines.LeaderFollower` with ``shape=None``: each follower drives
    to the target of its observation (``target_offset``, eq. 12 as the scenario defines it)
    with position control (v_max 0.35 m/s, ω_max 4 rad/s, k_r 0.08 m), plus the leader's speed
    along its heading (feed-forward), then Braitenberg avoidance. Fits any shape and number of
    followers, and a PettingZoo follower's own observation.

    Args:
        observation: One follower block of shape (23,), or any batch of them (..., 23).

    Returns:
        Wheel actions of shape (..., 2), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: Wrong length or NaN/inf in the observation.
    """
    return _FORMATION_POLICY(observation)


def formation_heuristic(observation: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Joint action of :class:`FormationEnv` from its joint observation.

    Every follower block gets :func:`formation_follower_heuristic`; an agent leader's Nav block
    (present when the observation length is 18 + 23K) gets :func:`avoid_heuristic`.

    Args:
        observation: One Formation observation of shape (obs_dim,) or a batch (N, obs_dim).

    Returns:
        Actions of shape (act_dim,) or (N, act_dim), float32, for ``action_type="wheels"``.

    Raises:
        ActionError: The length is neither 23K nor 18 + 23K (a ``ValueError``), or NaN/inf.
    """
    return _FORMATION_POLICY(observation)


__all__ = [
    "ACTION_TYPES",
    "BRAITENBERG_WEIGHTS",
    "AvoidEnv",
    "FormationEnv",
    "KheperaEnv",
    "NavEnv",
    "avoid_heuristic",
    "formation_follower_heuristic",
    "formation_heuristic",
    "nav_heuristic",
]
