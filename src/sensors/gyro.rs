//! Gyroscope: the z axis of the ST LSM330DLC at the robot's rotation centre (K-Team manual §4.10,
//! docs/robot.md §6): ±2000 °/s, read as raw counts of 0.066 °/s (`KH4_GYRO_DEG_S`). The reading is
//! the body's yaw rate over the last control step plus a constant bias (the zero-rate offset) and
//! Gaussian noise, quantised to whole counts and clamped to the full scale. Scenario keys:
//! `sensors.gyro_noise_sigma`, `gyro_bias`.
//!
//! Units: raw counts in `sensor_readings()["gyro_raw"]`, rad/s in `["gyro_z"]`; the observation
//! block `gyro` is the rate over the full scale, in [-1, 1]. Robot frame z up: counter-clockwise
//! positive.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::{DrawContext, Readout, SenseContext, Sensor};
use crate::config::{Domain, Param};
use crate::draw::Mark;
use crate::obs::Block;

/// One raw count (°/s): `KH4_GYRO_DEG_S` of libkhepera (docs/robot.md §6, §10).
pub const DEG_S_PER_COUNT: f32 = 0.066;
/// Full scale (°/s): the ±2000 °/s range K-Team configures (manual §4.10).
pub const FULL_SCALE_DEG_S: f32 = 2000.0;

crate::config_table! {
    /// The gyroscope's keys in `[sensors]`.
    pub struct GyroConfig {
        /// °/s, Gaussian, per reading [E: the LSM330DLC's rate noise density 0.03 °/s/√Hz over its 95 Hz output, averaged over a reading]
        gyro_noise_sigma: f32 = 0.2 => Domain::range(0.0, FULL_SCALE_DEG_S as f64),
        /// °/s added to every reading: the gyroscope's zero-rate offset (0 = none; khepera-gym calibrate measures a robot's own) [E]; may be a [low, high] range, drawn per episode
        gyro_bias: Param = 0.0 => Domain::range(-(FULL_SCALE_DEG_S as f64), FULL_SCALE_DEG_S as f64),
    }
}

/// One robot's gyroscope reading.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct GyroReading {
    /// Raw counts of 0.066 °/s.
    pub raw: i32,
    /// The same in rad/s.
    pub rate: f32,
}

/// The z-axis gyroscope as a [`Sensor`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Gyro {
    /// Standard deviation of the noise (°/s).
    pub noise_sigma: f32,
    /// Zero-rate offset added to every reading (°/s).
    pub bias: f32,
}

impl Sensor for Gyro {
    const NAME: &'static str = "gyro";
    type Config = GyroConfig;
    type Reading = GyroReading;

    fn new(cfg: &GyroConfig) -> Self {
        Self {
            noise_sigma: cfg.gyro_noise_sigma,
            bias: cfg.gyro_bias.bounds().0,
        }
    }

    fn randomise(&mut self, cfg: &GyroConfig, rng: &mut ChaCha8Rng) {
        self.bias = cfg.gyro_bias.sample(rng);
    }

    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut GyroReading) {
        let noise: f32 = rng.sample(StandardNormal);
        let deg_s = ctx.yaw_rate.to_degrees() + self.bias + self.noise_sigma * noise;
        let counts = (deg_s / DEG_S_PER_COUNT).round();
        let limit = (FULL_SCALE_DEG_S / DEG_S_PER_COUNT).round();
        reading.raw = counts.clamp(-limit, limit) as i32;
        reading.rate = (reading.raw as f32 * DEG_S_PER_COUNT).to_radians();
    }

    fn block(&self) -> Block {
        Block::new(Self::NAME, 1, -1.0, 1.0)
    }

    fn obs_len(&self) -> usize {
        1
    }

    #[inline]
    fn observe(&self, reading: &GyroReading, out: &mut [f32]) {
        out[0] = (reading.raw as f32 * DEG_S_PER_COUNT / FULL_SCALE_DEG_S).clamp(-1.0, 1.0);
    }

    fn readout(&self, reading: &GyroReading, out: &mut Readout) {
        out.ints("gyro_raw", 0, &[i64::from(reading.raw)]);
        out.reals("gyro_z", 0, &[reading.rate]);
    }

    fn draw(&self, _at: &DrawContext, _reading: &GyroReading, _marks: &mut Vec<Mark>) {}

    fn reach(&self, _radius: f32) -> f32 {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::scene::Scene;
    use rand::SeedableRng;

    #[test]
    fn reads_the_yaw_rate_in_whole_counts() {
        let scene = Scene::arena(2.0, 2.0, 0.05);
        let mut gyro = Gyro {
            noise_sigma: 0.0,
            bias: 0.0,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut reading = GyroReading::default();
        let ctx = SenseContext {
            scene: &scene,
            position: rapier2d::math::Vector::ZERO,
            sin_cos: (0.0, 1.0),
            radius: 0.07,
            others: &[],
            other_leds: &[],
            other_ids: &[],
            robot_reflectance: 1.0,
            yaw_rate: 1.0,
            acceleration: rapier2d::math::Vector::ZERO,
            floor: &crate::world::floor::Floor::default(),
            floor_marks: &crate::world::floor::FloorMarks::default(),
            dt: 0.05,
            fresh: false,
        };
        gyro.read(&ctx, &mut rng, &mut reading);
        // 1 rad/s = 57.2958 °/s = 868.1 counts → 868.
        assert_eq!(reading.raw, 868);
        assert!((reading.rate - 1.0).abs() < DEG_S_PER_COUNT.to_radians());
        // A bias of 1.32 °/s adds 20 counts to every reading, at rest too.
        gyro.bias = 1.32;
        gyro.read(&ctx, &mut rng, &mut reading);
        assert_eq!(reading.raw, 888);
        let at_rest = SenseContext {
            yaw_rate: 0.0,
            ..ctx
        };
        gyro.read(&at_rest, &mut rng, &mut reading);
        assert_eq!(reading.raw, 20);
    }

    #[test]
    fn a_bias_beyond_the_full_scale_is_an_error_naming_the_key() {
        let mut cfg = GyroConfig::default();
        Gyro::validate(&cfg, "f.toml").expect("the default");
        cfg.gyro_bias = Param::Range([-2.0, 2.0]);
        Gyro::validate(&cfg, "f.toml").expect("a range");
        for bad in [
            Param::Value(2500.0),
            Param::Value(f32::NAN),
            Param::Range([1.0, -1.0]),
        ] {
            cfg.gyro_bias = bad;
            let e = Gyro::validate(&cfg, "f.toml").unwrap_err().to_string();
            assert!(e.contains("sensors.gyro_bias"), "{e}");
        }
    }
}
