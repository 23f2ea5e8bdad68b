//! Platoon (PettingZoo `platoon_v1`): N robots track time-shifted copies of one reference
//! (issue 14, item 5). Robot k must be at p_r(t − k·τ) at time t, heading along the curve, where
//! p_r is a Track reference ([`reference`]: circle, lemniscate, square, spline or waypoints)
//! and τ = `platoon.time_gap`; so neighbours are τ·v_r apart along the curve (0.30 m by
//! default). One reference is drawn per episode (phase, direction, spline) as Track draws it.
//!
//! Agents `robot_0` .. `robot_{N-1}`, robot k driven by agent k, each with Track's observation
//! of its own reference (sensors' blocks, then [`Track::blocks`]: `tracking_error`,
//! `heading_error`, `reference_rates`, `preview`, `wheel_speeds`), so a tracking controller
//! runs on each agent's block unchanged, and Track's reward: `−error_weight·‖e_k‖ −
//! heading_weight·(1 − cos e_θk) − collision_penalty·[robot k in contact]`. The robots are
//! obstacles to one another: their discs block each other's rays, and rapier resolves their
//! contacts (a contact with a neighbour costs as one with a wall).
//!
//! Reset: each robot is placed up to `start_offset` from its own reference point at t = 0 with a
//! heading up to `start_heading_offset` from its reference heading, at rest, at least a diameter
//! plus `obstacles.spawn_clearance` from the robots placed before it (its start is drawn again
//! if not, up to [`START_TRIES`] times, then the whole platoon, up to [`PLATOON_TRIES`] times;
//! then every robot starts on its reference point, which the checks keep apart).
//!
//! End: an agent whose error exceeds `lost_distance` is terminated (lost) and parks (zero wheel
//! commands), still an obstacle; the episode terminates when every robot is lost and is
//! truncated after one period plus `truncation_margin`, as Track.
//!
//! Extra statistics, Track's four over the platoon, each robot's counted until it is lost:
//! `track_error_rms` (m: the root mean square of the robots' RMS errors after the transient,
//! each as Track computes it), `track_error_max` (m: the largest over robots), `track_iae`
//! (m·s: the sum of the robots' IAE) and `track_converge_time` (s: the latest robot's;
//! infinite if any robot is above `converge_radius` at the end or lost).
//!
//! Units: metres, seconds, radians; world frame, arena centred at the origin; observations in
//! each robot's frame (x forward, y left).

mod config;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use super::error_stats::ErrorStats;
use super::nav;
use super::reference::Reference;
use super::track::{draw_reference, Track};
use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::draw::{Mark, PALETTE};
use crate::error::Result;
use crate::obs::ObsWriter;
use crate::robot::wrap_angle;
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;
pub use config::{PlatoonConfig, PlatoonKeys, KEYS, MAX_ROBOTS, SPACING_MARGIN};

/// Draws of one robot's start before the platoon is drawn again.
pub const START_TRIES: usize = 64;

/// Platoons drawn at reset before every robot is put on its reference point.
pub const PLATOON_TRIES: usize = 16;

/// platoon: Track's defaults and the `[platoon]` table.
pub const PLATOON: TaskInfo = TaskInfo {
    env_id: None,
    summary: "a platoon: several robots track time-shifted copies of one reference \
              (platoon.time_gap apart), one agent each; they are obstacles to each other",
    schema: TaskSchema {
        name: "platoon",
        since: 1, // as Track: built on the real robot's dynamics
        defaults: r#"
[task]
max_steps = 4000             # cap only: the episode is truncated after one period + platoon.truncation_margin (circle 543 steps)
"#,
        section: Some(Section {
            name: "platoon",
            keys: &KEYS,
            check: config::check_section,
        }),
    },
    scoring: Scoring::GOAL,
    agents: AgentFacts {
        end_separately: true,
        ..AgentFacts::TEAM
    },
};

/// One robot's tracking: its reference posture now, error and statistics.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
struct Follower {
    /// Its reference posture now: position (m), heading (rad), v_r (m/s), ω_r (rad/s).
    now: [f32; 5],
    /// Position error after the last step (m).
    error: f32,
    /// Lost (terminated): its statistics stopped, its wheels get zero commands.
    lost: bool,
    /// Its error statistics, recorded until it is lost (Track's).
    stats: ErrorStats,
}

impl Follower {
    fn position(&self) -> Vector {
        Vector::new(self.now[0], self.now[1])
    }

    /// When its error fell below the radius for good (s); infinite if above it now or lost.
    fn converge_time(&self, dt: f32) -> f32 {
        if self.lost {
            f32::INFINITY
        } else {
            self.stats.converge_time(dt)
        }
    }
}

/// Per-world state of the platoon task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Platoon {
    cfg: PlatoonConfig,
    /// This episode's reference (robot 0's; robot k's is it delayed by k·time_gap).
    pub reference: Reference,
    dt: f32,
    steps: u32,
    max_steps: u32,
    robots: Vec<Follower>,
}

impl Platoon {
    /// Robot `k`'s reference time after `steps` control steps (s).
    fn time(&self, k: usize, steps: u32) -> f64 {
        steps as f64 * self.dt as f64 - self.cfg.lag(k)
    }

    fn set_now(&mut self) {
        for k in 0..self.robots.len() {
            let p = self.reference.at(self.time(k, self.steps));
            self.robots[k].now = [p.position.x, p.position.y, p.heading, p.speed, p.turn_rate];
        }
    }

    /// Each robot's reference point now (m, world frame).
    pub fn reference_points(&self) -> Vec<Vector> {
        self.robots.iter().map(Follower::position).collect()
    }

    /// Robot `k`'s preview points (m, world frame).
    fn preview(&self, k: usize) -> impl Iterator<Item = Vector> + '_ {
        let t = self.time(k, self.steps);
        let c = &self.cfg.track;
        (1..=c.preview_points).map(move |j| {
            self.reference
                .at(t + j as f64 * c.preview_step as f64)
                .position
        })
    }

    /// Start poses: each robot near its own reference point, apart from those before it.
    fn starts(&self, cfg: &Scenario, rng: &mut ChaCha8Rng) -> Vec<(Vector, f32)> {
        let c = &self.cfg.track;
        let apart = 2.0 * cfg.robot.radius + cfg.obstacles.spawn_clearance;
        let references: Vec<_> = (0..self.robots.len())
            .map(|k| self.reference.at(-self.cfg.lag(k)))
            .collect();
        'platoon: for _ in 0..PLATOON_TRIES {
            let mut poses: Vec<(Vector, f32)> = Vec::with_capacity(references.len());
            for r in &references {
                let mut start = None;
                for _ in 0..START_TRIES {
                    let distance = c.start_offset * rng.random::<f32>();
                    let bearing = rng.random::<f32>() * std::f32::consts::TAU;
                    let heading = c.start_heading_offset * (2.0 * rng.random::<f32>() - 1.0);
                    let offset = Vector::new(bearing.cos(), bearing.sin()) * distance;
                    let position = r.position + offset;
                    if poses.iter().all(|(p, _)| (*p - position).length() >= apart) {
                        start = Some((position, wrap_angle(r.heading + heading)));
                        break;
                    }
                }
                match start {
                    Some(pose) => poses.push(pose),
                    None => continue 'platoon,
                }
            }
            return poses;
        }
        references.iter().map(|r| (r.position, r.heading)).collect()
    }
}

impl Task for Platoon {
    const EXTRA_STATS: &'static [&'static str] = &[
        "track_error_rms",
        "track_error_max",
        "track_iae",
        "track_converge_time",
    ];

    fn new(cfg: &Scenario) -> Result<Self> {
        let table: toml::Table = cfg.own()?;
        let platoon = PlatoonConfig::from_table(&table, &cfg.origin)?;
        let mut state = Self {
            reference: platoon.track.base_reference(0.0, 1.0),
            dt: cfg.physics.dt,
            steps: 0,
            max_steps: cfg.task.max_steps,
            robots: vec![Follower::default(); platoon.n_robots()],
            cfg: platoon,
        };
        state.set_now();
        Ok(state)
    }

    fn spawn(cfg: &Scenario) -> Result<Spawn> {
        let table: toml::Table = cfg.own()?;
        let platoon = PlatoonConfig::from_table(&table, &cfg.origin)?;
        // Drawn by the spawner, then replaced in `arrange`.
        Ok(Spawn::Multi(platoon.n_robots()))
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let table: toml::Table = cfg.own()?;
        let platoon = PlatoonConfig::from_table(&table, &cfg.origin)?;
        let layout = Track::blocks(cfg, &platoon.track);
        Ok((0..platoon.n_robots())
            .map(|k| Agent {
                name: format!("robot_{k}"),
                body: Body::Robot(k),
                layout: layout.clone(),
            })
            .collect())
    }

    /// Draws this episode's reference and the robots' starts relative to it.
    fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, layout: &mut Layout) {
        self.reference = draw_reference(&self.cfg.track, cfg, rng);
        let poses = self.starts(cfg, rng);
        for (slot, pose) in layout.poses.iter_mut().zip(poses) {
            *slot = pose;
        }
        let seconds = self.reference.period + self.cfg.track.truncation_margin as f64;
        self.max_steps = super::episode_steps(cfg.task.max_steps, seconds, self.dt);
    }

    fn reset(&mut self, world: &World, _layout: &Layout) {
        self.steps = 0;
        for f in &mut self.robots {
            *f = Follower::default();
        }
        self.set_now();
        let radius = self.cfg.track.converge_radius;
        for (f, robot) in self.robots.iter_mut().zip(&world.robots) {
            f.error = (f.position() - robot.position).length();
            f.stats = ErrorStats::start(f.error, radius);
        }
    }

    fn max_steps(&self, _cfg: &Scenario) -> u32 {
        self.max_steps
    }

    /// Lost robots get zero wheel commands (they park).
    fn before_step(&self, world: &mut World) {
        for (robot, f) in world.robots.iter_mut().zip(&self.robots) {
            if f.lost {
                robot.wheel_command = [0.0, 0.0];
            }
        }
    }

    fn judge(
        &mut self,
        world: &World,
        cfg: &Scenario,
        rewards: &mut [f32],
        terminated: &mut [bool],
    ) -> bool {
        self.steps = self.steps.saturating_add(1);
        self.set_now();
        let c = &self.cfg.track;
        for (k, (f, robot)) in self.robots.iter_mut().zip(&world.robots).enumerate() {
            if f.lost {
                rewards[k] = 0.0;
                terminated[k] = true;
                continue;
            }
            let error = (f.position() - robot.position).length();
            let heading_error = wrap_angle(f.now[2] - robot.heading);
            f.error = error;
            f.stats
                .record(error, self.steps, self.dt, c.transient, c.converge_radius);
            let contact = robot.in_contact as u8 as f32;
            rewards[k] = -c.error_weight * error
                - c.heading_weight * (1.0 - heading_error.cos())
                - cfg.task.collision_penalty * contact;
            f.lost = error > c.lost_distance;
            terminated[k] = f.lost;
        }
        false
    }

    fn extra_stats(&self, out: &mut [f32]) {
        let n = self.robots.len().max(1) as f64;
        let (mut square_sum, mut max, mut iae, mut converge) = (0.0, 0.0f32, 0.0, 0.0f32);
        for f in &self.robots {
            let (rms, error_max) = f.stats.rms_max();
            square_sum += rms * rms;
            max = max.max(error_max);
            iae += f.stats.iae();
            converge = converge.max(f.converge_time(self.dt));
        }
        out[0] = (square_sum / n).sqrt() as f32;
        out[1] = max;
        out[2] = iae as f32;
        out[3] = converge;
    }

    /// Agent `k` drives robot `k`.
    fn observe(&self, world: &World, cfg: &Scenario, agent: usize, out: &mut ObsWriter) {
        let reach = cfg.diagonal();
        let vmax = world.drive.max_wheel_speed;
        let wmax = world.drive.max_yaw_rate();
        let (k, f) = (agent, &self.robots[agent]);
        let local = nav::to_robot_frame(world, k, f.position());
        out.put(local.x.clamp(-reach, reach));
        out.put(local.y.clamp(-reach, reach));
        let heading_error = f.now[2] - world.believed_pose(k).1;
        out.put(heading_error.sin());
        out.put(heading_error.cos());
        out.put((f.now[3] / vmax).clamp(-1.0, 1.0));
        out.put((f.now[4] / wmax).clamp(-1.0, 1.0));
        for point in self.preview(k) {
            let local = nav::to_robot_frame(world, k, point);
            out.put(local.x.clamp(-reach, reach));
            out.put(local.y.clamp(-reach, reach));
        }
        let [l, r] = nav::wheel_obs(world, k);
        out.put(l);
        out.put(r);
    }

    /// Each robot's reference point.
    fn goals(&self) -> Vec<Vector> {
        self.reference_points()
    }

    /// Each robot's preview points, robot by robot.
    fn targets(&self, _world: &World) -> Vec<Vector> {
        (0..self.robots.len())
            .flat_map(|k| self.preview(k))
            .collect()
    }

    fn fits(&self, twin: &Self) -> bool {
        self.cfg == twin.cfg && self.robots.len() == twin.robots.len()
    }

    fn draw(&self, _world: &World, _cfg: &Scenario, marks: &mut Vec<Mark>) {
        const PATH_POINTS: usize = 240;
        let period = self.reference.period;
        let points = (0..PATH_POINTS)
            .map(|i| {
                let t = i as f64 * period / PATH_POINTS as f64;
                self.reference.at(t).position
            })
            .collect();
        marks.push(Mark::Path {
            points,
            colour: [120, 120, 120],
            alpha: 160,
            width: 0.006,
            closed: true,
        });
        for (k, f) in self.robots.iter().enumerate() {
            marks.push(Mark::Cross {
                position: f.position(),
                size: 0.025,
                colour: PALETTE[k % 8],
            });
        }
    }
}
