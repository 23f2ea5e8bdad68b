//! Ultrasonic sensors: 5 Prowave 400PT12B transceivers (left, front-left, front, front-right,
//! right), readings in whole centimetres from 25 to 200 cm with the K-Team library's codes for
//! "too close" (0), "nothing in range" (1000) and "disabled" (2000). Spec §5.
//!
//! One ray per sensor along its axis (the beam width is not documented; Webots uses one ray too).

use rand::Rng;
use rand_distr::StandardNormal;

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
}

impl UsModel {
    /// The reading (cm or code) of sensor `index` for a true distance in metres (None: no echo
    /// within the cast range). The noise draw happens for every sensor on every call.
    pub fn read<R: Rng>(&self, index: usize, distance: Option<f32>, rng: &mut R) -> i32 {
        let noise: f32 = rng.sample(StandardNormal);
        if !self.enabled[index] {
            return US_DISABLED;
        }
        match distance {
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
    pub fn normalise(&self, code: i32) -> f32 {
        match code {
            US_TOO_CLOSE => 0.0,
            US_NOTHING | US_DISABLED => 1.0,
            cm => (cm as f32 / (self.max_range * 100.0)).clamp(0.0, 1.0),
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
        };
        assert_eq!(us.read(0, Some(0.1), &mut rng), US_TOO_CLOSE);
        assert_eq!(us.read(0, Some(2.5), &mut rng), US_NOTHING);
        assert_eq!(us.read(0, None, &mut rng), US_NOTHING);
        assert_eq!(us.read(0, Some(1.234), &mut rng), 123);
        us.enabled[3] = false;
        assert_eq!(us.read(3, Some(1.0), &mut rng), US_DISABLED);
        assert_eq!(us.normalise(100), 0.5);
        assert_eq!(us.normalise(US_NOTHING), 1.0);
    }
}
