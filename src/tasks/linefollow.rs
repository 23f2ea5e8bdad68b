//! KheperaIV-LineFollow: follow a black line on a white floor with the four ground sensors
//! (issue 15; docs/task-design.md §5.2). One closed line per episode, `linefollow.width` wide
//! (2.7 cm: K-Team's demo asks for a line at least 2.7 cm wide, docs/robot.md §4), drawn on the
//! floor (the world's [`FloorMarks`]) along a closed curve: a circle, a figure eight (Gerono's
//! lemniscate, which crosses itself), a square with sharp corners, a random smooth closed
//! spline per seed (the curves of the tracking tasks, `reference.rs`), or the scenario's own
//! line through its `points` (`track = "waypoints"`). The robot starts on the
//! line, heading along it up to `start_heading_offset` (±10°: a front sensor starts over the
//! line) off, at rest.
//!
//! Observation (no pose, no goal, no cross-track error): the observed sensors' blocks (by
//! default IR and the ground sensors, raw / 1023) and the wheel speeds. Ground truth is used for
//! the reward and the statistics only: the closest line point p_c is tracked along the curve as
//! in PathFollow ([`Path`]); Δs its progress (m) and d the signed offset.
//!
//! Reward per step: `progress_weight`·Δs − `error_weight`·|d| − `collision_penalty`·[contact].
//! Terminated as a success after one lap; as lost when no ground sensor has read black (below
//! K-Team's 800) for `lost_time` s and |d| > `lost_distance`; truncated after
//! `truncation_factor` × the lap time at `reference_speed` (0.061 m/s, the speed of K-Team's
//! demo), or `task.max_steps` if sooner. Extra statistics: `line_offset_rms` (|d|, m),
//! `on_line_share` (steps with a front ground sensor over black).
//!
//! Units: metres, seconds, radians; world frame.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;
use toml::Table;

use super::pathfollow::geometry::Path;
use super::reference::{random_spline, Curve, Shape};
use super::track::Direction;
use super::{Agent, AgentFacts, Body, Column, Scoring, Task, TaskInfo};
use crate::config::{limits, ConfigTable, Domain};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::geometry::floor::{polyline, Segment};
use crate::obs::{Block, ObsLayout, ObsWriter};
use crate::robot::wrap_angle;
use crate::scenario::{Scenario, Section, TaskSchema};
use crate::sensors::ground::KTEAM_BLACK_THRESHOLD;
use crate::world::layout::{Layout, Spawn};
use crate::world::World;

/// Spacing (m) of the points of the drawn line along its curve: chords within 0.1 mm of a
/// 0.3 m radius.
const DRAW_STEP: f64 = 0.01;

/// LineFollow: the task, its defaults and its table.
pub const LINEFOLLOW: TaskInfo = TaskInfo {
    env_id: Some("KheperaIV-LineFollow"),
    summary: "follow a closed black line on a white floor with the four ground sensors, one lap",
    schema: TaskSchema {
        name: "linefollow",
        since: 1,
        defaults: r#"
[sensors]
carry = ["ir", "us", "gyro", "ground"]  # the ground sensors see the line
observe = ["ir", "ground"]              # no sonars, no pose: what a line follower reads

[task]
max_steps = 4000             # cap; truncation is truncation_factor laps at reference_speed
"#,
        section: Some(Section {
            name: "linefollow",
            keys: LineFollowConfig::KEYS,
            check: check_section,
        }),
    },
    scoring: Scoring {
        success: Some("lap"),
        time: "lap time",
        termination: Some("lost"),
        columns: &[
            Column {
                stat: "on_line_share",
                header: "on line %",
                scale: 100.0,
                digits: 1,
            },
            Column {
                stat: "line_offset_rms",
                header: "offset RMS mm",
                scale: 1000.0,
                digits: 1,
            },
        ],
        ..Scoring::GOAL
    },
    agents: AgentFacts::ONE,
};

/// Most points of a scenario's own line (`linefollow.points`).
pub const MAX_LINE_POINTS: usize = 1024;

crate::config_table! {
    /// `[linefollow]`: the line and the episode.
    pub struct LineFollowConfig {
        /// circle, lemniscate (a figure eight), square (sharp corners), spline (random per seed) or waypoints (the points below)
        track: Shape = "circle",
        /// m: radius, half-width, half-side, or the spline's largest radius
        size: f32 = 0.6 => Domain::at_least(0.1).at_most(limits::LENGTH),
        /// m, the line's width [C: K-Team's demo needs at least 2.7 cm, robot.md §4]
        width: f32 = 0.027 => Domain::range(0.005, 0.2),
        /// grey level of the line, 0 black .. 1 white (black tape)
        grey: f32 = 0.0 => Domain::UNIT,
        /// random, ccw (the curve's own) or cw
        direction: Direction = "random",
        /// spline: its harmonics' amplitudes, 0..0.5 [E]
        spline_irregularity: f32 = 0.3 => Domain::range(0.0, 0.5),
        /// rad, largest start heading error from the line's (10 deg): a front ground sensor then starts over the line (62 mm x tan 10 deg = 11 mm < 10 + 13.5 mm) [D; docs/task-design.md §5.2 proposed 30 deg]
        start_heading_offset: f32 = 0.1745 => Domain::range(0.0, std::f64::consts::PI),
        /// s without any ground sensor over black before the robot may be lost
        lost_time: f32 = 1.0 => Domain::POSITIVE.at_most(limits::TIME),
        /// m, the robot is lost only this far from the line [E: docs/task-design.md §5.2]
        lost_distance: f32 = 0.1 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// reward per metre of progress along the line
        progress_weight: f32 = 10.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward per metre of distance from the line
        error_weight: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// m/s, the speed of K-Team's demo (90 units of 0.678 mm/s) that sets the truncation
        reference_speed: f32 = 0.061 => Domain::POSITIVE.at_most(limits::SPEED),
        /// laps at reference_speed before truncation
        truncation_factor: f32 = 2.0 => Domain::POSITIVE.at_most(1.0e6),
        /// track = "waypoints": the scenario's own line, a smooth closed curve through [[x, y], ...] (m), the last point repeating the first
        points: Vec<[f32; 2]> = [] => Domain::range(-limits::LENGTH, limits::LENGTH).at_most_entries(MAX_LINE_POINTS),
    }
}

fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    let lf = LineFollowConfig::from_table(table, origin, "linefollow")?;
    let bad =
        |key: &str, msg: String| Err(Error::config(origin, &format!("linefollow.{key}"), msg));
    let limit = 0.5 * scenario.arena.width.min(scenario.arena.height) - scenario.robot.radius;
    if lf.track == Shape::Waypoints {
        let p = &lf.points;
        let closed = p.len() >= 5 && p.first() == p.last();
        let apart = p
            .windows(2)
            .all(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) > 0.001);
        if !closed || !apart || p.iter().flatten().any(|v| !v.is_finite()) {
            return bad(
                "points",
                "track = \"waypoints\" needs at least 4 finite points [x, y], 1 mm apart or \
                 more, and the first repeated last (a closed line)"
                    .into(),
            );
        }
        let half = (0.5 * scenario.arena.width, 0.5 * scenario.arena.height);
        let line = LineFollow::waypoint_curve(p);
        let e = extent_xy(&line);
        if e[0] > half.0 - scenario.robot.radius || e[1] > half.1 - scenario.robot.radius {
            return bad(
                "points",
                "the line through them leaves the arena (less the robot's radius)".into(),
            );
        }
    } else if !lf.points.is_empty() {
        return bad("points", "are only for track = \"waypoints\"".into());
    }
    if lf.size > limit {
        return bad(
            "size",
            format!(
                "must be in [0.1, {limit:.3}] m to keep the robot inside the arena, got {}",
                lf.size
            ),
        );
    }
    if !scenario.sensors.carry.iter().any(|s| s == "ground") {
        return Err(Error::config(
            origin,
            "sensors.carry",
            "line following needs the ground sensors: add \"ground\"",
        ));
    }
    Ok(())
}

/// The largest |x| and |y| of a curve (m), from 720 samples.
fn extent_xy(curve: &Curve) -> [f32; 2] {
    (0..720).fold([0.0f32; 2], |e, k| {
        let [p, _, _] = curve.eval(k as f64 / 720.0);
        [e[0].max(p[0].abs() as f32), e[1].max(p[1].abs() as f32)]
    })
}

/// The largest |x| or |y| of a curve (m).
fn extent(curve: &Curve) -> f32 {
    let [x, y] = extent_xy(curve);
    x.max(y)
}

/// Per-world state of the line-following task.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LineFollow {
    cfg: LineFollowConfig,
    /// This episode's line, as a path.
    pub path: Path,
    /// Phase of the closest line point.
    pub phase: f64,
    /// Progress along the line so far (m).
    pub progress: f64,
    /// Signed offset from the line after the last step (m).
    pub offset: f32,
    dt: f32,
    max_steps: u32,
    unseen_for: f32,
    squares: f64,
    on_line: u32,
    steps: u32,
}

impl LineFollow {
    /// The smooth closed curve through a scenario's points, timed by the chord length so far
    /// (an even pace), as PathFollow's own paths.
    fn waypoint_curve(points: &[[f32; 2]]) -> Curve {
        let mut along = 0.0;
        let mut previous = points.first().copied().unwrap_or([0.0; 2]);
        let timed: Vec<[f32; 3]> = points
            .iter()
            .map(|p| {
                along += (p[0] - previous[0]).hypot(p[1] - previous[1]);
                previous = *p;
                [along, p[0], p[1]]
            })
            .collect();
        Curve::waypoints(&timed).0
    }

    fn base_curve(&self) -> Curve {
        match self.cfg.track {
            Shape::Waypoints => Self::waypoint_curve(&self.cfg.points),
            Shape::Spline => Curve::new(
                Shape::Spline,
                self.cfg.size / (1.0 + self.cfg.spline_irregularity),
            ),
            shape => Curve::new(shape, self.cfg.size),
        }
    }

    /// The line's segments along the path.
    fn segments(&self) -> Vec<Segment> {
        let n = (self.path.length / DRAW_STEP).ceil().max(8.0) as usize;
        let step = self.path.length / n as f64;
        let mut u = 0.0;
        let mut points = Vec::with_capacity(n);
        for _ in 0..n {
            points.push(self.path.at(u).position);
            u = self.path.advance(u, step);
        }
        // The square's corners, exactly (its phases 0, ¼, ½, ¾ are the corners).
        if self.cfg.track == Shape::Square {
            points = (0..4)
                .map(|k| self.path.at(0.25 * k as f64).position)
                .collect();
        }
        polyline(&points, true, self.cfg.width, self.cfg.grey)
    }
}

impl Task for LineFollow {
    const EXTRA_STATS: &'static [&'static str] = &["line_offset_rms", "on_line_share"];

    fn new(cfg: &Scenario) -> Result<Self> {
        let lf: LineFollowConfig = cfg.own()?;
        let mut task = Self {
            path: Path::new(Curve::new(Shape::Circle, lf.size), 1.0),
            cfg: lf,
            phase: 0.0,
            progress: 0.0,
            offset: 0.0,
            dt: cfg.physics.dt,
            max_steps: cfg.task.max_steps,
            unseen_for: 0.0,
            squares: 0.0,
            on_line: 0,
            steps: 0,
        };
        task.path = Path::new(task.base_curve(), 1.0);
        Ok(task)
    }

    fn spawn(_cfg: &Scenario) -> Result<Spawn> {
        Ok(Spawn::Single)
    }

    fn agents(_cfg: &Scenario) -> Result<Vec<Agent>> {
        Ok(vec![Agent {
            name: "robot".into(),
            body: Body::Robot(0),
            layout: ObsLayout::new(vec![Block::new("wheel_speeds", 2, -1.0, 1.0)]),
        }])
    }

    /// Draws the line (a spline per seed), the start point and heading; puts the line on the
    /// floor.
    fn arrange(&mut self, cfg: &Scenario, rng: &mut ChaCha8Rng, layout: &mut Layout) {
        let direction = self.cfg.direction.draw(rng);
        let base = self.base_curve();
        let curve = if self.cfg.track == Shape::Spline {
            let limit = 0.5 * cfg.arena.width.min(cfg.arena.height) - cfg.robot.radius;
            random_spline(&base, self.cfg.spline_irregularity, rng, |c| {
                extent(c) <= limit
            })
        } else {
            base
        };
        self.path = Path::new(curve, direction);
        let start: f64 = rng.random();
        let c = self.path.at(start);
        let heading = self.cfg.start_heading_offset * (2.0 * rng.random::<f32>() - 1.0);
        if let Some(pose) = layout.poses.first_mut() {
            *pose = (c.position, wrap_angle(c.heading + heading));
        }
        self.phase = start;
        let lap =
            self.cfg.truncation_factor as f64 * self.path.length / self.cfg.reference_speed as f64;
        self.max_steps = super::episode_steps(cfg.task.max_steps, lap, self.dt);
        layout.floor = self.segments();
    }

    fn reset(&mut self, world: &World, _layout: &Layout) {
        let p = world.robots[0].position;
        self.phase = self.path.project(p, self.phase);
        self.offset = self.path.cross_track(&self.path.at(self.phase), p);
        self.progress = 0.0;
        self.unseen_for = 0.0;
        self.squares = 0.0;
        self.on_line = 0;
        self.steps = 0;
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
        let robot = &world.robots[0];
        let phase = self.path.project(robot.position, self.phase);
        let progress = self.path.progress(self.phase, phase);
        self.phase = phase;
        self.progress += progress;
        self.offset = self.path.cross_track(&self.path.at(phase), robot.position);
        let raw = robot.readings.ground.raw;
        let black = |k: usize| raw[k] < KTEAM_BLACK_THRESHOLD;
        self.unseen_for = if (0..4).any(black) {
            0.0
        } else {
            self.unseen_for + self.dt
        };
        self.steps += 1;
        self.squares += f64::from(self.offset * self.offset);
        self.on_line += u32::from(black(1) || black(2));
        let contact = f32::from(u8::from(robot.in_contact));
        rewards[0] = self.cfg.progress_weight * progress as f32
            - self.cfg.error_weight * self.offset.abs()
            - cfg.task.collision_penalty * contact;
        let lost = self.unseen_for >= self.cfg.lost_time - 1e-4
            && self.offset.abs() > self.cfg.lost_distance;
        terminated[0] = lost;
        self.progress >= self.path.length
    }

    fn extra_stats(&self, out: &mut [f32]) {
        let n = f64::from(self.steps.max(1));
        out[0] = (self.squares / n).sqrt() as f32;
        out[1] = (f64::from(self.on_line) / n) as f32;
    }

    fn observe(&self, world: &World, _cfg: &Scenario, _agent: usize, out: &mut ObsWriter) {
        for w in super::nav::wheel_obs(world, 0) {
            out.put(w);
        }
    }

    fn goals(&self) -> Vec<Vector> {
        vec![self.path.at(self.phase).position]
    }

    fn fits(&self, twin: &Self) -> bool {
        self.cfg == twin.cfg
    }

    fn draw(&self, _world: &World, _cfg: &Scenario, marks: &mut Vec<Mark>) {
        marks.push(Mark::Cross {
            position: self.path.at(self.phase).position,
            size: 0.02,
            colour: [214, 39, 40],
        });
    }
}
