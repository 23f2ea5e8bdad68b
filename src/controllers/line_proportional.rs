//! A proportional line follower on the difference of the two front ground sensors, as Webots'
//! e-puck line-following example (`e-puck_line.c`, "LFM": v_{L,R} = 200 ∓ 0.4·(g_R − g_L) in
//! e-puck units; docs/task-design.md §5.2), rescaled to the Khepera IV: the wheels at
//! v_{L,R} = `speed` ∓ `gain`·(g_R − g_L), g the raw counts. The e-puck's full differential is
//! twice its base speed (0.4 × 1000 counts against 200); with white − black = 654 counts here
//! (954 − 300), `gain` = 2·`speed`/654 per count keeps that ratio [D].
//!
//! A line to the left darkens the left sensor (g_L < g_R), slowing the left wheel: the robot
//! turns toward the line. Units: raw counts, m/s; robot frame x forward, y left.

use super::{non_negative, positive, Controller, WheelMap};
use crate::error::Result;
use crate::obs::ObsLayout;

crate::config_table! {
    /// Parameters of the proportional line follower.
    pub struct LineProportionalParams {
        /// m/s, base speed [C: K-Team's demo's 90 units x 0.678 mm/s]
        speed: f32 = 0.06102,
        /// m/s per raw count of g_R - g_L [D: 2 x speed / (954 - 300), the e-puck LFM's ratio]
        gain: f32 = 0.0001866,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// The proportional line follower on a line-following observation.
#[derive(Debug, Clone, PartialEq)]
pub struct LineProportionalPolicy {
    speed: f32,
    gain: f32,
    wheels: WheelMap,
    ground: usize,
    obs_dim: usize,
}

impl Controller for LineProportionalPolicy {
    const NAME: &'static str = "line_proportional";
    const READS: &'static str = "linefollow";
    type Params = LineProportionalParams;

    fn new(params: &LineProportionalParams, layout: &ObsLayout) -> Result<Self> {
        let who = Self::NAME;
        Ok(Self {
            speed: positive(who, "speed", params.speed)?,
            gain: non_negative(who, "gain", params.gain)?,
            wheels: WheelMap::new(who, params.axle_length, params.max_wheel_speed)?,
            ground: layout.require("ground", 4, who)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let difference = (obs[self.ground + 2] - obs[self.ground + 1]) * 1023.0;
        let delta = self.gain * difference;
        out.copy_from_slice(&self.wheels.action([self.speed - delta, self.speed + delta]));
    }
}
