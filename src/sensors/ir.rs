//! Infrared proximity ring: 8 TCRT5000 sensors, 45° apart on the rim, raw value 0..1023
//! (1023 = touching), from a response curve interpolated linearly in distance (by default
//! K-Team's measured curve, docs/robot.md §3, user manual fig. 10, digitised ±10 counts; a
//! calibrated robot's own with `sensors.ir_curve`), plus Gaussian noise in raw counts.
//!
//! Distances are measured from the sensor (on the body rim) to the obstacle surface, in metres.
//! One ray per sensor along its axis, cast against the obstacles and robots within reach only.
//! Scenario keys: `sensors.ir_range`, `ir_floor_value`, `ir_noise_sigma`, `ir_curve`.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rapier2d::math::Vector;

use super::ir_lanes::{read_ring, Ring};
use super::{rotate, unit, DrawContext, Readout, SenseContext, Sensor};
use crate::config::{Domain, Param};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::obs::Block;

/// Number of ring sensors.
pub const IR_COUNT: usize = 8;

/// Bearings (rad, CCW from forward) in K-Team order: back-left, left, front-left, front,
/// front-right, right, back-right, back.
pub const IR_BEARINGS: [f32; IR_COUNT] = [
    135.0 * DEG,
    90.0 * DEG,
    45.0 * DEG,
    0.0,
    -45.0 * DEG,
    -90.0 * DEG,
    -135.0 * DEG,
    180.0 * DEG,
];
const DEG: f32 = std::f32::consts::PI / 180.0;

/// Largest raw value.
pub const IR_MAX_RAW: f32 = 1023.0;

/// Distances (mm) of the response curve's points (K-Team fig. 10, docs/robot.md §3); the raw
/// counts at them are `sensors.ir_curve`. The value beyond the last point comes from the
/// scenario's floor value (floor reflection), reached at `ir_range`.
pub const CURVE_MM: [f32; 16] = [
    0.0, 10.0, 20.0, 30.0, 35.0, 40.0, 45.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0, 120.0, 150.0,
    200.0,
];
/// K-Team's raw counts at [`CURVE_MM`] on white paper: the default of `sensors.ir_curve`.
pub const CURVE_RAW: [f32; 16] = [
    1018.0, 1012.0, 1002.0, 979.0, 889.0, 764.0, 597.0, 492.0, 380.0, 319.0, 254.0, 228.0, 199.0,
    163.0, 133.0, 111.0,
];

crate::config_table! {
    /// The IR ring's keys in `[sensors]` (robot.md §2–3).
    pub struct IrConfig {
        /// m, beyond this the IR reads the floor value
        ir_range: f32 = 0.25 => Domain::above(0.2).at_most(1.0),
        /// raw count with nothing in range (floor reflection) [E]; may be a [low, high] range
        ir_floor_value: Param = 100.0 => Domain::range(0.0, IR_MAX_RAW as f64),
        /// raw counts, Gaussian, per reading [E]; may be a range
        ir_noise_sigma: Param = 10.0 => Domain::range(0.0, IR_MAX_RAW as f64),
        /// raw counts on white paper at 0, 10, 20, 30, 35, 40, 45, 50, 60, 70, 80, 90, 100, 120, 150 and 200 mm from the sensor, interpolated linearly; non-increasing (K-Team manual fig. 10, robot.md §3; khepera-gym calibrate measures a robot's own)
        ir_curve: [f32; 16] = [1018.0, 1012.0, 1002.0, 979.0, 889.0, 764.0, 597.0, 492.0, 380.0, 319.0, 254.0, 228.0, 199.0, 163.0, 133.0, 111.0] => Domain::range(0.0, IR_MAX_RAW as f64),
    }
}

/// The IR ring's response and noise.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct IrModel {
    /// Distance (m) beyond which a sensor reads the floor value.
    pub range: f32,
    /// Raw reading with nothing in range.
    pub floor_value: f32,
    /// Standard deviation of the additive Gaussian noise (raw counts).
    pub noise_sigma: f32,
    /// Raw counts on white paper at the distances [`CURVE_MM`].
    pub curve: [f32; 16],
}

impl IrModel {
    /// Noise-free raw value at `distance` metres (None: nothing within range).
    pub fn mean_raw(&self, distance: Option<f32>) -> f32 {
        let d = match distance {
            Some(d) if d < self.range => d.max(0.0) * 1000.0,
            _ => return self.floor_value,
        };
        let curve = &self.curve;
        let last = CURVE_MM.len() - 1;
        if d >= CURVE_MM[last] {
            // From the last measured point down to the floor value at the range limit.
            let span = self.range * 1000.0 - CURVE_MM[last];
            let t = (d - CURVE_MM[last]) / span;
            return curve[last] + t * (self.floor_value - curve[last]);
        }
        let i = CURVE_MM.partition_point(|&x| x <= d).clamp(1, last);
        let (x0, x1) = (CURVE_MM[i - 1], CURVE_MM[i]);
        let (y0, y1) = (curve[i - 1], curve[i]);
        y0 + (d - x0) / (x1 - x0) * (y1 - y0)
    }

    /// A raw reading (integer count 0..1023) with noise drawn from `rng`. The noise draw happens
    /// whatever the distance, so the random stream does not depend on the scene.
    pub fn read<R: Rng>(&self, distance: Option<f32>, rng: &mut R) -> u16 {
        self.read_surface(distance, 1.0, rng)
    }

    /// Like [`IrModel::read`] for a surface of infrared `reflectance` relative to white paper:
    /// the reading rises above the floor value in proportion to it [E] (a dark obstacle reads
    /// lower than a white one at the same distance; Webots likewise scales by a reflectance).
    pub fn read_surface<R: Rng>(
        &self,
        distance: Option<f32>,
        reflectance: f32,
        rng: &mut R,
    ) -> u16 {
        let noise: f32 = rng.sample(StandardNormal);
        self.surface_raw(distance, reflectance, noise)
    }

    /// [`IrModel::read_surface`] with its standard normal draw `noise` given.
    #[inline]
    pub fn surface_raw(&self, distance: Option<f32>, reflectance: f32, noise: f32) -> u16 {
        let white = self.mean_raw(distance);
        let mean = if reflectance == 1.0 {
            white
        } else {
            self.floor_value + reflectance * (white - self.floor_value)
        };
        let raw = mean + self.noise_sigma * noise;
        // Round half up; the value is clamped non-negative first (avoids a libm call).
        (raw.clamp(0.0, IR_MAX_RAW) + 0.5) as u16
    }

    /// Normalised proximity in [0, 1]: 0 at the floor value (nothing seen), 1 at 1023.
    #[inline]
    pub fn normalise(&self, raw: u16) -> f32 {
        ((raw as f32 - self.floor_value) / (IR_MAX_RAW - self.floor_value)).clamp(0.0, 1.0)
    }
}

/// One robot's IR ring reading.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct IrReading {
    /// Raw readings (0..1023), K-Team order.
    pub raw: [u16; IR_COUNT],
    /// True distance (m) each ray travelled before a hit (its range when none), for drawing.
    pub hit: [f32; IR_COUNT],
}

/// The 8-sensor IR proximity ring as a [`Sensor`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct IrRing {
    /// Response and noise.
    pub model: IrModel,
    // Constants and scratch buffers: not state.
    #[serde(skip, default = "ir_dirs")]
    dirs: [Vector; IR_COUNT],
    #[serde(skip)]
    near_shapes: Vec<usize>,
    #[serde(skip)]
    near_others: Vec<Vector>,
}

fn ir_dirs() -> [Vector; IR_COUNT] {
    IR_BEARINGS.map(unit)
}

impl Sensor for IrRing {
    const NAME: &'static str = "ir";
    type Config = IrConfig;
    type Reading = IrReading;

    fn new(cfg: &IrConfig) -> Self {
        Self {
            model: IrModel {
                range: cfg.ir_range,
                floor_value: cfg.ir_floor_value.bounds().0,
                noise_sigma: cfg.ir_noise_sigma.bounds().0,
                curve: cfg.ir_curve,
            },
            dirs: ir_dirs(),
            near_shapes: Vec::new(),
            near_others: Vec::new(),
        }
    }

    fn validate(cfg: &IrConfig, origin: &str) -> Result<()> {
        // The domains check each key; what is left relates keys to each other.
        let curve = &cfg.ir_curve;
        if !curve.windows(2).all(|pair| pair[1] <= pair[0]) {
            return Err(Error::config(
                origin,
                "sensors.ir_curve",
                format!("must not increase with distance, got {curve:?}"),
            ));
        }
        let last = curve[curve.len() - 1];
        if cfg.ir_floor_value.max() > last {
            return Err(Error::config(
                origin,
                "sensors.ir_floor_value",
                format!(
                    "must be in [0, {last}] (sensors.ir_curve reads {last} at 0.2 m), got {:?}",
                    cfg.ir_floor_value
                ),
            ));
        }
        Ok(())
    }

    fn randomise(&mut self, cfg: &IrConfig, rng: &mut ChaCha8Rng) {
        self.model.floor_value = cfg.ir_floor_value.sample(rng);
        self.model.noise_sigma = cfg.ir_noise_sigma.sample(rng);
    }

    fn reach(&self, radius: f32) -> f32 {
        // A ray of `range` from the rim meets discs whose centre is within this.
        2.0 * radius + self.model.range
    }

    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut IrReading) {
        let (pos, radius) = (ctx.position, ctx.radius);
        // The IR rays are short: only obstacles and robots within reach of the rim can be hit.
        let reach = radius + self.model.range;
        self.near_others.clear();
        for other in ctx.others {
            if (*other - pos).length() < reach + radius {
                self.near_others.push(*other);
            }
        }
        self.near_shapes.clear();
        for (k, shape) in ctx.scene.shapes.iter().enumerate() {
            if (shape.center - pos).length() - shape.bound_radius < reach {
                self.near_shapes.push(k);
            }
        }
        // The rays draw nothing: the noise of the eight readings comes first, in K-Team order,
        // as each reading drew its own before.
        let mut noise = [0.0f32; IR_COUNT];
        for n in &mut noise {
            *n = rng.sample(StandardNormal);
        }
        let ring = Ring {
            model: &self.model,
            dirs: &self.dirs,
            position: pos,
            radius,
            sin_cos: ctx.sin_cos,
            scene: ctx.scene,
            shapes: &self.near_shapes,
            // Every robot's shell reflects alike: which of two robots met at the same distance
            // is hit does not change the reading, so their order does not matter.
            others: &self.near_others,
            robot_reflectance: ctx.robot_reflectance,
            noise: &noise,
        };
        read_ring(&ring, reading);
    }

    fn block(&self) -> Block {
        Block::new(Self::NAME, IR_COUNT, 0.0, 1.0)
    }

    fn obs_len(&self) -> usize {
        IR_COUNT
    }

    #[inline]
    fn observe(&self, reading: &IrReading, out: &mut [f32]) {
        for (o, raw) in out.iter_mut().zip(reading.raw) {
            *o = self.model.normalise(raw);
        }
    }

    fn readout(&self, reading: &IrReading, out: &mut Readout) {
        out.ints("ir_raw", IR_COUNT, &reading.raw.map(i64::from));
    }

    fn draw(&self, at: &DrawContext, reading: &IrReading, marks: &mut Vec<Mark>) {
        let (s, c) = at.heading.sin_cos();
        for ((dir, hit), raw) in self.dirs.iter().zip(reading.hit).zip(reading.raw) {
            let d = rotate(*dir, c, s);
            let start = at.position + at.radius * d;
            let p = self.model.normalise(raw);
            marks.push(Mark::Ray {
                from: start,
                to: start + hit.min(self.model.range) * d,
                // Green when nothing is seen, toward red as an obstacle nears.
                colour: [
                    (60.0 + 195.0 * p) as u8,
                    (170.0 * (1.0 - p) + 40.0) as u8,
                    40,
                ],
                alpha: (110.0 + 145.0 * p) as u8,
                width: 0.007,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODEL: IrModel = IrModel {
        range: 0.25,
        floor_value: 100.0,
        noise_sigma: 0.0,
        curve: CURVE_RAW,
    };

    #[test]
    fn curve_points_are_exact() {
        for (mm, raw) in CURVE_MM.iter().zip(CURVE_RAW) {
            let got = MODEL.mean_raw(Some(mm / 1000.0));
            assert!((got - raw).abs() < 1e-3, "{mm} mm: {got} != {raw}");
        }
    }

    #[test]
    fn interpolates_and_falls_to_floor() {
        assert!((MODEL.mean_raw(Some(0.055)) - 436.0).abs() < 1e-3);
        assert!((MODEL.mean_raw(Some(0.225)) - 105.5).abs() < 1e-3);
        assert_eq!(MODEL.mean_raw(Some(0.25)), 100.0);
        assert_eq!(MODEL.mean_raw(None), 100.0);
        assert_eq!(MODEL.normalise(100), 0.0);
        assert_eq!(MODEL.normalise(1023), 1.0);
    }

    #[test]
    fn a_robots_own_curve_replaces_kteams() {
        let mut own = MODEL;
        own.curve = CURVE_RAW.map(|raw| 0.9 * raw);
        assert!((own.mean_raw(Some(0.04)) - 0.9 * 764.0).abs() < 1e-3);
        assert!((own.mean_raw(Some(0.055)) - 0.9 * 436.0).abs() < 1e-3);
        let mut cfg = IrConfig::default();
        IrRing::validate(&cfg, "f.toml").expect("the default");
        cfg.ir_curve[4] = 990.0; // rises from 979 at 30 mm
        let e = IrRing::validate(&cfg, "f.toml").unwrap_err().to_string();
        assert!(e.contains("sensors.ir_curve"), "{e}");
        let mut cfg = IrConfig::default();
        cfg.ir_curve[15] = 90.0; // below the floor value of 100
        let e = IrRing::validate(&cfg, "f.toml").unwrap_err().to_string();
        assert!(
            e.contains("sensors.ir_floor_value") && e.contains("[0, 90]"),
            "{e}"
        );
    }

    #[test]
    fn curve_is_monotone() {
        let mut prev = f32::INFINITY;
        for i in 0..=250 {
            let v = MODEL.mean_raw(Some(i as f32 / 1000.0));
            assert!(v <= prev);
            prev = v;
        }
    }
}
