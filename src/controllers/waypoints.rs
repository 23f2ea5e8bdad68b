//! Waypoint switching: the paper's position control (eqs. 1–4) toward successive waypoints of
//! the path, the way the KH4VREP scripts chain targets (and IR-SIM's sequential goals with a
//! 0.1 m `goal_threshold`). The task keeps the chain: its `waypoint` block is the current
//! waypoint in the robot frame, and it moves on to the next once the robot is within
//! `pathfollow.waypoint_radius` of it; so this controller, like the others, holds no state.
//!
//! Law (see [`super::position`]): v = v_d beyond k_r, else d·v_d/k_r (eq. 3, with v_max the
//! task's desired speed v_d from `desired_speed`); ω = ω_max·sin(bearing) (eq. 4). Inside k_r it
//! slows toward each waypoint before switching: with k_r = 0.15 m and switching at 0.1 m it
//! drives at 2/3 of v_d or less near every waypoint, the stop-and-go of chained targets.
//!
//! Units: metres, m/s, radians, rad/s; robot frame x forward, y left, angles CCW.

use super::position::PositionControl;
use super::{positive, Controller, WheelMap};
use crate::error::Result;
use crate::obs::ObsLayout;

crate::config_table! {
    /// Parameters of waypoint switching (position control's, the speed from the task).
    pub struct WaypointParams {
        /// largest turn rate omega_max (rad/s), reached at a bearing of +-90 degrees [position_control's]
        wmax: f32 = 4.0,
        /// radius k_r of the docking area where the speed falls linearly (m) [position_control's]
        kr: f32 = 0.15,
        /// wheel separation (m) turning (v, omega) into wheel speeds
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// Position control toward the waypoint of a path-following observation.
#[derive(Debug, Clone, PartialEq)]
pub struct WaypointPolicy {
    /// Largest turn rate ω_max (rad/s).
    pub wmax: f32,
    /// Docking radius k_r (m).
    pub kr: f32,
    /// The drive.
    pub wheels: WheelMap,
    waypoint: usize,
    speed: usize,
    obs_dim: usize,
}

impl Controller for WaypointPolicy {
    const NAME: &'static str = "waypoint_switching";
    const READS: &'static str = "pathfollow";
    type Params = WaypointParams;

    fn new(params: &WaypointParams, layout: &ObsLayout) -> Result<Self> {
        Ok(Self {
            wmax: positive(Self::NAME, "wmax", params.wmax)?,
            kr: positive(Self::NAME, "kr", params.kr)?,
            wheels: WheelMap::new(Self::NAME, params.axle_length, params.max_wheel_speed)?,
            waypoint: layout.require("waypoint", 2, Self::NAME)?,
            speed: layout.require("desired_speed", 1, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let law = PositionControl {
            vmax: obs[self.speed] * self.wheels.max_wheel_speed,
            wmax: self.wmax,
            kr: self.kr,
            stop_radius: 0.0,
        };
        let (x, y) = (obs[self.waypoint], obs[self.waypoint + 1]);
        let (v, w) = law.twist(x.hypot(y), y.atan2(x));
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}
