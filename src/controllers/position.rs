//! Position control (paper eqs. 1–4, after Vilella et al. 2004): drive toward a target point.
//!
//! d = distance to the target (eq. 1), α − θ = its bearing in the robot frame (eq. 2);
//! v = v_max if d > k_r else d·v_max/k_r (eq. 3); ω = ω_max·sin(α − θ) (eq. 4);
//! both 0 once d < stop_radius (the library's 0.05 m).
//!
//! [`PositionControl`] is the law; [`PositionPolicy`] the controller reading a Nav-like
//! observation (`goal_distance`, `goal_bearing_sin`, `goal_bearing_cos`); [`PositionChasePolicy`]
//! the same law chasing the moving reference point of a tracking observation
//! (`tracking_error`: the point's x, y in the robot frame), the way the paper's scripts would
//! track a trajectory. It lags: inside k_r the speed is d·v_max/k_r, so holding the reference's
//! speed v_r needs a steady distance d = v_r·k_r/v_max (v_r over the loop's bandwidth
//! v_max/k_r): 7.5 cm at 0.15 m/s with the defaults.
//!
//! Units: metres, m/s, radians, rad/s; robot frame x forward, y left, angles CCW.

use super::{goal_of, non_negative, positive, Controller, GoalBlocks, WheelMap};
use crate::error::Result;
use crate::obs::ObsLayout;

crate::config_table! {
    /// Parameters of position control (eqs. 1–4).
    pub struct PositionParams {
        /// cruise speed v_max (m/s)
        vmax: f32 = 0.3,
        /// largest turn rate ω_max (rad/s), reached at a bearing of ±90°
        wmax: f32 = 4.0,
        /// radius k_r of the docking area where the speed falls linearly (m)
        kr: f32 = 0.15,
        /// distance to the goal under which the robot stops (m; the task succeeds within 0.05 m, so the default stops closer)
        stop_radius: f32 = 0.02,
        /// wheel separation (m) turning (v, ω) into wheel speeds
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

impl PositionParams {
    /// The law and the drive of these parameters, checked (`who` names the controller).
    pub fn law(&self, who: &str) -> Result<(PositionControl, WheelMap)> {
        Ok((
            PositionControl {
                vmax: positive(who, "vmax", self.vmax)?,
                wmax: positive(who, "wmax", self.wmax)?,
                kr: positive(who, "kr", self.kr)?,
                stop_radius: non_negative(who, "stop_radius", self.stop_radius)?,
            },
            WheelMap::new(who, self.axle_length, self.max_wheel_speed)?,
        ))
    }
}

/// Position control to the goal of a Nav-like observation.
#[derive(Debug, Clone, PartialEq)]
pub struct PositionPolicy {
    /// The law.
    pub law: PositionControl,
    /// The drive.
    pub wheels: WheelMap,
    goal: GoalBlocks,
    obs_dim: usize,
}

impl Controller for PositionPolicy {
    const NAME: &'static str = "position_control";
    const READS: &'static str = "nav";
    type Params = PositionParams;

    fn new(params: &PositionParams, layout: &ObsLayout) -> Result<Self> {
        let (law, wheels) = params.law(Self::NAME)?;
        Ok(Self {
            law,
            wheels,
            goal: GoalBlocks::find(layout, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (d, bearing) = goal_of(obs, self.goal);
        let (v, w) = self.law.twist(d, bearing);
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

/// Position control chasing the reference point of a tracking observation (`tracking_error`).
#[derive(Debug, Clone, PartialEq)]
pub struct PositionChasePolicy {
    /// The law.
    pub law: PositionControl,
    /// The drive.
    pub wheels: WheelMap,
    error: usize,
    obs_dim: usize,
}

impl Controller for PositionChasePolicy {
    const NAME: &'static str = "position_chase";
    const READS: &'static str = "track";
    type Params = PositionParams;

    fn new(params: &PositionParams, layout: &ObsLayout) -> Result<Self> {
        let (law, wheels) = params.law(Self::NAME)?;
        Ok(Self {
            law,
            wheels,
            error: layout.require("tracking_error", 2, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (x, y) = (obs[self.error], obs[self.error + 1]);
        let (v, w) = self.law.twist(x.hypot(y), y.atan2(x));
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

/// The position controller's parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PositionControl {
    /// Cruise speed v_max (m/s).
    pub vmax: f32,
    /// Largest turn rate ω_max (rad/s), reached at a bearing of ±90°.
    pub wmax: f32,
    /// Radius k_r of the docking area where the speed falls linearly (m).
    pub kr: f32,
    /// Distance under which the robot stops (m).
    pub stop_radius: f32,
}

impl PositionControl {
    /// (v, ω) toward a target at `distance` (m) and `bearing` (rad, robot frame).
    pub fn twist(&self, distance: f32, bearing: f32) -> (f32, f32) {
        if distance < self.stop_radius {
            return (0.0, 0.0);
        }
        let v = if distance > self.kr {
            self.vmax
        } else {
            distance * self.vmax / self.kr
        };
        (v, self.wmax * bearing.sin())
    }
}

/// Wheel speeds (left, right, m/s) of a twist for a robot with wheel separation `axle`.
pub fn twist_to_wheels(v: f32, w: f32, axle: f32) -> [f32; 2] {
    [v - 0.5 * w * axle, v + 0.5 * w * axle]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equations_three_and_four() {
        let pc = PositionControl {
            vmax: 0.2,
            wmax: 1.0,
            kr: 0.1,
            stop_radius: 0.05,
        };
        assert_eq!(pc.twist(1.0, 0.0), (0.2, 0.0));
        let (v, w) = pc.twist(0.08, std::f32::consts::FRAC_PI_2);
        assert!((v - 0.16).abs() < 1e-6 && (w - 1.0).abs() < 1e-6);
        assert_eq!(pc.twist(0.04, 1.0), (0.0, 0.0));
    }
}
