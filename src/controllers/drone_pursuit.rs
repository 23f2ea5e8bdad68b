//! PD pursuit for the quadcopter of DroneFollow (docs/task-design.md §7): steer the drone's
//! horizontal acceleration so that the robot's offset e (metres, from the camera's image
//! coordinates times the footprint's radius z·tan(fov/2)) and its rate ė (the observed
//! relative velocity) obey ë + k_d·ė + k_p·e = a_robot:
//!   a = k_p·e + k_d·ė + c·v_drone,
//! the last term cancelling the drone's drag (c = a_max / v_max). With k_p = 4 s⁻² and
//! k_d = 4 s⁻¹ the error is critically damped, ω_n = 2 rad/s [D/E]: a robot at constant
//! velocity is tracked with no steady error, and one accelerating by a_robot lags by
//! a_robot/k_p (0.15 m/s at 1 rad/s: 4 cm, well inside the 0.29 m footprint at 0.5 m).
//! Out of view it brakes (a = −k_d·v_drone + c·v_drone) while the autopilot climbs to search
//! (the UNED course's rule). The command is a / a_max, a_max = g·tan(tilt_max).
//!
//! Units: metres, seconds, radians; world frame (the drone holds its yaw).

use super::{positive, Controller};
use crate::error::Result;
use crate::obs::ObsLayout;

crate::config_table! {
    /// Parameters of the drone's PD pursuit.
    pub struct DronePursuitParams {
        /// k_p (1/s^2), gain on the offset [D/E: omega_n^2 with omega_n = 2 rad/s, task-design.md §7]
        kp: f32 = 4.0,
        /// k_d (1/s), gain on the offset's rate [D/E: 2 zeta omega_n with zeta = 1]
        kd: f32 = 4.0,
        /// rad, full angle of the camera's cone (drone.fov)
        fov: f32 = 1.0472,
        /// rad, the drone's largest tilt (drone.tilt_max): a_max = g tan(tilt_max)
        tilt_max: f32 = 0.2618,
        /// m/s, its terminal speed (drone.speed_max): drag c = a_max / speed_max
        speed_max: f32 = 1.0,
    }
}

/// The PD pursuit on a DroneFollow observation.
#[derive(Debug, Clone, PartialEq)]
pub struct DronePursuitPolicy {
    kp: f32,
    kd: f32,
    tan_half_fov: f32,
    accel_max: f32,
    drag: f32,
    offset: usize,
    seen: usize,
    rate: usize,
    velocity: usize,
    altitude: usize,
    obs_dim: usize,
}

impl Controller for DronePursuitPolicy {
    const NAME: &'static str = "drone_pursuit";
    const READS: &'static str = "dronefollow";
    type Params = DronePursuitParams;

    fn new(params: &DronePursuitParams, layout: &ObsLayout) -> Result<Self> {
        let who = Self::NAME;
        let accel_max = 9.80665 * positive(who, "tilt_max", params.tilt_max)?.tan();
        Ok(Self {
            kp: positive(who, "kp", params.kp)?,
            kd: positive(who, "kd", params.kd)?,
            tan_half_fov: (0.5 * positive(who, "fov", params.fov)?).tan(),
            accel_max,
            drag: accel_max / positive(who, "speed_max", params.speed_max)?,
            offset: layout.require("camera_offset", 2, who)?,
            seen: layout.require("seen", 1, who)?,
            rate: layout.require("relative_velocity", 2, who)?,
            velocity: layout.require("drone_velocity", 2, who)?,
            altitude: layout.require("altitude", 1, who)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let radius = obs[self.altitude] * self.tan_half_fov;
        for axis in 0..2 {
            let v = obs[self.velocity + axis];
            let a = if obs[self.seen] > 0.5 {
                self.kp * obs[self.offset + axis] * radius + self.kd * obs[self.rate + axis]
            } else {
                -self.kd * v
            };
            out[axis] = ((a + self.drag * v) / self.accel_max).clamp(-1.0, 1.0);
        }
    }
}
