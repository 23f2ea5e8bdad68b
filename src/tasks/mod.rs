//! Tasks: what a world is for. Each task file (nav.rs, later avoid.rs, formation.rs) resets its
//! world, judges a step (reward, success) and writes the observation. [`Env`] joins a task to a
//! world and keeps the episode's bookkeeping (step counter, termination, statistics) in one place.

pub mod nav;

use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use crate::robot::ActionType;
use crate::scenario::Scenario;
use crate::world::{Scene, World};

/// The tasks the simulator knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskKind {
    /// Position control to a goal in an empty arena.
    Nav,
}

impl TaskKind {
    /// Every task, for listings.
    pub const ALL: [TaskKind; 1] = [TaskKind::Nav];

    /// Parses a task name ("nav").
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The task's name, also its built-in scenario's name.
    pub fn name(self) -> &'static str {
        match self {
            TaskKind::Nav => "nav",
        }
    }

    /// Observation layout: (name, length) in order.
    pub fn obs_layout(self) -> &'static [(&'static str, usize)] {
        match self {
            TaskKind::Nav => nav::OBS_LAYOUT,
        }
    }

    /// Observation length.
    pub fn obs_dim(self) -> usize {
        self.obs_layout().iter().map(|(_, n)| n).sum()
    }

    /// Robots in a world of this task.
    pub fn n_robots(self, _cfg: &Scenario) -> usize {
        match self {
            TaskKind::Nav => 1,
        }
    }

    /// Action length: two wheel numbers per controlled robot.
    pub fn act_dim(self, cfg: &Scenario) -> usize {
        2 * self.n_robots(cfg)
    }

    /// Observation bounds (low, high).
    pub fn obs_bounds(self, cfg: &Scenario) -> (Vec<f32>, Vec<f32>) {
        match self {
            TaskKind::Nav => nav::Nav::bounds(cfg),
        }
    }
}

/// Statistics of one episode.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EpisodeStats {
    /// Sum of rewards.
    pub ret: f32,
    /// Steps taken.
    pub length: u32,
    /// Whether the task succeeded.
    pub success: bool,
    /// Distance travelled by the robot(s) (m, summed over robots).
    pub path_length: f32,
    /// Steps in which a robot was in contact with something.
    pub collisions: u32,
}

/// What a step returns besides the observation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepOutcome {
    /// Reward of the step.
    pub reward: f32,
    /// The episode ended by the task's rules (success, or collision when configured).
    pub terminated: bool,
    /// The episode hit its step limit.
    pub truncated: bool,
}

#[derive(Debug, Clone)]
enum TaskState {
    Nav(nav::Nav),
}

/// One environment: a world, its task and the episode's bookkeeping.
pub struct Env {
    /// The simulated world.
    pub world: World,
    /// The scenario it was built from.
    pub cfg: Arc<Scenario>,
    kind: TaskKind,
    state: TaskState,
    action_type: ActionType,
    /// Statistics of the running episode.
    pub stats: EpisodeStats,
    /// Statistics of the episode that ended on the last step.
    pub last_episode: EpisodeStats,
    /// The episode has ended; the next step must be a reset.
    pub done: bool,
}

impl Env {
    /// An environment of `kind` built from `cfg`, seeded with 0 until [`Env::seed`].
    pub fn new(kind: TaskKind, cfg: Arc<Scenario>, action_type: ActionType) -> Self {
        let scene = Scene::arena(cfg.arena.width, cfg.arena.height, cfg.arena.wall_thickness);
        let world = World::new(&cfg, scene, kind.n_robots(&cfg));
        let state = match kind {
            TaskKind::Nav => TaskState::Nav(nav::Nav::default()),
        };
        Self {
            world,
            cfg,
            kind,
            state,
            action_type,
            stats: EpisodeStats::default(),
            last_episode: EpisodeStats::default(),
            done: true,
        }
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
        match &mut self.state {
            TaskState::Nav(nav) => nav.reset(&mut self.world, &self.cfg),
        }
        self.world.sense();
        self.observe(obs);
    }

    /// Applies `action` (normalised, two numbers per robot, already checked finite), advances
    /// one control step and writes the next observation.
    pub fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        for (robot, pair) in self.world.robots.iter_mut().zip(action.chunks_exact(2)) {
            robot.wheel_command = self
                .world
                .drive
                .wheel_command([pair[0], pair[1]], self.action_type);
        }
        self.world.advance();
        self.world.sense();
        let judgement = match &mut self.state {
            TaskState::Nav(nav) => nav.judge(&self.world, &self.cfg),
        };
        let collided = self.world.robots.iter().any(|r| r.in_contact);
        let stats = &mut self.stats;
        stats.ret += judgement.reward;
        stats.length += 1;
        stats.success |= judgement.success;
        stats.path_length += self.world.robots.iter().map(|r| r.step_travel).sum::<f32>();
        stats.collisions += collided as u32;
        let terminated = judgement.success || (collided && self.cfg.task.terminate_on_collision);
        let truncated = !terminated && stats.length >= self.cfg.task.max_steps;
        if terminated || truncated {
            self.done = true;
            self.last_episode = *stats;
        }
        self.observe(obs);
        StepOutcome {
            reward: judgement.reward,
            terminated,
            truncated,
        }
    }

    fn observe(&self, obs: &mut [f32]) {
        match &self.state {
            TaskState::Nav(nav) => nav.observe(&self.world, &self.cfg, obs),
        }
    }

    /// Goal positions (m).
    pub fn goals(&self) -> Vec<Vector> {
        match &self.state {
            TaskState::Nav(nav) => vec![nav.goal],
        }
    }

    /// How many goals [`Env::goals`] returns.
    pub fn n_goals(&self) -> usize {
        match self.kind {
            TaskKind::Nav => 1,
        }
    }
}
