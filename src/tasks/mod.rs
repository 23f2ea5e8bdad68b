//! Tasks: what a world is for. Each task is one file here implementing the [`Task`] contract
//! (its scenario defaults and table, spawn rule, agents and their observation blocks, reset,
//! per-step hook, rewards and termination, extra episode statistics, what success means for one
//! agent, what it draws) and one line
//! in `task_registry!` below. [`Env`] (`env.rs`) joins a task to a world and keeps the episode's
//! bookkeeping (layout at reset, step counter, termination, statistics, trails) in one place;
//! the batch, the world, the renderer and the binding never look at which task they hold.
//!
//! Agents: a task has one or more agents, each driving one [`Body`] (a robot of the world, or
//! the task's own vehicle: DroneFollow's drone) with two normalised numbers (a robot's wheels;
//! with `task.led_action`, three more for its top LEDs' colour, the same width for every agent:
//! [`action_width`]) and observing one block of the joint observation. The joint
//! action is the agents' actions in order; the joint reward is the mean of the agents' rewards.
//!
//! Dispatch is static: the registry generates an enum of the tasks' states and matches on it;
//! that enum is private to this module and `env.rs`.
//!
//! Units: metres, seconds, radians; observations in each block's units (see the task's file).

pub mod consensus;
pub mod drone;
mod env;
pub mod error_stats;
pub mod formation;
pub mod linefollow;
pub mod multinav;
pub mod nav;
pub mod pathfollow;
pub mod platoon;
pub mod reference;
pub mod seek;
pub mod track;

use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;
use serde::{de::DeserializeOwned, Serialize};

use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::obs::{ObsLayout, ObsWriter};
use crate::scenario::{Scenario, Source, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;

pub use env::{AgentStats, Env, EpisodeStats, StepOutcome};

/// What a task is, beyond its code: its Gymnasium id, a summary, and its scenario schema.
#[derive(Debug, Clone, Copy)]
pub struct TaskInfo {
    /// Gymnasium id without version (`"KheperaIV-Nav"`), or None for a PettingZoo-only task.
    pub env_id: Option<&'static str>,
    /// One line for the head of its default scenario file.
    pub summary: &'static str,
    /// Its name, defaults and own table.
    pub schema: TaskSchema,
    /// How its episodes are scored: what a comparison or a benchmark reports of it.
    pub scoring: Scoring,
    /// What its agents are to a learner: how many, whether alike, whether they end apart.
    pub agents: AgentFacts,
}

/// Facts about a task's agents that a learner's adapter needs before it builds an env (the
/// TorchRL groups' done flags, RLlib's multi-agent envs, the PettingZoo families); a test in
/// each task's file checks them against a built batch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AgentFacts {
    /// Its default scenario has more than one agent.
    pub several: bool,
    /// Every agent has the same kind of observation and action (a team of robots): one shared
    /// policy fits them all.
    pub alike: bool,
    /// An agent may end while the episode goes on (`agent_terminated()` true for some agents
    /// only): a multinav robot parks at its goal, a lost platoon robot parks where it is.
    pub end_separately: bool,
}

impl AgentFacts {
    /// One robot.
    pub const ONE: AgentFacts = AgentFacts {
        several: false,
        alike: true,
        end_separately: false,
    };
    /// Several alike robots whose episode ends for all at once.
    pub const TEAM: AgentFacts = AgentFacts {
        several: true,
        alike: true,
        end_separately: false,
    };
}

/// How a task's episodes are scored (`khepera_gym.analysis.compare`'s table and plots, the learning
/// benchmark): every task has the common statistics (success, length, path, contacts), and
/// says here what its success means and which of its own statistics matter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scoring {
    /// What a success is, as a table's header says it ("success", "lap"); None for a task
    /// without success.
    pub success: Option<&'static str>,
    /// Header of an episode's duration over the successful ones ("time to goal", "lap time").
    pub time: &'static str,
    /// Prefix of the task's four error statistics (`track` for `track_error_rms`,
    /// `track_error_max`, `track_iae`, `track_converge_time`), if it is scored by an error to a
    /// reference.
    pub error_prefix: Option<&'static str>,
    /// What that error is ("tracking error").
    pub error: &'static str,
    /// Header word of the share of episodes that terminated, when terminating is a failure
    /// ("lost"); None not to report it.
    pub termination: Option<&'static str>,
    /// Report the mean speed (a single robot's path over its time).
    pub speed: bool,
    /// The goal moves along a reference during an episode (plots draw it).
    pub moving_reference: bool,
    /// `targets()[0]` is the path's point closest to the robot (plots draw its trace).
    pub path_trace: bool,
    /// Further statistics reported as their mean over the episodes.
    pub columns: &'static [Column],
}

/// A statistic of a task reported as its mean over the episodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Column {
    /// The episode statistic (one of the task's `EXTRA_STATS`).
    pub stat: &'static str,
    /// The table's header, with its unit ("on line %").
    pub header: &'static str,
    /// Factor from the statistic's unit to the header's (100 for a share in %).
    pub scale: f64,
    /// Decimals shown.
    pub digits: u32,
}

impl Scoring {
    /// A task of goals reached: success, time to goal, speed.
    pub const GOAL: Scoring = Scoring {
        success: Some("success"),
        time: "time to goal",
        error_prefix: None,
        error: "error",
        termination: None,
        speed: true,
        moving_reference: false,
        path_trace: false,
        columns: &[],
    };
}

/// What an agent drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Body {
    /// Robot `i` of the world (a Khepera IV): its wheels, LEDs and sensors.
    Robot(usize),
    /// The task's own vehicle `v` (DroneFollow's drone), not part of the world: its actions go
    /// to [`Task::act`], its travel comes from [`Task::vehicle_travel`]; no sensors, no LEDs.
    Vehicle(usize),
}

impl Body {
    /// The robot it is, if it is one.
    pub fn robot(self) -> Option<usize> {
        match self {
            Body::Robot(i) => Some(i),
            Body::Vehicle(_) => None,
        }
    }

    /// Its number in the Python API (`Batch.agents()`): a robot's index, or a vehicle's
    /// `n_robots + v` (the world's robots first, then the task's vehicles).
    pub fn index(self, n_robots: usize) -> usize {
        match self {
            Body::Robot(i) => i,
            Body::Vehicle(v) => n_robots + v,
        }
    }
}

/// One agent of a task.
#[derive(Debug, Clone, PartialEq)]
pub struct Agent {
    /// Its name (PettingZoo agent id).
    pub name: String,
    /// What it drives: a robot of the world, or the task's own vehicle.
    pub body: Body,
    /// Its observation block's layout.
    pub layout: ObsLayout,
}

/// Who drives a robot that a task can script (Formation's leader, DroneFollow's Khepera): the
/// scenario value `"scripted"` or `"agent"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Driver {
    /// The task's own controller (position control with Braitenberg avoidance, in Rust).
    Scripted,
    /// A learning agent's actions: the robot is one more agent.
    Agent,
}

/// Action values per agent for its wheels (normalised left, right; or a vehicle's command).
pub const WHEEL_ACTIONS: usize = 2;
/// Action values per agent for its robot's top LEDs (red, green, blue) with `task.led_action`.
pub const LED_ACTIONS: usize = 3;
/// Highest level of each LED colour: 6 bits, `kh4_SetRGBLeds` takes 0..63 (docs/robot.md §6).
pub const LED_LEVELS: f32 = 63.0;

/// Action values per agent in a scenario: the wheels, and the LEDs with `task.led_action`.
pub fn action_width(cfg: &Scenario) -> usize {
    WHEEL_ACTIONS + if cfg.task.led_action { LED_ACTIONS } else { 0 }
}

/// The LED colour (RGB in [0, 1]) an agent's three normalised LED values ask for: each value in
/// [-1, 1] (clamped) to the nearest of the 64 levels the real LEDs have.
pub fn led_color(values: [f32; 3]) -> [f32; 3] {
    let level = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * LED_LEVELS).round() / LED_LEVELS;
    values.map(level)
}

/// Most extra statistics a task may keep ([`Task::EXTRA_STATS`]).
pub const MAX_EXTRA_STATS: usize = 4;

/// The contract every task implements. `Self` is the per-world task state; it is saved with the
/// world (`get_state`), so it must serialise whole.
pub trait Task: Clone + Serialize + DeserializeOwned + Send + Sync {
    /// Names of its extra episode statistics (at most [`MAX_EXTRA_STATS`]).
    const EXTRA_STATS: &'static [&'static str] = &[];

    /// The state of one world for a validated scenario (its own table read with
    /// `cfg.own()`).
    fn new(cfg: &Scenario) -> Result<Self>;

    /// How its robots are spawned: how many, and where relative to one another.
    fn spawn(cfg: &Scenario) -> Result<Spawn>;

    /// Its agents, each with the task's own observation blocks ([`Env`] puts a robot's observed
    /// sensor blocks before them).
    fn agents(cfg: &Scenario) -> Result<Vec<Agent>>;

    /// Before the robots are placed: may draw from the world's stream (after the spawner) and
    /// change `layout` (the tracking task starts the robot relative to its reference).
    fn arrange(&mut self, _cfg: &Scenario, _rng: &mut ChaCha8Rng, _layout: &mut Layout) {}

    /// Starts an episode; the robots are already placed at `layout`'s poses.
    fn reset(&mut self, world: &World, layout: &Layout);

    /// Steps of the running episode before truncation (the tracking task: one period plus a
    /// margin).
    fn max_steps(&self, cfg: &Scenario) -> u32 {
        cfg.task.max_steps
    }

    /// Before the world moves (agents' commands are set): commands of scripted robots.
    fn before_step(&self, _world: &mut World) {}

    /// The action of an agent that drives the task's vehicle `vehicle` (its [`Agent::body`] is
    /// [`Body::Vehicle`]: a drone), normalised to [-1, 1]; called before `before_step`.
    fn act(&mut self, _vehicle: usize, _action: [f32; 2]) {}

    /// After the world moved and sensed: each agent's reward and termination; returns whether
    /// the task succeeded (which terminates the episode).
    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool;

    /// Its extra statistics of the running episode, in the order of `EXTRA_STATS`.
    fn extra_stats(&self, _out: &mut [f32]) {}

    /// Whether agent `agent` (its index in [`Task::agents`]' order) succeeded: asked once, after
    /// `judge` on the step in which the agent leaves the episode (it terminated, or the episode
    /// ended); `episode_success` is whether the task has succeeded so far. By default an agent
    /// succeeds with its task.
    fn agent_success(
        &self,
        _world: &World,
        _cfg: &Scenario,
        _agent: usize,
        episode_success: bool,
    ) -> bool {
        episode_success
    }

    /// The distance (m) vehicle `vehicle` (an agent whose [`Agent::body`] is
    /// [`Body::Vehicle`]: a drone) travelled on the last step, for its agent's path length;
    /// asked after `judge`. None by default.
    fn vehicle_travel(&self, _vehicle: usize) -> f32 {
        0.0
    }

    /// Writes agent `agent`'s own blocks (its index in [`Task::agents`]' order), those its
    /// [`Task::agents`] layout declares; [`Env`] has written its robot's sensor blocks before.
    fn observe(&self, world: &World, cfg: &Scenario, agent: usize, out: &mut ObsWriter);

    /// Goal positions (m).
    fn goals(&self) -> Vec<Vector>;

    /// Target points other than goals (formation targets), m.
    fn targets(&self, _world: &World) -> Vec<Vector> {
        Vec::new()
    }

    /// Whether a saved state of this task fits `twin`, a fresh state of this env.
    fn fits(&self, _twin: &Self) -> bool {
        true
    }

    /// What the renderer draws for it (goals, targets, references).
    fn draw(&self, world: &World, cfg: &Scenario, marks: &mut Vec<Mark>);
}

/// Declares the tasks. Each line is `Variant(StateType) = INFO`; several variants may share a
/// state type (Nav and Avoid).
macro_rules! task_registry {
    ($($variant:ident($ty:ty) = $info:expr),* $(,)?) => {
        /// The tasks the simulator knows.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum TaskKind {
            $(
                #[doc = concat!("See [`", stringify!($info), "`].")]
                $variant,
            )*
        }

        /// A world's task state, one variant per task.
        #[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
        enum TaskState {
            $($variant($ty),)*
        }

        impl TaskKind {
            /// Every task, in registry order.
            pub const ALL: &'static [TaskKind] = &[$(TaskKind::$variant),*];

            /// What the task is: id, summary, scenario schema.
            pub fn info(self) -> &'static TaskInfo {
                match self {
                    $(TaskKind::$variant => &$info,)*
                }
            }

            /// Names of its extra episode statistics.
            pub fn extra_stats(self) -> &'static [&'static str] {
                match self {
                    $(TaskKind::$variant => <$ty as Task>::EXTRA_STATS,)*
                }
            }

            /// How its robots are spawned.
            pub fn spawn(self, cfg: &Scenario) -> Result<Spawn> {
                match self {
                    $(TaskKind::$variant => <$ty as Task>::spawn(cfg),)*
                }
            }

            /// Its agents with their observation layouts, for a scenario: an agent driving a
            /// robot observes its robot's observed sensor blocks, then the task's own blocks.
            pub fn agents(self, cfg: &Scenario) -> Result<Vec<Agent>> {
                let mut agents = match self {
                    $(TaskKind::$variant => <$ty as Task>::agents(cfg)?,)*
                };
                let sensors = crate::sensors::Suite::new(&cfg.sensors).blocks();
                for agent in agents.iter_mut().filter(|a| a.body.robot().is_some()) {
                    let mut blocks = sensors.clone();
                    blocks.extend_from_slice(agent.layout.blocks());
                    agent.layout = ObsLayout::new(blocks);
                }
                Ok(agents)
            }

            fn new_state(self, cfg: &Scenario) -> Result<TaskState> {
                match self {
                    $(TaskKind::$variant => Ok(TaskState::$variant(<$ty as Task>::new(cfg)?)),)*
                }
            }
        }

        impl TaskState {
            fn kind(&self) -> TaskKind {
                match self {
                    $(TaskState::$variant(_) => TaskKind::$variant,)*
                }
            }

            fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, layout: &mut Layout) {
                match self {
                    $(TaskState::$variant(t) => t.arrange(cfg, rng, layout),)*
                }
            }

            fn reset(&mut self, world: &World, layout: &Layout) {
                match self {
                    $(TaskState::$variant(t) => t.reset(world, layout),)*
                }
            }

            fn max_steps(&self, cfg: &Scenario) -> u32 {
                match self {
                    $(TaskState::$variant(t) => t.max_steps(cfg),)*
                }
            }

            fn before_step(&self, world: &mut World) {
                match self {
                    $(TaskState::$variant(t) => t.before_step(world),)*
                }
            }

            fn act(&mut self, vehicle: usize, action: [f32; 2]) {
                match self {
                    $(TaskState::$variant(t) => t.act(vehicle, action),)*
                }
            }

            #[inline]
            fn judge(
                &mut self,
                world: &World,
                cfg: &Scenario,
                rewards: &mut [f32],
                terminated: &mut [bool],
            ) -> bool {
                match self {
                    $(TaskState::$variant(t) => t.judge(world, cfg, rewards, terminated),)*
                }
            }

            fn extra_stats(&self, out: &mut [f32]) {
                match self {
                    $(TaskState::$variant(t) => t.extra_stats(out),)*
                }
            }

            fn agent_success(
                &self,
                world: &World,
                cfg: &Scenario,
                agent: usize,
                episode_success: bool,
            ) -> bool {
                match self {
                    $(TaskState::$variant(t) => {
                        t.agent_success(world, cfg, agent, episode_success)
                    })*
                }
            }

            fn vehicle_travel(&self, vehicle: usize) -> f32 {
                match self {
                    $(TaskState::$variant(t) => t.vehicle_travel(vehicle),)*
                }
            }

            #[inline]
            fn observe(&self, world: &World, cfg: &Scenario, agent: usize, out: &mut ObsWriter) {
                match self {
                    $(TaskState::$variant(t) => t.observe(world, cfg, agent, out),)*
                }
            }

            fn goals(&self) -> Vec<Vector> {
                match self {
                    $(TaskState::$variant(t) => t.goals(),)*
                }
            }

            fn targets(&self, world: &World) -> Vec<Vector> {
                match self {
                    $(TaskState::$variant(t) => t.targets(world),)*
                }
            }

            fn fits(&self, twin: &TaskState) -> bool {
                match (self, twin) {
                    $((TaskState::$variant(a), TaskState::$variant(b)) => a.fits(b),)*
                    #[allow(unreachable_patterns)]
                    _ => false,
                }
            }

            fn draw(&self, world: &World, cfg: &Scenario, marks: &mut Vec<Mark>) {
                match self {
                    $(TaskState::$variant(t) => t.draw(world, cfg, marks),)*
                }
            }
        }
    };
}

// New tasks go at the end: saved states name a task by its place in this list.
task_registry! {
    Nav(nav::Nav) = nav::NAV,
    Avoid(nav::Nav) = nav::AVOID,
    Formation(formation::Formation) = formation::FORMATION,
    MultiNav(multinav::MultiNav) = multinav::MULTINAV,
    Track(track::Track) = track::TRACK,
    PathFollow(pathfollow::PathFollow) = pathfollow::PATHFOLLOW,
    Platoon(platoon::Platoon) = platoon::PLATOON,
    DroneFollow(drone::DroneFollow) = drone::DRONE_FOLLOW,
    LineFollow(linefollow::LineFollow) = linefollow::LINEFOLLOW,
    Seek(seek::Seek) = seek::SEEK,
    Consensus(consensus::Consensus) = consensus::CONSENSUS,
}

impl TaskKind {
    /// Parses a task name: the [`TaskKind::name`] of one of [`TaskKind::ALL`] ("nav", ...).
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|k| k.name() == name)
    }

    /// The task's name, also its default scenario's name.
    pub fn name(self) -> &'static str {
        self.info().schema.name
    }

    /// Loads the task's scenario: its defaults, then `source`'s file and overrides.
    pub fn scenario(self, source: &Source) -> Result<Scenario> {
        self.info().schema.load(source)
    }

    /// The task's default scenario file for behaviour `version` (None: the latest): every key
    /// with its default and comment.
    pub fn default_config(self, version: Option<u32>) -> Result<String> {
        let info = self.info();
        let title = info.env_id.unwrap_or(info.schema.name);
        let header = format!(
            "{title}: {}.\nEvery key the scenario has, with its default; a scenario file or keyword \
             override may change any of them and may not add others.\nUnits: metres, seconds, \
             radians, m/s. [E] marks an estimate (the tags of robot.md).",
            info.summary
        );
        info.schema.render_defaults(&header, version)
    }

    /// The joint observation layout: the agents' blocks in order; with several agents each
    /// name is prefixed by the agent's (`follower_0/ir`).
    pub fn obs_layout(self, cfg: &Scenario) -> Result<ObsLayout> {
        let agents = self.agents(cfg)?;
        let single = agents.len() == 1;
        let mut joint = ObsLayout::default();
        for agent in &agents {
            joint.extend(&agent.layout, (!single).then_some(agent.name.as_str()));
        }
        Ok(joint)
    }
}

/// Steps of an episode that lasts `seconds` (s) at `dt` (s) per step, rounded up, capped at
/// `cap` (`task.max_steps`): the tasks whose episodes last a lap.
pub(crate) fn episode_steps(cap: u32, seconds: f64, dt: f32) -> u32 {
    cap.min((seconds / dt as f64).ceil().min(u32::MAX as f64) as u32)
}

/// Loads the scenario of the task named `task` (its defaults, then the file, then the
/// overrides); an unknown task is a [`crate::error::Error::Config`] listing the known ones.
pub fn load_scenario(task: &str, source: &Source) -> Result<Scenario> {
    let kind = TaskKind::parse(task).ok_or_else(|| {
        let known: Vec<&str> = TaskKind::ALL.iter().map(|k| k.name()).collect();
        Error::config(
            "<built-in>",
            "task",
            format!("unknown task {task:?}; known: {known:?}"),
        )
    })?;
    kind.scenario(source)
}
