//! Consensus with real messages (PettingZoo `consensus_v1`; issue 16, docs/task-design.md §8):
//! N robots on a communication graph reach a rendezvous or a formation using only what their
//! neighbours broadcast. The KH4VREP paper's future work (§6): multi-agent consensus with
//! event-based communication.
//!
//! **Objective.** Robot i has an offset c_i (0 for `rendezvous`; for `formation`, the vertex i
//! of a regular polygon of radius `formation_radius`); the robots agree when the displacements
//! z_i = x_i − c_i are equal (displacement-based formation, Ren & Beard 2008, ch. 2). The
//! error is the RMS disagreement e = sqrt(mean_i ‖z_i − z̄‖²), z̄ the mean over all robots, from
//! true positions. Rendezvous cannot bring solid robots to one point: its error has a floor, the
//! RMS radius of N discs packed hexagonally, r·sqrt(N / (2·0.9069)) (0.10 m for 4 robots).
//!
//! **Messages.** A robot's broadcast carries its position estimate x̂_i (its believed position:
//! odometry with `task.localization = "odometry"`) and is sent when its trigger fires: every
//! `period` s (`trigger = "periodic"`) or when its estimate has moved more than `threshold` m
//! from its last broadcast (`trigger = "event"`, Dimarogonas, Frazzoli & Johansson, IEEE TAC
//! 57(5), 2012); every robot broadcasts at reset. Each neighbour (the graph at the time of
//! sending) receives it unless it is dropped (probability `drop`, drawn per receiver from the
//! world's seed) after `delay_steps` control steps; a receiver keeps the last message of each
//! neighbour, and sees its age. The trigger is the robots' radio firmware, a scenario choice:
//! the action stays the two wheel numbers of every task.
//!
//! **Graphs.** `ring`, `line` (a path), `complete`, `geometric` (robots within `range` m of one
//! another, the true distance, at each step: the graph changes as they move) or `edges` (the
//! undirected pairs of `edges`).
//!
//! **Observation** of agent i (robot frame, from its believed pose): the observed sensors, then
//! `neighbours`: for each other robot j in index order, (p_x, p_y, age, valid) with
//! p = x̂_j − c_j + c_i (where j's last message says robot i should be, m), the message's age
//! (s, at most 10) and valid = 1 when j is i's neighbour now and a message of it has arrived
//! (else the slot is zeros); `own_drift`: x̂_i(last broadcast) − x̂_i (m), what the event
//! trigger measures; `wheel_speeds`.
//!
//! **Reward** (shared, cooperative): −`error_weight`·e per step, minus `task.collision_penalty`
//! for an agent in contact. No termination; truncated at `task.max_steps` (600: 30 s).
//! Extra statistics: `consensus_error_final` (m), `consensus_error_rms` (m, over the episode's
//! steps), `consensus_converge_time` (s: when e fell below `tolerance` (plus the rendezvous
//! floor) for good; inf if above at the end) and `messages_per_robot_s` (broadcasts per robot
//! per second, the reset's included).
//!
//! Units: metres, seconds, radians; world frame (x right, y up) unless stated.

use std::collections::VecDeque;

use super::nav;
use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::config::ConfigTable;
use crate::draw::{Mark, PALETTE};
use crate::error::Result;
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

mod config;
pub use config::{ConsensusConfig, Graph, Objective, Trigger, MAX_ROBOTS};

/// Values per neighbour slot: p_x, p_y, age, valid.
pub const SLOT: usize = 4;
/// Largest age a slot reports (s).
pub const MAX_AGE: f32 = 10.0;
/// Most control steps a message may be delayed.
pub const MAX_DELAY_STEPS: u32 = 100;
/// Density of the hexagonal packing of discs, π/(2√3).
const HEX_DENSITY: f32 = 0.9069;

/// consensus: its defaults and the `[consensus]` table.
pub const CONSENSUS: TaskInfo = TaskInfo {
    env_id: None,
    summary: "robots on a communication graph reach a rendezvous or a formation from what their \
              neighbours broadcast (periodic or event-triggered messages, with drops and delay)",
    schema: TaskSchema {
        name: "consensus",
        since: 1,
        defaults: r#"
[task]
max_steps = 600              # 30 s
collision_penalty = 0.1      # per step in contact
"#,
        section: Some(Section {
            name: "consensus",
            keys: ConsensusConfig::KEYS,
            check: config::check_section,
        }),
    },
    scoring: Scoring::GOAL,
    agents: AgentFacts::TEAM,
};

/// One broadcast: the sender's estimate and when it was sent.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Message {
    /// The sender's position estimate (m).
    pub position: Vector,
    /// Control step it was sent at.
    pub sent: u32,
}

/// A message on its way.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
struct InFlight {
    due: u32,
    from: u32,
    to: u32,
    message: Message,
}

/// Per-world state of the consensus task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Consensus {
    cfg: ConsensusConfig,
    n: usize,
    /// Offsets c_i (m).
    pub offsets: Vec<Vector>,
    /// Links now, row-major n × n.
    links: Vec<bool>,
    /// Last message received by i from j, at `i * n + j`.
    inbox: Vec<Option<Message>>,
    /// Each robot's last broadcast.
    pub sent: Vec<Message>,
    in_flight: VecDeque<InFlight>,
    /// The loss stream (boxed: it is most of the state's size).
    rng: Box<ChaCha8Rng>,
    step: u32,
    dt: f32,
    period_steps: u32,
    /// Broadcasts this episode, the reset's included.
    pub messages: u64,
    /// The error now (m).
    pub error: f32,
    error_sq_sum: f64,
    last_above: Option<u32>,
    floor: f32,
    /// Robots that broadcast at the last step.
    pub broadcast: Vec<bool>,
}

impl Consensus {
    /// The convergence bound: `tolerance`, plus the packing floor for a rendezvous (m).
    pub fn bound(&self) -> f32 {
        self.cfg.tolerance + self.floor
    }

    /// Whether robots `i` and `j` are linked now.
    pub fn linked(&self, i: usize, j: usize) -> bool {
        self.links[i * self.n + j]
    }

    fn update_links(&mut self, world: &World) {
        let n = self.n;
        let range_sq = self.cfg.range * self.cfg.range;
        for i in 0..n {
            for j in 0..n {
                self.links[i * n + j] = i != j
                    && match self.cfg.graph {
                        Graph::Complete => true,
                        Graph::Ring => (i + 1) % n == j || (j + 1) % n == i,
                        Graph::Line => i + 1 == j || j + 1 == i,
                        Graph::Geometric => {
                            (world.robots[i].position - world.robots[j].position).length_squared()
                                <= range_sq
                        }
                        Graph::Edges => self.cfg.edges.iter().any(|&[a, b]| {
                            (a as usize, b as usize) == (i, j) || (a as usize, b as usize) == (j, i)
                        }),
                    };
            }
        }
    }

    /// Robot `i` broadcasts its estimate to its neighbours now.
    fn send(&mut self, world: &World, i: usize) {
        let message = Message {
            position: world.believed_pose(i).0,
            sent: self.step,
        };
        self.sent[i] = message;
        self.messages += 1;
        self.broadcast[i] = true;
        for j in 0..self.n {
            if !self.linked(i, j) {
                continue;
            }
            // One draw per receiver whatever `drop`, so the stream does not depend on it.
            let lost = self.rng.random::<f32>() < self.cfg.drop;
            if lost {
                continue;
            }
            if self.cfg.delay_steps == 0 {
                self.inbox[j * self.n + i] = Some(message);
            } else {
                self.in_flight.push_back(InFlight {
                    due: self.step + self.cfg.delay_steps,
                    from: i as u32,
                    to: j as u32,
                    message,
                });
            }
        }
    }

    fn deliver(&mut self) {
        while let Some(m) = self.in_flight.front() {
            if m.due > self.step {
                break;
            }
            let m = self.in_flight.pop_front().expect("front exists");
            self.inbox[m.to as usize * self.n + m.from as usize] = Some(m.message);
        }
    }

    fn fires(&self, world: &World, i: usize) -> bool {
        match self.cfg.trigger {
            Trigger::Periodic => self.step.is_multiple_of(self.period_steps),
            Trigger::Event => {
                (world.believed_pose(i).0 - self.sent[i].position).length() > self.cfg.threshold
            }
        }
    }

    /// The RMS disagreement of the displacements x_i − c_i (true positions), m.
    pub fn disagreement(&self, world: &World) -> f32 {
        let n = self.n as f32;
        let z: Vec<Vector> = (0..self.n)
            .map(|i| world.robots[i].position - self.offsets[i])
            .collect();
        let mean = z.iter().fold(Vector::ZERO, |a, b| a + *b) / n;
        (z.iter()
            .map(|zi| (*zi - mean).length_squared())
            .sum::<f32>()
            / n)
            .sqrt()
    }
}

/// Offsets c_i: zeros, or the vertices of a regular polygon of radius `r` (vertex 0 on +x).
pub fn offsets(objective: Objective, n: usize, r: f32) -> Vec<Vector> {
    (0..n)
        .map(|i| match objective {
            Objective::Rendezvous => Vector::ZERO,
            Objective::Formation => {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                Vector::new(r * a.cos(), r * a.sin())
            }
        })
        .collect()
}

impl Task for Consensus {
    const EXTRA_STATS: &'static [&'static str] = &[
        "consensus_error_final",
        "consensus_error_rms",
        "consensus_converge_time",
        "messages_per_robot_s",
    ];

    fn new(cfg: &Scenario) -> Result<Self> {
        let c: ConsensusConfig = cfg.own()?;
        let n = c.n_robots as usize;
        let dt = cfg.physics.dt;
        let floor = match c.objective {
            Objective::Rendezvous => cfg.robot.radius * (n as f32 / (2.0 * HEX_DENSITY)).sqrt(),
            Objective::Formation => 0.0,
        };
        Ok(Self {
            offsets: offsets(c.objective, n, c.formation_radius),
            links: vec![false; n * n],
            inbox: vec![None; n * n],
            sent: vec![
                Message {
                    position: Vector::ZERO,
                    sent: 0
                };
                n
            ],
            in_flight: VecDeque::new(),
            rng: Box::new(ChaCha8Rng::seed_from_u64(0)),
            step: 0,
            dt,
            period_steps: ((c.period / dt).round() as u32).max(1),
            messages: 0,
            error: 0.0,
            error_sq_sum: 0.0,
            last_above: None,
            floor,
            broadcast: vec![false; n],
            n,
            cfg: c,
        })
    }

    fn spawn(cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Multi(
            cfg.own::<ConsensusConfig>()?.n_robots as usize,
        ))
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let n = cfg.own::<ConsensusConfig>()?.n_robots as usize;
        let reach = cfg.diagonal() + 2.0 * cfg.arena.width.max(cfg.arena.height);
        let mut low = Vec::with_capacity(SLOT * (n - 1));
        let mut high = Vec::with_capacity(SLOT * (n - 1));
        for _ in 1..n {
            low.extend([-reach, -reach, 0.0, 0.0]);
            high.extend([reach, reach, MAX_AGE, 1.0]);
        }
        let layout = ObsLayout::new(vec![
            Block {
                name: "neighbours".into(),
                low,
                high,
            },
            Block::new("own_drift", 2, -cfg.diagonal(), cfg.diagonal()),
            Block::new("wheel_speeds", 2, -1.0, 1.0),
        ]);
        Ok((0..n)
            .map(|i| Agent {
                name: format!("robot_{i}"),
                body: Body::Robot(i),
                layout: layout.clone(),
            })
            .collect())
    }

    /// Seeds the message stream (drops) from the world's.
    fn arrange(&mut self, _cfg: &Scenario, rng: &mut ChaCha8Rng, _layout: &mut Layout) {
        *self.rng = ChaCha8Rng::seed_from_u64(rng.random());
    }

    fn reset(&mut self, world: &World, _layout: &Layout) {
        let n = self.n;
        self.step = 0;
        self.dt = world.dt();
        self.inbox = vec![None; n * n];
        self.in_flight.clear();
        self.messages = 0;
        self.broadcast = vec![false; n];
        self.update_links(world);
        for i in 0..n {
            self.send(world, i);
        }
        self.deliver();
        self.error = self.disagreement(world);
        self.error_sq_sum = 0.0;
        self.last_above = (self.error >= self.bound()).then_some(0);
    }

    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool {
        self.step += 1;
        self.update_links(world);
        self.deliver();
        self.broadcast.iter_mut().for_each(|b| *b = false);
        for i in 0..self.n {
            if self.fires(world, i) {
                self.send(world, i);
            }
        }
        self.deliver();
        self.error = self.disagreement(world);
        self.error_sq_sum += (self.error as f64).powi(2);
        if self.error >= self.bound() {
            self.last_above = Some(self.step);
        }
        let shared = -self.cfg.error_weight * self.error;
        for i in 0..self.n {
            rewards[i] = shared
                - if world.robots[i].in_contact {
                    cfg.task.collision_penalty
                } else {
                    0.0
                };
            terminated[i] = false;
        }
        false
    }

    fn extra_stats(&self, out: &mut [f32]) {
        let steps = self.step.max(1) as f64;
        let converge = match self.last_above {
            None => 0.0,
            Some(s) if s == self.step => f32::INFINITY,
            Some(s) => (s + 1) as f32 * self.dt,
        };
        let seconds = (self.step as f32 * self.dt).max(self.dt);
        out[0] = self.error;
        out[1] = (self.error_sq_sum / steps).sqrt() as f32;
        out[2] = converge;
        out[3] = self.messages as f32 / (self.n as f32 * seconds);
    }

    /// Agent `i` drives robot `i`.
    fn observe(&self, world: &World, _cfg: &Scenario, agent: usize, out: &mut ObsWriter) {
        let (n, i) = (self.n, agent);
        for j in (0..n).filter(|&j| j != i) {
            match self.inbox[i * n + j].filter(|_| self.linked(i, j)) {
                Some(m) => {
                    let p = nav::to_robot_frame(
                        world,
                        i,
                        m.position - self.offsets[j] + self.offsets[i],
                    );
                    out.put(p.x);
                    out.put(p.y);
                    out.put(((self.step - m.sent) as f32 * self.dt).min(MAX_AGE));
                    out.put(1.0);
                }
                None => {
                    for _ in 0..SLOT {
                        out.put(0.0);
                    }
                }
            }
        }
        let drift = nav::to_robot_frame(world, i, self.sent[i].position);
        out.put(drift.x);
        out.put(drift.y);
        for w in nav::wheel_obs(world, i) {
            out.put(w);
        }
    }

    /// None: the robots agree on a point they find themselves.
    fn goals(&self) -> Vec<Vector> {
        Vec::new()
    }

    /// Each robot's last broadcast position.
    fn targets(&self, _world: &World) -> Vec<Vector> {
        self.sent.iter().map(|m| m.position).collect()
    }

    fn fits(&self, twin: &Self) -> bool {
        self.n == twin.n && self.links.len() == twin.links.len()
    }

    /// The graph's links now (grey) and each robot's last broadcast (a cross of its colour).
    fn draw(&self, world: &World, _cfg: &Scenario, marks: &mut Vec<Mark>) {
        for i in 0..self.n {
            for j in i + 1..self.n {
                if self.linked(i, j) {
                    marks.push(Mark::Ray {
                        from: world.robots[i].position,
                        to: world.robots[j].position,
                        colour: [120, 120, 120],
                        alpha: 140,
                        width: 0.006,
                    });
                }
            }
        }
        for (i, m) in self.sent.iter().enumerate() {
            marks.push(Mark::Cross {
                position: m.position,
                size: 0.03,
                colour: PALETTE[i % PALETTE.len()],
            });
        }
    }
}
