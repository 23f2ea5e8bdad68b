//! The `[pathfollow]` table of the path-following task: its keys (default, units, source) and
//! the checks that a path fits the arena and the robot's wheels at the desired speed, with
//! errors naming the key. Units: metres, seconds, radians, m/s.

use toml::Table;

use super::geometry::Path;
use crate::config::{limits, ConfigTable, Domain};
use crate::error::{Error, Result};
use crate::scenario::Scenario;
use crate::tasks::reference::{Curve, Shape};
use crate::tasks::track::Direction;

/// Most curvature preview points.
pub const MAX_PREVIEW_POINTS: u32 = 16;

/// Most points of a scenario's path.
pub const MAX_POINTS: usize = 1024;

/// Most obstacles on the path.
pub const MAX_PATH_OBSTACLES: u32 = 16;

/// How far the closing point may lie from the first (m).
const CLOSING_TOLERANCE: f32 = 1.0e-3;

/// Arc length kept free of obstacles ahead of and behind the robot's start (m).
pub const START_CLEARANCE: f32 = 0.3;

crate::config_table! {
    /// `[pathfollow]`: the path, desired speed, start, reward, end, statistics and obstacles.
    pub struct PathFollowConfig {
        /// circle, lemniscate (Gerono's figure eight), square (corners: the limit of smooth controllers), spline (a random smooth closed curve from the world's stream) or waypoints (the scenario's own, pathfollow.points)
        path: Shape = "circle",
        /// m: circle radius, lemniscate half-width A, square half-side, spline's largest possible radius [task-design.md §3-4: R = 0.6 m]
        size: f32 = 0.6 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m/s, desired speed v_d along the path, observed as desired_speed [task-design.md §4: 0.15 m/s]
        speed: f32 = 0.15 => Domain::POSITIVE.at_most(limits::SPEED),
        /// "random" (drawn each reset), "ccw" (the curve's own direction) or "cw" [task-design.md §3]
        direction: Direction = "random",
        /// start at a uniformly drawn point of the path; false: at phase 0 [task-design.md §3]
        random_start: bool = true,
        /// m, largest start cross-track offset from the path, drawn uniformly on either side [E]
        start_offset: f32 = 0.1 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// rad, largest start heading error from the path tangent (45 degrees), drawn uniformly [task-design.md §3]
        start_heading_offset: f32 = 0.7853982 => Domain::range(0.0, std::f64::consts::PI),
        /// spline: sum of the harmonics' relative amplitudes (k = 2, 3, 4), in [0, 0.5] [E]
        spline_irregularity: f32 = 0.3 => Domain::range(0.0, 0.5),
        /// at the desired speed the path's curvature asks the wheels for at most this fraction of robot.max_wheel_speed, speed * (1 + max|kappa| * axle / 2) [E]
        max_wheel_fraction: f32 = 0.5 => Domain::POSITIVE.at_most(1.0),
        /// m, terminated as lost beyond this cross-track error [task-design.md §4]
        lost_distance: f32 = 0.3 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// truncated after this many times the lap time at the desired speed, length / speed [task-design.md §4: 2]
        truncation_factor: f32 = 2.0 => Domain::POSITIVE.at_most(1.0e6),
        /// path points previewed ahead of the closest point (0..16), with their curvature [task-design.md §4: 3]
        preview_points: u32 = 3 => Domain::range(0.0, MAX_PREVIEW_POINTS as f64),
        /// m of arc between previewed points [task-design.md §4: 0.1 m]
        preview_spacing: f32 = 0.1 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// reward per metre of progress along the path [task-design.md §4]
        progress_weight: f32 = 10.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward per metre of cross-track error, every step [task-design.md §4]
        error_weight: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward lost every step [task-design.md §4]
        time_penalty: f32 = 0.01 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward lost per unit of relative speed above the desired one along the path, max(0, ds/dt - speed) / speed, every step: over a lap the progress reward is fixed, so any weight above time_penalty makes the desired speed the fastest worth driving (without it PPO laps at twice the speed; at 0.1 it did not learn to lap in 500k steps) [E]
        speed_weight: f32 = 0.02 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// s, start-up excluded from the RMS and maximum error statistics [task-design.md §3]
        transient: f32 = 5.0 => Domain::NON_NEGATIVE.at_most(limits::TIME),
        /// m, converged once the cross-track error stays below this [issue 14]
        converge_radius: f32 = 0.02 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m of arc between the waypoints of the waypoint block [E, as IR-SIM's sequential goals]
        waypoint_spacing: f32 = 0.2 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, the waypoint block moves to the next waypoint once the robot is this close [IR-SIM goal_threshold 0.1 m]
        waypoint_radius: f32 = 0.1 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// cylinders placed on or near the path at every reset, spread over the lap ahead of the start (0..16)
        obstacle_count: u32 = 0 => Domain::range(0.0, MAX_PATH_OBSTACLES as f64),
        /// m, their radius [E: obstacles.circle_radius's lower bound]
        obstacle_radius: f32 = 0.04 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, largest distance of their centres from the path, drawn uniformly on either side [E]
        obstacle_offset: f32 = 0.05 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// path = "waypoints": [[x, y], ...] (m), a closed loop (the last point repeats the first) joined by a smooth periodic curve through the points
        points: Vec<[f32; 2]> = [] => Domain::range(-limits::LENGTH, limits::LENGTH).at_most_entries(MAX_POINTS),
    }
}

impl PathFollowConfig {
    /// The path before any random draw, in `direction`: a spline's is its mean circle, of radius
    /// size / (1 + irregularity), so that its harmonics never take it beyond `size`.
    pub(crate) fn base_path(&self, direction: f64) -> Path {
        let curve = match self.path {
            Shape::Spline => {
                Curve::new(Shape::Spline, self.size / (1.0 + self.spline_irregularity))
            }
            Shape::Waypoints => Curve::waypoints(&self.timed_points()).0,
            shape => Curve::new(shape, self.size),
        };
        Path::new(curve, direction)
    }

    /// The scenario's points with the chord length travelled so far as their time: the curve
    /// then runs through them at a nearly even pace.
    fn timed_points(&self) -> Vec<[f32; 3]> {
        let mut along = 0.0;
        let mut previous = self.points.first().copied().unwrap_or([0.0; 2]);
        self.points
            .iter()
            .map(|p| {
                along += (p[0] - previous[0]).hypot(p[1] - previous[1]);
                previous = *p;
                [along, p[0], p[1]]
            })
            .collect()
    }

    /// Whether `path` is within the robot's wheels at the desired speed, else what it asks.
    pub(crate) fn within_limits(
        &self,
        path: &Path,
        cfg: &Scenario,
    ) -> std::result::Result<(), String> {
        let vmax = cfg.robot.max_wheel_speed.bounds().0;
        let axle = cfg.robot.axle_length.bounds().1;
        let kappa = path.max_curvature();
        let wheel = self.speed * (1.0 + 0.5 * kappa * axle);
        let cap = self.max_wheel_fraction * vmax;
        if wheel > cap {
            return Err(format!(
                "at {} m/s the path's curvature up to {kappa:.2} 1/m needs wheel speeds up to \
                 {wheel:.3} m/s, more than max_wheel_fraction x robot.max_wheel_speed = \
                 {cap:.3} m/s (too fast or too sharp for the robot)",
                self.speed
            ));
        }
        Ok(())
    }

    /// Checks `points` against `path`: present exactly for "waypoints", 4 to [`MAX_POINTS`],
    /// finite, distinct neighbours, the last point closing the loop.
    fn check_points(&self) -> std::result::Result<(), String> {
        let points = &self.points;
        if self.path != Shape::Waypoints {
            return match points.is_empty() {
                true => Ok(()),
                false => Err("points are given but pathfollow.path is not \"waypoints\"".into()),
            };
        }
        if points.len() < 4 || points.len() > MAX_POINTS {
            return Err(format!(
                "needs 4 to {MAX_POINTS} [x, y] points (3 distinct and the closing one), got {}",
                points.len()
            ));
        }
        if let Some(p) = points.iter().find(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(format!("every value must be finite, got {p:?}"));
        }
        if let Some(w) = points
            .windows(2)
            .find(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) < CLOSING_TOLERANCE)
        {
            return Err(format!(
                "neighbouring points must differ, got {:?} twice",
                w[0]
            ));
        }
        let (first, last) = (points[0], points[points.len() - 1]);
        if (first[0] - last[0]).hypot(first[1] - last[1]) > CLOSING_TOLERANCE {
            return Err(format!(
                "the last point must repeat the first (a closed loop): {last:?} vs {first:?}"
            ));
        }
        Ok(())
    }

    /// Checks the table against the scenario (each key alone is checked by its declaration):
    /// the points, the start within the lost distance, the path inside the arena and within
    /// the robot's limits, the obstacles along it; errors name `pathfollow.<key>`.
    fn validate(&self, origin: &str, cfg: &Scenario) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        if self.start_offset >= self.lost_distance {
            return bad(
                "pathfollow.start_offset",
                format!(
                    "must be less than pathfollow.lost_distance ({}), got {}",
                    self.lost_distance, self.start_offset
                ),
            );
        }
        if let Err(msg) = self.check_points() {
            return bad("pathfollow.points", msg);
        }
        let path = self.base_path(1.0);
        let shape_key = match self.path {
            Shape::Waypoints => "pathfollow.points",
            _ => "pathfollow.size",
        };
        // The path, the start offset and the robot's body inside the arena's margin.
        let (hx, hy) = (0.5 * cfg.arena.width, 0.5 * cfg.arena.height);
        let room = self
            .start_offset
            .max(self.obstacle_offset + self.obstacle_radius)
            + cfg.robot.radius
            + cfg.spawn.wall_margin;
        let [ex, ey] = match self.path {
            Shape::Lemniscate => [self.size, 0.5 * self.size],
            Shape::Waypoints => {
                crate::tasks::reference::Reference::timed(path.curve.clone(), 1.0, 0.0, 1.0)
                    .limits(0.0)
                    .extent
            }
            _ => [self.size; 2],
        };
        if ex + room > hx || ey + room > hy {
            return bad(
                shape_key,
                format!(
                    "the path reaches {ex:.3} m x {ey:.3} m from the centre; with the start \
                     offset or obstacles, the robot's radius and spawn.wall_margin ({room:.3} m) \
                     it leaves the {:.3} m x {:.3} m arena",
                    cfg.arena.width, cfg.arena.height
                ),
            );
        }
        if let Err(msg) = self.within_limits(&path, cfg) {
            let key = match self.path {
                Shape::Waypoints => "pathfollow.points",
                _ => "pathfollow.speed",
            };
            return bad(
                key,
                format!("{msg}: lower pathfollow.speed or smooth the path"),
            );
        }
        let steps =
            self.truncation_factor as f64 * path.length / self.speed as f64 / cfg.physics.dt as f64;
        if !steps.is_finite() || steps > 1.0e7 {
            return bad(
                "pathfollow.speed",
                format!("a lap would take {:.3e} steps", steps),
            );
        }
        // Arc lengths walked every step: at most a lap (a longer one would only repeat it, and
        // an unbounded one would integrate for ever).
        for (key, v) in [
            ("pathfollow.preview_spacing", self.preview_spacing),
            ("pathfollow.waypoint_spacing", self.waypoint_spacing),
        ] {
            if v as f64 > path.length {
                return bad(
                    key,
                    format!(
                        "must be at most the path's length, {:.3} m, got {v}",
                        path.length
                    ),
                );
            }
        }
        // Obstacles are spread over the lap, clear of the start by START_CLEARANCE each side,
        // and must not touch one another (2 r apart along the path at least).
        let free = path.length as f32 - 2.0 * START_CLEARANCE;
        let needed = self.obstacle_count as f32 * 2.0 * (self.obstacle_radius + cfg.robot.radius);
        if self.obstacle_count > 0 && needed > free {
            return bad(
                "pathfollow.obstacle_count",
                format!(
                    "{} obstacles with a robot's room between them need {needed:.2} m of path; \
                     the lap has {free:.2} m clear of the start",
                    self.obstacle_count
                ),
            );
        }
        Ok(())
    }
}

pub(super) fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    PathFollowConfig::from_table(table, origin, "pathfollow")?.validate(origin, scenario)
}
