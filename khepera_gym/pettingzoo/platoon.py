"""The ``platoon_vN`` modules (one a behaviour version, the same env on that version's
dynamics): a platoon of Khepera IV robots tracking time-shifted copies of one reference
trajectory, one PettingZoo agent per robot. The manual is :class:`PlatoonParallelEnv`'s
docstring. Units are SI (m, s, rad); robot frame x forward, y left::

    from khepera_gym.pettingzoo import platoon_v3

    env = platoon_v3.parallel_env(robots=3)
"""

from __future__ import annotations

from typing import Any, ClassVar

from khepera_gym.config import ConfigArg
from khepera_gym.pettingzoo._parallel import (
    KheperaParallelEnv,
    merge_table_keywords,
)


class PlatoonParallelEnv(KheperaParallelEnv):
    r"""N robots track one reference trajectory, robot k delayed by k · `platoon.time_gap`.

    ## Description

    The multi-robot form of trajectory tracking (:class:`khepera_gym.envs.TrackEnv`). One
    reference point p_r(t) moves on a closed curve centred in the 2 m × 2 m walled
    arena (`platoon.reference`: circle, lemniscate, square, spline or waypoints, as Track's
    `track.reference`); robot k must be at p_r(t − k·τ) at time t, heading along the curve, with
    τ = `platoon.time_gap` (2 s). Its reference is robot k − 1's, τ seconds later: the robots
    drive in a column, neighbours τ · v_r apart along the curve (0.30 m on the default circle at
    0.15 m/s, about one body of free space between the 0.14 m shells). The robots are obstacles
    to one another: their discs block each other's sensor rays and rapier resolves their
    contacts. :class:`khepera_gym.baselines.Kanayama` applied to each agent's observation
    converges every robot within a few seconds (measured below).

    ## Agents

    `robot_0` .. `robot_{N-1}` (`platoon.robots` = 3, up to 16 and as many as one lap holds),
    agent k driving robot k (`env.agent_robot(agent)`); robot 0 leads. Every agent has the same
    spaces.

    ## Action Space

    `Box(-1, 1, (2,), float32)` per agent: normalised (left, right) wheel speeds,
    1 = 0.813 m/s; `action_type="unicycle"` makes them a normalised (v, ω).

    ## Observation Space

    Per agent `Box(low, high, (29,), float32)`, Track's observation of its own reference
    (:class:`khepera_gym.envs.TrackEnv`'s table), so a Track policy runs on each agent
    unchanged; `env.agent_obs_layout(agent)` names the slices, `state()` is the joint
    observation (N × 29, blocks prefixed `robot_k/`). In the robot frame, from the pose the robot
    believes it has:

    | Index | Name            | Observation                                        | Min   | Max  |
    |-------|-----------------|----------------------------------------------------|-------|------|
    | 0-7   | ir              | IR proximity, K-Team order back-left ... back      | 0     | 1    |
    | 8-12  | us              | ultrasonic left, front-left, front, front-right,   | 0     | 1    |
    |       |                 | right                                              |       |      |
    | 13-14 | tracking_error  | e_x, e_y: its reference point in the robot frame   | -2.83 | 2.83 |
    |       |                 | (m)                                                |       |      |
    | 15-16 | heading_error   | sin e_θ, cos e_θ with e_θ = θ_r - θ                | -1    | 1    |
    | 17-18 | reference_rates | feed-forward v_r / 0.813 m/s, ω_r / 15.4 rad/s     | -1    | 1    |
    | 19-26 | preview         | x, y of its next 4 reference points, every 0.25 s  | -2.83 | 2.83 |
    |       |                 | ahead, in the robot frame (m)                      |       |      |
    | 27-28 | wheel_speeds    | left, right wheel speed / 0.813 m/s                | -1    | 1    |

    The IR and ultrasonic sensors see the neighbours as well as the walls.

    ## Rewards

    Per agent and step, Track's: `-error_weight · ‖e_k‖ - heading_weight · (1 - cos e_θk)`
    with ‖e_k‖ the distance from robot k's centre to its reference point after the step (m)
    (`platoon.error_weight` = 1, `platoon.heading_weight` = 0.1), minus
    `task.collision_penalty` (0.1) on a step that ends with robot k in contact (with a wall or a
    neighbour). A lost agent gets 0.

    ## Starting State

    One reference per episode: its starting phase is uniform (`platoon.random_phase`) and its
    direction drawn (`platoon.direction`). Robot k starts at rest up to `platoon.start_offset`
    (0.2 m) from its own reference point p_r(−k·τ) with a heading up to
    `platoon.start_heading_offset` (45°) from its reference's, and at least a diameter plus
    `obstacles.spawn_clearance` (0.05 m) from the robots before it (its start is drawn again
    otherwise, up to 64 times, then the whole platoon, up to 16 times; then every robot starts
    on its reference point). All of it comes from the world's random stream: `reset(seed=s)`
    reproduces it bit for bit.

    ## Episode End

    1. Termination of one agent (lost): robot k is more than `platoon.lost_distance` (0.5 m)
       from its reference point. It leaves `env.agents` and parks (zero wheel commands, braking
       at the wheels' acceleration limit), still an obstacle for the others.
    2. Termination of every agent: all are lost, or any contact if
       `task.terminate_on_collision = true`.
    3. Truncation of the remaining agents: one period plus `platoon.truncation_margin` (2 s) has
       passed (the circle: 543 steps), or `max_cycles` steps if sooner.

    At the episode's end each remaining agent's info holds its own `"episode_stats"` (its
    return, length, success, path length and contacts) and `"world_episode_stats"`: the common
    statistics (`"return"`: the sum of the agents' mean reward, `"length"`, `"success"`, always
    False, `"path_length"` summed over robots, `"collisions"`: steps with any robot in contact)
    and Track's four over the platoon, each robot counted until it is lost:
    `"track_error_rms"` (m: the root mean square of the robots' RMS errors after the first
    `platoon.transient` = 5 s), `"track_error_max"` (m: the largest over robots),
    `"track_iae"` (m·s: the sum of the robots' Σ ‖e_k‖ dt) and `"track_converge_time"` (s: when
    the last robot's error fell below `platoon.converge_radius` = 2 cm for good; inf if a robot
    is above it at the end or lost).

    Measured: Kanayama (default gains) on every agent of the default platoon (3 robots on the
    circle), 20 episodes seeded 0..19 (`python examples/platoon_kanayama.py`): no robot lost,
    no contact; each robot's RMS error after 5 s averages 0.9, 0.9 and 1.1 mm (robots 0, 1, 2;
    worst episode 3.0 mm), its largest error after 5 s is at most 20 mm, `track_error_rms`
    averages 1.1 mm, `track_iae` 0.91 m·s, and `track_converge_time` 4.0 s (5.0 s at worst).
    With 5 robots on the lemniscate (`--robots 5 --reference lemniscate`) neighbours are
    closer where the curve slows down and the 0.2 m start offsets make them meet during the
    transient: 20 steps with a robot in contact per episode on average (119 at most), the
    largest error after 5 s 0.25 m, the per-robot RMS after 5 s 1.4 to 6.8 mm on average, no
    robot lost.

    ## Arguments

    ```python
    >>> from khepera_gym.pettingzoo import platoon_v3
    >>> from khepera_gym.baselines import Kanayama
    >>> env = platoon_v3.parallel_env(robots=4, reference="lemniscate")
    >>> env.possible_agents
    ['robot_0', 'robot_1', 'robot_2', 'robot_3']
    >>> observations, infos = env.reset(seed=0)
    >>> env.goals().shape   # each robot's reference point now
    (4, 2)
    >>> observations, rewards, terminations, truncations, infos = env.step(Kanayama()(observations))

    ```

    `robots` and `time_gap` set `platoon.robots` and `platoon.time_gap`; `config`,
    `action_type`, `max_cycles`, `render_mode`, `frame_size` and further scenario overrides
    (`reference="square"`, `speed=0.1`, `platoon={"direction": "ccw"}`) are those of the other
    PettingZoo envs. `env(**kwargs)` is the AEC version. `env.poses()` gives the robots' poses,
    (N, 3); `env.goals()` their reference points, (N, 2); `env.targets()` their preview points,
    robot by robot, (N · 4, 2).

    ## Scenario file

    The keys of :class:`khepera_gym.envs.NavEnv` with Track's `task.max_steps` (4000, a cap:
    the episode is truncated after one lap) and a `[platoon]` table: `robots` (3), `time_gap`
    (2.0 s, [E]: 0.30 m at 0.15 m/s, the road's two-second headway), then every key of Track's
    `[track]` table with Track's default (:class:`khepera_gym.envs.TrackEnv`'s Scenario file
    table), named `platoon.<key>` (a scenario has one task table). The resolved default file is
    `khepera_gym.default_config("platoon")` (also `configs/platoon.toml`).
    `khepera_gym.errors.ConfigError` names the key when: `platoon.robots` is outside 1..16 or
    more robots than one lap holds (N · τ > the period); `platoon.time_gap` is not positive, or
    τ times the mean reference speed is less than a robot's diameter plus 2 cm (0.16 m), or the
    curve brings two robots' reference points closer than that (where it slows down or crosses
    itself; checked on the mean circle for splines, which are drawn at reset); `spawn.start` or
    `spawn.goal` is given (the platoon places its robots); or Track's checks fail
    (`platoon.size`, `platoon.speed`, `platoon.waypoints`, ...).
    """

    TASK: ClassVar[str] = "platoon"
    FAMILY: ClassVar[str] = "platoon"

    def __init__(
        self,
        robots: int | None = None,
        time_gap: float | None = None,
        config: ConfigArg = None,
        max_cycles: int | None = None,
        **kwargs: Any,
    ) -> None:
        merge_table_keywords(kwargs, "platoon", {"robots": robots, "time_gap": time_gap})
        super().__init__(config=config, max_cycles=max_cycles, **kwargs)


__all__ = ["PlatoonParallelEnv"]
