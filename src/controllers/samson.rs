//! A Lyapunov path follower of Samson's type (C. Samson, "Path following and time-varying
//! feedback stabilization of a wheeled mobile robot", ICARCV 1992; the "rear-wheel feedback"
//! law of PythonRobotics): at the desired speed v, steer from the Frenet errors at the closest
//! path point.
//!
//! With d the cross-track error (left of the path positive), θ̃ = θ − θ_p the heading error
//! (the observation's `path_heading_error` is θ_p − θ = −θ̃) and κ the path's curvature there:
//!   ω = v·κ·cos θ̃ / (1 − κ·d) − k_θ·|v|·θ̃ − k_d·v·d·sin θ̃ / θ̃.
//! The Frenet errors evolve as ḋ = v·sin θ̃ and θ̃̇ = ω − v·κ·cos θ̃ / (1 − κ·d), so the first
//! term cancels the path's turning and θ̃̇ = −k_θ|v|θ̃ − k_d·v·d·sin θ̃/θ̃; V = d² + θ̃²/k_d
//! decreases along solutions (Samson's Lyapunov function). Linearised: s² + k_θ·v·s + k_d·v² = 0,
//! ω_n = v·√k_d. The defaults give ω_n = 1 rad/s and ζ = 0.7 at v = 0.15 m/s (docs/task-design.md
//! §4): k_d = (1/0.15)² = 44.4 m⁻², k_θ = 2·0.7/0.15 = 9.33 m⁻¹. Where 1 − κ·d ≤ 0 (the robot
//! beyond the centre of curvature) the feed-forward is undefined; it is taken at 1 − κ·d =
//! [`MIN_DENOMINATOR`].
//!
//! Units: metres, m/s, radians, rad/s; robot frame x forward, y left, angles CCW.

use super::{non_negative, Controller, PathBlocks, WheelMap};
use crate::error::Result;
use crate::obs::ObsLayout;

/// Smallest 1 − κ·d the feed-forward divides by.
pub const MIN_DENOMINATOR: f32 = 0.1;

crate::config_table! {
    /// Parameters of Samson's path follower.
    pub struct SamsonParams {
        /// k_d (1/m^2), gain on the cross-track error [D: (omega_n / v)^2 = (1 / 0.15)^2, task-design.md §4]
        kd: f32 = 44.44,
        /// k_theta (1/m), gain on the heading error [D: 2 zeta omega_n / v = 2 * 0.7 / 0.15, task-design.md §4]
        ktheta: f32 = 9.33,
        /// wheel separation (m) turning (v, omega) into wheel speeds
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// The law itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Samson {
    /// k_d (1/m²).
    pub kd: f32,
    /// k_θ (1/m).
    pub ktheta: f32,
}

impl Samson {
    /// ω for speed `v`, cross-track error `d`, heading error θ̃ = θ − θ_p and curvature `kappa`.
    pub fn turn_rate(&self, v: f32, d: f32, theta: f32, kappa: f32) -> f32 {
        let sinc = if theta.abs() < 1e-6 {
            1.0
        } else {
            theta.sin() / theta
        };
        let feed = v * kappa * theta.cos() / (1.0 - kappa * d).max(MIN_DENOMINATOR);
        feed - self.ktheta * v.abs() * theta - self.kd * v * d * sinc
    }
}

/// Samson's path follower on a path-following observation.
#[derive(Debug, Clone, PartialEq)]
pub struct SamsonPolicy {
    /// The law.
    pub law: Samson,
    /// The drive.
    pub wheels: WheelMap,
    at: PathBlocks,
    obs_dim: usize,
}

impl Controller for SamsonPolicy {
    const NAME: &'static str = "samson";
    const READS: &'static str = "pathfollow";
    type Params = SamsonParams;

    fn new(params: &SamsonParams, layout: &ObsLayout) -> Result<Self> {
        Ok(Self {
            law: Samson {
                kd: non_negative(Self::NAME, "kd", params.kd)?,
                ktheta: non_negative(Self::NAME, "ktheta", params.ktheta)?,
            },
            wheels: WheelMap::new(Self::NAME, params.axle_length, params.max_wheel_speed)?,
            at: PathBlocks::find(layout, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let v = obs[self.at.speed] * self.wheels.max_wheel_speed;
        let d = obs[self.at.cross_track];
        // θ̃ = θ − θ_p = −(θ_p − θ).
        let theta = -obs[self.at.heading].atan2(obs[self.at.heading + 1]);
        let w = self.law.turn_rate(v, d, theta, obs[self.at.curvature]);
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_the_path_it_turns_with_it_and_off_it_turns_back() {
        let law = Samson {
            kd: 44.44,
            ktheta: 9.33,
        };
        // On a circle of radius 0.6 m at 0.15 m/s: ω = v κ = 0.25 rad/s.
        assert!((law.turn_rate(0.15, 0.0, 0.0, 1.0 / 0.6) - 0.25).abs() < 1e-6);
        // Left of a straight path: turn right; heading left of it: turn right.
        assert!(law.turn_rate(0.15, 0.05, 0.0, 0.0) < 0.0);
        assert!(law.turn_rate(0.15, 0.0, 0.3, 0.0) < 0.0);
        // Beyond the centre of curvature the feed-forward stays finite.
        assert!(law.turn_rate(0.15, 1.0, 0.0, 2.0).is_finite());
    }
}
