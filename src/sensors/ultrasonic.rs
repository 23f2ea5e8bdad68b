//! Ultrasonic sensors: 5 Prowave 400PT12B transceivers (left, front-left, front, front-right,
//! right), readings in whole centimetres from 25 to 200 cm with the K-Team library's codes for
//! "too close" (0), "nothing in range" (1000) and "disabled" (2000). Spec §5.
//!
//! One ray per sensor along its axis (the beam width is not documented; Webots uses one ray too),
//! cast against every obstacle and robot (the range is long). A sensor measures the distance plus
//! a constant offset (`us_offset`, a robot's own from calibration) plus noise; the codes follow
//! from the measured distance. Scenario keys: `sensors.us_min_range`, `us_max_range`,
//! `us_noise_sigma`, `us_enabled`, `us_period`, `us_acceptance`, `us_offset`.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rapier2d::math::Vector;

use super::{rotate, unit, DrawContext, Readout, SenseContext, Sensor};
use crate::config::{limits, Domain, Param};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::obs::Block;

/// Number of ultrasonic sensors.
pub const US_COUNT: usize = 5;
/// Bearings (rad, CCW from forward): left, front-left, front, front-right, right.
pub const US_BEARINGS: [f32; US_COUNT] = [
    std::f32::consts::FRAC_PI_2,
    std::f32::consts::FRAC_PI_4,
    0.0,
    -std::f32::consts::FRAC_PI_4,
    -std::f32::consts::FRAC_PI_2,
];
/// Code for an object closer than the minimum range.
pub const US_TOO_CLOSE: i32 = 0;
/// Code for nothing within the maximum range.
pub const US_NOTHING: i32 = 1000;
/// Code for a disabled sensor.
pub const US_DISABLED: i32 = 2000;

crate::config_table! {
    /// The ultrasonic sensors' keys in `[sensors]` (robot.md §5).
    pub struct UsConfig {
        /// m, closer objects read code 0 ("too close")
        us_min_range: f32 = 0.25 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, farther than this reads code 1000 ("nothing")
        us_max_range: f32 = 2.0 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, Gaussian [E] (K-Team states +-2 cm tolerance); may be a range
        us_noise_sigma: Param = 0.01 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// left, front-left, front, front-right, right; off reads 2000
        us_enabled: [bool; 5] = [true, true, true, true, true],
        /// s between two readings of the five sensors: 20 ms each, 100 ms for all five (K-Team manual §4.2); a reading holds until the next (0 = every step)
        us_period: f32 = 0.1 => Domain::range(0.0, 10.0),
        /// rad, largest angle between the beam and a surface's normal that still echoes [S: Webots' sonar model, 22.5°]; pi/2 = any
        us_acceptance: f32 = 0.39269908169872414 => Domain::POSITIVE.at_most(std::f64::consts::FRAC_PI_2),
        /// m added to every measured distance (0 = none; khepera-gym calibrate measures a robot's own) [E]; may be a [low, high] range, drawn per episode
        us_offset: Param = 0.0 => Domain::above(-0.5).below(0.5),
    }
}

/// The ultrasonic model.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct UsModel {
    /// Closest measurable distance (m).
    pub min_range: f32,
    /// Farthest measurable distance (m).
    pub max_range: f32,
    /// Standard deviation of the Gaussian range noise (m).
    pub noise_sigma: f32,
    /// Which sensors are on.
    pub enabled: [bool; US_COUNT],
    /// Offset added to every measured distance (m).
    pub offset: f32,
}

impl UsModel {
    /// The reading (cm or code) of sensor `index` for a true distance in metres (None: no echo
    /// within the cast range). The noise draw happens for every sensor on every call.
    pub fn read<R: Rng>(&self, index: usize, distance: Option<f32>, rng: &mut R) -> i32 {
        let noise: f32 = rng.sample(StandardNormal);
        if !self.enabled[index] {
            return US_DISABLED;
        }
        match distance.map(|d| d + self.offset) {
            None => US_NOTHING,
            Some(d) if d > self.max_range => US_NOTHING,
            Some(d) if d < self.min_range => US_TOO_CLOSE,
            Some(d) => {
                let cm = (d + self.noise_sigma * noise) * 100.0;
                // Round half up after clamping to the positive measurable range.
                (cm.clamp(self.min_range * 100.0, self.max_range * 100.0) + 0.5) as i32
            }
        }
    }

    /// Normalised reading in [0, 1]: distance / max range; 0 when too close, 1 when nothing is
    /// in range or the sensor is disabled.
    #[inline]
    pub fn normalise(&self, code: i32) -> f32 {
        match code {
            US_TOO_CLOSE => 0.0,
            US_NOTHING | US_DISABLED => 1.0,
            cm => (cm as f32 / (self.max_range * 100.0)).clamp(0.0, 1.0),
        }
    }
}

/// One robot's ultrasonic reading.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct UsReading {
    /// Readings in cm, or the codes [`US_TOO_CLOSE`], [`US_NOTHING`], [`US_DISABLED`].
    pub code: [i32; US_COUNT],
    /// True distance (m) each beam travelled to the first surface it met (echo or not; the cast
    /// range when none), for drawing.
    pub hit: [f32; US_COUNT],
    /// Time (s) since these readings were taken.
    pub age: f32,
}

/// The five ultrasonic sensors as a [`Sensor`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Ultrasonic {
    /// Ranges, noise, enabled sensors.
    pub model: UsModel,
    /// Time (s) between two readings.
    pub period: f32,
    /// Cosine of the largest incidence angle that echoes (0: any).
    pub acceptance_cos: f32,
    #[serde(skip, default = "us_dirs")]
    dirs: [Vector; US_COUNT],
    /// Scratch: the other robots a ray can meet (not behind the robot), in the order of
    /// `SenseContext::others`.
    #[serde(skip)]
    ahead: Vec<Vector>,
    /// Scratch: their indices, when `SenseContext::other_ids` gives them (else empty).
    #[serde(skip)]
    ahead_ids: Vec<u32>,
}

impl Ultrasonic {
    /// Whether the sweep takes new readings when the last ones are `age` s old (always at a
    /// new episode).
    #[inline]
    fn due(&self, age: f32, fresh: bool) -> bool {
        fresh || age >= self.period - 1e-6
    }
}

fn us_dirs() -> [Vector; US_COUNT] {
    US_BEARINGS.map(unit)
}

impl Sensor for Ultrasonic {
    const NAME: &'static str = "us";
    type Config = UsConfig;
    type Reading = UsReading;

    fn new(cfg: &UsConfig) -> Self {
        Self {
            model: UsModel {
                min_range: cfg.us_min_range,
                max_range: cfg.us_max_range,
                noise_sigma: cfg.us_noise_sigma.bounds().0,
                enabled: cfg.us_enabled,
                offset: cfg.us_offset.bounds().0,
            },
            period: cfg.us_period,
            acceptance_cos: if cfg.us_acceptance >= std::f32::consts::FRAC_PI_2 {
                0.0
            } else {
                cfg.us_acceptance.cos()
            },
            dirs: us_dirs(),
            ahead: Vec::new(),
            ahead_ids: Vec::new(),
        }
    }

    fn validate(cfg: &UsConfig, origin: &str) -> Result<()> {
        if cfg.us_min_range >= cfg.us_max_range {
            return Err(Error::config(
                origin,
                "sensors.us_min_range",
                format!(
                    "must be below sensors.us_max_range ({}), got {}",
                    cfg.us_max_range, cfg.us_min_range
                ),
            ));
        }
        Ok(())
    }

    fn randomise(&mut self, cfg: &UsConfig, rng: &mut ChaCha8Rng) {
        self.model.noise_sigma = cfg.us_noise_sigma.sample(rng);
        self.model.offset = cfg.us_offset.sample(rng);
    }

    fn reach(&self, radius: f32) -> f32 {
        // The cast (max range + 1 cm) starts on the rim and meets discs of `radius`.
        2.0 * radius + self.model.max_range + 0.01
    }

    fn reach_now(&self, radius: f32, reading: &UsReading, dt: f32, fresh: bool) -> f32 {
        if self.due(reading.age + dt, fresh) {
            self.reach(radius)
        } else {
            0.0
        }
    }

    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut UsReading) {
        // The five readings hold until the sweep comes round again.
        reading.age += ctx.dt;
        if !self.due(reading.age, ctx.fresh) {
            return;
        }
        reading.age = 0.0;
        let cast_range = self.model.max_range + 0.01;
        let (s, c) = ctx.sin_cos;
        // Every beam points ahead or sideways (bearings within ±90°) from the rim: a robot whose
        // centre lies more than a radius (plus 1 mm for rounding) behind the robot's centre
        // cannot be met, so the rays skip it; the robots kept are in the same order (with
        // their indices, if given), and the readings are those of a cast against all of them.
        //
        // Nor can a beam meet a disc whose centre lies farther than a radius from the beam's
        // line: a robot farther than that (plus 1 mm, far above rounding) from all five lines
        // is skipped too, since every ray would miss it.
        let forward = Vector::new(c, s);
        let left = Vector::new(-s, c);
        let behind = -(ctx.radius + 0.001);
        let corridor = ctx.radius + 0.001;
        self.ahead.clear();
        self.ahead_ids.clear();
        for (k, &q) in ctx.others.iter().enumerate() {
            let d = q - ctx.position;
            let (x, y) = (d.dot(forward), d.dot(left));
            let mut on_a_line = false;
            for u in &self.dirs {
                on_a_line |= (x * u.y - y * u.x).abs() <= corridor;
            }
            if x >= behind && on_a_line {
                self.ahead.push(q);
                if let Some(&id) = ctx.other_ids.get(k) {
                    self.ahead_ids.push(id);
                }
            }
        }
        for k in 0..US_COUNT {
            let dir = rotate(self.dirs[k], c, s);
            let origin = ctx.position + ctx.radius * dir;
            let surface = ctx.scene.cast_hit(
                origin,
                dir,
                cast_range,
                ctx.scene.shapes.iter(),
                &self.ahead,
                &self.ahead_ids,
                ctx.radius,
            );
            // A surface hit at a grazing angle reflects the ping away: no echo from it.
            let echo = surface.filter(|h| {
                self.acceptance_cos <= 0.0
                    || h.incidence_cos(ctx.scene, ctx.radius) >= self.acceptance_cos
            });
            reading.code[k] = self.model.read(k, echo.map(|h| h.distance), rng);
            // The beam stops at the surface it met, whether or not it echoed.
            reading.hit[k] = surface.map_or(cast_range, |h| h.distance);
        }
    }

    fn block(&self) -> Block {
        Block::new(Self::NAME, US_COUNT, 0.0, 1.0)
    }

    fn obs_len(&self) -> usize {
        US_COUNT
    }

    #[inline]
    fn observe(&self, reading: &UsReading, out: &mut [f32]) {
        for (o, code) in out.iter_mut().zip(reading.code) {
            *o = self.model.normalise(code);
        }
    }

    fn readout(&self, reading: &UsReading, out: &mut Readout) {
        out.ints("us_cm", US_COUNT, &reading.code.map(i64::from));
    }

    /// Each enabled beam, blue, to the surface it met or to its range: solid when the reading
    /// is an echo (a distance, or too close), dashed when it reports nothing (no surface in
    /// range, or one met at too grazing an angle to echo). A disabled sensor draws nothing.
    fn draw(&self, at: &DrawContext, reading: &UsReading, marks: &mut Vec<Mark>) {
        let (s, c) = at.heading.sin_cos();
        let beams = self.dirs.iter().zip(reading.hit).zip(reading.code);
        for ((dir, hit), code) in beams {
            if code == US_DISABLED {
                continue;
            }
            let d = rotate(*dir, c, s);
            let from = at.position + at.radius * d;
            let to = from + hit.min(self.model.max_range) * d;
            let colour = [60, 110, 220];
            marks.push(if code == US_NOTHING {
                Mark::Dashed {
                    from,
                    to,
                    colour,
                    alpha: 110,
                    width: 0.004,
                    dash: 0.03,
                }
            } else {
                Mark::Ray {
                    from,
                    to,
                    colour,
                    alpha: 60,
                    width: 0.004,
                }
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn codes_and_centimetres() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let mut us = UsModel {
            min_range: 0.25,
            max_range: 2.0,
            noise_sigma: 0.0,
            enabled: [true; 5],
            offset: 0.0,
        };
        assert_eq!(us.read(0, Some(0.1), &mut rng), US_TOO_CLOSE);
        assert_eq!(us.read(0, Some(2.5), &mut rng), US_NOTHING);
        assert_eq!(us.read(0, None, &mut rng), US_NOTHING);
        assert_eq!(us.read(0, Some(1.234), &mut rng), 123);
        us.enabled[3] = false;
        assert_eq!(us.read(3, Some(1.0), &mut rng), US_DISABLED);
        assert_eq!(us.normalise(100), 0.5);
        assert_eq!(us.normalise(US_NOTHING), 1.0);
        // An offset moves every measured distance, and the codes follow the measured one.
        us.offset = 0.03;
        assert_eq!(us.read(0, Some(1.234), &mut rng), 126);
        assert_eq!(us.read(0, Some(0.23), &mut rng), 26);
        assert_eq!(us.read(0, Some(1.98), &mut rng), US_NOTHING);
    }

    /// Issue 33: a beam without echo is drawn dashed, to the surface it met (never through it)
    /// or to the sensor's range; an echo is a solid ray to its surface; a disabled sensor draws
    /// nothing.
    #[test]
    fn beams_are_drawn_to_their_surface_dashed_without_echo() {
        use crate::config::ConfigTable;
        let us = Ultrasonic::new(
            &UsConfig::from_table(&UsConfig::defaults_table(), "defaults", "sensors")
                .expect("the defaults"),
        );
        let at = DrawContext {
            position: Vector::new(0.5, -0.25),
            heading: 0.3,
            radius: 0.0704,
        };
        let reading = UsReading {
            // An echo at 1.2 m; a surface 0.6 m away met too obliquely to echo; nothing within
            // range (the cast stops at the range); too close; disabled.
            code: [120, US_NOTHING, US_NOTHING, US_TOO_CLOSE, US_DISABLED],
            hit: [1.2, 0.6, f32::INFINITY, 0.1, 0.9],
            age: 0.0,
        };
        let mut marks = Vec::new();
        us.draw(&at, &reading, &mut marks);
        assert_eq!(marks.len(), 4, "a disabled sensor draws nothing");
        let (s, c) = at.heading.sin_cos();
        for (i, mark) in marks.iter().enumerate() {
            let dir = rotate(unit(US_BEARINGS[i]), c, s);
            let rim = at.position + at.radius * dir;
            let (from, to, dashed) = match mark {
                Mark::Ray { from, to, .. } => (*from, *to, false),
                Mark::Dashed { from, to, .. } => (*from, *to, true),
                other => panic!("beam {i}: {other:?}"),
            };
            let length = [1.2, 0.6, us.model.max_range, 0.1][i];
            assert!((from - rim).length() < 1e-6, "beam {i} starts on the rim");
            assert!(
                ((to - from).length() - length).abs() < 1e-5,
                "beam {i}: {to:?}"
            );
            assert!(
                (to - from).normalize().dot(dir) > 0.99999,
                "beam {i} along its bearing"
            );
            assert_eq!(dashed, matches!(i, 1 | 2), "beam {i}: dashed iff no echo");
        }
    }
}
