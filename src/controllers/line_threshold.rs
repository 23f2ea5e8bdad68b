//! K-Team's line follower: the logic of the line-following demo shipped with the Khepera IV
//! (`khepera4_test.c`, docs/task-design.md §5.2, docs/robot.md §4), on the two front ground sensors
//! read against a threshold (800: darker is black).
//!
//! - both front sensors over black: straight on at `speed` (90 units of 0.678 mm/s = 61 mm/s);
//! - one over black: turn toward it, the wheels at `speed` ∓ `turn` (50 units);
//! - neither: turn in place at `search` (60 units = 41 mm/s) toward the side the line was last
//!   seen. The demo remembers that side; here the observation's wheel speeds do (the last
//!   command turned toward it), so the policy stays a function of the observation.
//!
//! The demo loops every 20 ms; khepera_gym's control step is 50 ms. Units: raw ground counts,
//! m/s; robot frame x forward, y left.

use super::{positive, Controller, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;

/// One K-Team speed unit (m/s): 0.678 mm/s (docs/robot.md §1).
pub const SPEED_UNIT: f32 = 0.000678;

crate::config_table! {
    /// Parameters of K-Team's threshold line follower.
    pub struct LineThresholdParams {
        /// raw ground count below which a sensor is over black [C: K-Team's demo, 700-800, robot.md §4]
        threshold: f32 = 800.0,
        /// m/s, speed on the line [C: the demo's 90 units x 0.678 mm/s]
        speed: f32 = 0.06102,
        /// m/s, differential toward the line when one sensor sees it [C: the demo's 50 units]
        turn: f32 = 0.0339,
        /// m/s, wheel speed turning in place to find the line [C: the demo's 60 units]
        search: f32 = 0.04068,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// K-Team's threshold line follower on a line-following observation.
#[derive(Debug, Clone, PartialEq)]
pub struct LineThresholdPolicy {
    threshold: f32,
    speed: f32,
    turn: f32,
    search: f32,
    wheels: WheelMap,
    ground: usize,
    wheel_speeds: usize,
    obs_dim: usize,
}

impl Controller for LineThresholdPolicy {
    const NAME: &'static str = "line_threshold";
    const READS: &'static str = "linefollow";
    type Params = LineThresholdParams;

    fn new(params: &LineThresholdParams, layout: &ObsLayout) -> Result<Self> {
        let who = Self::NAME;
        if !(0.0..=1023.0).contains(&params.threshold) {
            return Err(Error::Param(format!(
                "{who}: threshold must be a raw count in [0, 1023], got {}",
                params.threshold
            )));
        }
        Ok(Self {
            threshold: params.threshold,
            speed: positive(who, "speed", params.speed)?,
            turn: positive(who, "turn", params.turn)?,
            search: positive(who, "search", params.search)?,
            wheels: WheelMap::new(who, params.axle_length, params.max_wheel_speed)?,
            ground: layout.require("ground", 4, who)?,
            wheel_speeds: layout.require("wheel_speeds", 2, who)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let black = |k: usize| obs[self.ground + k] * 1023.0 < self.threshold;
        let (left, right) = (black(1), black(2));
        let wheels = match (left, right) {
            (true, true) => [self.speed, self.speed],
            (true, false) => [self.speed - self.turn, self.speed + self.turn],
            (false, true) => [self.speed + self.turn, self.speed - self.turn],
            (false, false) => {
                // Toward the side the wheels last turned to (left when they did not).
                let turning_right = obs[self.wheel_speeds] > obs[self.wheel_speeds + 1];
                if turning_right {
                    [self.search, -self.search]
                } else {
                    [-self.search, self.search]
                }
            }
        };
        out.copy_from_slice(&self.wheels.action(wheels));
    }
}
