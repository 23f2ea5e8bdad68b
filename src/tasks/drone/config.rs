//! DroneFollow's scenario table `[drone]`: the quadcopter, its camera, the robot's route and who
//! drives the robot, with the checks that make an impossible scenario a `ConfigError` naming the
//! key. Units: metres, seconds, radians.

use toml::Table;

use super::model::DroneParams;
use crate::config::{limits, ConfigTable, Domain};
use crate::error::{Error, Result};
use crate::scenario::Scenario;
use crate::tasks::Driver;

/// Most route waypoints.
pub const MAX_ROUTE_POINTS: u32 = 32;

crate::config_table! {
    /// `[drone]`: the quadcopter, its camera and the robot's route.
    pub struct DroneConfig {
        /// rad, largest tilt: a_max = g tan(tilt_max) = 2.63 m/s^2 [D/E: 15 deg, task-design.md §7; VMAS resets beyond 30 deg]
        tilt_max: f32 = 0.2618 => Domain::POSITIVE.below(1.2),
        /// m/s, terminal horizontal speed (drag c = a_max / speed_max) [E]
        speed_max: f32 = 1.0 => Domain::POSITIVE.at_most(limits::SPEED),
        /// s, altitude time constant of the autopilot [E: Crazyflie attitude constants are 0.12-0.2 s]
        altitude_tau: f32 = 0.3 => Domain::POSITIVE.at_most(limits::TIME),
        /// m, height while the robot is in view [S: the UNED course's quadcopter descends to 0.5 m]
        track_altitude: f32 = 0.5 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, height while searching [E: the course climbs to 4 m in a larger scene]
        search_altitude: f32 = 1.5 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// s out of view before the autopilot climbs to search [E]
        search_delay: f32 = 0.5 => Domain::NON_NEGATIVE.at_most(limits::TIME),
        /// rad, full angle of the downward camera's cone [D/E: 60 deg, task-design.md §7]
        fov: f32 = 1.0472 => Domain::POSITIVE.below(3.0),
        /// s out of view before the episode ends (lost) [E: task-design.md §7]
        lost_time: f32 = 3.0 => Domain::POSITIVE.at_most(limits::TIME),
        /// reward subtracted per step out of view
        unseen_penalty: f32 = 0.5 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// m, the drone starts this far at most from above the robot
        start_offset: f32 = 0.1 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// waypoints of the robot's closed route, drawn at every reset
        route_points: u32 = 6 => Domain::range(2.0, MAX_ROUTE_POINTS as f64),
        /// m, the robot heads for the next waypoint within this of the current one
        waypoint_radius: f32 = 0.1 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m/s, the robot's cruise speed v_max (position control, eqs. 1-4)
        robot_vmax: f32 = 0.15 => Domain::POSITIVE.at_most(limits::SPEED),
        /// rad/s, the robot's omega_max
        robot_wmax: f32 = 1.0 => Domain::POSITIVE.at_most(limits::TURN_RATE),
        /// who drives the robot: scripted (position control, then avoidance) or agent (a second agent, robot)
        driver: Driver = "scripted",
    }
}

impl DroneConfig {
    pub(super) fn params(&self) -> DroneParams {
        DroneParams::new(
            self.tilt_max,
            self.speed_max,
            self.altitude_tau,
            (self.track_altitude, self.search_altitude),
            self.search_delay,
            self.fov,
        )
    }
}

pub(super) fn check_section(table: &Table, _scenario: &Scenario, origin: &str) -> Result<()> {
    let d = DroneConfig::from_table(table, origin, "drone")?;
    let bad = |key: &str, msg: String| Err(Error::config(origin, &format!("drone.{key}"), msg));
    if d.search_altitude < d.track_altitude {
        return bad(
            "search_altitude",
            format!(
                "must be at least drone.track_altitude ({}), got {}",
                d.track_altitude, d.search_altitude
            ),
        );
    }
    if d.start_offset > d.track_altitude * (0.5 * d.fov).tan() {
        return bad(
            "start_offset",
            "the robot would start out of view: keep it within track_altitude * tan(fov / 2)"
                .to_string(),
        );
    }
    Ok(())
}
