//! Kanayama's tracking controller (Kanayama, Kimura, Miyazaki & Noguchi, "A stable tracking
//! control method for an autonomous mobile robot", ICRA 1990, pp. 384–389): feed-forward of the
//! reference's speed and turn rate plus feedback of the error posture in the robot frame.
//!
//! Error posture (the observation's `tracking_error`, `heading_error`): e_x, e_y = R(θ)ᵀ(p_r − p),
//! e_θ = θ_r − θ. Law:
//!   v = v_r·cos e_θ + K_x·e_x,
//!   ω = ω_r + v_r·(K_y·e_y + K_θ·sin e_θ).
//! Linearised about zero error on a straight or curved reference, the longitudinal error decays
//! at rate K_x and the lateral loop is s² + v_r·K_θ·s + v_r²·K_y = 0: natural frequency
//! ω_n = v_r·√K_y, critically damped when K_y = K_θ²/4. The defaults give ω_n = 1 rad/s and
//! ζ = 1 at v_r = 0.15 m/s (docs/task-design.md §3): K_y = (1/0.15)² = 44.4 m⁻², K_θ = 2/0.15 =
//! 13.3 m⁻¹, K_x = 1 s⁻¹. (The paper's own gains, K_x = 10 s⁻¹, K_y = 6.4e-3 cm⁻² = 64 m⁻²,
//! K_θ = 0.16 cm⁻¹ = 16 m⁻¹, as cited in docs/task-design.md, also satisfy K_y = K_θ²/4; they are
//! not checked against the paper's text.)
//!
//! Units: metres, m/s, radians, rad/s; robot frame x forward, y left, angles CCW.

use super::{non_negative, Controller, WheelMap};
use crate::error::Result;
use crate::obs::ObsLayout;

crate::config_table! {
    /// Parameters of Kanayama's tracking controller.
    pub struct KanayamaParams {
        /// K_x (1/s), gain on the along-track error e_x [task-design.md §3: 1, the longitudinal loop as fast as the lateral]
        kx: f32 = 1.0,
        /// K_y (1/m^2), gain on the cross-track error e_y [D: (omega_n / v_r)^2 = (1 / 0.15)^2]
        ky: f32 = 44.44,
        /// K_theta (1/m), gain on sin of the heading error [D: 2 zeta omega_n / v_r = 2 / 0.15, zeta = 1]
        ktheta: f32 = 13.33,
        /// wheel separation (m) turning (v, omega) into wheel speeds
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// The law itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kanayama {
    /// K_x (1/s).
    pub kx: f32,
    /// K_y (1/m²).
    pub ky: f32,
    /// K_θ (1/m).
    pub ktheta: f32,
}

impl Kanayama {
    /// (v, ω) for the error (e_x, e_y, sin e_θ, cos e_θ) and feed-forward (v_r, ω_r).
    pub fn twist(&self, error: [f32; 4], v_r: f32, w_r: f32) -> (f32, f32) {
        let [ex, ey, sin_t, cos_t] = error;
        let v = v_r * cos_t + self.kx * ex;
        let w = w_r + v_r * (self.ky * ey + self.ktheta * sin_t);
        (v, w)
    }
}

/// Kanayama's controller on a tracking observation (`tracking_error`, `heading_error`,
/// `reference_rates`).
#[derive(Debug, Clone, PartialEq)]
pub struct KanayamaPolicy {
    /// The law.
    pub law: Kanayama,
    /// The drive.
    pub wheels: WheelMap,
    error: usize,
    heading: usize,
    rates: usize,
    obs_dim: usize,
}

impl Controller for KanayamaPolicy {
    const NAME: &'static str = "kanayama";
    const READS: &'static str = "track";
    type Params = KanayamaParams;

    fn new(params: &KanayamaParams, layout: &ObsLayout) -> Result<Self> {
        Ok(Self {
            law: Kanayama {
                kx: non_negative(Self::NAME, "kx", params.kx)?,
                ky: non_negative(Self::NAME, "ky", params.ky)?,
                ktheta: non_negative(Self::NAME, "ktheta", params.ktheta)?,
            },
            wheels: WheelMap::new(Self::NAME, params.axle_length, params.max_wheel_speed)?,
            error: layout.require("tracking_error", 2, Self::NAME)?,
            heading: layout.require("heading_error", 2, Self::NAME)?,
            rates: layout.require("reference_rates", 2, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let vmax = self.wheels.max_wheel_speed;
        // reference_rates are v_r / v_max and ω_r / (2 v_max / axle).
        let v_r = obs[self.rates] * vmax;
        let w_r = obs[self.rates + 1] * 2.0 * vmax / self.wheels.axle_length;
        let error = [
            obs[self.error],
            obs[self.error + 1],
            obs[self.heading],
            obs[self.heading + 1],
        ];
        let (v, w) = self.law.twist(error, v_r, w_r);
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_error_gives_the_feed_forward_and_errors_steer_toward_the_reference() {
        let law = Kanayama {
            kx: 1.0,
            ky: 44.44,
            ktheta: 13.33,
        };
        assert_eq!(law.twist([0.0, 0.0, 0.0, 1.0], 0.15, 0.25), (0.15, 0.25));
        // Reference ahead: faster; reference to the left or heading left: turn left.
        assert!(law.twist([0.1, 0.0, 0.0, 1.0], 0.15, 0.0).0 > 0.15);
        assert!(law.twist([0.0, 0.05, 0.0, 1.0], 0.15, 0.0).1 > 0.0);
        assert!(law.twist([0.0, 0.0, 0.3, 0.95], 0.15, 0.0).1 > 0.0);
    }
}
