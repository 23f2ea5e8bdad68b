//! The KH4VREP paper's classical controllers (Farias et al. 2017, §3.3–3.5), written once in
//! Rust: the scripted formation leader uses them inside the simulator, and the baselines of
//! `khepera_gym.baselines` run the same code on observations, batched.
//!
//! A [`Policy`] maps one observation row to one action row: normalised wheel speeds (left,
//! right) in [-1, 1] per agent, for environments with `action_type = "wheels"`. Units: metres,
//! seconds, radians; robot frame x forward, y left, angles CCW.

pub mod braitenberg;
pub mod formation;
pub mod position;
pub mod vfh;

pub use braitenberg::Braitenberg;
pub use formation::LeaderFollower;
pub use position::PositionControl;
pub use vfh::Vfh;

use crate::error::{Error, Result};
use crate::sensors::{IR_COUNT, US_COUNT};
use crate::tasks::formation::FOLLOWER_OBS_DIM;
use crate::tasks::nav;
use position::twist_to_wheels;

/// The robot's drive as a policy needs it to turn (v, ω) into normalised wheel actions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelMap {
    /// Wheel separation (m).
    pub axle_length: f32,
    /// Wheel speed that action 1 stands for (m/s).
    pub max_wheel_speed: f32,
}

impl Default for WheelMap {
    fn default() -> Self {
        Self {
            axle_length: crate::robot::AXLE_LENGTH,
            max_wheel_speed: crate::robot::MAX_WHEEL_SPEED,
        }
    }
}

impl WheelMap {
    fn action(&self, wheels: [f32; 2]) -> [f32; 2] {
        wheels.map(|w| (w / self.max_wheel_speed).clamp(-1.0, 1.0))
    }
}

/// A baseline policy on observations.
#[derive(Debug, Clone, PartialEq)]
pub enum Policy {
    /// Position control to the goal of a Nav-layout observation (eqs. 1–4).
    PositionControl(PositionControl, WheelMap),
    /// Position control followed by Braitenberg avoidance (eqs. 1–7, Fig. 5).
    Braitenberg(PositionControl, Braitenberg, WheelMap),
    /// Vector Field Histogram (eqs. 8–11).
    Vfh(Vfh, WheelMap),
    /// Leader–follower formation control (eq. 12) for every follower block; a leader block
    /// (when the leader is an agent) is driven by `leader`.
    LeaderFollower {
        /// One controller per follower, or one shared by all when a single one is given.
        followers: Vec<LeaderFollower>,
        /// Policy of the leader's Nav block, if the observation has one.
        leader: Box<Policy>,
        /// The drive.
        wheels: WheelMap,
    },
}

impl Policy {
    /// Length of the action for an observation row of length `obs_dim`.
    pub fn act_dim(&self, obs_dim: usize) -> Result<usize> {
        match self {
            Policy::LeaderFollower { .. } => {
                let (leader, k) = split_formation(obs_dim)?;
                Ok(2 * (k + usize::from(leader)))
            }
            _ if obs_dim == nav::OBS_DIM => Ok(2),
            _ => Err(Error::Action(format!(
                "this policy reads Nav/Avoid observations of {} values, got {obs_dim}",
                nav::OBS_DIM
            ))),
        }
    }

    /// Writes the action for one observation row into `out` (length from [`Policy::act_dim`]).
    pub fn act(&self, obs: &[f32], out: &mut [f32]) {
        match self {
            Policy::PositionControl(pc, map) => {
                let (d, bearing) = goal_of(obs);
                let (v, w) = pc.twist(d, bearing);
                out.copy_from_slice(&map.action(twist_to_wheels(v, w, map.axle_length)));
            }
            Policy::Braitenberg(pc, b, map) => {
                let (d, bearing) = goal_of(obs);
                let (v, w) = pc.twist(d, bearing);
                let mut p = [0.0f32; IR_COUNT];
                p.copy_from_slice(&obs[..IR_COUNT]);
                let wheels = if d < pc.stop_radius {
                    [0.0, 0.0]
                } else {
                    b.apply(twist_to_wheels(v, w, map.axle_length), &p)
                };
                out.copy_from_slice(&map.action(wheels));
            }
            Policy::Vfh(vfh, map) => {
                let (d, bearing) = goal_of(obs);
                let ir = &obs[..IR_COUNT];
                let us = &obs[IR_COUNT..IR_COUNT + US_COUNT];
                let wheels = &obs[IR_COUNT + US_COUNT + 3..IR_COUNT + US_COUNT + 5];
                let (v, w) = vfh.twist(ir, us, d, bearing, wheels[1] - wheels[0]);
                out.copy_from_slice(&map.action(twist_to_wheels(v, w, map.axle_length)));
            }
            Policy::LeaderFollower {
                followers,
                leader,
                wheels,
            } => {
                let (has_leader, k) = split_formation(obs.len()).unwrap_or((false, 0));
                let (mut blocks, mut actions) = (obs, &mut out[..]);
                if has_leader {
                    leader.act(&blocks[..nav::OBS_DIM], &mut actions[..2]);
                    blocks = &blocks[nav::OBS_DIM..];
                    actions = &mut actions[2..];
                }
                for i in 0..k {
                    let block = &blocks[i * FOLLOWER_OBS_DIM..(i + 1) * FOLLOWER_OBS_DIM];
                    let lf = followers.get(i).or(followers.first());
                    let w = lf.map_or([0.0, 0.0], |lf| {
                        lf.wheels(block, wheels.axle_length, wheels.max_wheel_speed)
                    });
                    actions[2 * i..2 * i + 2].copy_from_slice(&wheels.action(w));
                }
            }
        }
    }

    /// Actions for `rows` observation rows of `obs_dim` values each (row-major).
    pub fn act_batch(&self, obs: &[f32], obs_dim: usize) -> Result<Vec<f32>> {
        let act_dim = self.act_dim(obs_dim)?;
        if let Policy::LeaderFollower { followers, .. } = self {
            let (_, k) = split_formation(obs_dim)?;
            if followers.len() > 1 && followers.len() != k {
                return Err(Error::Action(format!(
                    "the policy has {} follower offsets but the observation has {k} followers",
                    followers.len()
                )));
            }
        }
        if let Some(i) = obs.iter().position(|v| !v.is_finite()) {
            return Err(Error::Action(format!(
                "observation row {} element {} is {}",
                i / obs_dim.max(1),
                i % obs_dim.max(1),
                obs[i]
            )));
        }
        let rows = obs.len() / obs_dim.max(1);
        let mut out = vec![0.0f32; rows * act_dim];
        for (row, action) in obs.chunks_exact(obs_dim).zip(out.chunks_exact_mut(act_dim)) {
            self.act(row, action);
        }
        Ok(out)
    }
}

/// Goal distance and bearing of a Nav-layout observation.
fn goal_of(obs: &[f32]) -> (f32, f32) {
    let base = IR_COUNT + US_COUNT;
    (obs[base], obs[base + 1].atan2(obs[base + 2]))
}

/// (leader block present, followers) of a formation observation of length `obs_dim`.
fn split_formation(obs_dim: usize) -> Result<(bool, usize)> {
    if obs_dim > 0 && obs_dim % FOLLOWER_OBS_DIM == 0 {
        Ok((false, obs_dim / FOLLOWER_OBS_DIM))
    } else if obs_dim > nav::OBS_DIM && (obs_dim - nav::OBS_DIM) % FOLLOWER_OBS_DIM == 0 {
        Ok((true, (obs_dim - nav::OBS_DIM) / FOLLOWER_OBS_DIM))
    } else {
        Err(Error::Action(format!(
            "not a formation observation: {obs_dim} values is neither K x {FOLLOWER_OBS_DIM} \
             (followers) nor {} + K x {FOLLOWER_OBS_DIM} (leader and followers)",
            nav::OBS_DIM
        )))
    }
}
