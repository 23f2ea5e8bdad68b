//! The consensus law on what neighbours broadcast (consensus_v1; docs/task-design.md §8).
//!
//! With x̂_j the last message of neighbour j, x̂_i the robot's own last broadcast and c the
//! formation offsets, the law of Dimarogonas, Frazzoli & Johansson (IEEE TAC 57(5), 2012,
//! eq. 3) is u_i = −k Σ_{j∈N_i} ((x̂_i − c_i) − (x̂_j − c_j)): on single integrators it keeps the
//! average of the z_i = x_i − c_i of each connected component and drives their disagreement to
//! zero at the rate k·λ₂ of the graph's Laplacian (λ₂ = 2 for a ring of 4). It uses the robot's
//! own last broadcast rather than its current estimate: with event-triggered messages that is
//! what makes the error bounded by the trigger's threshold. In the robot frame the observation
//! gives p_j = x̂_j − c_j + c_i − x̂ (`neighbours`) and d = x̂_i − x̂ (`own_drift`), so
//! u = k Σ_j (p_j − d).
//!
//! The unicycle follows u with the point-offset linearisation (a point `offset` ahead of the
//! axle moves as a single integrator): v = u_x, ω = u_y / offset, u first scaled to at most
//! `vmax`, ω clipped to `wmax`. Below `deadband` the robot stops (the motors' 3 mm/s floor would
//! otherwise make it dither). The law alone drives robots into one another when they cross to
//! their places (in contact, with the v1 tyre grip, two robots pushing head on stall); with
//! `avoid` Braitenberg avoidance on the IR ring is added while the robot moves.
//!
//! Units: m, s, m/s, rad/s; robot frame x forward, y left.

use super::braitenberg::Braitenberg;
use super::position::twist_to_wheels;
use super::{non_negative, positive, Controller, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::IR_COUNT;
use crate::tasks::consensus::SLOT;

crate::config_table! {
    /// Parameters of the consensus law.
    pub struct ConsensusParams {
        /// k, 1/s, the consensus gain: a ring of 4 converges at k*lambda_2 = 1/s once the speed is not saturated [E]
        k: f32 = 0.5,
        /// m/s, largest speed of the offset point [E: half the paper's 0.3 m/s; the wheels accelerate at 0.203 m/s^2]
        vmax: f32 = 0.15,
        /// rad/s, omega_max [E]
        wmax: f32 = 3.0,
        /// m, distance ahead of the axle of the point that follows u [E: inside the 70 mm shell]
        offset: f32 = 0.05,
        /// m/s, below this |u| the robot stops [E: about the wheels' 3 mm/s floor]
        deadband: f32 = 0.005,
        /// add Braitenberg avoidance (the paper's eqs. 5-7, K-Team-style weights) on the IR ring when moving, so that robots crossing to their places in the formation steer round one another; needs an `ir` block
        avoid: bool = true,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// The consensus law on a consensus_v1 agent's observation.
#[derive(Debug, Clone, PartialEq)]
pub struct ConsensusPolicy {
    k: f32,
    vmax: f32,
    wmax: f32,
    offset: f32,
    deadband: f32,
    avoidance: Option<(Braitenberg, usize)>,
    neighbours: usize,
    slots: usize,
    drift: usize,
    wheels: WheelMap,
    obs_dim: usize,
}

impl Controller for ConsensusPolicy {
    const NAME: &'static str = "consensus";
    const READS: &'static str = "consensus";
    type Params = ConsensusParams;

    fn new(params: &ConsensusParams, layout: &ObsLayout) -> Result<Self> {
        let who = Self::NAME;
        let neighbours = layout.find("neighbours").ok_or_else(|| {
            Error::Param(format!("{who}: the observation has no `neighbours` block"))
        })?;
        if neighbours.len() % SLOT != 0 {
            return Err(Error::Param(format!(
                "{who}: a neighbours block of {} values is not whole slots of {SLOT}",
                neighbours.len()
            )));
        }
        Ok(Self {
            k: non_negative(who, "k", params.k)?,
            vmax: positive(who, "vmax", params.vmax)?,
            wmax: positive(who, "wmax", params.wmax)?,
            offset: positive(who, "offset", params.offset)?,
            deadband: non_negative(who, "deadband", params.deadband)?,
            avoidance: if params.avoid {
                Some((Braitenberg::default(), layout.require("ir", IR_COUNT, who)?))
            } else {
                None
            },
            slots: neighbours.len() / SLOT,
            neighbours: neighbours.start,
            drift: layout.require("own_drift", 2, who)?,
            wheels: WheelMap::new(who, params.axle_length, params.max_wheel_speed)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (dx, dy) = (obs[self.drift], obs[self.drift + 1]);
        let (mut ux, mut uy) = (0.0f32, 0.0f32);
        for s in 0..self.slots {
            let slot = &obs[self.neighbours + s * SLOT..self.neighbours + (s + 1) * SLOT];
            if slot[3] > 0.5 {
                ux += slot[0] - dx;
                uy += slot[1] - dy;
            }
        }
        ux *= self.k;
        uy *= self.k;
        let norm = ux.hypot(uy);
        if norm < self.deadband {
            out.copy_from_slice(&self.wheels.action([0.0, 0.0]));
            return;
        }
        if norm > self.vmax {
            ux *= self.vmax / norm;
            uy *= self.vmax / norm;
        }
        let w = (uy / self.offset).clamp(-self.wmax, self.wmax);
        let mut wheels = twist_to_wheels(ux, w, self.wheels.axle_length);
        if let Some((braitenberg, ir)) = &self.avoidance {
            let mut proximity = [0.0f32; IR_COUNT];
            proximity.copy_from_slice(&obs[*ir..*ir + IR_COUNT]);
            wheels = braitenberg.apply(wheels, &proximity);
        }
        out.copy_from_slice(&self.wheels.action(wheels));
    }
}
