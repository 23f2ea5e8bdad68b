//! KheperaIV-Track: trajectory tracking, the reference given in time (the KH4VREP paper's
//! abstract names it; the definitions are docs/task-design.md §3). The robot must be at p_r(t) at
//! time t, heading along the reference, on a closed curve ([`reference`]: circle, lemniscate,
//! square or a random spline) travelled once per period T = length / `track.speed`.
//!
//! Reset: the reference's phase and direction are drawn (`random_phase`, `direction`), a spline
//! drawn from the world's stream, and the robot placed up to `start_offset` from p_r(0) with a
//! heading up to `start_heading_offset` from θ_r(0), at rest.
//!
//! Error after each step (true pose): e = R(θ)ᵀ(p_r − p) = (e_x, e_y) in the robot frame,
//! e_θ = θ_r − θ wrapped. Reward per step: `−error_weight·‖e‖ − heading_weight·(1 − cos e_θ)
//!  − collision_penalty·[in contact]`. Terminated (lost, not a success) when ‖e‖ >
//! `lost_distance`; truncated after one period plus `truncation_margin` (or `task.max_steps`
//! if sooner).
//!
//! Observation (robot frame x forward, y left; from the believed pose, as Nav's): the observed
//! sensors' blocks, `tracking_error` (e_x, e_y, m), `heading_error` (sin e_θ, cos e_θ),
//! `reference_rates` (v_r / max wheel speed, ω_r / max yaw rate), `preview` (the next
//! `preview_points` reference points, every `preview_step` s, in the robot frame, m),
//! `wheel_speeds`. Extra statistics: `track_error_rms`, `track_error_max` (m, after the first
//! `transient` s), `track_iae` (Σ‖e‖·dt, m·s) and `track_converge_time` (s: when ‖e‖ fell below
//! `converge_radius` for good; infinite if it is above at the end). An episode that ends within
//! the transient (lost) has its RMS and maximum over every step.

mod config;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use super::error_stats::ErrorStats;
use super::nav;
use super::reference::{random_spline, Posture, Reference, Shape};
use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::config::ConfigTable;
use crate::draw::Mark;
use crate::error::Result;
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::robot::wrap_angle;
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;
use config::check_section;
pub use config::{Direction, TrackConfig, MAX_PREVIEW_POINTS};

/// KheperaIV-Track: the shared defaults and the `[track]` table.
pub const TRACK: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-Track"),
    summary: "trajectory tracking: follow a reference point moving on a closed curve (circle, \
              lemniscate, square, random spline) in time; the robot starts off the reference",
    schema: TaskSchema {
        name: "track",
        since: 1, // added with the real robot's dynamics; v0 means the paper's older ones
        defaults: r#"
[task]
max_steps = 4000             # cap only: the episode is truncated after one period + track.truncation_margin (circle 543 steps)
"#,
        section: Some(Section {
            name: "track",
            keys: TrackConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring {
        success: None,
        error_prefix: Some("track"),
        error: "tracking error",
        termination: Some("lost"),
        moving_reference: true,
        ..Scoring::GOAL
    },
    agents: AgentFacts::ONE,
};

/// Per-world state of the tracking task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Track {
    cfg: TrackConfig,
    /// This episode's reference.
    pub reference: Reference,
    dt: f32,
    steps: u32,
    max_steps: u32,
    /// The reference posture now: position (m), heading (rad), v_r (m/s), ω_r (rad/s).
    now: [f32; 5],
    /// Position error after the last step (m).
    pub error: f32,
    stats: ErrorStats,
}

impl Track {
    /// The reference posture at `steps` control steps from the start.
    fn posture(&self, steps: u32) -> Posture {
        self.reference.at(steps as f64 * self.dt as f64)
    }

    fn set_now(&mut self) {
        let p = self.posture(self.steps);
        self.now = [p.position.x, p.position.y, p.heading, p.speed, p.turn_rate];
    }

    /// The reference point now (m, world frame).
    pub fn reference_point(&self) -> Vector {
        Vector::new(self.now[0], self.now[1])
    }

    /// The reference's preview points (m, world frame).
    pub fn preview(&self) -> impl Iterator<Item = Vector> + '_ {
        let t = self.steps as f64 * self.dt as f64;
        (1..=self.cfg.preview_points).map(move |j| {
            self.reference
                .at(t + j as f64 * self.cfg.preview_step as f64)
                .position
        })
    }

    /// Its own observation blocks (after the sensors'): tracking_error, heading_error,
    /// reference_rates, preview (when previewing), wheel_speeds.
    pub fn blocks(cfg: &Scenario, track: &TrackConfig) -> ObsLayout {
        let reach = cfg.diagonal();
        let mut blocks = vec![
            Block::new("tracking_error", 2, -reach, reach),
            Block::new("heading_error", 2, -1.0, 1.0),
            Block::new("reference_rates", 2, -1.0, 1.0),
        ];
        if track.preview_points > 0 {
            blocks.push(Block::new(
                "preview",
                2 * track.preview_points as usize,
                -reach,
                reach,
            ));
        }
        blocks.push(Block::new("wheel_speeds", 2, -1.0, 1.0));
        ObsLayout::new(blocks)
    }
}

impl Task for Track {
    const EXTRA_STATS: &'static [&'static str] = &[
        "track_error_rms",
        "track_error_max",
        "track_iae",
        "track_converge_time",
    ];

    fn new(cfg: &Scenario) -> Result<Self> {
        let track: TrackConfig = cfg.own()?;
        let reference = track.base_reference(0.0, 1.0);
        let mut state = Self {
            reference,
            dt: cfg.physics.dt,
            steps: 0,
            max_steps: cfg.task.max_steps,
            now: [0.0; 5],
            error: 0.0,
            stats: ErrorStats::default(),
            cfg: track,
        };
        state.set_now();
        Ok(state)
    }

    fn spawn(_cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Single)
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let track: TrackConfig = cfg.own()?;
        Ok(vec![Agent {
            name: "robot".into(),
            body: Body::Robot(0),
            layout: Self::blocks(cfg, &track),
        }])
    }

    /// Draws this episode's reference and the robot's start relative to it.
    fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, layout: &mut Layout) {
        let c = self.cfg.clone();
        let reference = draw_reference(&c, cfg, rng);
        let start = reference.at(0.0);
        let seconds = reference.period + c.truncation_margin as f64;
        self.reference = reference;
        let distance = c.start_offset * rng.random::<f32>();
        let bearing = rng.random::<f32>() * std::f32::consts::TAU;
        let heading = c.start_heading_offset * (2.0 * rng.random::<f32>() - 1.0);
        let position = start.position + Vector::new(bearing.cos(), bearing.sin()) * distance;
        if let Some(pose) = layout.poses.first_mut() {
            *pose = (position, wrap_angle(start.heading + heading));
        }
        self.max_steps = super::episode_steps(cfg.task.max_steps, seconds, self.dt);
    }

    fn reset(&mut self, world: &World, _layout: &Layout) {
        self.steps = 0;
        self.set_now();
        self.error = (self.reference_point() - world.robots[0].position).length();
        self.stats = ErrorStats::start(self.error, self.cfg.converge_radius);
    }

    fn max_steps(&self, _cfg: &Scenario) -> u32 {
        self.max_steps
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
        let robot = &world.robots[0];
        let error = (self.reference_point() - robot.position).length();
        let heading_error = wrap_angle(self.now[2] - robot.heading);
        let track = &self.cfg;
        self.error = error;
        self.stats.record(
            error,
            self.steps,
            self.dt,
            track.transient,
            track.converge_radius,
        );
        let contact = robot.in_contact as u8 as f32;
        rewards[0] = -track.error_weight * error
            - track.heading_weight * (1.0 - heading_error.cos())
            - cfg.task.collision_penalty * contact;
        terminated[0] = error > track.lost_distance;
        false
    }

    fn extra_stats(&self, out: &mut [f32]) {
        self.stats.write(self.dt, out);
    }

    fn observe(&self, world: &World, cfg: &Scenario, _agent: usize, out: &mut ObsWriter) {
        let reach = cfg.diagonal();
        let local = nav::to_robot_frame(world, 0, self.reference_point());
        out.put(local.x.clamp(-reach, reach));
        out.put(local.y.clamp(-reach, reach));
        let heading_error = self.now[2] - world.believed_pose(0).1;
        out.put(heading_error.sin());
        out.put(heading_error.cos());
        out.put((self.now[3] / world.drive.max_wheel_speed).clamp(-1.0, 1.0));
        out.put((self.now[4] / world.drive.max_yaw_rate()).clamp(-1.0, 1.0));
        for point in self.preview() {
            let local = nav::to_robot_frame(world, 0, point);
            out.put(local.x.clamp(-reach, reach));
            out.put(local.y.clamp(-reach, reach));
        }
        let [l, r] = nav::wheel_obs(world, 0);
        out.put(l);
        out.put(r);
    }

    fn goals(&self) -> Vec<Vector> {
        vec![self.reference_point()]
    }

    fn targets(&self, _world: &World) -> Vec<Vector> {
        self.preview().collect()
    }

    fn fits(&self, twin: &Self) -> bool {
        self.cfg == twin.cfg
    }

    fn draw(&self, _world: &World, _cfg: &Scenario, marks: &mut Vec<Mark>) {
        const PATH_POINTS: usize = 240;
        let period = self.reference.period;
        let points = (0..PATH_POINTS)
            .map(|i| {
                self.reference
                    .at(i as f64 * period / PATH_POINTS as f64)
                    .position
            })
            .collect();
        marks.push(Mark::Path {
            points,
            colour: [120, 120, 120],
            alpha: 160,
            width: 0.006,
            closed: true,
        });
        for point in self.preview() {
            marks.push(Mark::Cross {
                position: point,
                size: 0.012,
                colour: [255, 127, 14],
            });
        }
        marks.push(Mark::Cross {
            position: self.reference_point(),
            size: 0.025,
            colour: [214, 39, 40],
        });
    }
}

/// This episode's reference for `c`, drawn from the world's stream: its phase
/// (`random_phase`), direction, and a spline's harmonics, shrunk toward its mean circle (at most
/// [`super::reference::SPLINE_SHRINKS`] times) until it fits the robot's limits. Shared with the platoon task,
/// which draws one reference for all its robots.
pub(crate) fn draw_reference(c: &TrackConfig, cfg: &Scenario, rng: &mut ChaCha8Rng) -> Reference {
    let phase = if c.random_phase {
        rng.random::<f64>()
    } else {
        0.0
    };
    let direction = c.direction.draw(rng);
    let mut reference = c.base_reference(phase, direction);
    if c.reference == Shape::Spline {
        let curve = random_spline(&reference.curve, c.spline_irregularity, rng, |curve| {
            let candidate = Reference::new(curve.clone(), c.speed, phase, direction);
            c.within_limits(&candidate, cfg).is_ok()
        });
        reference = Reference::new(curve, c.speed, phase, direction);
    }
    reference
}
