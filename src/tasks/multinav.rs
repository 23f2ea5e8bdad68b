//! Multi-robot navigation (PettingZoo `multinav_v0`): every robot drives to its own goal; the
//! robots are obstacles to one another (their discs block each other's rays and rapier resolves
//! their contacts). Each robot is an agent with the Nav observation and reward; a robot that
//! reaches its goal is terminated as an agent and parks there (its actions are ignored), still
//! an obstacle for the others. The episode terminates when every robot has arrived (the task's
//! success); an agent succeeds when its own robot arrived.
//!
//! Units: metres, seconds, radians; observations in the robot frame (x forward, y left), as
//! Nav's.

use rapier2d::math::Vector;
use toml::Table;

use super::nav;
use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::config::{ConfigTable, Domain};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::obs::ObsWriter;
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;

/// Largest number of robots in a multinav world (a swarm; issues 16 and 54): ARGoS's largest
/// swarms (Pinciroli et al., Swarm Intelligence 6, 2012: 10,000 robots faster than real time).
/// Checked with the other keys when the scenario loads, before anything is allocated.
pub const MAX_ROBOTS: u32 = 10_000;

/// Share of the spawn region random sequential placement can cover with the robots' exclusion
/// discs before it jams: 0.547 for discs in the plane (Feder, J. Theor. Biol. 87, 1980); 0.5
/// leaves room for the finite number of tries per robot.
const PLACEMENT_COVERAGE: f32 = 0.5;

/// multinav: the Nav defaults and the `[multinav]` table.
pub const MULTINAV: TaskInfo = TaskInfo {
    env_id: None,
    summary: "several robots, each driving to its own goal; they are obstacles to each other",
    schema: TaskSchema {
        name: "multinav",
        since: 0,
        defaults: r#"
[obstacles]
placement = "anywhere"       # with count > 0, obstacles anywhere in the arena

[spawn]
min_goal_distance = 1.0      # m: each robot crosses the arena, so robots meet on the way

[task]
max_steps = 600              # 30 s: robots make way for one another
collision_penalty = 0.5      # contacts (with walls and other robots) cost as in Avoid
"#,
        section: Some(Section {
            name: "multinav",
            keys: MultiNavConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring {
        speed: false,
        ..Scoring::GOAL
    },
    agents: AgentFacts {
        end_separately: true,
        ..AgentFacts::TEAM
    },
};

crate::config_table! {
    /// `[multinav]`: several robots, each with its own goal.
    pub struct MultiNavConfig {
        /// robots, each with its own goal; they are obstacles to each other (1..10000; a swarm needs an arena to match, see `configs/swarm.toml`)
        n_robots: u32 = 4 => Domain::range(1.0, MAX_ROBOTS as f64),
    }
}

fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    let m = MultiNavConfig::from_table(table, origin, "multinav")?;
    let fit = robots_that_fit(scenario);
    if m.n_robots as usize > fit {
        let a = &scenario.arena;
        return Err(Error::config(
            origin,
            "multinav.n_robots",
            format!(
                "{} robots do not fit in a {} m x {} m arena: random placement fits about {fit} \
                 (centres and goals at least 2 radii + obstacles.spawn_clearance apart); use \
                 fewer robots or a larger arena.width and arena.height",
                m.n_robots, a.width, a.height
            ),
        ));
    }
    Ok(())
}

/// About how many robots (and as many goals) random sequential placement fits in the spawn
/// region, each excluding a disc of half their least spacing.
pub fn robots_that_fit(cfg: &Scenario) -> usize {
    let radius = cfg.robot.radius;
    let apart = 2.0 * radius + cfg.obstacles.spawn_clearance;
    let margin = radius + cfg.spawn.wall_margin;
    // Centres range over the arena less the margins; their discs reach half a spacing beyond.
    let side = |length: f32| (length - 2.0 * margin).max(0.0) + apart;
    let area = side(cfg.arena.width) * side(cfg.arena.height);
    let per_robot = std::f32::consts::PI * 0.25 * apart * apart;
    (PLACEMENT_COVERAGE * area / per_robot) as usize
}

/// Per-world state of the multi-robot navigation task.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct MultiNav {
    /// Each robot's goal (m).
    pub goals: Vec<Vector>,
    prev_distance: Vec<f32>,
    /// Robots that have reached their goal.
    pub arrived: Vec<bool>,
}

impl Task for MultiNav {
    fn new(cfg: &Scenario) -> Result<Self> {
        let n = cfg.own::<MultiNavConfig>()?.n_robots as usize;
        Ok(Self {
            goals: vec![Vector::ZERO; n],
            prev_distance: vec![0.0; n],
            arrived: vec![false; n],
        })
    }

    fn spawn(cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Multi(cfg.own::<MultiNavConfig>()?.n_robots as usize))
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let n = cfg.own::<MultiNavConfig>()?.n_robots as usize;
        Ok((0..n)
            .map(|i| Agent {
                name: format!("robot_{i}"),
                body: Body::Robot(i),
                layout: nav::nav_blocks(cfg),
            })
            .collect())
    }

    fn reset(&mut self, world: &World, layout: &Layout) {
        self.goals = layout.goals.clone();
        self.prev_distance = self
            .goals
            .iter()
            .zip(&world.robots)
            .map(|(g, r)| (*g - r.position).length())
            .collect();
        self.arrived = vec![false; self.goals.len()];
    }

    /// Parked robots (arrived) get zero wheel commands.
    fn before_step(&self, world: &mut World) {
        for (robot, arrived) in world.robots.iter_mut().zip(&self.arrived) {
            if *arrived {
                robot.wheel_command = [0.0, 0.0];
            }
        }
    }

    /// Rewards and arrivals after a step: `rewards[i]` and `terminated[i]` per robot; returns
    /// whether every robot has now arrived.
    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool {
        for i in 0..self.goals.len() {
            if self.arrived[i] {
                rewards[i] = 0.0;
                terminated[i] = true;
                continue;
            }
            let j = nav::judge_robot(world, i, self.goals[i], &mut self.prev_distance[i], cfg);
            rewards[i] = j.reward;
            self.arrived[i] = j.success;
            terminated[i] = j.success;
        }
        self.arrived.iter().all(|a| *a)
    }

    /// Robot `agent` reached its goal.
    fn agent_success(&self, _: &World, _: &Scenario, agent: usize, _: bool) -> bool {
        self.arrived[agent]
    }

    /// Writes every robot's Nav observation, one block after another.
    /// Agent `i` drives robot `i` toward goal `i`.
    fn observe(&self, world: &World, cfg: &Scenario, agent: usize, out: &mut ObsWriter) {
        nav::observe_robot(world, agent, self.goals[agent], cfg, out);
    }

    fn goals(&self) -> Vec<Vector> {
        self.goals.clone()
    }

    fn fits(&self, twin: &Self) -> bool {
        self.goals.len() == twin.goals.len() && self.arrived.len() == twin.arrived.len()
    }

    fn draw(&self, _world: &World, cfg: &Scenario, marks: &mut Vec<Mark>) {
        for (k, goal) in self.goals.iter().enumerate() {
            marks.push(nav::goal_mark(*goal, cfg, Some(k)));
        }
    }
}
