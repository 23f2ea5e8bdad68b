//! KheperaIV-Nav and KheperaIV-Avoid: position control to a goal, in an empty walled arena (Nav,
//! the paper's §3.3) or among obstacles (Avoid, §3.4). Both are this file; they differ only in
//! their defaults ([`NAV`], [`AVOID`]).
//!
//! Reset: the spawner (world/layout.rs) draws the start pose, the goal and random obstacles.
//! Reward per step: `progress_weight·(d_prev − d) − time_cost + success_bonus·[d < goal_radius]
//!  − collision_penalty·[in contact]`. Terminates on success (or on contact when
//! `terminate_on_collision`); `Env` truncates at `max_steps`.
//!
//! Observation (robot frame x forward, y left): the observed sensors' blocks, then
//! `goal_distance`, `goal_bearing_sin`, `goal_bearing_cos`, `wheel_speeds` ([`nav_blocks`]).
//! The helpers here work on any robot of a world, so multi-robot tasks reuse them.

use rapier2d::math::Vector;

use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::draw::Mark;
use crate::error::Result;
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::scenario::{Scenario, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;

/// KheperaIV-Nav: the shared defaults as they are.
pub const NAV: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-Nav"),
    summary: "drive a Khepera IV to a goal in an empty walled arena (position control)",
    schema: TaskSchema {
        name: "nav",
        since: 0,
        defaults: "",
        section: None,
    },
    scoring: Scoring::GOAL,
    agents: AgentFacts::ONE,
};

/// KheperaIV-Avoid: Nav among random obstacles, new ones every episode.
pub const AVOID: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-Avoid"),
    summary: "the Nav task among random obstacles (circles, boxes, wall segments), new ones \
              every episode",
    schema: TaskSchema {
        name: "avoid",
        since: 0,
        defaults: r#"
[obstacles]
count = 10                   # random obstacles per episode
placement = "anywhere"       # at this density several lie between start and goal

[spawn]
min_goal_distance = 1.0      # far enough for obstacles to be in the way

[task]
max_steps = 600              # 30 s: detours take longer
collision_penalty = 0.5      # contacts cost more than in Nav
"#,
        section: None,
    },
    scoring: Scoring::GOAL,
    agents: AgentFacts::ONE,
};

/// Per-world state of the Nav/Avoid task.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Nav {
    /// Goal position (m).
    pub goal: Vector,
    prev_distance: f32,
}

/// What one step meant for one robot.
#[derive(Debug, Clone, Copy)]
pub struct Judgement {
    /// The step's reward.
    pub reward: f32,
    /// The robot reached its goal.
    pub success: bool,
}

impl Task for Nav {
    fn new(_cfg: &Scenario) -> Result<Self> {
        Ok(Self::default())
    }

    fn spawn(_cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Single)
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        Ok(vec![Agent {
            name: "robot".into(),
            body: Body::Robot(0),
            layout: nav_blocks(cfg),
        }])
    }

    fn reset(&mut self, world: &World, layout: &Layout) {
        self.goal = layout.goals[0];
        self.prev_distance = (self.goal - world.robots[0].position).length();
    }

    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool {
        let j = judge_robot(world, 0, self.goal, &mut self.prev_distance, cfg);
        rewards[0] = j.reward;
        terminated[0] = j.success;
        j.success
    }

    fn observe(&self, world: &World, cfg: &Scenario, _agent: usize, out: &mut ObsWriter) {
        observe_robot(world, 0, self.goal, cfg, out);
    }

    fn goals(&self) -> Vec<Vector> {
        vec![self.goal]
    }

    fn draw(&self, _world: &World, cfg: &Scenario, marks: &mut Vec<Mark>) {
        marks.push(goal_mark(self.goal, cfg, None));
    }
}

/// A navigating robot's own observation blocks (after its sensors'): the goal's distance (m,
/// up to the arena diagonal) and bearing (sin, cos), then its wheel speeds (normalised by the
/// maximum wheel speed).
pub fn nav_blocks(cfg: &Scenario) -> ObsLayout {
    ObsLayout::new(vec![
        Block::new("goal_distance", 1, 0.0, cfg.diagonal()),
        Block::new("goal_bearing_sin", 1, -1.0, 1.0),
        Block::new("goal_bearing_cos", 1, -1.0, 1.0),
        Block::new("wheel_speeds", 2, -1.0, 1.0),
    ])
}

/// Reward and success of robot `i` heading for `goal`; updates its previous distance.
#[inline]
pub fn judge_robot(
    world: &World,
    i: usize,
    goal: Vector,
    prev_distance: &mut f32,
    cfg: &Scenario,
) -> Judgement {
    let robot = &world.robots[i];
    let distance = (goal - robot.position).length();
    let success = distance < cfg.task.goal_radius;
    let reward = progress_reward(cfg, *prev_distance, distance, success, robot.in_contact);
    *prev_distance = distance;
    Judgement { reward, success }
}

/// Nav's reward for a step that brought a robot from `prev_distance` to `distance` (m) from
/// its goal: progress × `task.progress_weight` − `task.time_cost`, + `task.success_bonus` when
/// it `arrived`, − `task.collision_penalty` when it is `in_contact`.
#[inline]
pub fn progress_reward(
    cfg: &Scenario,
    prev_distance: f32,
    distance: f32,
    arrived: bool,
    in_contact: bool,
) -> f32 {
    let task = &cfg.task;
    let mut reward = task.progress_weight * (prev_distance - distance) - task.time_cost;
    if arrived {
        reward += task.success_bonus;
    }
    if in_contact {
        reward -= task.collision_penalty;
    }
    reward
}

/// `point` in robot `i`'s frame (x forward, y left), metres, as the robot sees it: from the
/// pose it believes it has ([`World::believed_pose`]: its odometry with `localization =
/// "odometry"`, else its true pose). `point` itself is in the world frame (a goal, or another
/// robot's true position as an external tracker reports it).
#[inline]
pub fn to_robot_frame(world: &World, i: usize, point: Vector) -> Vector {
    let (position, heading) = world.believed_pose(i);
    let d = point - position;
    let (s, c) = heading.sin_cos();
    Vector::new(c * d.x + s * d.y, -s * d.x + c * d.y)
}

/// Robot `i`'s wheel speeds normalised by the maximum wheel speed, in [-1, 1].
pub fn wheel_obs(world: &World, i: usize) -> [f32; 2] {
    let vmax = world.drive.max_wheel_speed;
    world.robots[i]
        .wheel_speeds
        .map(|w| (w / vmax).clamp(-1.0, 1.0))
}

/// Writes robot `i`'s own navigation observation ([`nav_blocks`]) toward `goal`.
#[inline]
pub fn observe_robot(world: &World, i: usize, goal: Vector, cfg: &Scenario, out: &mut ObsWriter) {
    let local = to_robot_frame(world, i, goal);
    let distance = local.length();
    let (bs, bc) = if distance > 0.0 {
        (local.y / distance, local.x / distance)
    } else {
        (0.0, 1.0)
    };
    out.put(distance.min(cfg.diagonal()));
    out.put(bs.clamp(-1.0, 1.0));
    out.put(bc.clamp(-1.0, 1.0));
    let [l, r] = wheel_obs(world, i);
    out.put(l);
    out.put(r);
}

/// The mark of a goal: red, or robot `k`'s colour when each robot has its own.
pub fn goal_mark(goal: Vector, cfg: &Scenario, robot: Option<usize>) -> Mark {
    Mark::Goal {
        position: goal,
        radius: cfg.task.goal_radius.max(0.01),
        colour: robot.map_or([214, 39, 40], |k| crate::draw::PALETTE[k % 8]),
    }
}
