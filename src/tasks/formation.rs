//! KheperaIV-Formation: leader–follower formation control (the paper's §3.5, Fig. 7).
//!
//! Robot 0 is the leader; it drives to the goal, scripted by default (position control, eqs.
//! 1–4, on its true pose, followed by Braitenberg avoidance on its IR ring, eqs. 5–7) or driven
//! by an agent (`leader = "agent"`, with the Nav observation and reward). Robots 1..=K are the
//! followers; follower k's target is the leader's pose composed with its offset (r_k, β_k)
//! (eq. 12): x = x_L + r cos(β + θ_L), y = y_L + r sin(β + θ_L).
//!
//! A follower observes its own sensors, its target and the leader in its own frame (x forward,
//! y left): the target offset (m), the leader's position (m) and relative heading (sin, cos),
//! the leader's velocity (v / v_max, ω / ω_max) and its own wheel speeds; so a controller can
//! compute eq. 12 targets of its own from the leader's pose (`khepera_gym.baselines`).
//!
//! Follower reward per step: `−error_weight·e_k − collision_penalty·[k in contact]
//!  − team_weight·mean_j e_j`, with e_k the distance (m) from follower k to its target. The
//! episode terminates when the leader reaches its goal (success) or, with
//! `terminate_on_collision`, on any contact; `Env` truncates at `max_steps`.

use rapier2d::math::Vector;

use super::nav;
use crate::controllers::position::twist_to_wheels;
use crate::controllers::{Braitenberg, PositionControl};
use crate::scenario::{FormationConfig, LeaderMode, Scenario};
use crate::sensors::{IR_COUNT, US_COUNT};
use crate::world::World;

/// A follower's observation layout: (name, length) in order.
pub const FOLLOWER_LAYOUT: &[(&str, usize)] = &[
    ("ir", IR_COUNT),
    ("us", US_COUNT),
    ("target_offset", 2),
    ("leader_offset", 2),
    ("leader_heading", 2),
    ("leader_velocity", 2),
    ("wheel_speeds", 2),
];

/// A follower's observation length.
pub const FOLLOWER_OBS_DIM: usize = IR_COUNT + US_COUNT + 10;

/// Per-world state of the formation task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Formation {
    /// The leader's goal (m).
    pub goal: Vector,
    /// Followers' (r, β) offsets.
    pub offsets: Vec<[f32; 2]>,
    /// Whether an agent drives the leader.
    pub leader_agent: bool,
    leader_control: PositionControl,
    avoidance: Braitenberg,
    prev_leader_distance: f32,
    /// Each follower's distance to its target after the last step (m).
    pub errors: Vec<f32>,
    error_sum: f64,
    error_count: u64,
    error_max: f32,
}

impl Formation {
    /// The task for a scenario with the `[formation]` table `f`.
    pub fn new(cfg: &Scenario, f: &FormationConfig) -> Self {
        let offsets = f.offsets();
        Self {
            goal: Vector::ZERO,
            errors: vec![0.0; offsets.len()],
            offsets,
            leader_agent: f.leader == LeaderMode::Agent,
            leader_control: PositionControl {
                vmax: f.leader_vmax,
                wmax: f.leader_wmax,
                kr: f.leader_kr,
                stop_radius: 0.5 * cfg.task.goal_radius,
            },
            avoidance: Braitenberg::default(),
            prev_leader_distance: 0.0,
            error_sum: 0.0,
            error_count: 0,
            error_max: 0.0,
        }
    }

    /// Followers.
    pub fn n_followers(&self) -> usize {
        self.offsets.len()
    }

    /// Follower k's target: the leader's pose composed with offset k (eq. 12).
    pub fn target(&self, world: &World, k: usize) -> Vector {
        let leader = &world.robots[0];
        let [r, beta] = self.offsets[k];
        let a = beta + leader.heading;
        leader.position + Vector::new(r * a.cos(), r * a.sin())
    }

    /// Starts an episode toward `goal` (robots already placed in formation).
    pub fn reset(&mut self, world: &World, goal: Vector) {
        self.goal = goal;
        self.prev_leader_distance = (goal - world.robots[0].position).length();
        self.error_sum = 0.0;
        self.error_count = 0;
        self.error_max = 0.0;
        for k in 0..self.n_followers() {
            self.errors[k] = (self.target(world, k) - world.robots[k + 1].position).length();
        }
    }

    /// Sets the scripted leader's wheel command from its true pose and last IR readings.
    pub fn drive_leader(&self, world: &mut World) {
        let local = nav::to_robot_frame(world, 0, self.goal);
        let distance = local.length();
        let bearing = local.y.atan2(local.x);
        let (v, w) = self.leader_control.twist(distance, bearing);
        let axle = world.drive.axle_length;
        let mut proximity = [0.0f32; IR_COUNT];
        for (p, raw) in proximity.iter_mut().zip(world.robots[0].ir_raw) {
            *p = world.ir.normalise(raw);
        }
        let wheels = self
            .avoidance
            .apply(twist_to_wheels(v, w, axle), &proximity);
        let vmax = world.drive.max_wheel_speed;
        world.robots[0].wheel_command = wheels.map(|s| s.clamp(-vmax, vmax));
    }

    /// Per-agent rewards after a step (leader first when it is an agent); returns whether the
    /// leader reached its goal.
    pub fn judge(&mut self, world: &World, cfg: &Scenario, rewards: &mut [f32]) -> bool {
        let (error_weight, team_weight) = cfg
            .formation
            .as_ref()
            .map_or((1.0, 0.0), |f| (f.error_weight, f.team_weight));
        for k in 0..self.n_followers() {
            let e = (self.target(world, k) - world.robots[k + 1].position).length();
            self.errors[k] = e;
            self.error_sum += e as f64;
            self.error_count += 1;
            self.error_max = self.error_max.max(e);
        }
        let mean = self.errors.iter().sum::<f32>() / self.n_followers().max(1) as f32;
        let leader = nav::judge_robot(world, 0, self.goal, &mut self.prev_leader_distance, cfg);
        let first = usize::from(self.leader_agent);
        if self.leader_agent {
            rewards[0] = leader.reward;
        }
        for k in 0..self.n_followers() {
            let contact = world.robots[k + 1].in_contact as u8 as f32;
            rewards[first + k] = -error_weight * self.errors[k]
                - cfg.task.collision_penalty * contact
                - team_weight * mean;
        }
        leader.success
    }

    /// Mean and largest follower error over the episode so far (m).
    pub fn error_stats(&self) -> (f32, f32) {
        let mean = if self.error_count == 0 {
            0.0
        } else {
            (self.error_sum / self.error_count as f64) as f32
        };
        (mean, self.error_max)
    }

    /// Writes the joint observation: the leader's Nav block when it is an agent, then one block
    /// per follower (layout [`FOLLOWER_LAYOUT`]).
    pub fn observe(&self, world: &World, cfg: &Scenario, obs: &mut [f32]) {
        let mut rest = obs;
        if self.leader_agent {
            let (block, tail) = rest.split_at_mut(nav::OBS_DIM);
            nav::observe_robot(world, 0, self.goal, cfg, block);
            rest = tail;
        }
        let (v, w) = world.drive.twist(world.robots[0].wheel_speeds);
        let leader_velocity = [
            (v / world.drive.max_wheel_speed).clamp(-1.0, 1.0),
            (w / world.drive.max_yaw_rate()).clamp(-1.0, 1.0),
        ];
        let reach = nav::diagonal(cfg);
        for (k, block) in rest.chunks_exact_mut(FOLLOWER_OBS_DIM).enumerate() {
            let i = k + 1;
            nav::observe_sensors(world, i, block);
            let base = IR_COUNT + US_COUNT;
            let offset = nav::to_robot_frame(world, i, self.target(world, k));
            block[base] = offset.x.clamp(-reach, reach);
            block[base + 1] = offset.y.clamp(-reach, reach);
            let leader = nav::to_robot_frame(world, i, world.robots[0].position);
            block[base + 2] = leader.x.clamp(-reach, reach);
            block[base + 3] = leader.y.clamp(-reach, reach);
            let relative = world.robots[0].heading - world.robots[i].heading;
            block[base + 4] = relative.sin();
            block[base + 5] = relative.cos();
            block[base + 6] = leader_velocity[0];
            block[base + 7] = leader_velocity[1];
            let [l, r] = nav::wheel_obs(world, i);
            block[base + 8] = l;
            block[base + 9] = r;
        }
    }

    /// Bounds of one follower block.
    pub fn follower_bounds(cfg: &Scenario) -> (Vec<f32>, Vec<f32>) {
        let reach = nav::diagonal(cfg);
        let mut low = vec![0.0; IR_COUNT + US_COUNT];
        let mut high = vec![1.0; IR_COUNT + US_COUNT];
        low.extend([-reach, -reach, -reach, -reach]);
        high.extend([reach, reach, reach, reach]);
        low.extend([-1.0; 6]);
        high.extend([1.0; 6]);
        (low, high)
    }
}
