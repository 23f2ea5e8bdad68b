//! Braitenberg obstacle avoidance (paper eqs. 5–7): a 2×8 weight matrix W maps the IR ring to
//! wheel speeds, v_{L,R} = W·(1 − S/S_max) (eq. 7). Our IR observation is already the proximity
//! p = 1 − S/S_max in [0, 1] (0 = nothing seen), so the avoidance wheel speeds are W·p. As in the
//! paper's block diagram (Fig. 5) the block sits after the control law: with no obstacle seen
//! (every p below `threshold`) the control law's wheel speeds pass unchanged; otherwise W·p is
//! added to them.

use crate::sensors::IR_COUNT;

/// Default weights (m/s per unit of proximity), K-Team order back-left, left, front-left,
/// front, front-right, right, back-right, back; rows left wheel, right wheel. An obstacle on
/// one side speeds up that side's wheel and slows the other (turn away); one straight ahead
/// slows both and turns right. Tuned on KheperaIV-Avoid (about 97% success over 400 seeds
/// with v_max 0.3 m/s, ω_max 4 rad/s); larger weights make the robot oscillate between
/// obstacles.
pub const DEFAULT_WEIGHTS: [[f32; IR_COUNT]; 2] = [
    [0.0, 0.36, 0.96, -0.24, -1.08, -0.48, 0.0, 0.0],
    [0.0, -0.48, -1.08, -1.44, 0.96, 0.36, 0.0, 0.0],
];

/// The Braitenberg avoidance block.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Braitenberg {
    /// Weight matrix W (m/s per unit proximity): row 0 left wheel, row 1 right wheel.
    pub weights: [[f32; IR_COUNT]; 2],
    /// Proximity under which a sensor counts as seeing nothing.
    pub threshold: f32,
}

impl Default for Braitenberg {
    fn default() -> Self {
        Self {
            weights: DEFAULT_WEIGHTS,
            // Above the IR noise (σ = 10 counts ≈ 0.011 in proximity) so that noise alone does
            // not steer; an obstacle about 15 cm from a sensor crosses it.
            threshold: 0.05,
        }
    }
}

impl Braitenberg {
    /// Whether any sensor sees an obstacle.
    pub fn sees_obstacle(&self, proximity: &[f32; IR_COUNT]) -> bool {
        proximity.iter().any(|p| *p > self.threshold)
    }

    /// Wheel speeds after the avoidance block: `wheels` unchanged with nothing seen, else
    /// `wheels + W·p`.
    pub fn apply(&self, wheels: [f32; 2], proximity: &[f32; IR_COUNT]) -> [f32; 2] {
        if !self.sees_obstacle(proximity) {
            return wheels;
        }
        let mut out = wheels;
        for (side, row) in self.weights.iter().enumerate() {
            out[side] += row.iter().zip(proximity).map(|(w, p)| w * p).sum::<f32>();
        }
        out
    }
}

/// The weights of K-Team's `braitenbergAvoidance` demo (spec §8: left +2 +3 +4 −7 −4 −3 −2 +1,
/// right −2 −3 −4 −9 +4 +3 +2 +1 on raw counts less 80, summed and divided by 5, in speed
/// units), converted to m/s per unit of proximity: × 923 counts / 5 × 0.678 mm/s ≈ × 0.125.
pub const KTEAM_WEIGHTS: [[f32; IR_COUNT]; 2] = {
    const S: f32 = 923.0 / 5.0 * 0.000678181;
    [
        [
            2.0 * S,
            3.0 * S,
            4.0 * S,
            -7.0 * S,
            -4.0 * S,
            -3.0 * S,
            -2.0 * S,
            1.0 * S,
        ],
        [
            -2.0 * S,
            -3.0 * S,
            -4.0 * S,
            -9.0 * S,
            4.0 * S,
            3.0 * S,
            2.0 * S,
            1.0 * S,
        ],
    ]
};
