//! Inertial measurement unit: the ST LSM330DLC at the robot's rotation centre (K-Team manual
//! §4.9–4.10, docs/robot.md §6), an accelerometer and a gyroscope of three axes each.
//!
//! - **Accelerometer**: ±2 g, read in whole milli-g as libkhepera's `kh4_measure_acc` gives them
//!   (raw >> 4, /1000 for g; docs/robot.md §6). It measures the body's acceleration in the plane
//!   (the world's contacts included, since it comes from how the body really moved) and gravity on
//!   z. K-Team's axes are x forward, y left, and z negative with gravity (docs/robot.md §6, manual
//!   §4.9): a robot at rest on a level floor reads (0, 0, −1) g. The planar acceleration is the
//!   change of the body's mean velocity between the last two control steps, rotated into the
//!   robot's frame at the step boundary: the mean acceleration over the 50 ms around the start of
//!   the last step. The real chip samples at 100 Hz and the library returns its last 100 ms of
//!   samples, so a real reading lags about as much. Constant speed on a straight line reads 0;
//!   constant speed v on a circle of yaw rate ω reads the centripetal v·ω on y; a robot stopped
//!   by a wall within a step reads a spike of at least v/(2·dt) over two readings.
//! - **Gyroscope**: ±2000 °/s in raw counts of 0.066 °/s (`KH4_GYRO_DEG_S`), as the `gyro`
//!   sensor's z axis; x and y (roll and pitch rates) are 0 on a planar robot, plus noise.
//!
//! Noise is Gaussian per reading and axis, then the reading is quantised and clamped to the full
//! scale. The IMU is not carried by default (`[sensors] carry`); carried, it draws six numbers
//! per robot and step from the world's stream. Scenario keys: `sensors.imu_accel_noise_sigma`,
//! `sensors.imu_gyro_noise_sigma`.
//!
//! Units: `sensor_readings()["accel_raw"]` milli-g counts and `["accel_g"]` g, (x, y, z);
//! `["imu_gyro_raw"]` counts of 0.066 °/s and `["imu_gyro"]` rad/s, (x, y, z). The observation
//! block `imu` (6 values) is each axis over its full scale, in [-1, 1]: accel x, y, z, gyro x,
//! y, z.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::gyro::{DEG_S_PER_COUNT, FULL_SCALE_DEG_S};
use super::{DrawContext, Readout, SenseContext, Sensor};
use crate::config::Domain;
use crate::draw::Mark;
use crate::obs::Block;

/// Standard gravity (m/s²), the unit "g" of the accelerometer (ISO 80000-3).
pub const STANDARD_GRAVITY: f32 = 9.80665;
/// One accelerometer count (g): libkhepera returns (raw >> 4) / 1000 g (docs/robot.md §6).
pub const G_PER_COUNT: f32 = 0.001;
/// Accelerometer full scale (g): the ±2 g range K-Team configures (manual §4.9).
pub const ACCEL_FULL_SCALE_G: f32 = 2.0;
/// Sign of gravity on the accelerometer's z axis: K-Team's z is negative with gravity
/// (docs/robot.md §6).
pub const GRAVITY_Z_G: f32 = -1.0;

crate::config_table! {
    /// The IMU's keys in `[sensors]`.
    pub struct ImuConfig {
        /// g, Gaussian, per reading and axis [E: the LSM330DLC's accelerometer noise density, about 0.2 mg/√Hz, over its 50 Hz bandwidth]
        imu_accel_noise_sigma: f32 = 0.002 => Domain::range(0.0, ACCEL_FULL_SCALE_G as f64),
        /// °/s, Gaussian, per reading and axis [E: as sensors.gyro_noise_sigma]
        imu_gyro_noise_sigma: f32 = 0.2 => Domain::range(0.0, FULL_SCALE_DEG_S as f64),
    }
}

/// One robot's IMU reading.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct ImuReading {
    /// Accelerometer, x forward, y left, z (negative with gravity): counts of 1 mg.
    pub accel_raw: [i32; 3],
    /// The same in g.
    pub accel: [f32; 3],
    /// Gyroscope, rates about x, y, z (counter-clockwise positive): counts of 0.066 °/s.
    pub gyro_raw: [i32; 3],
    /// The same in rad/s.
    pub gyro: [f32; 3],
}

/// The accelerometer and gyroscope as a [`Sensor`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Imu {
    /// Standard deviation of the accelerometer's noise (g).
    pub accel_noise_sigma: f32,
    /// Standard deviation of the gyroscope's noise (°/s).
    pub gyro_noise_sigma: f32,
}

/// `value` plus `sigma`-scaled noise, in whole counts of `per_count`, clamped to ±`full_scale`.
fn quantise(value: f32, sigma: f32, per_count: f32, full_scale: f32, rng: &mut ChaCha8Rng) -> i32 {
    let noise: f32 = rng.sample(StandardNormal);
    let limit = (full_scale / per_count).round();
    ((value + sigma * noise) / per_count)
        .round()
        .clamp(-limit, limit) as i32
}

impl Sensor for Imu {
    const NAME: &'static str = "imu";
    type Config = ImuConfig;
    type Reading = ImuReading;

    fn new(cfg: &ImuConfig) -> Self {
        Self {
            accel_noise_sigma: cfg.imu_accel_noise_sigma,
            gyro_noise_sigma: cfg.imu_gyro_noise_sigma,
        }
    }

    fn randomise(&mut self, _cfg: &ImuConfig, _rng: &mut ChaCha8Rng) {}

    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut ImuReading) {
        let a = ctx.acceleration / STANDARD_GRAVITY;
        for (axis, value) in [a.x, a.y, GRAVITY_Z_G].into_iter().enumerate() {
            let counts = quantise(
                value,
                self.accel_noise_sigma,
                G_PER_COUNT,
                ACCEL_FULL_SCALE_G,
                rng,
            );
            reading.accel_raw[axis] = counts;
            reading.accel[axis] = counts as f32 * G_PER_COUNT;
        }
        let rates = [0.0, 0.0, ctx.yaw_rate.to_degrees()];
        for (axis, deg_s) in rates.into_iter().enumerate() {
            let counts = quantise(
                deg_s,
                self.gyro_noise_sigma,
                DEG_S_PER_COUNT,
                FULL_SCALE_DEG_S,
                rng,
            );
            reading.gyro_raw[axis] = counts;
            reading.gyro[axis] = (counts as f32 * DEG_S_PER_COUNT).to_radians();
        }
    }

    fn block(&self) -> Block {
        Block::new(Self::NAME, 6, -1.0, 1.0)
    }

    fn obs_len(&self) -> usize {
        6
    }

    #[inline]
    fn observe(&self, reading: &ImuReading, out: &mut [f32]) {
        for axis in 0..3 {
            out[axis] = (reading.accel[axis] / ACCEL_FULL_SCALE_G).clamp(-1.0, 1.0);
            let deg_s = reading.gyro_raw[axis] as f32 * DEG_S_PER_COUNT;
            out[3 + axis] = (deg_s / FULL_SCALE_DEG_S).clamp(-1.0, 1.0);
        }
    }

    fn readout(&self, reading: &ImuReading, out: &mut Readout) {
        out.ints("accel_raw", 3, &reading.accel_raw.map(i64::from));
        out.reals("accel_g", 3, &reading.accel);
        out.ints("imu_gyro_raw", 3, &reading.gyro_raw.map(i64::from));
        out.reals("imu_gyro", 3, &reading.gyro);
    }

    fn draw(&self, _at: &DrawContext, _reading: &ImuReading, _marks: &mut Vec<Mark>) {}

    fn reach(&self, _radius: f32) -> f32 {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::scene::Scene;
    use rand::SeedableRng;
    use rapier2d::math::Vector;

    fn read(acceleration: Vector, yaw_rate: f32) -> ImuReading {
        let scene = Scene::arena(2.0, 2.0, 0.05);
        let mut imu = Imu {
            accel_noise_sigma: 0.0,
            gyro_noise_sigma: 0.0,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut reading = ImuReading::default();
        let ctx = SenseContext {
            scene: &scene,
            position: Vector::ZERO,
            sin_cos: (0.0, 1.0),
            radius: 0.07,
            others: &[],
            other_leds: &[],
            other_ids: &[],
            robot_reflectance: 1.0,
            yaw_rate,
            acceleration,
            floor: &crate::world::floor::Floor::default(),
            floor_marks: &crate::world::floor::FloorMarks::default(),
            dt: 0.05,
            fresh: false,
        };
        imu.read(&ctx, &mut rng, &mut reading);
        reading
    }

    #[test]
    fn at_rest_it_reads_gravity_on_z_only() {
        let r = read(Vector::ZERO, 0.0);
        assert_eq!(r.accel_raw, [0, 0, -1000]);
        assert_eq!(r.gyro_raw, [0, 0, 0]);
    }

    #[test]
    fn reads_acceleration_in_milli_g_and_clamps_at_two_g() {
        // 1 m/s² forward = 101.97 mg → 102 counts; 30 m/s² left = 3.06 g → clamped to 2 g.
        let r = read(Vector::new(1.0, 30.0), 1.0);
        assert_eq!(r.accel_raw[0], 102);
        assert_eq!(r.accel_raw[1], 2000);
        // 1 rad/s = 868.1 counts of 0.066 °/s, as the gyro sensor reads it.
        assert_eq!(r.gyro_raw[2], 868);
    }
}
