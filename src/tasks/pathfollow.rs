//! KheperaIV-PathFollow: path following, geometry with no clock (the KH4VREP paper's abstract
//! names it; the definitions are docs/task-design.md §4). The robot must drive along a closed
//! path (circle, lemniscate, square, random spline, or the scenario's points) at about the
//! desired speed v_d and complete one lap; unlike tracking, being late costs nothing but time.
//!
//! Reset: the direction of travel and a spline are drawn (as the tracking task's), the start
//! point uniformly over the path (`random_start`), and the robot placed up to `start_offset`
//! to either side of it, heading up to `start_heading_offset` from the path's tangent, at rest.
//! With `obstacle_count` > 0, cylinders are placed near the path over the lap ahead, each up to
//! `obstacle_offset` to either side of it.
//!
//! After each step (true pose; [`geometry`] tracks the closest point p_c): cross-track error
//! d = (p − p_c)·n, left of the path positive; progress Δs = arc length travelled by p_c (m,
//! negative when going backwards). Reward per step: `progress_weight·Δs − error_weight·|d| −
//! time_penalty − speed_weight·max(0, Δs/dt − v_d)/v_d − collision_penalty·[in contact]`. Over
//! a lap the progress terms sum to `progress_weight`·length whatever the speed, so the time
//! penalty favours fast laps and the speed term slow ones: a lap at v ≥ v_d costs
//! (length/dt)·(speed_weight/v_d − (speed_weight − time_penalty)/v), least at v = v_d. A
//! two-sided speed term would also cost standing still, making early loss (termination) the
//! cheapest start for a learner. Terminated as a success once the progress
//! sums to one lap; as lost when |d| > `lost_distance`; truncated after `truncation_factor` ×
//! length / v_d (or `task.max_steps` if sooner).
//!
//! Observation (robot frame x forward, y left; from the believed pose, as Nav's): the observed
//! sensors' blocks, `cross_track_error` (d, m), `path_heading_error` (sin, cos of θ_p − θ),
//! `curvature` (κ at p_c and at each preview point, 1/m, left turns positive), `preview` (the
//! path points every `preview_spacing` m of arc ahead of p_c, robot frame, m), `waypoint` (the
//! current waypoint, robot frame, m: waypoints lie every `waypoint_spacing` m of arc from the
//! start; the next one is shown once the robot is within `waypoint_radius` of it or p_c has
//! passed it, the way the paper's scripts chain position-control targets), `desired_speed`
//! (v_d / max wheel speed), `wheel_speeds`. Extra statistics: `path_error_rms`,
//! `path_error_max` (|d|, m, after the first `transient` s), `path_iae` (Σ|d|·dt, m·s) and
//! `path_converge_time` (s: when |d| fell below `converge_radius` for good; infinite if above
//! at the end). Lap time and mean speed follow from the common statistics.

pub mod config;
pub mod geometry;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use super::error_stats::ErrorStats;
use super::nav;
use super::reference::{random_spline, Shape};
use super::{Agent, AgentFacts, Body, Scoring, Task, TaskInfo};
use crate::config::ConfigTable;
use crate::draw::Mark;
use crate::error::Result;
use crate::geometry::scene::SceneShape;
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::robot::wrap_angle;
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::world::layout::{Layout, Spawn};
use crate::world::World;
use config::{check_section, START_CLEARANCE};
pub use config::{PathFollowConfig, MAX_PREVIEW_POINTS};
use geometry::{Path, PathPoint};

/// Largest |κ| observed (1/m): a turn about one wheel, 2 / axle (19 1/m); sharper turns need a
/// wheel to run backwards.
pub const CURVATURE_BOUND: f32 = 2.0 / crate::robot::AXLE_LENGTH;

/// Draws of an obstacle's place before it is left out (it would touch the robot's start).
const OBSTACLE_TRIES: usize = 8;

/// KheperaIV-PathFollow: the shared defaults and the `[pathfollow]` table.
pub const PATHFOLLOW: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-PathFollow"),
    summary: "path following: drive one lap along a closed path (circle, lemniscate, square, \
              random spline) at a desired speed, with no clock; the robot starts off the path",
    schema: TaskSchema {
        name: "pathfollow",
        since: 1, // added with the real robot's dynamics; v0 means the paper's older ones
        defaults: r#"
[task]
max_steps = 4000             # cap only: the episode is truncated after pathfollow.truncation_factor laps at the desired speed (circle 1006 steps)
"#,
        section: Some(Section {
            name: "pathfollow",
            keys: PathFollowConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring {
        success: Some("lap"),
        time: "lap time",
        error_prefix: Some("path"),
        error: "cross-track error",
        termination: Some("lost"),
        path_trace: true,
        ..Scoring::GOAL
    },
    agents: AgentFacts::ONE,
};

/// Per-world state of the path-following task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct PathFollow {
    cfg: PathFollowConfig,
    /// This episode's path.
    pub path: Path,
    dt: f32,
    steps: u32,
    max_steps: u32,
    /// Phase of the closest path point to the robot's true and believed positions.
    phase: f64,
    believed_phase: f64,
    /// Arc length travelled by the closest point since the start (m).
    pub progress: f64,
    /// Cross-track error after the last step (m, signed).
    pub cross_track: f32,
    /// Phase and arc position (m from the start) of the current waypoint.
    waypoint_phase: f64,
    /// The current waypoint's position (m), kept with its phase.
    waypoint_at: Vector,
    waypoint_along: f64,
    stats: ErrorStats,
}

impl PathFollow {
    /// Its own observation blocks (after the sensors'): cross_track_error, path_heading_error,
    /// curvature, preview (when previewing), waypoint, desired_speed, wheel_speeds.
    pub fn blocks(cfg: &Scenario, pf: &PathFollowConfig) -> ObsLayout {
        let reach = cfg.diagonal();
        let k = pf.preview_points as usize;
        let mut blocks = vec![
            Block::new("cross_track_error", 1, -reach, reach),
            Block::new("path_heading_error", 2, -1.0, 1.0),
            Block::new("curvature", 1 + k, -CURVATURE_BOUND, CURVATURE_BOUND),
        ];
        if k > 0 {
            blocks.push(Block::new("preview", 2 * k, -reach, reach));
        }
        blocks.extend([
            Block::new("waypoint", 2, -reach, reach),
            Block::new("desired_speed", 1, 0.0, 1.0),
            Block::new("wheel_speeds", 2, -1.0, 1.0),
        ]);
        ObsLayout::new(blocks)
    }

    /// The closest path point to the robot's true position.
    pub fn closest(&self) -> PathPoint {
        self.path.at(self.phase)
    }

    /// The current waypoint (m, world frame).
    pub fn waypoint(&self) -> Vector {
        self.waypoint_at
    }

    /// The previewed path points ahead of the closest point to `phase` (world frame).
    fn preview_from(&self, phase: f64) -> impl Iterator<Item = PathPoint> + '_ {
        let spacing = self.cfg.preview_spacing as f64;
        (0..self.cfg.preview_points).scan(phase, move |u, _| {
            *u = self.path.advance(*u, spacing);
            Some(self.path.at(*u))
        })
    }

    /// Moves the waypoint on while the robot (believed position `p`) is within the radius of it
    /// or the closest point has passed it.
    fn update_waypoint(&mut self, p: Vector) {
        let spacing = self.cfg.waypoint_spacing as f64;
        // At most one lap of waypoints per step.
        let most = (self.path.length / spacing).ceil() as usize + 1;
        for _ in 0..most {
            let reached = (self.waypoint() - p).length() < self.cfg.waypoint_radius;
            if !reached && self.progress < self.waypoint_along {
                break;
            }
            self.waypoint_phase = self.path.advance(self.waypoint_phase, spacing);
            self.waypoint_at = self.path.at(self.waypoint_phase).position;
            self.waypoint_along += spacing;
        }
    }

    /// Cylinders near the path over the lap ahead of the start at phase `start`, none touching
    /// the robot at `robot`.
    fn obstacles(
        &self,
        cfg: &Scenario,
        rng: &mut ChaCha8Rng,
        start: f64,
        robot: Vector,
    ) -> Vec<SceneShape> {
        let pf = &self.cfg;
        let n = pf.obstacle_count;
        let free = self.path.length - 2.0 * START_CLEARANCE as f64;
        let slot = free / n.max(1) as f64;
        let clear = cfg.robot.radius + pf.obstacle_radius + cfg.obstacles.spawn_clearance;
        let mut shapes = Vec::with_capacity(n as usize);
        for k in 0..n {
            for _ in 0..OBSTACLE_TRIES {
                // In the middle half of its slot of the lap, to either side of the path.
                let along =
                    START_CLEARANCE as f64 + slot * (k as f64 + 0.25 + 0.5 * rng.random::<f64>());
                let offset = pf.obstacle_offset * (2.0 * rng.random::<f32>() - 1.0);
                let c = self.path.at(self.path.advance(start, along));
                let normal = Vector::new(-c.heading.sin(), c.heading.cos());
                let centre = c.position + normal * offset;
                if (centre - robot).length() >= clear {
                    shapes.push(SceneShape::circle(centre, pf.obstacle_radius));
                    break;
                }
            }
        }
        shapes
    }
}

impl Task for PathFollow {
    const EXTRA_STATS: &'static [&'static str] = &[
        "path_error_rms",
        "path_error_max",
        "path_iae",
        "path_converge_time",
    ];

    fn new(cfg: &Scenario) -> Result<Self> {
        let pf: PathFollowConfig = cfg.own()?;
        let path = pf.base_path(1.0);
        Ok(Self {
            path,
            dt: cfg.physics.dt,
            steps: 0,
            max_steps: cfg.task.max_steps,
            phase: 0.0,
            believed_phase: 0.0,
            progress: 0.0,
            cross_track: 0.0,
            waypoint_phase: 0.0,
            waypoint_at: Vector::ZERO,
            waypoint_along: 0.0,
            stats: ErrorStats::default(),
            cfg: pf,
        })
    }

    fn spawn(_cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Single)
    }

    fn agents(cfg: &Scenario) -> Result<Vec<Agent>> {
        let pf: PathFollowConfig = cfg.own()?;
        Ok(vec![Agent {
            name: "robot".into(),
            body: Body::Robot(0),
            layout: Self::blocks(cfg, &pf),
        }])
    }

    /// Draws this episode's path, the robot's start beside it and the obstacles along it.
    fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, layout: &mut Layout) {
        let pf = self.cfg.clone();
        let direction = pf.direction.draw(rng);
        let mut path = pf.base_path(direction);
        if pf.path == Shape::Spline {
            let curve = random_spline(&path.curve, pf.spline_irregularity, rng, |curve| {
                pf.within_limits(&Path::new(curve.clone(), direction), cfg)
                    .is_ok()
            });
            path = Path::new(curve, direction);
        }
        self.path = path;
        let start = if pf.random_start {
            rng.random::<f64>()
        } else {
            0.0
        };
        let c = self.path.at(start);
        let offset = pf.start_offset * (2.0 * rng.random::<f32>() - 1.0);
        let heading = pf.start_heading_offset * (2.0 * rng.random::<f32>() - 1.0);
        let normal = Vector::new(-c.heading.sin(), c.heading.cos());
        let position = c.position + normal * offset;
        if let Some(pose) = layout.poses.first_mut() {
            *pose = (position, wrap_angle(c.heading + heading));
        }
        if pf.obstacle_count > 0 {
            let shapes = self.obstacles(cfg, rng, start, position);
            layout.obstacles.extend(shapes);
        }
        self.phase = start;
        let lap = pf.truncation_factor as f64 * self.path.length / pf.speed as f64;
        self.max_steps = super::episode_steps(cfg.task.max_steps, lap, self.dt);
    }

    fn reset(&mut self, world: &World, _layout: &Layout) {
        let robot = &world.robots[0];
        self.steps = 0;
        self.progress = 0.0;
        self.phase = self.path.project(robot.position, self.phase);
        self.believed_phase = self.phase;
        let c = self.closest();
        self.cross_track = self.path.cross_track(&c, robot.position);
        self.waypoint_phase = self
            .path
            .advance(self.phase, self.cfg.waypoint_spacing as f64);
        self.waypoint_at = self.path.at(self.waypoint_phase).position;
        self.waypoint_along = self.cfg.waypoint_spacing as f64;
        self.stats = ErrorStats::start(self.cross_track.abs(), self.cfg.converge_radius);
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
        let robot = &world.robots[0];
        let phase = self.path.project(robot.position, self.phase);
        let progress = self.path.progress(self.phase, phase);
        self.phase = phase;
        self.progress += progress;
        let (believed, _) = world.believed_pose(0);
        self.believed_phase = if believed == robot.position {
            phase
        } else {
            self.path.project(believed, self.believed_phase)
        };
        self.update_waypoint(believed);
        self.cross_track = self.path.cross_track(&self.closest(), robot.position);
        let error = self.cross_track.abs();
        let pf = &self.cfg;
        self.stats
            .record(error, self.steps, self.dt, pf.transient, pf.converge_radius);
        let contact = robot.in_contact as u8 as f32;
        let speeding = (progress as f32 / self.dt - pf.speed).max(0.0) / pf.speed;
        rewards[0] = pf.progress_weight * progress as f32
            - pf.error_weight * error
            - pf.time_penalty
            - pf.speed_weight * speeding
            - cfg.task.collision_penalty * contact;
        let lost = error > pf.lost_distance;
        let lap = self.progress >= self.path.length;
        terminated[0] = lost || lap;
        lap && !lost
    }

    fn extra_stats(&self, out: &mut [f32]) {
        self.stats.write(self.dt, out);
    }

    fn observe(&self, world: &World, cfg: &Scenario, _agent: usize, out: &mut ObsWriter) {
        let reach = cfg.diagonal();
        let (position, heading) = world.believed_pose(0);
        let c = self.path.at(self.believed_phase);
        let (d, path_heading) = self.path.frame(&c, position);
        out.put(d.clamp(-reach, reach));
        let heading_error = path_heading - heading;
        out.put(heading_error.sin());
        out.put(heading_error.cos());
        let bound = |k: f32| k.clamp(-CURVATURE_BOUND, CURVATURE_BOUND);
        out.put(bound(c.curvature));
        // The preview once (at most MAX_PREVIEW_POINTS points): curvatures, then positions.
        let mut preview = [c; MAX_PREVIEW_POINTS as usize];
        let n = self.cfg.preview_points as usize;
        for (slot, p) in preview
            .iter_mut()
            .zip(self.preview_from(self.believed_phase))
        {
            *slot = p;
        }
        for p in &preview[..n] {
            out.put(bound(p.curvature));
        }
        for p in &preview[..n] {
            let local = nav::to_robot_frame(world, 0, p.position);
            out.put(local.x.clamp(-reach, reach));
            out.put(local.y.clamp(-reach, reach));
        }
        let local = nav::to_robot_frame(world, 0, self.waypoint());
        out.put(local.x.clamp(-reach, reach));
        out.put(local.y.clamp(-reach, reach));
        out.put((self.cfg.speed / world.drive.max_wheel_speed).clamp(0.0, 1.0));
        let [l, r] = nav::wheel_obs(world, 0);
        out.put(l);
        out.put(r);
    }

    /// The current waypoint.
    fn goals(&self) -> Vec<Vector> {
        vec![self.waypoint()]
    }

    /// The closest path point and the previewed points.
    fn targets(&self, _world: &World) -> Vec<Vector> {
        std::iter::once(self.closest().position)
            .chain(self.preview_from(self.phase).map(|p| p.position))
            .collect()
    }

    fn fits(&self, twin: &Self) -> bool {
        self.cfg == twin.cfg
    }

    fn draw(&self, _world: &World, _cfg: &Scenario, marks: &mut Vec<Mark>) {
        const PATH_POINTS: usize = 240;
        let points = (0..PATH_POINTS)
            .map(|i| self.path.at(i as f64 / PATH_POINTS as f64).position)
            .collect();
        marks.push(Mark::Path {
            points,
            colour: [120, 120, 120],
            alpha: 160,
            width: 0.006,
            closed: true,
        });
        for p in self.preview_from(self.phase) {
            marks.push(Mark::Cross {
                position: p.position,
                size: 0.012,
                colour: [255, 127, 14],
            });
        }
        marks.push(Mark::Cross {
            position: self.closest().position,
            size: 0.02,
            colour: [120, 120, 120],
        });
        marks.push(Mark::Cross {
            position: self.waypoint(),
            size: 0.025,
            colour: [214, 39, 40],
        });
    }
}
