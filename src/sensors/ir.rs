//! Infrared proximity ring: 8 TCRT5000 sensors, 45° apart on the rim, raw value 0..1023
//! (1023 = touching), from K-Team's measured response curve (spec §3, user manual fig. 10,
//! digitised ±10 counts) interpolated linearly in distance, plus Gaussian noise in raw counts.
//!
//! Distances are measured from the sensor (on the body rim) to the obstacle surface, in metres.

use rand::Rng;
use rand_distr::StandardNormal;

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

/// Response curve: distance (mm) → raw count, K-Team fig. 10 (spec §3). The value beyond the
/// last point comes from the scenario's floor value (floor reflection), reached at `ir_range`.
const CURVE_MM: [f32; 16] = [
    0.0, 10.0, 20.0, 30.0, 35.0, 40.0, 45.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0, 120.0, 150.0,
    200.0,
];
const CURVE_RAW: [f32; 16] = [
    1018.0, 1012.0, 1002.0, 979.0, 889.0, 764.0, 597.0, 492.0, 380.0, 319.0, 254.0, 228.0, 199.0,
    163.0, 133.0, 111.0,
];

/// The IR ring's response and noise.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct IrModel {
    /// Distance (m) beyond which a sensor reads the floor value.
    pub range: f32,
    /// Raw reading with nothing in range.
    pub floor_value: f32,
    /// Standard deviation of the additive Gaussian noise (raw counts).
    pub noise_sigma: f32,
}

impl IrModel {
    /// Noise-free raw value at `distance` metres (None: nothing within range).
    pub fn mean_raw(&self, distance: Option<f32>) -> f32 {
        let d = match distance {
            Some(d) if d < self.range => d.max(0.0) * 1000.0,
            _ => return self.floor_value,
        };
        let last = CURVE_MM.len() - 1;
        if d >= CURVE_MM[last] {
            // From the last measured point down to the floor value at the range limit.
            let span = self.range * 1000.0 - CURVE_MM[last];
            let t = (d - CURVE_MM[last]) / span;
            return CURVE_RAW[last] + t * (self.floor_value - CURVE_RAW[last]);
        }
        let i = CURVE_MM.partition_point(|&x| x <= d).clamp(1, last);
        let (x0, x1) = (CURVE_MM[i - 1], CURVE_MM[i]);
        let (y0, y1) = (CURVE_RAW[i - 1], CURVE_RAW[i]);
        y0 + (d - x0) / (x1 - x0) * (y1 - y0)
    }

    /// A raw reading (integer count 0..1023) with noise drawn from `rng`. The noise draw happens
    /// whatever the distance, so the random stream does not depend on the scene.
    pub fn read<R: Rng>(&self, distance: Option<f32>, rng: &mut R) -> u16 {
        let noise: f32 = rng.sample(StandardNormal);
        let raw = self.mean_raw(distance) + self.noise_sigma * noise;
        // Round half up; the value is clamped non-negative first (avoids a libm call).
        (raw.clamp(0.0, IR_MAX_RAW) + 0.5) as u16
    }

    /// Normalised proximity in [0, 1]: 0 at the floor value (nothing seen), 1 at 1023.
    pub fn normalise(&self, raw: u16) -> f32 {
        ((raw as f32 - self.floor_value) / (IR_MAX_RAW - self.floor_value)).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODEL: IrModel = IrModel {
        range: 0.25,
        floor_value: 100.0,
        noise_sigma: 0.0,
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
    fn curve_is_monotone() {
        let mut prev = f32::INFINITY;
        for i in 0..=250 {
            let v = MODEL.mean_raw(Some(i as f32 / 1000.0));
            assert!(v <= prev);
            prev = v;
        }
    }
}
