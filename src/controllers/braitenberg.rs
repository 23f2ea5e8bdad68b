//! Braitenberg obstacle avoidance (paper eqs. 5–7): a 2×8 weight matrix W maps the IR ring to
//! wheel speeds, v_{L,R} = W·(1 − S/S_max) (eq. 7). Our IR observation is already the proximity
//! p = 1 − S/S_max in [0, 1] (0 = nothing seen), so the avoidance wheel speeds are W·p. As in the
//! paper's block diagram (Fig. 5) the block sits after the control law: with no obstacle seen
//! (every p below `threshold`) the control law's wheel speeds pass unchanged; otherwise W·p is
//! added to them.
//!
//! [`Braitenberg`] is the avoidance block; [`BraitenbergPolicy`] the controller of the paper's
//! Fig. 5: position control to the goal of a Nav-like observation, then the block on its `ir`.
//!
//! Units: W in m/s per unit of proximity, wheel speeds in m/s until they are normalised to
//! actions; robot frame x forward, y left, angles CCW.

use super::position::{twist_to_wheels, PositionControl, PositionParams};
use super::{goal_of, positive, Controller, GoalBlocks, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::IR_COUNT;

/// A weight matrix by name (`"default"`, `"kteam"`) or given (2 rows of 8).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Weights {
    /// A built-in set: "default" or "kteam".
    Named(String),
    /// Rows left and right wheel; columns the IR sensors in K-Team order (m/s per unit
    /// proximity).
    Matrix(Vec<Vec<f32>>),
}

/// Names of the built-in weight sets.
pub const WEIGHT_SETS: &[&str] = &["default", "kteam"];

impl Weights {
    /// The matrix, checked: a known name, or 2 finite rows of 8.
    pub fn matrix(&self) -> Result<[[f32; IR_COUNT]; 2]> {
        match self {
            Weights::Named(name) => match name.as_str() {
                "default" => Ok(DEFAULT_WEIGHTS),
                "kteam" => Ok(KTEAM_WEIGHTS),
                _ => Err(Error::Param(format!(
                    "unknown Braitenberg weights '{name}'; give one of {WEIGHT_SETS:?} or a 2 x 8 \
                     array"
                ))),
            },
            Weights::Matrix(rows) => {
                if rows.len() != 2 || rows.iter().any(|r| r.len() != IR_COUNT) {
                    return Err(Error::Param(format!(
                        "braitenberg: weights must be a 2 x 8 matrix (rows left, right wheel; \
                         columns the IR sensors in K-Team order), got {} rows of {:?}",
                        rows.len(),
                        rows.iter().map(Vec::len).collect::<Vec<_>>()
                    )));
                }
                if rows.iter().flatten().any(|w| !w.is_finite()) {
                    return Err(Error::Param(
                        "braitenberg: weights must be finite (a 2 x 8 matrix)".into(),
                    ));
                }
                let mut m = [[0.0f32; IR_COUNT]; 2];
                for (dst, src) in m.iter_mut().zip(rows) {
                    dst.copy_from_slice(src);
                }
                Ok(m)
            }
        }
    }
}

crate::config_table! {
    /// Parameters of position control followed by Braitenberg avoidance (eqs. 1–7, Fig. 5).
    pub struct BraitenbergParams {
        /// weight matrix W of eq. 5: "default" (tuned on KheperaIV-Avoid), "kteam" (K-Team's braitenbergAvoidance demo in m/s) or a 2 x 8 array (m/s per unit proximity; rows left, right wheel; columns K-Team sensor order)
        weights: Weights = "default",
        /// full scale S_max of the proximity relative to the observation's (> 0): W is divided by it
        smax: f32 = 1.0,
        /// proximity above which a sensor sees an obstacle (above the IR noise)
        threshold: f32 = 0.05,
        /// position control's cruise speed v_max (m/s)
        vmax: f32 = 0.3,
        /// position control's largest turn rate ω_max (rad/s)
        wmax: f32 = 4.0,
        /// position control's docking radius k_r (m)
        kr: f32 = 0.15,
        /// distance to the goal under which the robot stops (m)
        stop_radius: f32 = 0.02,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

impl BraitenbergParams {
    /// The avoidance block of these parameters: W / smax and the threshold, checked.
    pub fn block(&self, who: &str) -> Result<Braitenberg> {
        let smax = positive(who, "smax", self.smax)?;
        if self.threshold.is_nan() || self.threshold < 0.0 {
            return Err(Error::Param(format!(
                "{who}: threshold must be >= 0, got {}",
                self.threshold
            )));
        }
        let weights = self.weights.matrix()?.map(|row| row.map(|w| w / smax));
        Ok(Braitenberg {
            weights,
            threshold: self.threshold,
        })
    }

    /// The position control these parameters describe.
    pub fn position(&self) -> PositionParams {
        PositionParams {
            vmax: self.vmax,
            wmax: self.wmax,
            kr: self.kr,
            stop_radius: self.stop_radius,
            axle_length: self.axle_length,
            max_wheel_speed: self.max_wheel_speed,
        }
    }
}

/// Position control to the goal of a Nav-like observation, then Braitenberg avoidance.
#[derive(Debug, Clone, PartialEq)]
pub struct BraitenbergPolicy {
    /// The control law.
    pub law: PositionControl,
    /// The avoidance block.
    pub avoidance: Braitenberg,
    /// The drive.
    pub wheels: WheelMap,
    goal: GoalBlocks,
    ir: usize,
    obs_dim: usize,
}

impl Controller for BraitenbergPolicy {
    const NAME: &'static str = "braitenberg";
    const READS: &'static str = "nav";
    type Params = BraitenbergParams;

    fn new(params: &BraitenbergParams, layout: &ObsLayout) -> Result<Self> {
        let (law, wheels) = params.position().law(Self::NAME)?;
        Ok(Self {
            law,
            avoidance: params.block(Self::NAME)?,
            wheels,
            goal: GoalBlocks::find(layout, Self::NAME)?,
            ir: layout.require("ir", IR_COUNT, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (d, bearing) = goal_of(obs, self.goal);
        let (v, w) = self.law.twist(d, bearing);
        let mut p = [0.0f32; IR_COUNT];
        p.copy_from_slice(&obs[self.ir..self.ir + IR_COUNT]);
        let wheels = if d < self.law.stop_radius {
            [0.0, 0.0]
        } else {
            self.avoidance
                .apply(twist_to_wheels(v, w, self.wheels.axle_length), &p)
        };
        out.copy_from_slice(&self.wheels.action(wheels));
    }
}

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
    /// The block of the default [`BraitenbergParams`].
    fn default() -> Self {
        // The declared defaults are valid (tested): this cannot fail on user input.
        BraitenbergParams::default()
            .block("braitenberg")
            .expect("the default Braitenberg parameters are valid")
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

/// The weights of K-Team's `braitenbergAvoidance` demo (docs/robot.md §8: left +2 +3 +4 −7 −4 −3 −2
/// +1, right −2 −3 −4 −9 +4 +3 +2 +1 on raw counts less 80, summed and divided by 5, in speed
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
