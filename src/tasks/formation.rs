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
//! `terminate_on_collision`, on any contact; `Env` truncates at `max_steps`. Extra episode
//! statistics: `formation_error_mean`, `formation_error_max` (m).
//!
//! An agent's success: the leader's is the task's (it reached its goal); a follower succeeds
//! when the leader reached its goal and the follower then stands within `task.goal_radius` of its
//! target, the task's own tolerance for being at a point (the leader's, 0.05 m by default). A
//! follower that drifted away, or an episode that ended without the leader's arrival, is not a
//! success.

use rapier2d::math::Vector;
use toml::Table;

use super::nav;
use super::{Agent, AgentFacts, Body, Driver, Scoring, Task, TaskInfo};
use crate::config::{limits, ConfigTable, Domain};
use crate::controllers::position::twist_to_wheels;
use crate::controllers::{Braitenberg, PositionControl};
use crate::draw::{Mark, PALETTE};
use crate::error::{Error, Result};
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;

/// KheperaIV-Formation: a 3 m × 3 m arena and the `[formation]` table.
pub const FORMATION: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-Formation"),
    summary: "one leader drives to a goal; K followers keep offsets (r, beta) from the leader's \
              pose (paper eq. 12): x = xL + r cos(beta + thetaL), y = yL + r sin(beta + thetaL); \
              spawn.start/goal are the leader's, the robots start at rest in formation",
    schema: TaskSchema {
        name: "formation",
        since: 0,
        defaults: r#"
[arena]
width = 3.0                  # m: room for a formation to travel
height = 3.0

[spawn]
min_goal_distance = 1.5

[task]
max_steps = 800              # 40 s
"#,
        section: Some(Section {
            name: "formation",
            keys: FormationConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring {
        speed: false,
        ..Scoring::GOAL
    },
    agents: AgentFacts::TEAM,
};

/// Formation shapes: offsets (r, β) of the followers relative to the leader's pose (eq. 12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FormationShape {
    /// Arms ahead, left, behind, right of the leader (the paper's Fig. 7).
    Cross,
    /// Abreast, alternating left and right of the leader.
    Line,
    /// A V behind the leader.
    Wedge,
    /// Evenly round the leader.
    Circle,
    /// The `offsets` list.
    Custom,
}

/// Most followers (`formation.n_followers`, custom `formation.offsets`).
pub const MAX_FOLLOWERS: u32 = 16;

crate::config_table! {
    /// `[formation]`: leader–follower formation (paper §3.5).
    pub struct FormationConfig {
        /// cross (Fig. 7), line (abreast), wedge (V behind), circle, custom
        shape: FormationShape = "cross",
        /// K followers (cross: 4 fills the arms)
        n_followers: u32 = 4 => Domain::range(1.0, MAX_FOLLOWERS as f64),
        /// r (m): nearest followers' distance to the leader (the paper's example; > 2 x radius + IR range, so robots in formation do not see each other)
        spacing: f32 = 0.5 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// custom shape: [[r, beta], ...] (m, rad CCW from the leader's heading)
        offsets: Vec<[f32; 2]> = [] => Domain::range(-limits::LENGTH, limits::LENGTH).at_most_entries(MAX_FOLLOWERS as usize),
        /// "scripted": position control + Braitenberg in Rust; "agent": learnt
        leader: Driver = "scripted",
        /// m/s, scripted leader's speed (slow enough for followers to keep up)
        leader_vmax: f32 = 0.15 => Domain::POSITIVE.at_most(limits::SPEED),
        /// rad/s, scripted leader's turn rate limit (eq. 4)
        leader_wmax: f32 = 1.0 => Domain::POSITIVE.at_most(limits::TURN_RATE),
        /// m, scripted leader's docking radius (eq. 3)
        leader_kr: f32 = 0.15 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// reward per metre of a follower's distance to its target
        error_weight: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward per metre of the followers' mean error, shared by all
        team_weight: f32 = 0.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
    }
}

impl FormationShape {
    /// The followers' (r, β) offsets of `k` followers at `spacing` (β in radians, CCW from the
    /// leader's heading). `Custom` has none of its own.
    pub fn offsets(self, k: usize, spacing: f32) -> Vec<[f32; 2]> {
        use std::f32::consts::{FRAC_PI_2, PI};
        let r = spacing;
        match self {
            // Arms ahead, left, behind, right; further followers go one spacing further out.
            FormationShape::Cross => (0..k)
                .map(|i| [r * (1 + i / 4) as f32, FRAC_PI_2 * (i % 4) as f32])
                .collect(),
            FormationShape::Line => (0..k)
                .map(|i| {
                    let side = if i % 2 == 0 { FRAC_PI_2 } else { -FRAC_PI_2 };
                    [r * (1 + i / 2) as f32, side]
                })
                .collect(),
            FormationShape::Wedge => (0..k)
                .map(|i| {
                    let side = if i % 2 == 0 { 0.75 * PI } else { -0.75 * PI };
                    [r * (1 + i / 2) as f32, side]
                })
                .collect(),
            FormationShape::Circle => (0..k)
                .map(|i| [r, 2.0 * PI * i as f32 / k as f32])
                .collect(),
            FormationShape::Custom => Vec::new(),
        }
    }
}

impl FormationConfig {
    /// The followers' (r, β) offsets from the leader (β in radians, CCW from its heading).
    pub fn offsets(&self) -> Vec<[f32; 2]> {
        match self.shape {
            FormationShape::Custom => self.offsets.clone(),
            shape => shape.offsets(self.n_followers as usize, self.spacing),
        }
    }

    fn validate(&self, origin: &str, radius: f32) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        if self.shape == FormationShape::Custom && self.offsets.is_empty() {
            return bad(
                "formation.offsets",
                format!("a custom shape needs 1 to {MAX_FOLLOWERS} [r, beta] offsets, got none"),
            );
        }
        if self.shape != FormationShape::Custom && !self.offsets.is_empty() {
            return bad(
                "formation.offsets",
                format!(
                    "are only read with formation.shape = \"custom\" (the shape is {:?})",
                    self.shape
                ),
            );
        }
        // Robots in formation must not overlap one another (the leader sits at the origin).
        let points: Vec<(f32, f32)> = std::iter::once((0.0, 0.0))
            .chain(
                self.offsets()
                    .iter()
                    .map(|[r, b]| (r * b.cos(), r * b.sin())),
            )
            .collect();
        for (i, a) in points.iter().enumerate() {
            for b in &points[i + 1..] {
                let d = ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
                if !d.is_finite() || d < 2.0 * radius + 0.01 {
                    let key = if self.shape == FormationShape::Custom {
                        "formation.offsets"
                    } else {
                        "formation.spacing"
                    };
                    return bad(
                        key,
                        format!(
                            "robots in formation would be {d:.3} m apart, closer than a robot's \
                             diameter + 1 cm"
                        ),
                    );
                }
            }
        }
        Ok(())
    }
}

fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    FormationConfig::from_table(table, origin, "formation")?.validate(origin, scenario.robot.radius)
}

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
    error_weight: f32,
    team_weight: f32,
    prev_leader_distance: f32,
    /// Each follower's distance to its target after the last step (m).
    pub errors: Vec<f32>,
    error_sum: f64,
    error_count: u64,
    error_max: f32,
}

impl Formation {
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

    /// Mean and largest follower error over the episode so far (m).
    pub fn error_stats(&self) -> (f32, f32) {
        let mean = if self.error_count == 0 {
            0.0
        } else {
            (self.error_sum / self.error_count as f64) as f32
        };
        (mean, self.error_max)
    }

    /// One follower's own observation blocks (after its sensors'): target_offset,
    /// leader_offset (m, clipped to the arena diagonal), leader_heading, leader_velocity and
    /// wheel_speeds.
    pub fn follower_blocks(cfg: &Scenario) -> ObsLayout {
        let reach = cfg.diagonal();
        ObsLayout::new(vec![
            Block::new("target_offset", 2, -reach, reach),
            Block::new("leader_offset", 2, -reach, reach),
            Block::new("leader_heading", 2, -1.0, 1.0),
            Block::new("leader_velocity", 2, -1.0, 1.0),
            Block::new("wheel_speeds", 2, -1.0, 1.0),
        ])
    }
}

impl Task for Formation {
    const EXTRA_STATS: &'static [&'static str] = &["formation_error_mean", "formation_error_max"];

    fn new(cfg: &Scenario) -> Result<Self> {
        let f: FormationConfig = cfg.own()?;
        let offsets = f.offsets();
        Ok(Self {
            goal: Vector::ZERO,
            errors: vec![0.0; offsets.len()],
            offsets,
            leader_agent: f.leader == Driver::Agent,
            leader_control: PositionControl {
                vmax: f.leader_vmax,
                wmax: f.leader_wmax,
                kr: f.leader_kr,
                stop_radius: 0.5 * cfg.task.goal_radius,
            },
            avoidance: Braitenberg::default(),
            error_weight: f.error_weight,
            team_weight: f.team_weight,
            prev_leader_distance: 0.0,
            error_sum: 0.0,
            error_count: 0,
            error_max: 0.0,
        })
    }

    fn spawn(cfg: &Scenario) -> Result<Spawn> {
        let f: FormationConfig = cfg.own()?;
        Ok(Spawn::Formation(f.offsets()))
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let f: FormationConfig = cfg.own()?;
        let mut agents = Vec::new();
        if f.leader == Driver::Agent {
            agents.push(Agent {
                name: "leader".into(),
                body: Body::Robot(0),
                layout: nav::nav_blocks(cfg),
            });
        }
        for k in 0..f.offsets().len() {
            agents.push(Agent {
                name: format!("follower_{k}"),
                body: Body::Robot(k + 1),
                layout: Self::follower_blocks(cfg),
            });
        }
        Ok(agents)
    }

    fn reset(&mut self, world: &World, layout: &Layout) {
        self.goal = layout.goals[0];
        self.prev_leader_distance = (self.goal - world.robots[0].position).length();
        self.error_sum = 0.0;
        self.error_count = 0;
        self.error_max = 0.0;
        for k in 0..self.n_followers() {
            self.errors[k] = (self.target(world, k) - world.robots[k + 1].position).length();
        }
    }

    /// Sets the scripted leader's wheel command from its true pose and last IR readings.
    fn before_step(&self, world: &mut World) {
        if self.leader_agent {
            return;
        }
        let local = nav::to_robot_frame(world, 0, self.goal);
        let distance = local.length();
        let bearing = local.y.atan2(local.x);
        let (v, w) = self.leader_control.twist(distance, bearing);
        let axle = world.drive.axle_length;
        let mut proximity = [0.0f32; crate::sensors::IR_COUNT];
        if let Some(ir) = &world.sensors.ir {
            for (p, raw) in proximity.iter_mut().zip(world.robots[0].readings.ir.raw) {
                *p = ir.sensor.model.normalise(raw);
            }
        }
        let wheels = self
            .avoidance
            .apply(twist_to_wheels(v, w, axle), &proximity);
        let vmax = world.drive.max_wheel_speed;
        world.robots[0].wheel_command = wheels.map(|s| s.clamp(-vmax, vmax));
    }

    /// Per-agent rewards after a step (leader first when it is an agent); returns whether the
    /// leader reached its goal.
    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        _terminated: &mut [bool],
    ) -> bool {
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
            rewards[first + k] = -self.error_weight * self.errors[k]
                - cfg.task.collision_penalty * contact
                - self.team_weight * mean;
        }
        leader.success
    }

    fn extra_stats(&self, out: &mut [f32]) {
        (out[0], out[1]) = self.error_stats();
    }

    /// The leader: the task's success; a follower: the leader arrived and the follower is
    /// within `task.goal_radius` of its target.
    fn agent_success(
        &self,
        _: &World,
        cfg: &Scenario,
        agent: usize,
        episode_success: bool,
    ) -> bool {
        match agent.checked_sub(usize::from(self.leader_agent)) {
            None => episode_success,
            Some(k) => episode_success && self.errors[k] <= cfg.task.goal_radius,
        }
    }

    /// Writes an agent's own block: the leader's Nav block when it is an agent (agent 0), or
    /// a follower's ([`Formation::follower_blocks`]).
    fn observe(&self, world: &World, cfg: &Scenario, agent: usize, out: &mut ObsWriter) {
        let Some(k) = agent.checked_sub(usize::from(self.leader_agent)) else {
            nav::observe_robot(world, 0, self.goal, cfg, out);
            return;
        };
        let (v, w) = world.drive.twist(world.robots[0].wheel_speeds);
        let leader_velocity = [
            (v / world.drive.max_wheel_speed).clamp(-1.0, 1.0),
            (w / world.drive.max_yaw_rate()).clamp(-1.0, 1.0),
        ];
        let reach = cfg.diagonal();
        let i = k + 1;
        let offset = nav::to_robot_frame(world, i, self.target(world, k));
        out.put(offset.x.clamp(-reach, reach));
        out.put(offset.y.clamp(-reach, reach));
        let leader = nav::to_robot_frame(world, i, world.robots[0].position);
        out.put(leader.x.clamp(-reach, reach));
        out.put(leader.y.clamp(-reach, reach));
        let relative = world.robots[0].heading - world.believed_pose(i).1;
        out.put(relative.sin());
        out.put(relative.cos());
        out.put(leader_velocity[0]);
        out.put(leader_velocity[1]);
        let [l, r] = nav::wheel_obs(world, i);
        out.put(l);
        out.put(r);
    }

    fn goals(&self) -> Vec<Vector> {
        vec![self.goal]
    }

    fn targets(&self, world: &World) -> Vec<Vector> {
        (0..self.n_followers())
            .map(|k| self.target(world, k))
            .collect()
    }

    fn fits(&self, twin: &Self) -> bool {
        self.offsets.len() == twin.offsets.len() && self.errors.len() == twin.errors.len()
    }

    fn draw(&self, world: &World, cfg: &Scenario, marks: &mut Vec<Mark>) {
        marks.push(nav::goal_mark(self.goal, cfg, None));
        // Targets: crosses in their follower's colour.
        for (k, target) in self.targets(world).into_iter().enumerate() {
            marks.push(Mark::Cross {
                position: target,
                size: 0.025,
                colour: PALETTE[(k + 1) % 8],
            });
        }
    }
}
