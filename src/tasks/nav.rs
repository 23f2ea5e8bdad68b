//! KheperaIV-Nav and KheperaIV-Avoid: position control to a goal, in an empty walled arena (Nav,
//! the paper's §3.3) or among obstacles (Avoid, §3.4). Both are this file; they differ only in
//! their scenario (configs/nav.toml, configs/avoid.toml).
//!
//! Reset: the spawner (world/layout.rs) draws the start pose, the goal and random obstacles.
//! Reward per step: `progress_weight·(d_prev − d) − time_cost + success_bonus·[d < goal_radius]
//!  − collision_penalty·[in contact]`. Terminates on success (or on contact when
//! `terminate_on_collision`); `Env` truncates at `max_steps`.
//!
//! Observation (robot frame x forward, y left): see [`OBS_LAYOUT`]. The helpers here work on any
//! robot of a world, so multi-robot tasks reuse them.

use rapier2d::math::Vector;

use crate::scenario::Scenario;
use crate::sensors::{IR_COUNT, US_COUNT};
use crate::world::World;

/// Observation layout: (name, length) in order.
pub const OBS_LAYOUT: &[(&str, usize)] = &[
    ("ir", IR_COUNT),
    ("us", US_COUNT),
    ("goal_distance", 1),
    ("goal_bearing_sin", 1),
    ("goal_bearing_cos", 1),
    ("wheel_speeds", 2),
];

/// Observation length of one navigating robot.
pub const OBS_DIM: usize = IR_COUNT + US_COUNT + 5;

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

impl Nav {
    /// Starts an episode toward `goal` (the robot is already placed).
    pub fn reset(&mut self, world: &World, goal: Vector) {
        self.goal = goal;
        self.prev_distance = (goal - world.robots[0].position).length();
    }

    /// Reward and success after a step.
    pub fn judge(&mut self, world: &World, cfg: &Scenario) -> Judgement {
        judge_robot(world, 0, self.goal, &mut self.prev_distance, cfg)
    }

    /// Writes the observation into `obs`.
    pub fn observe(&self, world: &World, cfg: &Scenario, obs: &mut [f32]) {
        observe_robot(world, 0, self.goal, cfg, obs);
    }

    /// Observation bounds (low, high).
    pub fn bounds(cfg: &Scenario) -> (Vec<f32>, Vec<f32>) {
        let mut low = vec![0.0; IR_COUNT + US_COUNT];
        let mut high = vec![1.0; IR_COUNT + US_COUNT];
        low.extend([0.0, -1.0, -1.0, -1.0, -1.0]);
        high.extend([diagonal(cfg), 1.0, 1.0, 1.0, 1.0]);
        (low, high)
    }
}

/// Reward and success of robot `i` heading for `goal`; updates its previous distance.
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
    let mut reward = cfg.task.progress_weight * (*prev_distance - distance) - cfg.task.time_cost;
    if success {
        reward += cfg.task.success_bonus;
    }
    if robot.in_contact {
        reward -= cfg.task.collision_penalty;
    }
    *prev_distance = distance;
    Judgement { reward, success }
}

/// Writes robot `i`'s sensors, the part of its observation every task shares: IR proximity
/// (8) then ultrasonic (5), each normalised to [0, 1].
pub fn observe_sensors(world: &World, i: usize, obs: &mut [f32]) {
    let robot = &world.robots[i];
    for (o, raw) in obs[..IR_COUNT].iter_mut().zip(robot.ir_raw) {
        *o = world.ir.normalise(raw);
    }
    for (o, code) in obs[IR_COUNT..IR_COUNT + US_COUNT]
        .iter_mut()
        .zip(robot.us_code)
    {
        *o = world.us.normalise(code);
    }
}

/// `point` in robot `i`'s frame (x forward, y left), metres.
pub fn to_robot_frame(world: &World, i: usize, point: Vector) -> Vector {
    let robot = &world.robots[i];
    let d = point - robot.position;
    let (s, c) = robot.heading.sin_cos();
    Vector::new(c * d.x + s * d.y, -s * d.x + c * d.y)
}

/// Robot `i`'s wheel speeds normalised by the maximum wheel speed, in [-1, 1].
pub fn wheel_obs(world: &World, i: usize) -> [f32; 2] {
    let vmax = world.drive.max_wheel_speed;
    world.robots[i]
        .wheel_speeds
        .map(|w| (w / vmax).clamp(-1.0, 1.0))
}

/// Writes robot `i`'s navigation observation (layout [`OBS_LAYOUT`]) toward `goal`.
pub fn observe_robot(world: &World, i: usize, goal: Vector, cfg: &Scenario, obs: &mut [f32]) {
    observe_sensors(world, i, obs);
    let base = IR_COUNT + US_COUNT;
    let local = to_robot_frame(world, i, goal);
    let distance = local.length();
    let (bs, bc) = if distance > 0.0 {
        (local.y / distance, local.x / distance)
    } else {
        (0.0, 1.0)
    };
    obs[base] = distance.min(diagonal(cfg));
    obs[base + 1] = bs.clamp(-1.0, 1.0);
    obs[base + 2] = bc.clamp(-1.0, 1.0);
    let [l, r] = wheel_obs(world, i);
    obs[base + 3] = l;
    obs[base + 4] = r;
}

/// The arena's diagonal (m): the largest distance between two points in it.
pub fn diagonal(cfg: &Scenario) -> f32 {
    (cfg.arena.width * cfg.arena.width + cfg.arena.height * cfg.arena.height).sqrt()
}
