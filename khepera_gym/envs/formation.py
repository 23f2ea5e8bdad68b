"""KheperaIV-Formation: K followers hold a formation around a leader driving to a goal (paper
eq. 12); and the leader-follower heuristics that solve it.

The manual is the class's docstring. Units are SI (m, s, rad); robot frame x forward, y left.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import numpy.typing as npt

from khepera_gym.baselines import LeaderFollower
from khepera_gym.batch_face import BatchFace
from khepera_gym.envs.base import KheperaEnv
from khepera_gym.envs.nav import AVOID_POLICY


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
    >>> import gymnasium as gym
    >>> env = gym.make("KheperaIV-Formation", config="paper_fig7")
    >>> env.action_space.shape, env.observation_space.shape
    ((8,), (92,))
    >>> obs, info = env.reset(seed=0)
    >>> env.unwrapped.poses().shape, env.unwrapped.formation_targets().shape
    ((5, 3), (4, 2))
    >>> gym.make("KheperaIV-Formation", leader="agent", n_followers=2).action_space.shape
    (6,)

    ```

    The parameters are those of :class:`NavEnv` (`render_mode`, `config`, `action_type`,
    `**overrides`). The `[formation]` keys are overrides like any other, by leaf
    (`shape="wedge"`, `n_followers=3`, `leader="agent"`) or by section
    (`formation={"leader": "agent"}`). `env.unwrapped.formation_targets()` gives the followers'
    target points, shape (K, 2); `poses()` is (K + 1, 3) with the leader first; `goals()` (1, 2)
    is the leader's goal.

    ## Vectorized environment

    `gym.make_vec("KheperaIV-Formation", num_envs=N, num_threads=None)` returns the native
    :class:`khepera_gym.vector.FormationVectorEnv` (NEXT_STEP autoreset or DISABLED with resets
    by mask, episode statistics with masks, world i reset with seed s ≡ this env reset with seed
    s + i); its `formation_targets()` has shape (N, K, 2).

    ```python
    >>> envs = gym.make_vec("KheperaIV-Formation", num_envs=8)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape, envs.formation_targets().shape
    ((8, 92), (8, 4, 2))

    ```

    For one agent per follower use the PettingZoo environment
    :mod:`khepera_gym.pettingzoo.formation` (its `formation_vN` modules).

    ## Robot model

    As :class:`NavEnv`, for each of the K + 1 robots: Khepera IV discs (radius 0.0704 m, wheels
    0.1054 m apart, ±0.813 m/s) as rigid discs; contacts between robots are resolved by rapier2d,
    those with walls and obstacles as for one robot.

    ## Sensors

    As :class:`NavEnv`, per robot: 8 IR and 5 ultrasonic sensors; the other robots block their
    rays. `env.unwrapped.sensor_readings()` gives raw values with a robot axis (K + 1, ...).

    ## Scenario file

    The keys of :class:`NavEnv` plus a `[formation]` table (shape, followers, spacing, the scripted
    leader's gains, the reward's weights), in a 3 m × 3 m arena. `spawn.start` and `spawn.goal` are
    the leader's. Every key, with its default in each version, its units, its comment and its
    source, is tabled on this env's page of the documentation (generated from the core's
    declarations by `make docs`); `khepera_gym.default_config("formation")` prints them as a TOML
    file.

    Shapes: "cross" puts follower i at β = i · 90° (ahead, left, behind, right); "line" at
    ±90° (left, right alternately); "wedge" at ±135°; "circle" evenly at r. Robots in formation
    closer than a diameter + 1 cm raise `khepera_gym.errors.ConfigError` (`formation.spacing`
    or `formation.offsets`).
    """

    TASK: ClassVar[str] = "formation"

    def formation_targets(self: BatchFace) -> npt.NDArray[np.float64]:
        """The followers' target points (eq. 12) for the current leader pose, shape (K, 2), m
        ((N, K, 2) on :class:`khepera_gym.vector.FormationVectorEnv`, which shares this method):
        :meth:`targets` under its task's name."""
        return self.targets()


# --- heuristic policies: the paper's controllers of khepera_gym.baselines ------------------------


#: The heuristic's controller: followers toward their own targets, an agent leader by
#: Braitenberg.
FORMATION_POLICY = LeaderFollower(shape=None, leader=AVOID_POLICY)


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
    return FORMATION_POLICY(observation)


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
    return FORMATION_POLICY(observation)


__all__ = ["FormationEnv", "formation_follower_heuristic", "formation_heuristic"]
