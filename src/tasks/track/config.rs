//! The `[track]` table of the tracking task: its keys (default, units, source), and the checks
//! that a reference fits the arena and the robot's wheels (speed and acceleration limits), with
//! errors naming the key. Units: metres, seconds, radians, m/s.

use toml::Table;

use crate::config::{limits, ConfigTable, Domain};
use crate::error::{Error, Result};
use crate::scenario::Scenario;
use crate::tasks::reference::{Curve, Reference, Shape};

/// Most preview points.
pub const MAX_PREVIEW_POINTS: u32 = 16;

/// Most waypoints of a scenario's reference.
pub const MAX_WAYPOINTS: usize = 1024;

/// How far the closing waypoint may lie from the first (m).
const CLOSING_TOLERANCE: f32 = 1.0e-3;

/// Direction of travel along the reference.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// Drawn at every reset.
    Random,
    /// The curve's own direction (counter-clockwise for the circle and square).
    Ccw,
    /// Against it.
    Cw,
}

impl Direction {
    /// +1 (the curve's own direction) or −1; "random" draws one boolean from `rng`.
    pub fn draw<R: rand::Rng>(self, rng: &mut R) -> f64 {
        match self {
            Direction::Ccw => 1.0,
            Direction::Cw => -1.0,
            Direction::Random => {
                if rng.random::<bool>() {
                    1.0
                } else {
                    -1.0
                }
            }
        }
    }
}

crate::config_table! {
    /// `[track]`: the reference trajectory, start offsets, reward, end and statistics.
    pub struct TrackConfig {
        /// circle, lemniscate (Gerono's figure eight), square (corners: the limit of smooth controllers), spline (a random smooth closed curve from the world's stream) or waypoints (the waypoints key)
        reference: Shape = "circle",
        /// m: circle radius, lemniscate half-width A, square half-side, spline's largest possible radius [task-design.md §3: R = 0.6 m]
        size: f32 = 0.6 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m/s, mean speed along the reference; period = length / speed [task-design.md §3: 0.15 m/s, so omega_r = 0.25 rad/s on the circle]
        speed: f32 = 0.15 => Domain::POSITIVE.at_most(limits::SPEED),
        /// "random" (drawn each reset), "ccw" (the curve's own direction) or "cw" [task-design.md §3]
        direction: Direction = "random",
        /// draw the starting phase uniformly at each reset; false: start at phase 0 [task-design.md §3]
        random_phase: bool = true,
        /// m, largest start distance from the reference point, drawn uniformly [task-design.md §3]
        start_offset: f32 = 0.2 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// rad, largest start heading error (45 degrees), drawn uniformly [task-design.md §3]
        start_heading_offset: f32 = 0.7853982 => Domain::range(0.0, std::f64::consts::PI),
        /// spline: sum of the harmonics' relative amplitudes (k = 2, 3, 4), in [0, 0.5] [E]
        spline_irregularity: f32 = 0.3 => Domain::range(0.0, 0.5),
        /// the reference's wheel speeds stay within this fraction of robot.max_wheel_speed, leaving the feedback room to correct [E]
        max_wheel_fraction: f32 = 0.5 => Domain::POSITIVE.at_most(1.0),
        /// the reference's wheel accelerations stay within this fraction of the drive's acceleration (square corners excepted) [E]
        max_accel_fraction: f32 = 0.5 => Domain::POSITIVE.at_most(1.0),
        /// m, terminated as lost beyond this position error [task-design.md §3]
        lost_distance: f32 = 0.5 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// s, truncated after one period plus this [task-design.md §3]
        truncation_margin: f32 = 2.0 => Domain::NON_NEGATIVE.at_most(limits::TIME),
        /// reference points previewed (0..16) [task-design.md §3]
        preview_points: u32 = 4 => Domain::range(0.0, MAX_PREVIEW_POINTS as f64),
        /// s between previewed points [task-design.md §3]
        preview_step: f32 = 0.25 => Domain::POSITIVE.at_most(limits::TIME),
        /// reward per metre of position error [task-design.md §3]
        error_weight: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward per unit of 1 - cos(heading error) [task-design.md §3]
        heading_weight: f32 = 0.1 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// s, start-up excluded from the RMS and maximum error statistics [task-design.md §3]
        transient: f32 = 5.0 => Domain::NON_NEGATIVE.at_most(limits::TIME),
        /// m, converged once the error stays below this [issue 14]
        converge_radius: f32 = 0.02 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// reference = "waypoints": [[t, x, y], ...] (s, m, m), times strictly rising from 0; the last point repeats the first and its time is the period (speed is then unused)
        waypoints: Vec<[f32; 3]> = [] => Domain::range(-limits::TIME, limits::TIME).at_most_entries(MAX_WAYPOINTS),
    }
}

impl TrackConfig {
    /// The largest |x|, |y| a reference of this table can reach (m); waypoints: of `reference`.
    fn extent(&self, reference: &Reference) -> [f32; 2] {
        match self.reference {
            Shape::Lemniscate => [self.size, 0.5 * self.size],
            Shape::Waypoints => reference.limits(0.0).extent,
            _ => [self.size; 2],
        }
    }

    /// The reference before any random draw, from `phase` in `direction`: a spline's is its
    /// mean circle, of radius size / (1 + irregularity), so that its harmonics never take it
    /// beyond `size`; waypoints take their own times.
    pub(crate) fn base_reference(&self, phase: f64, direction: f64) -> Reference {
        let curve = match self.reference {
            Shape::Spline => {
                Curve::new(Shape::Spline, self.size / (1.0 + self.spline_irregularity))
            }
            Shape::Waypoints => {
                let (curve, period) = Curve::waypoints(&self.waypoints);
                return Reference::timed(curve, period, phase, direction);
            }
            shape => Curve::new(shape, self.size),
        };
        Reference::new(curve, self.speed, phase, direction)
    }

    /// The key a reference's shape or limits are blamed on.
    fn reference_key(&self) -> &'static str {
        if self.reference == Shape::Waypoints {
            "track.waypoints"
        } else {
            "track.speed"
        }
    }

    /// Checks `waypoints` against `reference`: present exactly for "waypoints", at least 4,
    /// finite, times strictly rising from 0, the last point closing the loop.
    fn check_waypoints(&self) -> std::result::Result<(), String> {
        let points = &self.waypoints;
        if self.reference != Shape::Waypoints {
            return match points.is_empty() {
                true => Ok(()),
                false => Err("waypoints are given but track.reference is not \"waypoints\"".into()),
            };
        }
        if points.len() < 4 || points.len() > MAX_WAYPOINTS {
            return Err(format!(
                "needs 4 to {MAX_WAYPOINTS} [t, x, y] points (3 distinct and the closing one), got {}",
                points.len()
            ));
        }
        if let Some(p) = points.iter().find(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(format!("every value must be finite, got {p:?}"));
        }
        if points[0][0] != 0.0 {
            return Err(format!("the first time must be 0, got {}", points[0][0]));
        }
        if let Some(w) = points.windows(2).find(|w| w[1][0] <= w[0][0]) {
            return Err(format!(
                "times must be strictly increasing, got {} then {}",
                w[0][0], w[1][0]
            ));
        }
        let (first, last) = (points[0], points[points.len() - 1]);
        if (first[1] - last[1]).hypot(first[2] - last[2]) > CLOSING_TOLERANCE {
            return Err(format!(
                "the last point must repeat the first (a closed loop): {:?} vs {:?}",
                &last[1..],
                &first[1..]
            ));
        }
        Ok(())
    }

    /// The robot's limits the reference must stay within: (wheel speed m/s, wheel acceleration
    /// m/s², axle m), the worst case of `[robot]`'s ranges.
    fn robot_limits(cfg: &Scenario) -> (f32, f32, f32) {
        (
            cfg.robot.max_wheel_speed.bounds().0,
            cfg.wheel_accel().bounds().0,
            cfg.robot.axle_length.bounds().1,
        )
    }

    /// Whether `reference` is within the robot's limits, else what it asks (for messages).
    pub(crate) fn within_limits(
        &self,
        reference: &Reference,
        cfg: &Scenario,
    ) -> std::result::Result<(), String> {
        let (vmax, amax, axle) = Self::robot_limits(cfg);
        let limits = reference.limits(axle);
        let speed_cap = self.max_wheel_fraction * vmax;
        if limits.wheel_speed > speed_cap {
            return Err(format!(
                "the reference needs wheel speeds up to {:.3} m/s, more than max_wheel_fraction \
                 x robot.max_wheel_speed = {speed_cap:.3} m/s (too fast or too sharp for the \
                 robot): lower track.speed or raise track.size",
                limits.wheel_speed
            ));
        }
        let accel_cap = self.max_accel_fraction * amax;
        if self.reference != Shape::Square && limits.wheel_accel > accel_cap {
            return Err(format!(
                "the reference needs wheel accelerations up to {:.3} m/s^2, more than \
                 max_accel_fraction x the drive's acceleration = {accel_cap:.3} m/s^2: lower \
                 track.speed or raise track.size",
                limits.wheel_accel
            ));
        }
        Ok(())
    }

    /// Checks the table against the scenario (each key alone is checked by its declaration):
    /// the waypoints, the reference inside the arena and within the robot's limits; errors
    /// name `track.<key>` and `origin`.
    pub(crate) fn validate(&self, origin: &str, cfg: &Scenario) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        if let Err(msg) = self.check_waypoints() {
            return bad("track.waypoints", msg);
        }
        // A spline shrinks toward its mean circle until it fits the limits; the circle must.
        let reference = self.base_reference(0.0, 1.0);
        // The reference, the start offset and the robot's body inside the arena's margin.
        let (hx, hy) = (0.5 * cfg.arena.width, 0.5 * cfg.arena.height);
        let room = self.start_offset + cfg.robot.radius + cfg.spawn.wall_margin;
        let [ex, ey] = self.extent(&reference);
        if ex + room > hx || ey + room > hy {
            let key = match self.reference {
                Shape::Waypoints => "track.waypoints",
                _ => "track.size",
            };
            return bad(
                key,
                format!(
                    "the reference reaches {ex:.3} m x {ey:.3} m from the centre; with \
                     track.start_offset, the robot's radius and spawn.wall_margin ({room:.3} m) \
                     it leaves the {:.3} m x {:.3} m arena",
                    cfg.arena.width, cfg.arena.height
                ),
            );
        }
        if let Err(msg) = self.within_limits(&reference, cfg) {
            return bad(self.reference_key(), msg);
        }
        if !reference.period.is_finite() || reference.period / cfg.physics.dt as f64 > 1.0e7 {
            return bad(
                self.reference_key(),
                format!("a lap would take {:.3e} s", reference.period),
            );
        }
        Ok(())
    }
}

pub(super) fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    TrackConfig::from_table(table, origin, "track")?.validate(origin, scenario)
}
