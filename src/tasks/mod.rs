//! Tasks: what a world is for. Each task file (nav.rs for Nav and Avoid, formation.rs,
//! multinav.rs) starts its episodes, judges a step (rewards, success) and writes observations.
//! [`Env`] joins a task to a world and keeps the episode's bookkeeping (layout at reset, step
//! counter, termination, statistics) in one place.
//!
//! Agents: a task has one or more agents, each acting on one robot with two normalised numbers
//! and observing one block of the joint observation. The joint action is the agents' actions
//! in order; the joint reward is the mean of the agents' rewards.

pub mod formation;
pub mod multinav;
pub mod nav;

use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use crate::error::{Error, Result};
use crate::robot::ActionType;
use crate::scenario::{LeaderMode, Scenario};
use crate::world::layout::{Spawn, Spawner};
use crate::world::World;

/// The tasks the simulator knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskKind {
    /// Position control to a goal in an empty arena.
    Nav,
    /// Position control to a goal among obstacles.
    Avoid,
    /// A leader and followers holding a formation.
    Formation,
    /// Several robots, each with its own goal.
    MultiNav,
}

impl TaskKind {
    /// Every task, for listings.
    pub const ALL: [TaskKind; 4] = [
        TaskKind::Nav,
        TaskKind::Avoid,
        TaskKind::Formation,
        TaskKind::MultiNav,
    ];

    /// Parses a task name ("nav", "avoid", "formation", "multinav").
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The task's name, also its built-in scenario's name.
    pub fn name(self) -> &'static str {
        match self {
            TaskKind::Nav => "nav",
            TaskKind::Avoid => "avoid",
            TaskKind::Formation => "formation",
            TaskKind::MultiNav => "multinav",
        }
    }

    /// The agents of a world of this task: (name, robot index, observation layout).
    pub fn agents(self, cfg: &Scenario) -> Vec<AgentSpec> {
        let nav_agent = |name: String, robot| AgentSpec {
            name,
            robot,
            layout: nav::OBS_LAYOUT,
        };
        match self {
            TaskKind::Nav | TaskKind::Avoid => vec![nav_agent("robot".into(), 0)],
            TaskKind::MultiNav => {
                let n = cfg.multinav.as_ref().map_or(1, |m| m.n_robots as usize);
                (0..n).map(|i| nav_agent(format!("robot_{i}"), i)).collect()
            }
            TaskKind::Formation => {
                let Some(f) = &cfg.formation else {
                    return Vec::new();
                };
                let mut agents = Vec::new();
                if f.leader == LeaderMode::Agent {
                    agents.push(nav_agent("leader".into(), 0));
                }
                for k in 0..f.offsets().len() {
                    agents.push(AgentSpec {
                        name: format!("follower_{k}"),
                        robot: k + 1,
                        layout: formation::FOLLOWER_LAYOUT,
                    });
                }
                agents
            }
        }
    }

    /// The joint observation layout: (name, length) blocks in order; with several agents each
    /// name is prefixed by the agent's (`follower_0/ir`).
    pub fn obs_layout(self, cfg: &Scenario) -> Vec<(String, usize)> {
        let agents = self.agents(cfg);
        let single = agents.len() == 1;
        agents
            .iter()
            .flat_map(|a| {
                a.layout.iter().map(move |(name, n)| {
                    let full = if single {
                        name.to_string()
                    } else {
                        format!("{}/{name}", a.name)
                    };
                    (full, *n)
                })
            })
            .collect()
    }

    /// Joint observation length.
    pub fn obs_dim(self, cfg: &Scenario) -> usize {
        self.agents(cfg).iter().map(AgentSpec::obs_dim).sum()
    }

    /// Joint action length: two wheel numbers per agent.
    pub fn act_dim(self, cfg: &Scenario) -> usize {
        2 * self.agents(cfg).len()
    }

    /// Robots in a world.
    pub fn n_robots(self, cfg: &Scenario) -> usize {
        match self {
            TaskKind::Nav | TaskKind::Avoid => 1,
            TaskKind::MultiNav => cfg.multinav.as_ref().map_or(1, |m| m.n_robots as usize),
            TaskKind::Formation => 1 + cfg.formation.as_ref().map_or(0, |f| f.offsets().len()),
        }
    }

    /// Joint observation bounds (low, high).
    pub fn obs_bounds(self, cfg: &Scenario) -> (Vec<f32>, Vec<f32>) {
        let (mut low, mut high) = (Vec::new(), Vec::new());
        for agent in self.agents(cfg) {
            let (l, h) = if agent.layout == formation::FOLLOWER_LAYOUT {
                formation::Formation::follower_bounds(cfg)
            } else {
                nav::Nav::bounds(cfg)
            };
            low.extend(l);
            high.extend(h);
        }
        (low, high)
    }
}

/// One agent of a task.
#[derive(Debug, Clone)]
pub struct AgentSpec {
    /// Its name (PettingZoo agent id).
    pub name: String,
    /// The robot it drives.
    pub robot: usize,
    /// Its observation block's layout.
    pub layout: &'static [(&'static str, usize)],
}

impl AgentSpec {
    /// Length of its observation block.
    pub fn obs_dim(&self) -> usize {
        self.layout.iter().map(|(_, n)| n).sum()
    }
}

/// Statistics of one episode.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EpisodeStats {
    /// Sum of (joint) rewards.
    pub ret: f32,
    /// Steps taken.
    pub length: u32,
    /// Whether the task succeeded (goal reached; formation: the leader's; multinav: every one).
    pub success: bool,
    /// Distance travelled by the robots (m, summed over robots).
    pub path_length: f32,
    /// Steps in which a robot was in contact with something.
    pub collisions: u32,
    /// Formation only: mean follower distance to target over the episode (m).
    pub formation_error_mean: f32,
    /// Formation only: largest follower distance to target in the episode (m).
    pub formation_error_max: f32,
}

/// What a step returns besides the observation.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepOutcome {
    /// Joint reward of the step (mean over agents).
    pub reward: f32,
    /// The episode ended by the task's rules (success, or collision when configured).
    pub terminated: bool,
    /// The episode hit its step limit.
    pub truncated: bool,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum TaskState {
    Nav(nav::Nav),
    Formation(formation::Formation),
    MultiNav(multinav::MultiNav),
}

/// What [`Env::save_state`] writes, borrowed from the env.
#[derive(serde::Serialize)]
struct EnvStateRef<'a> {
    world: &'a World,
    task: &'a TaskState,
    agent_rewards: &'a [f32],
    agent_terminated: &'a [bool],
    stats: &'a EpisodeStats,
    last_episode: &'a EpisodeStats,
    done: bool,
    trails: &'a [Vec<Vector>],
}

/// What [`Env::load_state`] reads (the owned twin of [`EnvStateRef`]).
#[derive(serde::Deserialize)]
struct EnvState {
    world: World,
    task: TaskState,
    agent_rewards: Vec<f32>,
    agent_terminated: Vec<bool>,
    stats: EpisodeStats,
    last_episode: EpisodeStats,
    done: bool,
    trails: Vec<Vec<Vector>>,
}

/// One environment: a world, its task and the episode's bookkeeping.
pub struct Env {
    /// The simulated world.
    pub world: World,
    /// The scenario it was built from.
    pub cfg: Arc<Scenario>,
    spawner: Arc<Spawner>,
    kind: TaskKind,
    state: TaskState,
    action_type: ActionType,
    agent_robots: Vec<usize>,
    /// Each agent's reward on the last step.
    pub agent_rewards: Vec<f32>,
    /// Each agent's termination on the last step (multinav: its robot arrived).
    pub agent_terminated: Vec<bool>,
    /// Statistics of the running episode.
    pub stats: EpisodeStats,
    /// Statistics of the episode that ended on the last step.
    pub last_episode: EpisodeStats,
    /// The episode has ended; the next step must be a reset.
    pub done: bool,
    /// Positions of each robot over the last `trail_length` steps (for rendering; empty and
    /// free when `trail_length` is 0).
    trails: Vec<Vec<Vector>>,
    trail_length: usize,
}

impl Env {
    /// An environment of `kind` built from `cfg`, seeded with 0 until [`Env::seed`].
    pub fn new(
        kind: TaskKind,
        cfg: Arc<Scenario>,
        spawner: Arc<Spawner>,
        action_type: ActionType,
    ) -> Result<Self> {
        let world = World::new(&cfg, spawner.base.clone(), kind.n_robots(&cfg));
        let state = match kind {
            TaskKind::Nav | TaskKind::Avoid => TaskState::Nav(nav::Nav::default()),
            TaskKind::MultiNav => TaskState::MultiNav(multinav::MultiNav::new(kind.n_robots(&cfg))),
            TaskKind::Formation => {
                let f = cfg.formation.as_ref().ok_or_else(|| {
                    Error::config(
                        "<batch>",
                        "formation",
                        "the formation task needs a [formation] table",
                    )
                })?;
                TaskState::Formation(formation::Formation::new(&cfg, f))
            }
        };
        let agent_robots: Vec<usize> = kind.agents(&cfg).iter().map(|a| a.robot).collect();
        let n_agents = agent_robots.len();
        Ok(Self {
            world,
            cfg,
            spawner,
            kind,
            state,
            action_type,
            agent_robots,
            agent_rewards: vec![0.0; n_agents],
            agent_terminated: vec![false; n_agents],
            stats: EpisodeStats::default(),
            last_episode: EpisodeStats::default(),
            done: true,
            trails: Vec::new(),
            trail_length: 0,
        })
    }

    /// The spawner of a scenario for `kind` (shared by every world of a batch).
    pub fn spawner(kind: TaskKind, cfg: &Scenario) -> Result<Spawner> {
        Spawner::new(
            cfg,
            Spawn::for_task(kind.name(), cfg, "<batch>")?,
            "<batch>",
        )
    }

    /// The task.
    pub fn kind(&self) -> TaskKind {
        self.kind
    }

    /// Restarts the world's random stream from `seed`.
    pub fn seed(&mut self, seed: u64) {
        self.world.rng = ChaCha8Rng::seed_from_u64(seed);
    }

    /// Starts a new episode (continuing the random stream) and writes its first observation.
    pub fn reset(&mut self, obs: &mut [f32]) {
        self.stats = EpisodeStats::default();
        self.done = false;
        self.agent_rewards.fill(0.0);
        self.agent_terminated.fill(false);
        self.world.randomise(&self.cfg);
        let layout = self.spawner.generate(&self.cfg, &mut self.world.rng);
        if self.cfg.obstacles.count > 0 {
            // New random obstacles: the fixed scene plus this episode's.
            let mut scene = self.spawner.base.clone();
            scene.shapes.extend(layout.obstacles);
            self.world.set_scene(scene);
        }
        for (i, (position, heading)) in layout.poses.iter().enumerate() {
            self.world.place_robot(i, *position, *heading);
        }
        match &mut self.state {
            TaskState::Nav(nav) => nav.reset(&self.world, layout.goals[0]),
            TaskState::MultiNav(m) => m.reset(&self.world, &layout.goals),
            TaskState::Formation(f) => f.reset(&self.world, layout.goals[0]),
        }
        self.world.sense();
        self.observe(obs);
        self.trails.clear();
        self.record_trail();
    }

    /// Keeps the last `length` positions of every robot for rendering (0: none, the default).
    pub fn set_trail_length(&mut self, length: usize) {
        self.trail_length = length;
        self.trails.clear();
        self.record_trail();
    }

    /// Robot positions over the last steps, oldest first, per robot.
    pub fn trails(&self) -> &[Vec<Vector>] {
        &self.trails
    }

    fn record_trail(&mut self) {
        if self.trail_length == 0 {
            return;
        }
        self.trails.resize(self.world.robots.len(), Vec::new());
        for (trail, robot) in self.trails.iter_mut().zip(&self.world.robots) {
            if trail.len() >= self.trail_length {
                trail.remove(0);
            }
            trail.push(robot.position);
        }
    }

    /// Applies `action` (normalised, two numbers per agent, already checked finite), advances
    /// one control step and writes the next observation.
    pub fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        for (robot, pair) in self.agent_robots.iter().zip(action.chunks_exact(2)) {
            let command = self
                .world
                .drive
                .wheel_command([pair[0], pair[1]], self.action_type);
            self.world.robots[*robot].wheel_command = command;
        }
        match &self.state {
            TaskState::Formation(f) if !f.leader_agent => f.drive_leader(&mut self.world),
            TaskState::MultiNav(m) => {
                for (robot, arrived) in self.world.robots.iter_mut().zip(&m.arrived) {
                    if *arrived {
                        robot.wheel_command = [0.0, 0.0];
                    }
                }
            }
            _ => {}
        }
        self.world.advance();
        self.world.sense();
        let success = match &mut self.state {
            TaskState::Nav(nav) => {
                let j = nav.judge(&self.world, &self.cfg);
                self.agent_rewards[0] = j.reward;
                self.agent_terminated[0] = j.success;
                j.success
            }
            TaskState::MultiNav(m) => m.judge(
                &self.world,
                &self.cfg,
                &mut self.agent_rewards,
                &mut self.agent_terminated,
            ),
            TaskState::Formation(f) => f.judge(&self.world, &self.cfg, &mut self.agent_rewards),
        };
        let reward = self.agent_rewards.iter().sum::<f32>() / self.agent_rewards.len() as f32;
        let collided = self.world.robots.iter().any(|r| r.in_contact);
        let stats = &mut self.stats;
        stats.ret += reward;
        stats.length += 1;
        stats.success |= success;
        stats.path_length += self.world.robots.iter().map(|r| r.step_travel).sum::<f32>();
        stats.collisions += collided as u32;
        if let TaskState::Formation(f) = &self.state {
            (stats.formation_error_mean, stats.formation_error_max) = f.error_stats();
        }
        let terminated = success || (collided && self.cfg.task.terminate_on_collision);
        let truncated = !terminated && stats.length >= self.cfg.task.max_steps;
        if terminated {
            self.agent_terminated.fill(true);
        }
        if terminated || truncated {
            self.done = true;
            self.last_episode = *stats;
        }
        self.observe(obs);
        self.record_trail();
        StepOutcome {
            reward,
            terminated,
            truncated,
        }
    }

    fn observe(&self, obs: &mut [f32]) {
        match &self.state {
            TaskState::Nav(nav) => nav.observe(&self.world, &self.cfg, obs),
            TaskState::MultiNav(m) => m.observe(&self.world, &self.cfg, obs),
            TaskState::Formation(f) => f.observe(&self.world, &self.cfg, obs),
        }
    }

    /// A fresh env of the same task, scenario, action type and trail length (its state to be
    /// loaded).
    pub fn empty_twin(&self) -> Result<Self> {
        let mut twin = Self::new(
            self.kind,
            self.cfg.clone(),
            self.spawner.clone(),
            self.action_type,
        )?;
        twin.trail_length = self.trail_length;
        Ok(twin)
    }

    /// Appends this env's state (world, physics, random stream, task and episode bookkeeping,
    /// trails) to `out`. The scenario, task and action type are not part of it: they are fixed at
    /// construction, and [`crate::batch::Batch::load_state`] checks that they match.
    pub fn save_state(&self, out: &mut Vec<u8>) -> Result<()> {
        let state = EnvStateRef {
            world: &self.world,
            task: &self.state,
            agent_rewards: &self.agent_rewards,
            agent_terminated: &self.agent_terminated,
            stats: &self.stats,
            last_episode: &self.last_episode,
            done: self.done,
            trails: &self.trails,
        };
        let bytes = postcard::to_extend(&state, std::mem::take(out))
            .map_err(|e| Error::State(format!("cannot encode the env state: {e}")))?;
        *out = bytes;
        Ok(())
    }

    /// Restores a state written by [`Env::save_state`] from the front of `bytes`, returning the
    /// rest. On error `self` is unchanged.
    pub fn load_state<'a>(&mut self, bytes: &'a [u8]) -> Result<&'a [u8]> {
        let (state, rest): (EnvState, _) = postcard::take_from_bytes(bytes)
            .map_err(|e| Error::SavedState(format!("corrupt env state: {e}")))?;
        let n_robots = self.world.robots.len();
        let n_agents = self.agent_robots.len();
        let task_fits = match (&state.task, &self.state) {
            (TaskState::Nav(_), TaskState::Nav(_)) => true,
            (TaskState::MultiNav(a), TaskState::MultiNav(_)) => {
                a.goals.len() == n_robots && a.arrived.len() == n_robots
            }
            (TaskState::Formation(a), TaskState::Formation(b)) => {
                a.offsets.len() == b.offsets.len() && a.errors.len() == b.errors.len()
            }
            _ => false,
        };
        if state.world.robots.len() != n_robots
            || state.agent_rewards.len() != n_agents
            || state.agent_terminated.len() != n_agents
            || !task_fits
        {
            return Err(Error::SavedState(
                "the state does not fit this env (other task or number of robots)".into(),
            ));
        }
        self.world = state.world;
        self.state = state.task;
        self.agent_rewards = state.agent_rewards;
        self.agent_terminated = state.agent_terminated;
        self.stats = state.stats;
        self.last_episode = state.last_episode;
        self.done = state.done;
        self.trails = state.trails;
        if self.trail_length == 0 {
            self.trails.clear();
        }
        for trail in &mut self.trails {
            let excess = trail.len().saturating_sub(self.trail_length);
            trail.drain(..excess);
        }
        Ok(rest)
    }

    /// Goal positions (m).
    pub fn goals(&self) -> Vec<Vector> {
        match &self.state {
            TaskState::Nav(nav) => vec![nav.goal],
            TaskState::MultiNav(m) => m.goals.clone(),
            TaskState::Formation(f) => vec![f.goal],
        }
    }

    /// How many goals [`Env::goals`] returns.
    pub fn n_goals(&self) -> usize {
        match &self.state {
            TaskState::MultiNav(_) => self.world.robots.len(),
            _ => 1,
        }
    }

    /// Formation targets of the followers (empty for other tasks).
    pub fn formation_targets(&self) -> Vec<Vector> {
        match &self.state {
            TaskState::Formation(f) => (0..f.n_followers())
                .map(|k| f.target(&self.world, k))
                .collect(),
            _ => Vec::new(),
        }
    }
}
