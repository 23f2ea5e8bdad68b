//! A batch of N independent worlds of one task, stepped in parallel.
//!
//! Layout: the worlds in a `Vec`, outputs in flat preallocated buffers (observations
//! `N × obs_dim`, one outcome per world); a step allocates nothing. Threading: the batch owns a
//! rayon pool of `num_threads` threads (none when 1); each world is stepped by exactly one thread
//! and draws only from its own ChaCha8 stream, so results are bit-for-bit the same for any
//! thread count. Seeding: `reset(Some(s))` seeds world i with `s + i` (Gymnasium's convention),
//! `reset(None)` continues every stream. Autoreset (Gymnasium NEXT_STEP): a world whose episode
//! ended on the previous step is reset instead of stepped, with reward 0 and both flags false.
//!
//! Units: actions normalised to [-1, 1], two per agent; rewards per step; the rest is the
//! worlds' (metres, seconds, radians, world frame).

use std::sync::Arc;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::memory;
use crate::robot::ActionType;
use crate::scenario::Scenario;
use crate::tasks::{Env, EpisodeStats, StepOutcome, TaskKind};

/// First bytes of a saved state.
pub const STATE_MAGIC: &[u8; 8] = b"KHEPGYM\0";
/// Version of the saved-state format; bumped whenever the layout of any saved type changes.
/// 2: sensors behind the sensor contract (readings per sensor), tasks behind the task contract.
/// 3: the robots' IMU state, the task's floor marks, colours of the scene's surfaces and robots,
/// the new tasks' states. 4: the drive's profile minimum order, rapier's contact prediction.
/// 5: each agent's own episode statistics.
pub const STATE_VERSION: u32 = 5;

/// What a saved state says about the batch it came from.
#[derive(serde::Serialize, serde::Deserialize)]
struct StateHeader {
    version: u32,
    task: String,
    num_worlds: u64,
    scenario: String,
    checksum: u32,
}

/// The first line in which two scenarios' TOML differ, for error messages.
fn first_difference(saved: &str, current: &str) -> String {
    let mut section = "";
    for (a, b) in saved.lines().zip(current.lines()) {
        if a.starts_with('[') {
            section = a;
        }
        if a != b {
            return format!("{section} saved `{a}`, this env has `{b}`");
        }
    }
    "different lengths".into()
}

/// Smallest number of worlds a rayon task takes (amortises scheduling), for worlds of up to
/// [`GRID_MIN_ROBOTS`](crate::world::GRID_MIN_ROBOTS) robots. A swarm's world (more robots) is
/// worth a task of its own: with 8, the 10 worlds of 100 robots or 3 of 300 went to one task,
/// so one thread stepped them all and the other only helped with their sensing.
const MIN_WORLDS_PER_TASK: usize = 8;

/// One world with its observation slot, its action and its outcome slot.
type WorldSlot<'a> = (
    (&'a mut Env, &'a mut [f32]),
    (&'a [f32], &'a mut StepOutcome),
);

/// N worlds, their output buffers and their thread pool.
pub struct Batch {
    envs: Vec<Env>,
    pool: Option<rayon::ThreadPool>,
    num_threads: usize,
    /// Smallest number of worlds a rayon task takes: [`MIN_WORLDS_PER_TASK`], or 1 for swarms.
    worlds_per_task: usize,
    autoreset: bool,
    obs_dim: usize,
    act_dim: usize,
    obs: Vec<f32>,
    outcomes: Vec<StepOutcome>,
}

impl Batch {
    /// Builds `num_worlds` worlds of `kind` from `cfg`. `num_threads` None uses every core.
    pub fn new(
        kind: TaskKind,
        cfg: Scenario,
        num_worlds: usize,
        action_type: ActionType,
        num_threads: Option<usize>,
        autoreset: bool,
    ) -> Result<Self> {
        if num_worlds == 0 {
            return Err(Error::config("<batch>", "num_envs", "must be >= 1, got 0"));
        }
        if num_worlds > 1 << 20 {
            return Err(Error::config(
                "<batch>",
                "num_envs",
                format!("must be <= 1048576, got {num_worlds}"),
            ));
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let num_threads = match num_threads {
            Some(0) => {
                return Err(Error::config(
                    "<batch>",
                    "num_threads",
                    "must be >= 1, got 0",
                ));
            }
            Some(n) if n > 1024 => {
                return Err(Error::config(
                    "<batch>",
                    "num_threads",
                    format!("must be <= 1024, got {n}"),
                ));
            }
            Some(n) => n,
            None => cores,
        };
        // A swarm's robots are read in parallel (world/swarm.rs): one world is then enough to
        // share among threads.
        let swarm = kind.spawn(&cfg)?.n_robots() > crate::world::GRID_MIN_ROBOTS;
        let pool = if num_threads > 1 && (num_worlds > 1 || swarm) {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(num_threads)
                .thread_name(|i| format!("khepera-gym-{i}"))
                .build()
                .map_err(|e| Error::State(format!("cannot start {num_threads} threads: {e}")))?;
            Some(pool)
        } else {
            None
        };
        let spawner = Arc::new(Env::spawner(kind, &cfg)?);
        let cfg = Arc::new(cfg);
        let obs_dim = kind.obs_layout(&cfg)?.len();
        let act_dim = crate::tasks::action_width(&cfg) * kind.agents(&cfg)?.len();
        // The first world, measured, and what a reset and a step add to a copy of it: what
        // every world costs, checked before the others are built.
        let (first, built) =
            memory::measure(|| Env::new(kind, cfg.clone(), spawner.clone(), action_type));
        let mut first = first?;
        first.seed(0);
        let mut twin = first.empty_twin()?;
        let (mut scratch, actions) = (vec![0.0; obs_dim], vec![0.0; act_dim]);
        let ((), grown) = memory::measure(|| {
            twin.reset(&mut scratch);
            twin.step(&actions, &mut scratch);
        });
        // A world builds its rapier side at the first substep that needs it: count it as built.
        let rapier = twin.world.unbuilt_physics_bytes();
        drop(twin);
        let buffers =
            (obs_dim * 4 + std::mem::size_of::<StepOutcome>() + std::mem::size_of::<Env>()) as u64;
        let per_world = built + grown + rapier + buffers;
        let total = per_world.saturating_mul(num_worlds as u64);
        if total > memory::MAX_BATCH_BYTES {
            return Err(Error::config(
                "<batch>",
                "num_envs",
                format!(
                    "{num_worlds} worlds of this scenario need about {} ({} each), more than \
                     the limit of {} a batch: fewer worlds, or several batches",
                    memory::human(total),
                    memory::human(per_world),
                    memory::human(memory::MAX_BATCH_BYTES)
                ),
            ));
        }
        memory::reserve(total, &format!("a batch of {num_worlds} worlds"))?;
        let mut envs: Vec<Env> = Vec::new();
        envs.try_reserve_exact(num_worlds).map_err(|_| {
            Error::Memory(format!("cannot allocate the list of {num_worlds} worlds"))
        })?;
        envs.push(first);
        for i in 1..num_worlds {
            let mut env = Env::new(kind, cfg.clone(), spawner.clone(), action_type)?;
            env.seed(i as u64);
            envs.push(env);
        }
        Ok(Self {
            envs,
            pool,
            num_threads,
            worlds_per_task: if swarm { 1 } else { MIN_WORLDS_PER_TASK },
            autoreset,
            obs_dim,
            act_dim,
            obs: vec![0.0; num_worlds * obs_dim],
            outcomes: vec![StepOutcome::default(); num_worlds],
        })
    }

    /// Number of worlds.
    pub fn len(&self) -> usize {
        self.envs.len()
    }

    /// Whether the batch has no worlds (never: construction requires one).
    pub fn is_empty(&self) -> bool {
        self.envs.is_empty()
    }

    /// Observation length per world.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// Action length per world.
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }

    /// Threads stepping the batch.
    pub fn num_threads(&self) -> usize {
        self.num_threads
    }

    /// The worlds, read-only.
    pub fn envs(&self) -> &[Env] {
        &self.envs
    }

    /// The scenario shared by every world.
    pub fn scenario(&self) -> &Scenario {
        &self.envs[0].cfg
    }

    /// Observations written by the last reset or step, `N × obs_dim`.
    pub fn obs(&self) -> &[f32] {
        &self.obs
    }

    /// Outcomes of the last step, one per world.
    pub fn outcomes(&self) -> &[StepOutcome] {
        &self.outcomes
    }

    /// Statistics of each world's last finished episode (valid where the last step ended one).
    pub fn episode_stats(&self) -> impl Iterator<Item = &EpisodeStats> {
        self.envs.iter().map(|e| &e.last_episode)
    }

    /// Keeps the last `length` robot positions of every world for rendering (0: off).
    pub fn set_trail_length(&mut self, length: usize) {
        for env in &mut self.envs {
            env.set_trail_length(length);
        }
    }

    /// The state of every world (see [`Env::save_state`]) and of the batch's output buffers,
    /// as bytes: restoring it with [`Batch::load_state`] and replaying the same actions gives the
    /// same results bit for bit. Layout: `STATE_MAGIC`, a postcard header (format version, task,
    /// number of worlds, scenario as TOML, CRC-32 of the body), then the postcard body.
    pub fn save_state(&self) -> Result<Vec<u8>> {
        let mut body = Vec::new();
        let buffers = (&self.obs, &self.outcomes);
        body = postcard::to_extend(&buffers, body)
            .map_err(|e| Error::State(format!("cannot encode the batch state: {e}")))?;
        for env in &self.envs {
            env.save_state(&mut body)?;
        }
        let header = StateHeader {
            version: STATE_VERSION,
            task: self.envs[0].kind().name().to_string(),
            num_worlds: self.envs.len() as u64,
            scenario: self.scenario().to_toml(),
            checksum: crc32fast::hash(&body),
        };
        let mut out = STATE_MAGIC.to_vec();
        out = postcard::to_extend(&header, out)
            .map_err(|e| Error::State(format!("cannot encode the state header: {e}")))?;
        out.extend_from_slice(&body);
        Ok(out)
    }

    /// Restores a state from [`Batch::save_state`] of a batch of the same task, scenario and
    /// number of worlds. On any error (not a state, corrupt, or from another batch) nothing is
    /// changed and the error says which.
    pub fn load_state(&mut self, bytes: &[u8]) -> Result<()> {
        let body = bytes.strip_prefix(STATE_MAGIC.as_slice()).ok_or_else(|| {
            Error::SavedState(
                "not a khepera_gym state (it does not start with the state marker)".into(),
            )
        })?;
        let (header, body): (StateHeader, _) = postcard::take_from_bytes(body)
            .map_err(|e| Error::SavedState(format!("corrupt state header: {e}")))?;
        if header.version != STATE_VERSION {
            return Err(Error::SavedState(format!(
                "state format version {} cannot be read by this version of khepera_gym \
                 (format {STATE_VERSION})",
                header.version
            )));
        }
        let task = self.envs[0].kind().name();
        if header.task != task {
            return Err(Error::SavedState(format!(
                "the state is of a {:?} env, this env is {task:?}",
                header.task
            )));
        }
        if header.num_worlds != self.envs.len() as u64 {
            return Err(Error::SavedState(format!(
                "the state has {} worlds, this env has {}",
                header.num_worlds,
                self.envs.len()
            )));
        }
        let scenario = self.scenario().to_toml();
        if header.scenario != scenario {
            return Err(Error::SavedState(format!(
                "the state was saved from another scenario ({})",
                first_difference(&header.scenario, &scenario)
            )));
        }
        if crc32fast::hash(body) != header.checksum {
            return Err(Error::SavedState(
                "corrupt state: its checksum does not match (truncated or altered bytes)".into(),
            ));
        }
        let ((obs, outcomes), mut rest): ((Vec<f32>, Vec<StepOutcome>), _) =
            postcard::take_from_bytes(body)
                .map_err(|e| Error::SavedState(format!("corrupt batch state: {e}")))?;
        if obs.len() != self.obs.len() || outcomes.len() != self.outcomes.len() {
            return Err(Error::SavedState(
                "corrupt batch state: wrong buffer sizes".into(),
            ));
        }
        // Decode into copies first so that a failure leaves the batch as it was.
        let mut envs = Vec::with_capacity(self.envs.len());
        for env in &self.envs {
            let mut copy = env.empty_twin()?;
            rest = copy.load_state(rest)?;
            envs.push(copy);
        }
        if !rest.is_empty() {
            return Err(Error::SavedState(format!(
                "corrupt state: {} unexpected bytes at the end",
                rest.len()
            )));
        }
        self.envs = envs;
        self.obs = obs;
        self.outcomes = outcomes;
        Ok(())
    }

    /// Resets every world; with `Some(seed)` world i is seeded with `seed + i` first.
    pub fn reset(&mut self, seed: Option<u64>) {
        if let Some(seed) = seed {
            for (i, env) in self.envs.iter_mut().enumerate() {
                env.seed(seed.wrapping_add(i as u64));
            }
        }
        self.outcomes.fill(StepOutcome::default());
        let (obs_dim, worlds_per_task) = (self.obs_dim, self.worlds_per_task);
        let work = |envs: &mut [Env], obs: &mut [f32]| {
            envs.par_iter_mut()
                .zip(obs.par_chunks_mut(obs_dim))
                .with_min_len(worlds_per_task)
                .for_each(|(env, o)| env.reset(o));
        };
        match &self.pool {
            Some(pool) => pool.install(|| work(&mut self.envs, &mut self.obs)),
            None => {
                for (env, o) in self.envs.iter_mut().zip(self.obs.chunks_mut(obs_dim)) {
                    env.reset(o);
                }
            }
        }
    }

    /// Resets world `index` alone (seeded with `seed` itself when given).
    pub fn reset_world(&mut self, index: usize, seed: Option<u64>) -> Result<&[f32]> {
        let n = self.envs.len();
        let env = self
            .envs
            .get_mut(index)
            .ok_or_else(|| Error::State(format!("world index {index} out of range 0..{n}")))?;
        if let Some(seed) = seed {
            env.seed(seed);
        }
        let o = &mut self.obs[index * self.obs_dim..(index + 1) * self.obs_dim];
        env.reset(o);
        self.outcomes[index] = StepOutcome::default();
        Ok(o)
    }

    /// Checks an action buffer: length `N × act_dim`, every value finite.
    pub fn check_actions(&self, actions: &[f32]) -> Result<()> {
        let expected = self.envs.len() * self.act_dim;
        if actions.len() != expected {
            return Err(Error::Action(format!(
                "expected {} actions of {} values ({expected} in all), got {}",
                self.envs.len(),
                self.act_dim,
                actions.len()
            )));
        }
        if let Some(i) = actions.iter().position(|a| !a.is_finite()) {
            return Err(Error::Action(format!(
                "action of world {} element {} is {} (actions must be finite; finite values \
                 outside [-1, 1] are clipped)",
                i / self.act_dim,
                i % self.act_dim,
                actions[i]
            )));
        }
        Ok(())
    }

    /// Steps every world with `actions` (`N × act_dim`, row-major). Nothing is changed when the
    /// actions are invalid.
    pub fn step(&mut self, actions: &[f32]) -> Result<()> {
        self.check_actions(actions)?;
        if !self.autoreset {
            if let Some(i) = self.envs.iter().position(|e| e.done) {
                return Err(Error::State(format!(
                    "world {i}: the episode has ended (or was never started); call reset() first"
                )));
            }
        }
        let (obs_dim, act_dim) = (self.obs_dim, self.act_dim);
        let worlds_per_task = self.worlds_per_task;
        let step_one = |((env, o), (a, out)): WorldSlot| {
            if env.done {
                env.reset(o);
                *out = StepOutcome::default();
            } else {
                *out = env.step(a, o);
            }
        };
        match &self.pool {
            Some(pool) => pool.install(|| {
                self.envs
                    .par_iter_mut()
                    .zip(self.obs.par_chunks_mut(obs_dim))
                    .zip(
                        actions
                            .par_chunks(act_dim)
                            .zip(self.outcomes.par_iter_mut()),
                    )
                    .with_min_len(worlds_per_task)
                    .for_each(step_one)
            }),
            None => self
                .envs
                .iter_mut()
                .zip(self.obs.chunks_mut(obs_dim))
                .zip(actions.chunks(act_dim).zip(self.outcomes.iter_mut()))
                .for_each(step_one),
        }
        Ok(())
    }
}
