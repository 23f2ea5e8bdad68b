"""A Khepera IV among five obstacles as a VMAS scenario: the VMAS peer of issue 54.

Benchmark-only code, outside the wheel; needs VMAS (``pip install vmas==1.5.2``, which brings
torch; see benchmarks/peers/README.md). It is written the way VMAS' own scenarios are
(``vmas/scenarios/navigation.py``): one :class:`Scenario` behind VMAS' contract (make the
world, reset worlds by index, observe, reward, done), batched over worlds by VMAS with torch,
using VMAS' own physics, differential drive (``DiffDrive``) and ray casting (``Lidar``).

The scene is the one of :mod:`benchmarks.peers.numpy_khepera` and Nav-v3 (numbers in
:mod:`benchmarks.peers.khepera_iv`, each with its source):

* One agent, a disc of the Khepera IV's radius and mass, with VMAS' differential drive
  (``DiffDrive``, its default RK4 integration). The action is the two normalised wheel speeds
  in [-1, 1] (1 = 0.813 m/s, as Nav's); :meth:`Scenario.process_action` turns them into the
  drive's (v, ω). The world has no drag (VMAS' default, 0.25, would hold the robot at 80 % of
  its command; the Khepera's speed loop holds the wheels at it).
* A 2 m × 2 m arena of four ``Line`` walls and five fixed ``Sphere`` obstacles whose radii span
  Nav's range (0.04 to 0.1 m; VMAS gives each entity one shape in every world, so they are not
  drawn per world). Contacts are VMAS' penalty forces, 2 substeps a 50 ms step (as Nav-v3 and
  VMAS' navigation scenario).
* Sensors: a ``Lidar`` of 8 rays at the infrared ring's bearings, in K-Team's order (135° down
  to -180°), seeing walls and obstacles up to ``RAY_MAX_RANGE`` (0.3204 m from the centre).
* Observation (13): the 8 ray distances / ``RAY_MAX_RANGE``, the goal distance (m), the goal
  bearing's sine and cosine in the robot frame, the two wheel speeds / 0.813 m/s.
* Reward: Nav's: 10 per metre of progress to the goal, -0.01 a step, -0.1 in contact, +10 on
  arrival. Done: the centre within 5 cm of the goal (and after ``max_steps``, given to
  ``vmas.make_env``).
* Reset: VMAS' ``ScenarioUtils.spawn_entities_randomly`` places the obstacles, robot and goal
  at least ``SPAWN_SEPARATION`` apart; the heading is uniform.

Units: metres, seconds, radians; world frame x right, y up, arena centred at the origin.
Threading: torch's intra-op pool (``torch.get_num_threads()``).
"""

from __future__ import annotations

import math
from typing import Any

import torch
from vmas.simulator.core import Agent, Landmark, Line, Sphere, World
from vmas.simulator.dynamics.diff_drive import DiffDrive
from vmas.simulator.scenario import BaseScenario
from vmas.simulator.sensors import Lidar
from vmas.simulator.utils import Color, ScenarioUtils

from benchmarks.peers import khepera_iv as k4

#: Least distance between the centres of any two of the obstacles, robot and goal at a reset
#: (m): the largest obstacle's radius, the robot's and Nav's ``obstacles.min_gap`` 0.16 between
#: them, so every gap lets the robot through (VMAS' spawner takes one distance for all).
SPAWN_SEPARATION = k4.OBSTACLE_RADIUS_RANGE[1] + k4.ROBOT_RADIUS + 0.16
#: The five obstacles' radii (m): evenly over Nav's ``obstacles.circle_radius`` range.
OBSTACLE_RADII = tuple(
    k4.OBSTACLE_RADIUS_RANGE[0]
    + i * (k4.OBSTACLE_RADIUS_RANGE[1] - k4.OBSTACLE_RADIUS_RANGE[0]) / (k4.N_OBSTACLES - 1)
    for i in range(k4.N_OBSTACLES)
)


class Scenario(BaseScenario):
    """The Khepera IV Nav scene with five obstacles, for ``vmas.make_env(Scenario(), ...)``.

    Takes no scenario keyword (an unknown one is an error, where VMAS only warns).
    """

    def make_world(self, batch_dim: int, device: torch.device, **kwargs: Any) -> World:
        """Builds the batched world: walls, obstacles, goal and the robot with its lidar."""
        if kwargs:
            raise TypeError(f"unknown scenario keywords {sorted(kwargs)}: this scenario has none")
        world = World(batch_dim, device, dt=k4.DT, substeps=k4.SUBSTEPS, drag=0.0)
        self.robot = Agent(
            name="khepera",
            shape=Sphere(radius=k4.ROBOT_RADIUS),
            mass=k4.ROBOT_MASS,
            # Normalised left and right wheel speeds; process_action makes them (v, ω).
            u_range=[1.0, 1.0],
            u_multiplier=[1.0, 1.0],
            dynamics=DiffDrive(world),
            sensors=[
                Lidar(
                    world,
                    # 135° first, then clockwise by 45°: K-Team's order (robot.md §2).
                    angle_start=3 * math.pi / 4,
                    angle_end=3 * math.pi / 4 - 2 * math.pi,
                    n_rays=len(k4.RAY_BEARINGS),
                    max_range=k4.RAY_MAX_RANGE,
                    entity_filter=lambda entity: entity.collide,
                    render=False,
                )
            ],
        )
        world.add_agent(self.robot)
        self.goal = Landmark(name="goal", collide=False, color=Color.GREEN)
        world.add_landmark(self.goal)
        self.obstacles = []
        for index, radius in enumerate(OBSTACLE_RADII):
            obstacle = Landmark(
                name=f"obstacle {index}",
                collide=True,
                movable=False,
                shape=Sphere(radius=radius),
                color=Color.RED,
            )
            world.add_landmark(obstacle)
            self.obstacles.append(obstacle)
        self.walls = []
        for index in range(4):
            wall = Landmark(
                name=f"wall {index}",
                collide=True,
                movable=False,
                shape=Line(length=2 * k4.ARENA_HALF),
                color=Color.BLACK,
            )
            world.add_landmark(wall)
            self.walls.append(wall)
        self.obstacle_radii = torch.tensor(OBSTACLE_RADII, device=device)
        self.goal_distance = torch.zeros(batch_dim, device=device)
        self.wheel_speeds = torch.zeros(batch_dim, 2, device=device)
        return world

    def reset_world_at(self, env_index: int | None = None) -> None:
        """Places obstacles, robot and goal (all worlds when ``env_index`` is None)."""
        half = k4.ARENA_HALF
        for index, wall in enumerate(self.walls):
            vertical = index < 2
            sign = -1.0 if index % 2 == 0 else 1.0
            position = [sign * half, 0.0] if vertical else [0.0, sign * half]
            wall.set_pos(torch.tensor(position, device=self.world.device), batch_index=env_index)
            wall.set_rot(
                torch.tensor([math.pi / 2 if vertical else 0.0], device=self.world.device),
                batch_index=env_index,
            )
        spawn = half - k4.ROBOT_RADIUS - k4.WALL_MARGIN
        ScenarioUtils.spawn_entities_randomly(
            [*self.obstacles, self.robot, self.goal],
            self.world,
            env_index,
            min_dist_between_entities=SPAWN_SEPARATION,
            x_bounds=(-spawn, spawn),
            y_bounds=(-spawn, spawn),
        )
        batch = self.world.batch_dim if env_index is None else 1
        heading = torch.empty(batch, 1, device=self.world.device).uniform_(-math.pi, math.pi)
        self.robot.set_rot(heading if env_index is None else heading[0], batch_index=env_index)
        distance = torch.linalg.vector_norm(self.goal.state.pos - self.robot.state.pos, dim=-1)
        if env_index is None:
            self.goal_distance = distance
            self.wheel_speeds.zero_()
        else:
            self.goal_distance[env_index] = distance[env_index]
            self.wheel_speeds[env_index] = 0.0

    def process_action(self, agent: Agent) -> None:
        """Normalised wheel speeds to the differential drive's (v, ω), within the limits."""
        wheels = agent.action.u.clamp(-1.0, 1.0) * k4.MAX_WHEEL_SPEED
        self.wheel_speeds = wheels
        forward = 0.5 * (wheels[:, 0] + wheels[:, 1])
        yaw_rate = (wheels[:, 1] - wheels[:, 0]) / k4.AXLE_LENGTH
        agent.action.u = torch.stack((forward, yaw_rate), dim=-1)

    def observation(self, agent: Agent) -> torch.Tensor:
        """Ray distances, goal distance and bearing, wheel speeds: (batch, 13)."""
        rays = agent.sensors[0].measure() / k4.RAY_MAX_RANGE
        to_goal = self.goal.state.pos - agent.state.pos
        distance = torch.linalg.vector_norm(to_goal, dim=-1, keepdim=True)
        heading = agent.state.rot
        cos_h, sin_h = torch.cos(heading), torch.sin(heading)
        ahead = cos_h * to_goal[:, :1] + sin_h * to_goal[:, 1:]
        left = cos_h * to_goal[:, 1:] - sin_h * to_goal[:, :1]
        safe = distance.clamp_min(1e-9)
        return torch.cat(
            [rays, distance, left / safe, ahead / safe, self.wheel_speeds / k4.MAX_WHEEL_SPEED],
            dim=-1,
        )

    def reward(self, agent: Agent) -> torch.Tensor:
        """Nav's reward: progress, time cost, contact penalty and arrival bonus: (batch,)."""
        distance = torch.linalg.vector_norm(self.goal.state.pos - agent.state.pos, dim=-1)
        progress = self.goal_distance - distance
        self.goal_distance = distance
        centres = torch.stack([obstacle.state.pos for obstacle in self.obstacles], dim=1)
        gaps = torch.linalg.vector_norm(centres - agent.state.pos[:, None], dim=-1)
        touching = (gaps <= self.obstacle_radii + k4.ROBOT_RADIUS).any(dim=-1)
        touching |= (agent.state.pos.abs() >= k4.ARENA_HALF - k4.ROBOT_RADIUS).any(dim=-1)
        return (
            k4.PROGRESS_WEIGHT * progress
            - k4.TIME_COST
            - k4.COLLISION_PENALTY * touching
            + k4.SUCCESS_BONUS * (distance < k4.GOAL_RADIUS)
        )

    def done(self) -> torch.Tensor:
        """Arrival: the robot's centre within ``GOAL_RADIUS`` of the goal: (batch,) bool."""
        distance = torch.linalg.vector_norm(self.goal.state.pos - self.robot.state.pos, dim=-1)
        return distance < k4.GOAL_RADIUS


__all__ = ["OBSTACLE_RADII", "SPAWN_SEPARATION", "Scenario"]
