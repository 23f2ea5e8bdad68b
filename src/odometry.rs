//! Dead reckoning: the pose a Khepera IV can compute on board from its wheel encoders and its
//! gyroscope, with the errors a real one has (`[task] localization = "odometry"`).
//!
//! At reset the estimate starts at the true pose (the robot knows where it starts), and each
//! episode draws the robot's calibration errors: the wheel radii and the axle length it
//! believes are off by a relative error drawn once (`[odometry] radius_error`, `axle_error`).
//! Every step each wheel's travel (the encoders count what the wheels turned, slip on the floor
//! included) is scaled by those errors and by a fresh relative noise (`slip_noise`), and the
//! heading advances by the gyroscope's reading when the robot carries one, else by the wheels'
//! difference over the believed axle. The estimate drifts as the robot travels, reproducibly per
//! seed. The true pose stays available to tests and plots (`poses()`).
//!
//! Units: metres, seconds, radians; world frame.

use rand::Rng;
use rand_distr::StandardNormal;
use rapier2d::math::Vector;

use crate::config::Domain;
use crate::robot::wrap_angle;

/// The values of a relative error: in [0, 0.5).
const RELATIVE_ERROR: Domain = Domain::NON_NEGATIVE.below(0.5);

crate::config_table! {
    /// `[odometry]`: the errors of the robot's dead reckoning, used with
    /// `task.localization = "odometry"`.
    pub struct OdometryConfig {
        /// relative error (standard deviation) of each wheel's believed radius, drawn per episode [E]
        radius_error: f32 = 0.01 => RELATIVE_ERROR,
        /// relative error (standard deviation) of the believed axle length, drawn per episode [D: the EPFL toolbox's calibrated 104.7 mm against the nominal 105.4 mm, 0.7%, robot.md §1]
        axle_error: f32 = 0.007 => RELATIVE_ERROR,
        /// relative noise (standard deviation) of each wheel's travel per step: slip on the floor [E: Enki adds ±5% uniform wheel-speed noise, 2.9% in standard deviation]
        slip_noise: f32 = 0.029 => RELATIVE_ERROR,
    }
}

/// One robot's dead reckoning.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Odometry {
    /// Estimated centre (m).
    pub position: Vector,
    /// Estimated heading (rad).
    pub heading: f32,
    /// Each wheel's travel is multiplied by this (its believed over its true radius).
    scale: [f32; 2],
    /// The axle length the robot believes (m).
    axle: f32,
    /// Encoder travel at the last update (m).
    last_travel: [f64; 2],
}

impl Odometry {
    /// Starts at the true pose, drawing this episode's calibration errors from `rng`; `axle`
    /// is the true axle length (m).
    pub fn start<R: Rng>(
        position: Vector,
        heading: f32,
        axle: f32,
        cfg: &OdometryConfig,
        rng: &mut R,
    ) -> Self {
        let mut relative = |sigma: f32| 1.0 + sigma * rng.sample::<f32, _>(StandardNormal);
        let scale = [relative(cfg.radius_error), relative(cfg.radius_error)];
        let axle = axle * relative(cfg.axle_error);
        Self {
            position,
            heading,
            scale,
            axle,
            last_travel: [0.0; 2],
        }
    }

    /// Advances by one step: `travel` is the encoders' total wheel travel (m), `gyro` the
    /// gyroscope's yaw rate over the step (rad/s) when the robot carries one, `dt` the step (s).
    pub fn update<R: Rng>(
        &mut self,
        travel: [f64; 2],
        gyro: Option<f32>,
        dt: f32,
        cfg: &OdometryConfig,
        rng: &mut R,
    ) {
        let mut wheel = |k: usize| {
            let delta = (travel[k] - self.last_travel[k]) as f32;
            let noise: f32 = rng.sample(StandardNormal);
            delta * self.scale[k] * (1.0 + cfg.slip_noise * noise)
        };
        let (left, right) = (wheel(0), wheel(1));
        self.last_travel = travel;
        let forward = 0.5 * (left + right);
        let turn = match gyro {
            Some(rate) => rate * dt,
            None => (right - left) / self.axle,
        };
        // Midpoint heading: the second-order estimate the EPFL toolbox's odometry uses too.
        let mid = self.heading + 0.5 * turn;
        self.position += forward * Vector::new(mid.cos(), mid.sin());
        self.heading = wrap_angle(self.heading + turn);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn without_errors_the_estimate_follows_the_wheels() {
        let cfg = OdometryConfig {
            radius_error: 0.0,
            axle_error: 0.0,
            slip_noise: 0.0,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let mut odo = Odometry::start(Vector::ZERO, 0.0, 0.1, &cfg, &mut rng);
        // Straight 1 m in 100 steps.
        for k in 1..=100 {
            let d = 0.01 * k as f64;
            odo.update([d, d], None, 0.05, &cfg, &mut rng);
        }
        assert!((odo.position - Vector::new(1.0, 0.0)).length() < 1e-4);
        // A quarter turn in place on encoders alone.
        let quarter = 0.25 * std::f64::consts::PI * 0.1;
        odo.update([1.0 - quarter, 1.0 + quarter], None, 0.05, &cfg, &mut rng);
        assert!((odo.heading - std::f32::consts::FRAC_PI_2).abs() < 1e-5);
    }
}
