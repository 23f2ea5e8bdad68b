//! The four ground (floor) infrared sensors under the front of the Khepera IV (docs/robot.md §4):
//! K-Team order left, front-left, front-right, right at (+20, +58.5), (+62, +10), (+62, −10),
//! (+20, −58.5) mm in the robot frame (Webots `Khepera4.proto`; ARGoS agrees within 1 mm),
//! 4.5 mm above the floor, the same TCRT5000 as the ring, read as 0..1023.
//!
//! Model: raw = black + (white − black)·g, with g the floor's grey level (0 black .. 1 white
//! paper) averaged over the sensor's spot (`ground_spot_radius`, 3 mm [E]: the centre and 8
//! points at 0.7 of the radius), plus Gaussian noise, rounded and clamped. White reads
//! `ground_white` = 954 (Webots' ground lookup table at 4.5 mm [S]), black `ground_black` = 300
//! [E]; K-Team's line-following demo takes < 800 as black (docs/robot.md §4). Noise
//! `ground_noise_sigma` = 4 counts (Webots: 0.45 % of the value at 4.5 mm [S]).
//!
//! Units: `sensor_readings()["ground_raw"]` counts 0..1023, (n_robots, 4); the observation block
//! `ground` is raw / 1023. Not carried by default (`[sensors] carry`).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rapier2d::math::Vector;

use super::{rotate, DrawContext, Readout, SenseContext, Sensor};
use crate::config::Domain;
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::obs::Block;

/// Number of ground sensors.
pub const GROUND_COUNT: usize = 4;
/// Their positions in the robot frame (m), K-Team order: left, front-left, front-right, right
/// (docs/robot.md §4, Webots `Khepera4.proto`).
pub const GROUND_POSITIONS: [[f32; 2]; GROUND_COUNT] = [
    [0.020, 0.0585],
    [0.062, 0.010],
    [0.062, -0.010],
    [0.020, -0.0585],
];
/// Largest raw reading.
pub const GROUND_MAX: f32 = 1023.0;
/// K-Team's line-following demo's threshold: darker (lower) reads as black (docs/robot.md §4).
pub const KTEAM_BLACK_THRESHOLD: i32 = 800;

crate::config_table! {
    /// The ground sensors' keys in `[sensors]`.
    pub struct GroundConfig {
        /// raw count over white paper [S: Webots ground lookup table at 4.5 mm, robot.md §4]
        ground_white: f32 = 954.0 => Domain::range(0.0, GROUND_MAX as f64),
        /// raw count over black tape [E]
        ground_black: f32 = 300.0 => Domain::range(0.0, GROUND_MAX as f64),
        /// raw counts, Gaussian, per reading [S: Webots, 0.45 % of the value at 4.5 mm]
        ground_noise_sigma: f32 = 4.0 => Domain::range(0.0, GROUND_MAX as f64),
        /// m, radius of the floor spot a sensor averages [E]
        ground_spot_radius: f32 = 0.003 => Domain::range(0.0, 0.02),
    }
}

/// One robot's ground readings.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct GroundReading {
    /// Raw counts, K-Team order.
    pub raw: [i32; GROUND_COUNT],
}

/// The four ground sensors as a [`Sensor`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct GroundSensors {
    /// Raw count over white.
    pub white: f32,
    /// Raw count over black.
    pub black: f32,
    /// Noise (counts).
    pub noise_sigma: f32,
    /// Spot radius (m).
    pub spot_radius: f32,
}

impl GroundSensors {
    /// The noiseless raw value over grey level `g`.
    pub fn response(&self, g: f32) -> f32 {
        self.black + (self.white - self.black) * g
    }
}

impl Sensor for GroundSensors {
    const NAME: &'static str = "ground";
    type Config = GroundConfig;
    type Reading = GroundReading;

    fn new(cfg: &GroundConfig) -> Self {
        Self {
            white: cfg.ground_white,
            black: cfg.ground_black,
            noise_sigma: cfg.ground_noise_sigma,
            spot_radius: cfg.ground_spot_radius,
        }
    }

    fn validate(cfg: &GroundConfig, origin: &str) -> Result<()> {
        if cfg.ground_black >= cfg.ground_white {
            return Err(Error::config(
                origin,
                "sensors.ground_black",
                format!(
                    "must be below sensors.ground_white ({}): black tape reflects less, got {}",
                    cfg.ground_white, cfg.ground_black
                ),
            ));
        }
        Ok(())
    }

    fn randomise(&mut self, _cfg: &GroundConfig, _rng: &mut ChaCha8Rng) {}

    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut GroundReading) {
        let (s, c) = ctx.sin_cos;
        let plain = ctx.floor.is_plain(ctx.floor_marks);
        for (k, at) in GROUND_POSITIONS.iter().enumerate() {
            let centre = ctx.position + rotate(Vector::new(at[0], at[1]), c, s);
            let grey = if plain {
                ctx.floor.background
            } else {
                ctx.floor
                    .spot_grey(centre, self.spot_radius, ctx.floor_marks)
            };
            let noise: f32 = rng.sample(StandardNormal);
            let value = self.response(grey) + self.noise_sigma * noise;
            reading.raw[k] = value.round().clamp(0.0, GROUND_MAX) as i32;
        }
    }

    fn block(&self) -> Block {
        Block::new(Self::NAME, GROUND_COUNT, 0.0, 1.0)
    }

    fn obs_len(&self) -> usize {
        GROUND_COUNT
    }

    #[inline]
    fn observe(&self, reading: &GroundReading, out: &mut [f32]) {
        for (o, raw) in out.iter_mut().zip(reading.raw) {
            *o = raw as f32 / GROUND_MAX;
        }
    }

    fn readout(&self, reading: &GroundReading, out: &mut Readout) {
        out.ints("ground_raw", GROUND_COUNT, &reading.raw.map(i64::from));
    }

    fn draw(&self, at: &DrawContext, reading: &GroundReading, marks: &mut Vec<Mark>) {
        let (s, c) = at.heading.sin_cos();
        for (k, p) in GROUND_POSITIONS.iter().enumerate() {
            let centre = at.position + rotate(Vector::new(p[0], p[1]), c, s);
            let black = reading.raw[k] < KTEAM_BLACK_THRESHOLD;
            marks.push(Mark::Cross {
                position: centre,
                size: 0.008,
                colour: if black { [214, 39, 40] } else { [44, 160, 44] },
            });
        }
    }

    fn reach(&self, _radius: f32) -> f32 {
        0.0
    }
}
