//! One environment: a world joined to its task ([`Env`]), with the episode's bookkeeping in one
//! place: the layout drawn at reset, agents' commands, the step counter, termination and
//! truncation, episode statistics (the world's [`EpisodeStats`] and each agent's own
//! [`AgentStats`]), trails for rendering, and the saved state
//! (`save_state` / `load_state`, postcard bytes). The task itself is reached only through the
//! registry's private `TaskState` enum (`tasks/mod.rs`), so nothing here names a task.
//!
//! Units: metres, seconds, radians; rewards per step; actions normalised to [-1, 1], two per
//! agent (five with `task.led_action`: the wheels, then the LEDs' red, green, blue). Frame: the
//! world frame (arena centred at the origin). Threading: an env is stepped by one thread at a
//! time and draws only from its world's random stream.

use std::collections::VecDeque;
use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use super::{action_width, led_color, Body, TaskKind, TaskState, MAX_EXTRA_STATS, WHEEL_ACTIONS};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::geometry::floor::FloorMarks;
use crate::obs::ObsWriter;
use crate::robot::ActionType;
use crate::scenario::Scenario;
use crate::world::layout::Spawner;
use crate::world::{Robot, World, ROBOT_CHUNK};

/// Statistics of one episode of the world (all its agents together).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EpisodeStats {
    /// Sum of (joint) rewards: each step's mean over the agents.
    pub ret: f32,
    /// Steps taken.
    pub length: u32,
    /// Whether the task succeeded (goal reached; formation: the leader's; multinav: every one).
    pub success: bool,
    /// Distance travelled by the robots (m, summed over robots).
    pub path_length: f32,
    /// Steps in which a robot was in contact with something.
    pub collisions: u32,
    /// The task's extra statistics, in the order of its `EXTRA_STATS`.
    pub extra: [f32; MAX_EXTRA_STATS],
}

/// One agent's statistics of an episode: its own figures, counted from the reset while it takes
/// part (until it terminates, or the episode ends).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AgentStats {
    /// Sum of its own rewards.
    pub ret: f32,
    /// Steps it took part in.
    pub length: u32,
    /// Whether it succeeded, as its task defines it for one agent
    /// ([`super::Task::agent_success`]); decided when it leaves.
    pub success: bool,
    /// Distance its robot travelled (m); a vehicle's (a drone's) flight, as its task reports it.
    pub path_length: f32,
    /// Steps in which its robot was in contact with something (a vehicle has no contacts).
    pub collisions: u32,
    /// It has left the episode: these figures are final.
    pub done: bool,
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

/// What [`Env::save_state`] writes, borrowed from the env.
#[derive(serde::Serialize)]
struct EnvStateRef<'a> {
    world: &'a World,
    task: &'a TaskState,
    agent_rewards: &'a [f32],
    agent_terminated: &'a [bool],
    stats: &'a EpisodeStats,
    last_episode: &'a EpisodeStats,
    agent_stats: &'a [AgentStats],
    last_agent_episodes: &'a [AgentStats],
    done: bool,
    trails: &'a [Vec<Vector>],
    pending_actions: &'a VecDeque<Vec<f32>>,
    pending_obs: &'a VecDeque<Vec<f32>>,
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
    agent_stats: Vec<AgentStats>,
    last_agent_episodes: Vec<AgentStats>,
    done: bool,
    trails: Vec<Vec<Vector>>,
    pending_actions: VecDeque<Vec<f32>>,
    pending_obs: VecDeque<Vec<f32>>,
}

/// One environment: a world, its task and the episode's bookkeeping.
pub struct Env {
    /// The simulated world.
    pub world: World,
    /// The scenario it was built from.
    pub cfg: Arc<Scenario>,
    spawner: Arc<Spawner>,
    task: TaskState,
    action_type: ActionType,
    /// What each agent drives, in agent order.
    agent_bodies: Vec<Body>,
    /// Action values per agent ([`action_width`]).
    action_width: usize,
    obs_dim: usize,
    /// The length of every agent's observation, when they all have one length (then written in
    /// blocks of agents, which a swarm's team shares).
    agent_width: Option<usize>,
    /// Whether agent k drives robot k, for every agent and robot (then the actions are applied
    /// in blocks of robots, which a swarm's team shares).
    agents_are_robots: bool,
    /// Each agent's reward on the last step.
    pub agent_rewards: Vec<f32>,
    /// Each agent's termination on the last step (multinav: its robot arrived).
    pub agent_terminated: Vec<bool>,
    /// Statistics of the running episode.
    pub stats: EpisodeStats,
    /// Statistics of the last episode that ended.
    pub last_episode: EpisodeStats,
    /// Each agent's statistics of the running episode (an agent that has left holds its final
    /// ones), in agent order.
    pub agent_stats: Vec<AgentStats>,
    /// Each agent's statistics of the last episode that ended, in agent order.
    pub last_agent_episodes: Vec<AgentStats>,
    /// The episode has ended; the next step must be a reset.
    pub done: bool,
    /// Positions of each robot over the last `trail_length` steps (for rendering; empty and
    /// free when `trail_length` is 0).
    trails: Vec<Vec<Vector>>,
    trail_length: usize,
    /// Joint actions sent but not yet received, oldest first (`task.action_delay` of them); an
    /// empty one stands for the steps before the first action (wheels still, LEDs unchanged).
    pending_actions: VecDeque<Vec<f32>>,
    /// Observations made but not yet delivered, oldest first (`task.observation_delay` of
    /// them).
    pending_obs: VecDeque<Vec<f32>>,
}

impl Env {
    /// An environment of `kind` built from `cfg`, seeded with 0 until [`Env::seed`].
    pub fn new(
        kind: TaskKind,
        cfg: Arc<Scenario>,
        spawner: Arc<Spawner>,
        action_type: ActionType,
    ) -> Result<Self> {
        let world = World::new(
            &cfg,
            spawner.base.clone(),
            spawner.floor.clone(),
            spawner.n_robots(),
        );
        let task = kind.new_state(&cfg)?;
        let agents = kind.agents(&cfg)?;
        let obs_dim = agents.iter().map(|a| a.layout.len()).sum();
        let width = agents.first().map_or(0, |a| a.layout.len());
        let agent_width = agents
            .iter()
            .all(|a| a.layout.len() == width)
            .then_some(width)
            .filter(|&w| w > 0);
        let agent_bodies: Vec<Body> = agents.iter().map(|a| a.body).collect();
        let agents_are_robots = agent_bodies.len() == spawner.n_robots()
            && (agent_bodies.iter().enumerate())
                .all(|(k, b)| matches!(b, Body::Robot(i) if *i == k));
        let n_agents = agent_bodies.len();
        let action_width = action_width(&cfg);
        // A vehicle (DroneFollow's drone) has no LEDs to set.
        let vehicle = agents.iter().find(|a| matches!(a.body, Body::Vehicle(_)));
        if let Some(vehicle) = vehicle.filter(|_| cfg.task.led_action) {
            return Err(Error::config(
                &cfg.origin,
                "task.led_action",
                format!(
                    "agent {:?} flies a vehicle without LEDs; LED actions need every agent to \
                     drive a Khepera (set task.led_action = false)",
                    vehicle.name
                ),
            ));
        }
        Ok(Self {
            world,
            cfg,
            spawner,
            task,
            action_type,
            agent_bodies,
            action_width,
            obs_dim,
            agent_width,
            agents_are_robots,
            agent_rewards: vec![0.0; n_agents],
            agent_terminated: vec![false; n_agents],
            stats: EpisodeStats::default(),
            last_episode: EpisodeStats::default(),
            agent_stats: vec![AgentStats::default(); n_agents],
            last_agent_episodes: vec![AgentStats::default(); n_agents],
            done: true,
            trails: Vec::new(),
            trail_length: 0,
            pending_actions: VecDeque::new(),
            pending_obs: VecDeque::new(),
        })
    }

    /// The spawner of a scenario for `kind` (built once and shared by every world of a batch);
    /// checks that its layouts are feasible, naming the scenario's origin in errors.
    pub fn spawner(kind: TaskKind, cfg: &Scenario) -> Result<Spawner> {
        Spawner::new(cfg, kind.spawn(cfg)?, &cfg.origin)
    }

    /// Length of the joint observation.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// The task.
    pub fn kind(&self) -> TaskKind {
        self.task.kind()
    }

    /// Restarts the world's random stream from `seed`.
    pub fn seed(&mut self, seed: u64) {
        self.world.rng = ChaCha8Rng::seed_from_u64(seed);
    }

    /// Starts a new episode (continuing the random stream) and writes its first observation.
    pub fn reset(&mut self, obs: &mut [f32]) {
        self.stats = EpisodeStats::default();
        self.agent_stats.fill(AgentStats::default());
        self.done = false;
        self.agent_rewards.fill(0.0);
        self.agent_terminated.fill(false);
        self.world.randomise(&self.cfg);
        let mut layout = self.spawner.generate(&self.cfg, &mut self.world.rng);
        self.task
            .arrange(&self.cfg, &mut self.world.rng, &mut layout);
        if self.cfg.obstacles.count > 0 || !layout.obstacles.is_empty() {
            // New random obstacles (the spawner's, or the task's: PathFollow's on its path): the
            // fixed scene plus this episode's.
            let mut scene = self.spawner.base.clone();
            scene.shapes.extend(layout.obstacles.iter().copied());
            self.world.set_scene(scene);
        }
        if !layout.floor.is_empty() || !self.world.floor_marks.segments().is_empty() {
            self.world.floor_marks = FloorMarks::new(std::mem::take(&mut layout.floor));
        }
        for (i, (position, heading)) in layout.poses.iter().enumerate() {
            self.world.place_robot(i, *position, *heading);
        }
        self.world.start_odometry(&self.cfg);
        self.task.reset(&self.world, &layout);
        // A swarm's team reads the sensors and writes the observations.
        self.world.step_team().scope(|| {
            self.world.sense(true);
            self.observe(obs);
        });
        // Delays start full: the wheels keep still and the first observations repeat the
        // reset's until the real ones arrive.
        self.pending_actions.clear();
        self.pending_actions
            .extend((0..self.cfg.task.action_delay).map(|_| Vec::new()));
        self.pending_obs.clear();
        self.pending_obs
            .extend((0..self.cfg.task.observation_delay).map(|_| obs.to_vec()));
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

    /// Applies `action` (normalised, [`action_width`] numbers per agent, already checked finite),
    /// advances one control step and writes the next observation.
    pub fn step(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        // A swarm's team stays for the whole step, the task's passes included.
        self.world.step_team().scope(|| self.step_now(action, obs))
    }

    fn step_now(&mut self, action: &[f32], obs: &mut [f32]) -> StepOutcome {
        if self.cfg.task.action_delay == 0 {
            self.apply(action);
        } else {
            // The action sent now arrives `action_delay` steps later; the oldest arrives now. Its
            // buffer then carries this one.
            let mut arrived = self.pending_actions.pop_front().unwrap_or_default();
            self.apply(&arrived);
            arrived.clear();
            arrived.extend_from_slice(action);
            self.pending_actions.push_back(arrived);
        }
        self.task.before_step(&mut self.world);
        self.world.advance();
        self.world.sense(false);
        self.world.update_odometry(&self.cfg);
        let success = self.task.judge(
            &self.world,
            &self.cfg,
            &mut self.agent_rewards,
            &mut self.agent_terminated,
        );
        let reward = self.agent_rewards.iter().sum::<f32>() / self.agent_rewards.len() as f32;
        let collided = self.world.robots.iter().any(|r| r.in_contact);
        let stats = &mut self.stats;
        stats.ret += reward;
        stats.length += 1;
        stats.success |= success;
        stats.path_length += self.world.robots.iter().map(|r| r.step_travel).sum::<f32>();
        stats.collisions += collided as u32;
        self.task.extra_stats(&mut stats.extra);
        // Every agent terminated by the task (the tracking robot lost) ends the episode too.
        let all_out = self.agent_terminated.iter().all(|&t| t);
        let terminated = success || all_out || (collided && self.cfg.task.terminate_on_collision);
        let truncated = !terminated && stats.length >= self.task.max_steps(&self.cfg);
        self.record_agents(terminated || truncated);
        if terminated {
            self.agent_terminated.fill(true);
        }
        if terminated || truncated {
            self.done = true;
            self.last_episode = self.stats;
            self.last_agent_episodes.clone_from(&self.agent_stats);
        }
        self.observe(obs);
        // Deliver the observation made `observation_delay` steps ago and keep this one.
        if let Some(mut oldest) = self.pending_obs.pop_front() {
            oldest.swap_with_slice(obs);
            self.pending_obs.push_back(oldest);
        }
        self.record_trail();
        StepOutcome {
            reward,
            terminated,
            truncated,
        }
    }

    /// Adds the last step to the statistics of each agent still in the episode; an agent that
    /// terminated on it, or every agent when the episode ended, leaves with the task's verdict
    /// on its success.
    fn record_agents(&mut self, episode_over: bool) {
        let robots = &self.world.robots;
        let agents = self.agent_bodies.iter().zip(&mut self.agent_stats);
        for (k, (&body, stats)) in agents.enumerate() {
            if stats.done {
                continue;
            }
            stats.ret += self.agent_rewards[k];
            stats.length += 1;
            match body {
                Body::Robot(i) => {
                    stats.path_length += robots[i].step_travel;
                    stats.collisions += robots[i].in_contact as u32;
                }
                Body::Vehicle(v) => stats.path_length += self.task.vehicle_travel(v),
            }
            if self.agent_terminated[k] || episode_over {
                let success = self.stats.success;
                stats.success = self.task.agent_success(&self.world, &self.cfg, k, success);
                stats.done = true;
            }
        }
    }

    /// Gives each agent its part of a joint `action`: wheel commands, a vehicle's command
    /// ([`TaskState::act`]), LED colours. An empty `action` (none sent yet) stops the wheels and
    /// leaves the LEDs as they are.
    fn apply(&mut self, action: &[f32]) {
        let team = self.world.step_team();
        let (width, drive, action_type) = (self.action_width, &self.world.drive, self.action_type);
        let set = |robot: &mut Robot, sent: Option<&[f32]>| {
            let wheels = sent.map_or([0.0; WHEEL_ACTIONS], |a| [a[0], a[1]]);
            robot.wheel_command = drive.wheel_command(wheels, action_type);
            if let Some(&[_, _, r, g, b]) = sent {
                robot.led = led_color([r, g, b]);
            }
        };
        let robots = &mut self.world.robots;
        if self.agents_are_robots && action.len() == robots.len() * width {
            // Agent k drives robot k: blocks of robots, which a swarm's team shares.
            let blocks = robots.chunks_mut(ROBOT_CHUNK);
            let blocks = blocks.zip(action.chunks(ROBOT_CHUNK * width));
            team.each(blocks, |_, (robots, sent): (&mut [Robot], &[f32])| {
                for (robot, sent) in robots.iter_mut().zip(sent.chunks(width)) {
                    set(robot, Some(sent));
                }
            });
            return;
        }
        for (k, body) in self.agent_bodies.iter().enumerate() {
            let sent = action.get(k * width..(k + 1) * width);
            match *body {
                Body::Robot(i) => set(&mut robots[i], sent),
                Body::Vehicle(v) => {
                    // Clipped to the action space like a robot's wheels (robot.rs): out-of-range
                    // values act as the nearest ones in [-1, 1].
                    let wheels = sent.map_or([0.0; WHEEL_ACTIONS], |a| [a[0], a[1]]);
                    self.task.act(v, wheels.map(|a| a.clamp(-1.0, 1.0)));
                }
            }
        }
    }

    /// Writes the joint observation: agent after agent, its robot's observed sensor blocks
    /// (an agent driving a robot), then the task's blocks for it.
    fn observe(&self, obs: &mut [f32]) {
        let agent = |k: usize, out: &mut ObsWriter| {
            if let Body::Robot(i) = self.agent_bodies[k] {
                self.world
                    .sensors
                    .observe(&self.world.robots[i].readings, out);
            }
            self.task.observe(&self.world, &self.cfg, k, out);
        };
        if let Some(width) = self.agent_width {
            // Blocks of agents, each agent with its own writer, which a swarm's team shares.
            let blocks = obs.chunks_mut(ROBOT_CHUNK * width);
            self.world
                .step_team()
                .each(blocks, |first, block: &mut [f32]| {
                    for (k, out) in block.chunks_mut(width).enumerate() {
                        let mut out = ObsWriter::new(out);
                        agent(first + k, &mut out);
                        debug_assert_eq!(out.position(), width, "agent {} wrote", first + k);
                    }
                });
            return;
        }
        let mut out = ObsWriter::new(obs);
        for k in 0..self.agent_bodies.len() {
            agent(k, &mut out);
        }
        debug_assert_eq!(
            out.position(),
            obs.len(),
            "observation layout and writer disagree"
        );
    }

    /// A fresh env of the same task, scenario, action type and trail length (its state to be
    /// loaded).
    pub fn empty_twin(&self) -> Result<Self> {
        let mut twin = Self::new(
            self.kind(),
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
            task: &self.task,
            agent_rewards: &self.agent_rewards,
            agent_terminated: &self.agent_terminated,
            stats: &self.stats,
            last_episode: &self.last_episode,
            agent_stats: &self.agent_stats,
            last_agent_episodes: &self.last_agent_episodes,
            done: self.done,
            trails: &self.trails,
            pending_actions: &self.pending_actions,
            pending_obs: &self.pending_obs,
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
        let n_agents = self.agent_bodies.len();
        if state.world.robots.len() != n_robots
            || state.agent_rewards.len() != n_agents
            || state.agent_terminated.len() != n_agents
            || state.agent_stats.len() != n_agents
            || state.last_agent_episodes.len() != n_agents
            || !state.task.fits(&self.task)
            || state.pending_actions.len() != self.cfg.task.action_delay as usize
            || state
                .pending_actions
                .iter()
                .any(|a| !a.is_empty() && a.len() != n_agents * self.action_width)
            || state.pending_obs.len() != self.cfg.task.observation_delay as usize
            || state.pending_obs.iter().any(|o| o.len() != self.obs_dim)
        {
            return Err(Error::SavedState(
                "the state does not fit this env (other task, number of robots or delays)".into(),
            ));
        }
        let floor = self.world.floor.clone();
        self.world = state.world;
        self.world.floor = floor;
        self.task = state.task;
        self.agent_rewards = state.agent_rewards;
        self.agent_terminated = state.agent_terminated;
        self.stats = state.stats;
        self.last_episode = state.last_episode;
        self.agent_stats = state.agent_stats;
        self.last_agent_episodes = state.last_agent_episodes;
        self.done = state.done;
        self.trails = state.trails;
        self.pending_actions = state.pending_actions;
        self.pending_obs = state.pending_obs;
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
        self.task.goals()
    }

    /// Target points of the task other than goals (the followers' formation targets), m.
    pub fn targets(&self) -> Vec<Vector> {
        self.task.targets(&self.world)
    }

    /// What the renderer draws for the task (goals, targets).
    pub fn task_marks(&self, marks: &mut Vec<Mark>) {
        self.task.draw(&self.world, &self.cfg, marks);
    }

    /// The task's extra statistics of an episode, by name.
    pub fn extra_stats(&self, stats: &EpisodeStats) -> Vec<(&'static str, f32)> {
        self.kind()
            .extra_stats()
            .iter()
            .zip(stats.extra)
            .map(|(n, v)| (*n, v))
            .collect()
    }
}
