//! KheperaIV-Nav: position control to a goal in an empty walled arena (the paper's §3.3).
//!
//! Reset: start pose uniform in the spawn region (the arena shrunk by the robot radius and
//! `spawn_margin`), heading uniform in (-π, π]; goal uniform in the same region at least
//! `min_goal_distance` from the start. Reward per step:
//! `progress_weight·(d_prev − d) − time_cost + success_bonus·[d < goal_radius]
//!  − collision_penalty·[in contact]`. Terminates on success (or on contact when
//! `terminate_on_collision`); the episode counter truncates at `max_steps`.
//!
//! Observation (robot frame x forward, y left): see [`OBS_LAYOUT`].

use rand::Rng;
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

/// Tries at drawing a goal far enough from the start before taking the farthest corner.
const GOAL_TRIES: usize = 64;

/// Per-world state of the Nav task.
#[derive(Debug, Clone, Default)]
pub struct Nav {
    /// Goal position (m).
    pub goal: Vector,
    prev_distance: f32,
}

/// What one step meant for the task.
#[derive(Debug, Clone, Copy)]
pub struct Judgement {
    /// The step's reward.
    pub reward: f32,
    /// The robot reached the goal.
    pub success: bool,
}

impl Nav {
    /// Draws a start pose and a goal from the world's stream and places the robot.
    pub fn reset(&mut self, world: &mut World, cfg: &Scenario) {
        let (hw, hh) = cfg.spawn_half_extent();
        let rng = &mut world.rng;
        let start = Vector::new(rng.random_range(-hw..=hw), rng.random_range(-hh..=hh));
        let heading = rng.random_range(-std::f32::consts::PI..std::f32::consts::PI);
        let mut goal = None;
        for _ in 0..GOAL_TRIES {
            let g = Vector::new(rng.random_range(-hw..=hw), rng.random_range(-hh..=hh));
            if (g - start).length() >= cfg.task.min_goal_distance {
                goal = Some(g);
                break;
            }
        }
        // Validation guarantees the farthest corner is at least min_goal_distance away.
        self.goal =
            goal.unwrap_or_else(|| Vector::new(-hw.copysign(start.x), -hh.copysign(start.y)));
        world.place_robot(0, start, heading);
        self.prev_distance = (self.goal - start).length();
    }

    /// Reward and success after a step.
    pub fn judge(&mut self, world: &World, cfg: &Scenario) -> Judgement {
        let robot = &world.robots[0];
        let distance = (self.goal - robot.position).length();
        let success = distance < cfg.task.goal_radius;
        let mut reward =
            cfg.task.progress_weight * (self.prev_distance - distance) - cfg.task.time_cost;
        if success {
            reward += cfg.task.success_bonus;
        }
        if robot.in_contact {
            reward -= cfg.task.collision_penalty;
        }
        self.prev_distance = distance;
        Judgement { reward, success }
    }

    /// Writes the observation (clipped to its bounds) into `obs`.
    pub fn observe(&self, world: &World, cfg: &Scenario, obs: &mut [f32]) {
        let robot = &world.robots[0];
        for (o, raw) in obs[..IR_COUNT].iter_mut().zip(robot.ir_raw) {
            *o = world.ir.normalise(raw);
        }
        for (o, code) in obs[IR_COUNT..IR_COUNT + US_COUNT]
            .iter_mut()
            .zip(robot.us_code)
        {
            *o = world.us.normalise(code);
        }
        let base = IR_COUNT + US_COUNT;
        let to_goal = self.goal - robot.position;
        let distance = to_goal.length();
        let (s, c) = robot.heading.sin_cos();
        // Goal in the robot frame: rotate the world offset by -heading.
        let local = Vector::new(
            c * to_goal.x + s * to_goal.y,
            -s * to_goal.x + c * to_goal.y,
        );
        let (bs, bc) = if distance > 0.0 {
            (local.y / distance, local.x / distance)
        } else {
            (0.0, 1.0)
        };
        obs[base] = distance.min(diagonal(cfg));
        obs[base + 1] = bs.clamp(-1.0, 1.0);
        obs[base + 2] = bc.clamp(-1.0, 1.0);
        let vmax = world.drive.max_wheel_speed;
        obs[base + 3] = (robot.wheel_speeds[0] / vmax).clamp(-1.0, 1.0);
        obs[base + 4] = (robot.wheel_speeds[1] / vmax).clamp(-1.0, 1.0);
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

fn diagonal(cfg: &Scenario) -> f32 {
    (cfg.arena.width * cfg.arena.width + cfg.arena.height * cfg.arena.height).sqrt()
}
