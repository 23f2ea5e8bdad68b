"""A Khepera IV among five obstacles, hand-vectorised in NumPy: the NumPy peer of issue 54.

Benchmark-only code, outside the wheel. It is the env a careful user would write in NumPy to
step many worlds at once, written independently of khepera_gym's Rust core (no code or formula
taken from it). The state is a structure of arrays with the worlds on the last, contiguous axis
(obstacles and rays on the first), so that every operation, reductions over obstacles and rays
included, runs over all worlds at once on contiguous memory. The only Python loops are over the
2 physics substeps, the 5 obstacles' push-outs and the rounds of a spawn's rejection sampling;
none is over worlds or rays.

The task is Nav's (``KheperaIV-Nav-v3``): drive to a goal in a 2 m × 2 m walled arena, here
with five circular obstacles, seen by 8 range rays. The numbers are in
:mod:`benchmarks.peers.khepera_iv`, each with its source.

* Drive: the action is the two normalised wheel speeds in [-1, 1] (1 = 0.813 m/s); the wheels
  take their speed at once (no acceleration limit; VMAS' differential drive has none either).
  Each substep moves the robot along the exact arc of its unicycle speeds
  v = (l + r) / 2, ω = (r - l) / axle.
* Contacts: after each substep the robot's disc is pushed out of each obstacle it overlaps, in
  turn, and kept inside the walls (kinematic: no friction, no bounce); a world in contact during
  a step pays the collision penalty.
* Rays: 8 rays from the robot's centre at the infrared ring's bearings, each the distance to
  the nearest wall or obstacle, or ``RAY_MAX_RANGE`` (0.3204 m: 0.25 m beyond the shell) when
  nothing is nearer.
* Observation (13, float32): the 8 ray distances / ``RAY_MAX_RANGE`` (1 = nothing), the goal
  distance (m), the goal bearing's sine and cosine in the robot frame, the two wheel speeds /
  0.813 m/s.
* Reward: Nav's: 10 per metre of progress to the goal, -0.01 a step, -0.1 in contact, +10 on
  arrival.
* Episodes: terminated when the centre is within 5 cm of the goal, truncated after 400 steps;
  next-step autoreset as khepera_gym's vector envs (the step after a world ended resets it,
  ignores its action and returns reward 0).

Units: metres, seconds, radians; world frame x right, y up, arena centred at the origin.
Precision: float32 state and observations (as khepera_gym's). Threading: NumPy's element-wise
kernels run on the calling thread.
"""

from __future__ import annotations

import numpy as np

from benchmarks.peers import khepera_iv as k4

#: Free gap between obstacles, and between obstacles and walls, at a reset (m): Nav's
#: ``obstacles.min_gap`` (the robot's diameter and 1 cm, so every goal stays reachable).
MIN_GAP = 0.16
#: Free gap between an obstacle and the robot's start or goal disc at a reset (m): Nav's
#: ``obstacles.spawn_clearance``.
SPAWN_CLEARANCE = 0.05
#: Shortest start-goal distance at a reset (m): Nav's ``spawn.min_goal_distance``.
MIN_GOAL_DISTANCE = 0.5
#: Rounds of rejection sampling at a reset; a world still failing keeps its last draw (the
#: push-out moves the robot clear on its first step).
SPAWN_ROUNDS = 8

_F32 = np.float32
_N_RAYS = len(k4.RAY_BEARINGS)


class NumpyKheperaNav:
    """Many Khepera IV Nav worlds with five obstacles, stepped together in NumPy.

    Args:
        num_envs: Number of worlds (>= 1).
        seed: Seed of the one random stream all worlds draw from (``numpy.random.default_rng``).

    Attributes (float32 unless said; worlds on the last axis):
        x, y, heading: (num_envs,) robot centre (m) and heading (rad, in (-π, π]).
        wheel_speeds: (2, num_envs) left and right wheel speeds (m/s).
        goal_x, goal_y: (num_envs,) goal point (m).
        obstacle_x, obstacle_y, obstacle_radius: (5, num_envs) obstacle circles (m).
        rays: (8, num_envs) the last rays' distances (m), K-Team's sensor order.
        in_contact: (num_envs,) bool, whether the robot touched a wall or obstacle in the last
            step.
    """

    def __init__(self, num_envs: int, seed: int = 0) -> None:
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        self.num_envs = n = num_envs
        self.rng = np.random.default_rng(seed)
        self.x = np.zeros(n, _F32)
        self.y = np.zeros(n, _F32)
        self.heading = np.zeros(n, _F32)
        self.wheel_speeds = np.zeros((2, n), _F32)
        self.goal_x = np.zeros(n, _F32)
        self.goal_y = np.zeros(n, _F32)
        self.goal_distance = np.zeros(n, _F32)
        # Parked far away until the first reset draws them.
        self.obstacle_x = np.full((k4.N_OBSTACLES, n), 1e3, _F32)
        self.obstacle_y = np.full((k4.N_OBSTACLES, n), 1e3, _F32)
        self.obstacle_radius = np.full((k4.N_OBSTACLES, n), k4.OBSTACLE_RADIUS_RANGE[0], _F32)
        self.rays = np.full((_N_RAYS, n), k4.RAY_MAX_RANGE, _F32)
        self.in_contact = np.zeros(n, bool)
        self.steps = np.zeros(n, np.int32)
        self._needs_reset = np.zeros(n, bool)
        self._bearings = np.asarray(k4.RAY_BEARINGS, _F32)[:, None]  # (8, 1)

    # --- episodes ------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> np.ndarray:
        """Starts a new episode in every world; ``seed`` restarts the random stream (None
        continues it). Returns the observations, (num_envs, 13)."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self._reset_worlds(np.ones(self.num_envs, bool))
        self._needs_reset[:] = False
        self._cast_rays()
        return self._observe()

    def _reset_worlds(self, mask: np.ndarray) -> None:
        """Draws new obstacles, start and goal for the worlds in ``mask``, all at once."""
        count = int(mask.sum())
        if count == 0:
            return
        rng = self.rng
        n_obstacles = k4.N_OBSTACLES
        radius = rng.uniform(*k4.OBSTACLE_RADIUS_RANGE, (n_obstacles, count)).astype(_F32)
        # Inside the arena with MIN_GAP to the walls and between any two.
        limit = k4.ARENA_HALF - MIN_GAP - radius
        ox = (rng.uniform(-1.0, 1.0, radius.shape) * limit).astype(_F32)
        oy = (rng.uniform(-1.0, 1.0, radius.shape) * limit).astype(_F32)
        others = ~np.eye(n_obstacles, dtype=bool)[:, :, None]
        for _ in range(SPAWN_ROUNDS):
            between = np.hypot(ox[:, None] - ox[None], oy[:, None] - oy[None])  # (5, 5, count)
            gap = between - radius[:, None] - radius[None]
            bad = ((gap < MIN_GAP) & others).any(axis=1)  # (5, count)
            if not bad.any():
                break
            ox = np.where(bad, rng.uniform(-1.0, 1.0, radius.shape) * limit, ox).astype(_F32)
            oy = np.where(bad, rng.uniform(-1.0, 1.0, radius.shape) * limit, oy).astype(_F32)

        spawn_half = k4.ARENA_HALF - k4.ROBOT_RADIUS - k4.WALL_MARGIN

        def draw(size: int) -> np.ndarray:
            return rng.uniform(-spawn_half, spawn_half, (2, size)).astype(_F32)

        def clear(px: np.ndarray, py: np.ndarray) -> np.ndarray:
            gap = np.hypot(px - ox, py - oy) - radius  # (5, count)
            return (gap >= k4.ROBOT_RADIUS + SPAWN_CLEARANCE).all(axis=0)

        start = draw(count)
        for _ in range(SPAWN_ROUNDS):
            bad = ~clear(start[0], start[1])
            if not bad.any():
                break
            start[:, bad] = draw(int(bad.sum()))
        goal = draw(count)
        for _ in range(SPAWN_ROUNDS):
            far = np.hypot(goal[0] - start[0], goal[1] - start[1]) >= MIN_GOAL_DISTANCE
            bad = ~(far & clear(goal[0], goal[1]))
            if not bad.any():
                break
            goal[:, bad] = draw(int(bad.sum()))

        self.obstacle_radius[:, mask] = radius
        self.obstacle_x[:, mask] = ox
        self.obstacle_y[:, mask] = oy
        self.x[mask], self.y[mask] = start
        self.goal_x[mask], self.goal_y[mask] = goal
        self.heading[mask] = rng.uniform(-np.pi, np.pi, count)
        self.wheel_speeds[:, mask] = 0.0
        self.steps[mask] = 0
        self.in_contact[mask] = False
        self.goal_distance[mask] = np.hypot(goal[0] - start[0], goal[1] - start[1])

    # --- one control step ----------------------------------------------------------------------
    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Advances every world by one control step (``DT`` = 50 ms).

        Args:
            actions: (num_envs, 2) normalised left and right wheel speeds; clipped to [-1, 1].

        Returns:
            observations (num_envs, 13), rewards, terminated, truncated (num_envs,) and an
            empty info dict (Gymnasium's vector order).
        """
        resetting = self._needs_reset
        any_resetting = bool(resetting.any())
        if any_resetting:
            self._reset_worlds(resetting)
        wheels = np.clip(actions.T, -1.0, 1.0).astype(_F32) * _F32(k4.MAX_WHEEL_SPEED)
        if any_resetting:
            wheels[:, resetting] = 0.0  # a world reset this step does not move
        self.wheel_speeds = wheels
        forward = 0.5 * (wheels[0] + wheels[1])
        yaw_rate = (wheels[1] - wheels[0]) * _F32(1.0 / k4.AXLE_LENGTH)
        contact = np.zeros(self.num_envs, bool)
        for _ in range(k4.SUBSTEPS):
            self._roll_arc(forward, yaw_rate, _F32(k4.DT / k4.SUBSTEPS))
            contact |= self._push_out()
        self.in_contact = contact
        self._cast_rays()

        previous = self.goal_distance
        observations = self._observe()
        reached = self.goal_distance < _F32(k4.GOAL_RADIUS)
        rewards = _F32(k4.PROGRESS_WEIGHT) * (previous - self.goal_distance) - _F32(k4.TIME_COST)
        rewards -= _F32(k4.COLLISION_PENALTY) * contact
        rewards += _F32(k4.SUCCESS_BONUS) * reached
        self.steps += 1
        terminated = reached
        truncated = (self.steps >= k4.MAX_STEPS) & ~terminated
        if any_resetting:
            rewards[resetting] = 0.0
            terminated &= ~resetting
            truncated &= ~resetting
            self.steps[resetting] = 0
        self._needs_reset = terminated | truncated
        return observations, rewards, terminated, truncated, {}

    def _roll_arc(self, forward: np.ndarray, yaw_rate: np.ndarray, seconds: np.float32) -> None:
        """Moves each robot along the exact arc of (v, ω) for ``seconds``: a chord of length
        v·t·sinc(ωt/2) along the mean heading θ + ωt/2 (a straight line when ω = 0)."""
        turn = yaw_rate * seconds
        chord = forward * seconds * np.sinc(turn * _F32(0.5 / np.pi))  # sinc(x) = sin πx / πx
        middle = self.heading + _F32(0.5) * turn
        self.x += chord * np.cos(middle)
        self.y += chord * np.sin(middle)
        # Wrapped to (-π, π].
        self.heading = _F32(np.pi) - np.mod(_F32(np.pi) - (self.heading + turn), _F32(2 * np.pi))

    def _push_out(self) -> np.ndarray:
        """Moves each robot's disc out of the obstacles it overlaps (one obstacle after the
        other) and inside the walls; returns which robots were in contact."""
        contact = np.zeros(self.num_envs, bool)
        reach = self.obstacle_radius + _F32(k4.ROBOT_RADIUS)  # (5, n)
        for index in range(k4.N_OBSTACLES):
            dx = self.x - self.obstacle_x[index]
            dy = self.y - self.obstacle_y[index]
            distance = np.hypot(dx, dy)
            overlap = reach[index] - distance
            touching = overlap > 0.0
            # Along the line of centres; a robot exactly on the centre leaves along +x.
            scale = np.where(touching, overlap / np.where(distance > 0.0, distance, 1), 0)
            self.x += np.where(touching & (distance == 0.0), overlap, scale * dx)
            self.y += scale * dy
            contact |= touching
        inner = _F32(k4.ARENA_HALF - k4.ROBOT_RADIUS)
        x = np.clip(self.x, -inner, inner)
        y = np.clip(self.y, -inner, inner)
        contact |= (x != self.x) | (y != self.y)
        self.x, self.y = x, y
        return contact

    def _cast_rays(self) -> None:
        """The 8 rays' distances to the nearest wall or obstacle, capped at RAY_MAX_RANGE."""
        angles = self.heading + self._bearings  # (8, n)
        ux, uy = np.cos(angles), np.sin(angles)
        half = _F32(k4.ARENA_HALF)
        with np.errstate(divide="ignore", invalid="ignore"):
            # Walls: the inner square's side each ray points toward, on each axis.
            to_x_wall = (np.copysign(half, ux) - self.x) / ux
            to_y_wall = (np.copysign(half, uy) - self.y) / uy
        nearest = np.fmin(np.fmin(to_x_wall, to_y_wall), _F32(k4.RAY_MAX_RANGE))
        # Circles: |p + t·u - c|² = r² with |u| = 1: t = -b - sqrt(b² - q), b = u·(p - c),
        # q = |p - c|² - r²; the nearer root, when the circle is hit ahead of the robot.
        for index in range(k4.N_OBSTACLES):
            dx = self.x - self.obstacle_x[index]
            dy = self.y - self.obstacle_y[index]
            q = dx * dx + dy * dy - self.obstacle_radius[index] ** 2  # (n,)
            b = ux * dx + uy * dy  # (8, n)
            discriminant = b * b - q
            with np.errstate(invalid="ignore"):
                hit = -b - np.sqrt(discriminant)
            # NaN (a miss) and negative (behind) roots lose to fmin's other operand.
            np.fmin(nearest, np.where(hit >= 0.0, hit, np.nan), out=nearest)
        self.rays = nearest

    def _observe(self) -> np.ndarray:
        """The observations, (num_envs, 13) float32; also updates ``goal_distance``."""
        to_x = self.goal_x - self.x
        to_y = self.goal_y - self.y
        distance = np.hypot(to_x, to_y)
        cos_h, sin_h = np.cos(self.heading), np.sin(self.heading)
        ahead = cos_h * to_x + sin_h * to_y
        left = cos_h * to_y - sin_h * to_x
        on_goal = distance == 0.0
        safe = np.where(on_goal, _F32(1.0), distance)
        observations = np.empty((self.num_envs, k4.OBS_SIZE), _F32)
        observations[:, :_N_RAYS] = (self.rays * _F32(1.0 / k4.RAY_MAX_RANGE)).T
        observations[:, 8] = distance
        observations[:, 9] = np.where(on_goal, _F32(0.0), left / safe)
        observations[:, 10] = np.where(on_goal, _F32(1.0), ahead / safe)
        observations[:, 11:13] = (self.wheel_speeds * _F32(1.0 / k4.MAX_WHEEL_SPEED)).T
        self.goal_distance = distance
        return observations


__all__ = [
    "MIN_GAP",
    "MIN_GOAL_DISTANCE",
    "SPAWN_CLEARANCE",
    "SPAWN_ROUNDS",
    "NumpyKheperaNav",
]
