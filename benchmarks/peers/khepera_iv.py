"""The Khepera IV numbers and the scene that both peer envs (VMAS and NumPy) simulate.

Benchmark-only code, outside the wheel (see benchmarks/peers/README.md). Each robot number is
taken from the project's spec dossier (docs/robot.md, written from the K-Team manual; the tags
[C] confirmed, [D] derived, [E] estimate are the dossier's); the scene's numbers are those of
``KheperaIV-Nav-v3`` (configs/nav.toml), so that the peers do the work Nav does, with five
circular obstacles added as the comparison in issue 54 asks.

Units: metres, seconds, radians, m/s. Frames: world x right, y up, the arena centred at the
origin; robot frame x forward, y left, angles counter-clockwise (robot.md, "Frame used").
"""

from __future__ import annotations

import math

# --- The robot (docs/robot.md) ------------------------------------------------------------------
#: Body radius (m): 140.8 mm diameter, K-Team manual fig. 8.1 [C] (robot.md §1).
ROBOT_RADIUS = 0.0704
#: Wheel separation (m): 105.4 mm, KH4_WHEELS_DISTANCE [C] (robot.md §1).
AXLE_LENGTH = 0.1054
#: Largest wheel speed (m/s): about 1200 speed units of 0.678 mm/s in closed loop [C]
#: (robot.md §1).
MAX_WHEEL_SPEED = 0.813
#: Largest yaw rate (rad/s) spinning in place at MAX_WHEEL_SPEED: 2 · 0.813 / 0.1054 = 15.4 [D]
#: (robot.md §1).
MAX_YAW_RATE = 2.0 * MAX_WHEEL_SPEED / AXLE_LENGTH
#: Mass (kg): K-Team's usual figure, not in the manual [E] (robot.md §1, §11); VMAS turns the
#: commanded velocity into a force with it.
ROBOT_MASS = 0.54
#: The 8 range rays: the infrared ring's bearings in the robot frame, K-Team order back-left,
#: left, front-left, front, front-right, right, back-right, back: 45° apart [C] (robot.md §2).
RAY_BEARINGS = tuple(math.radians(b) for b in (135.0, 90.0, 45.0, 0.0, -45.0, -90.0, -135.0, 180.0))
#: How far a ray sees beyond the shell (m): the infrared range 2-250 mm [C] (robot.md §2), Nav's
#: ``sensors.ir_range`` 0.25.
RAY_RANGE_BEYOND_SHELL = 0.25
#: How far a ray sees from the robot's centre (m), where both peers cast it from.
RAY_MAX_RANGE = ROBOT_RADIUS + RAY_RANGE_BEYOND_SHELL

# --- The scene (KheperaIV-Nav-v3, configs/nav.toml) -------------------------------------------
#: Control step (s): Nav's ``physics.dt`` (V-REP's default, robot.md §9).
DT = 0.05
#: Physics substeps per control step: Nav-v3's ``physics.substeps`` (and VMAS' navigation
#: scenario's ``substeps``).
SUBSTEPS = 2
#: Inner half-size of the square walled arena (m): Nav's ``arena.width`` = ``height`` = 2.
ARENA_HALF = 1.0
#: Obstacles in each world: the five circles of issue 54's comparison.
N_OBSTACLES = 5
#: Range of the obstacles' radii (m): Nav's ``obstacles.circle_radius``.
OBSTACLE_RADIUS_RANGE = (0.04, 0.1)
#: Gap between a spawned robot or goal and the walls (m): Nav's ``spawn.wall_margin``.
WALL_MARGIN = 0.05
#: Success when the robot's centre is this close to the goal (m): Nav's ``task.goal_radius``.
GOAL_RADIUS = 0.05
#: Control steps before truncation: Nav's ``task.max_steps`` (20 s).
MAX_STEPS = 400
#: Reward per metre of progress, per step, and per step in contact: Nav's ``task`` table.
PROGRESS_WEIGHT = 10.0
TIME_COST = 0.01
SUCCESS_BONUS = 10.0
COLLISION_PENALTY = 0.1
#: Length of one observation: 8 ray proximities, goal distance, goal bearing's sine and cosine,
#: the two wheel speeds (Nav's layout without the 5 ultrasonic readings).
OBS_SIZE = 8 + 3 + 2

__all__ = [
    "ARENA_HALF",
    "AXLE_LENGTH",
    "COLLISION_PENALTY",
    "DT",
    "GOAL_RADIUS",
    "MAX_STEPS",
    "MAX_WHEEL_SPEED",
    "MAX_YAW_RATE",
    "N_OBSTACLES",
    "OBSTACLE_RADIUS_RANGE",
    "OBS_SIZE",
    "PROGRESS_WEIGHT",
    "RAY_BEARINGS",
    "RAY_MAX_RANGE",
    "RAY_RANGE_BEYOND_SHELL",
    "ROBOT_MASS",
    "ROBOT_RADIUS",
    "SUBSTEPS",
    "SUCCESS_BONUS",
    "TIME_COST",
    "WALL_MARGIN",
]
