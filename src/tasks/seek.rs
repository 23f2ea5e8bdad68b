//! KheperaIV-Seek: find and reach a coloured pillar seen only through the camera (issue 15;
//! docs/task-design.md §6.3). Avoid's arena and random grey obstacles, plus one goal pillar (a
//! red cylinder at the goal) and optional distractor pillars of other colours. The observation
//! holds the IR ring, the camera's scanline and the wheel speeds: not the goal's distance or
//! bearing.
//!
//! Reward per step as Nav's: `progress_weight`·(progress toward the pillar's centre, m)
//! − `time_cost` + `success_bonus` on success − `collision_penalty` in contact (Avoid's 0.5).
//! Success when the robot's centre is within `task.goal_radius` of the pillar's: 0.1704 m, its
//! rim 5 cm from the pillar's surface (0.05 + 0.0704 + 0.05 m, docs/task-design.md §6.3);
//! truncated after 600 steps, as Avoid.
//!
//! Units: metres, seconds, radians; world frame.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;
use toml::Table;

use super::nav;
use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::config::{ConfigTable, Domain};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::geometry::scene::SceneShape;
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;

/// Colours of the distractor pillars, in turn: blue, yellow, magenta, cyan.
const DISTRACTOR_COLORS: [[f32; 3]; 4] = [
    [0.1, 0.2, 1.0],
    [1.0, 0.9, 0.1],
    [0.9, 0.1, 0.9],
    [0.1, 0.9, 0.9],
];
/// Tries to place each distractor.
const PLACE_TRIES: usize = 64;

/// Seek: the task, its defaults and its table.
pub const SEEK: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-Seek"),
    summary: "find and reach a coloured pillar among obstacles, seen only through the camera",
    schema: TaskSchema {
        name: "seek",
        since: 1,
        defaults: r#"
[obstacles]
count = 10                   # Avoid's random obstacles
placement = "anywhere"

[spawn]
min_goal_distance = 1.0      # as Avoid

[sensors]
carry = ["ir", "us", "gyro", "camera"]  # the camera sees the pillar
observe = ["ir", "camera"]              # no goal in the observation but what the camera shows

[task]
goal_radius = 0.1704         # m: the robot's rim 5 cm from the 5 cm pillar (0.05 + 0.0704 + 0.05)
max_steps = 600              # 30 s, as Avoid
collision_penalty = 0.5      # as Avoid
"#,
        section: Some(Section {
            name: "seek",
            keys: SeekConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring::GOAL,
    agents: AgentFacts::ONE,
};

crate::config_table! {
    /// `[seek]`: the pillar and the distractors.
    pub struct SeekConfig {
        /// m, the goal pillar's radius [E: docs/task-design.md §6.3]
        pillar_radius: f32 = 0.05 => Domain::range(0.01, 0.2),
        /// RGB in [0, 1] of the goal pillar (red)
        pillar_color: [f32; 3] = [1.0, 0.0, 0.0] => Domain::UNIT,
        /// pillars of other colours (blue, yellow, magenta, cyan in turn), 0..8
        distractors: u32 = 0 => Domain::range(0.0, 8.0),
    }
}

fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    let s = SeekConfig::from_table(table, origin, "seek")?;
    if scenario.task.goal_radius <= s.pillar_radius + scenario.robot.radius {
        return Err(Error::config(
            origin,
            "task.goal_radius",
            format!(
                "must exceed seek.pillar_radius + robot.radius ({}): the robot could never reach \
                 it, got {}",
                s.pillar_radius + scenario.robot.radius,
                scenario.task.goal_radius
            ),
        ));
    }
    if !scenario.sensors.carry.iter().any(|n| n == "camera") {
        return Err(Error::config(
            origin,
            "sensors.carry",
            "seeking a colour needs the camera: add \"camera\"",
        ));
    }
    Ok(())
}

/// Per-world state of the seek task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Seek {
    /// The pillar's centre (the goal), m.
    pub goal: Vector,
    prev_distance: f32,
    cfg: SeekConfig,
}

impl Task for Seek {
    fn new(cfg: &Scenario) -> Result<Self> {
        Ok(Self {
            goal: Vector::ZERO,
            prev_distance: 0.0,
            cfg: cfg.own()?,
        })
    }

    fn spawn(_cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Single)
    }

    fn agents(_cfg: &Scenario) -> Result<Vec<Agent>> {
        Ok(vec![Agent {
            name: "robot".into(),
            body: Body::Robot(0),
            layout: ObsLayout::new(vec![Block::new("wheel_speeds", 2, -1.0, 1.0)]),
        }])
    }

    /// Stands the pillar on the goal and the distractors where they clear everything.
    fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, layout: &mut Layout) {
        let goal = layout.goals[0];
        let r = self.cfg.pillar_radius;
        let pillar = SceneShape::circle(goal, r).with_color(self.cfg.pillar_color);
        let start = layout.poses[0].0;
        let (hx, hy) = (0.5 * cfg.arena.width - 0.2, 0.5 * cfg.arena.height - 0.2);
        let mut placed: Vec<SceneShape> = Vec::new();
        for k in 0..self.cfg.distractors as usize {
            for _ in 0..PLACE_TRIES {
                let p = Vector::new(rng.random_range(-hx..=hx), rng.random_range(-hy..=hy));
                let candidate = SceneShape::circle(p, r);
                let clear = (p - start).length() > 0.3
                    && (p - goal).length() > 0.3
                    && layout
                        .obstacles
                        .iter()
                        .chain(&placed)
                        .all(|o| o.gap(&candidate) > 2.0 * cfg.robot.radius + 0.02);
                if clear {
                    let color = DISTRACTOR_COLORS[k % DISTRACTOR_COLORS.len()];
                    placed.push(candidate.with_color(color));
                    break;
                }
            }
        }
        layout.obstacles.push(pillar);
        layout.obstacles.extend(placed);
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
        let j = nav::judge_robot(world, 0, self.goal, &mut self.prev_distance, cfg);
        rewards[0] = j.reward;
        terminated[0] = j.success;
        j.success
    }

    fn observe(&self, world: &World, _cfg: &Scenario, _agent: usize, out: &mut ObsWriter) {
        for w in nav::wheel_obs(world, 0) {
            out.put(w);
        }
    }

    fn goals(&self) -> Vec<Vector> {
        vec![self.goal]
    }

    fn draw(&self, _world: &World, cfg: &Scenario, marks: &mut Vec<Mark>) {
        marks.push(nav::goal_mark(self.goal, cfg, None));
    }
}
