//! Leader–follower formation control (paper §3.5, eq. 12) on followers' observations.
//!
//! A follower computes its target from the leader's pose in its own frame (observation blocks
//! `leader_offset`, `leader_heading`) and its (r, β): target = leader + R(θ_L − θ)·(r cos β,
//! r sin β), which is eq. 12 written in the follower's frame; with no offsets of its own it takes
//! its block's `target_offset` (eq. 12 as the scenario defines it). It drives there with
//! position control (eqs. 1–4) plus the leader's forward speed projected on its own heading
//! (`leader_velocity`: feed-forward, so it does not trail behind a moving target), then
//! Braitenberg avoidance on its `ir`.
//!
//! A joint observation is K follower blocks, or a leader's block then K follower blocks; the
//! leader's block is driven by another policy (`with_leader`).
//!
//! Units: metres, m/s, radians, rad/s; each follower's frame x forward, y left, angles CCW.

use super::braitenberg::{Braitenberg, Weights};
use super::position::{twist_to_wheels, PositionControl, PositionParams};
use super::{Controller, Policy, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::IR_COUNT;

crate::config_table! {
    /// Parameters of leader–follower control (eq. 12).
    pub struct LeaderFollowerParams {
        /// (r, β) offset of each follower from the leader (m, rad CCW from its heading); [] follows each block's target_offset; one pair serves every follower
        offsets: Vec<[f32; 2]> = [],
        /// followers' cruise speed v_max (m/s), above the leader's so they can catch up
        vmax: f32 = 0.35,
        /// followers' largest turn rate ω_max (rad/s)
        wmax: f32 = 4.0,
        /// followers' docking radius k_r (m)
        kr: f32 = 0.08,
        /// distance to its target under which a follower stops (m)
        stop_radius: f32 = 0.005,
        /// add the leader's speed along the follower's heading
        feedforward: bool = true,
        /// Braitenberg avoidance after the control law
        avoidance: bool = true,
        /// the avoidance block's weight matrix (as braitenberg's weights)
        weights: Weights = "default",
        /// the avoidance block's proximity full scale (as braitenberg's smax)
        smax: f32 = 1.0,
        /// the avoidance block's threshold (as braitenberg's threshold)
        threshold: f32 = 0.05,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s); also scales the leader's observed normalised speed back to m/s
        max_wheel_speed: f32 = 0.813,
    }
}

/// Where a follower's block keeps what it reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowerBlocks {
    ir: usize,
    target: usize,
    leader: usize,
    heading: usize,
    velocity: usize,
    len: usize,
}

impl FollowerBlocks {
    /// The indices of a follower block's layout.
    pub fn find(layout: &ObsLayout, who: &str) -> Result<Self> {
        Ok(Self {
            ir: layout.require("ir", IR_COUNT, who)?,
            target: layout.require("target_offset", 2, who)?,
            leader: layout.require("leader_offset", 2, who)?,
            heading: layout.require("leader_heading", 2, who)?,
            velocity: layout.require("leader_velocity", 2, who)?,
            len: layout.len(),
        })
    }
}

/// One follower's controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderFollower {
    /// (r, β) offset from the leader (m, rad); None: use the observation's own target.
    pub offset: Option<[f32; 2]>,
    /// Position control toward the target.
    pub control: PositionControl,
    /// Add the leader's speed along the follower's heading.
    pub feedforward: bool,
    /// Avoidance after the control law (None: off).
    pub avoidance: Option<Braitenberg>,
}

impl LeaderFollower {
    /// Wheel speeds (m/s) for one follower `block` laid out as `at`; `max_wheel_speed` scales
    /// the leader's normalised speed back to m/s.
    pub fn wheels(
        &self,
        block: &[f32],
        at: &FollowerBlocks,
        axle: f32,
        max_wheel_speed: f32,
    ) -> [f32; 2] {
        let (tx, ty) = match self.offset {
            None => (block[at.target], block[at.target + 1]),
            Some([r, beta]) => {
                let (s, c) = (block[at.heading], block[at.heading + 1]);
                let (ox, oy) = (r * beta.cos(), r * beta.sin());
                (
                    block[at.leader] + c * ox - s * oy,
                    block[at.leader + 1] + s * ox + c * oy,
                )
            }
        };
        let distance = (tx * tx + ty * ty).sqrt();
        let bearing = ty.atan2(tx);
        let (mut v, w) = self.control.twist(distance, bearing);
        if self.feedforward {
            let leader_v = block[at.velocity] * max_wheel_speed;
            v += leader_v * block[at.heading + 1] * bearing.cos().max(0.0);
        }
        let wheels = twist_to_wheels(v, w, axle);
        match &self.avoidance {
            None => wheels,
            Some(b) => {
                let mut p = [0.0f32; IR_COUNT];
                p.copy_from_slice(&block[at.ir..at.ir + IR_COUNT]);
                b.apply(wheels, &p)
            }
        }
    }
}

/// Leader–follower control of every follower block of an observation, and of a leader block
/// (when the observation has one) with the leader's policy.
#[derive(Debug, Clone, PartialEq)]
pub struct LeaderFollowerPolicy {
    /// One controller per follower, or one shared by all.
    pub followers: Vec<LeaderFollower>,
    /// Policy of a leader block (none: observations have follower blocks only).
    pub leader: Option<Box<Policy>>,
    /// The drive.
    pub wheels: WheelMap,
    blocks: FollowerBlocks,
    leader_dim: usize,
}

impl LeaderFollowerPolicy {
    /// The same policy with `leader` driving a leader block.
    pub fn with_leader(mut self, leader: Policy) -> Result<Self> {
        if matches!(leader, Policy::LeaderFollower(_)) {
            return Err(Error::Param(
                "leader_follower: the leader must be driven by a single-robot policy \
                 (position_control, braitenberg or vfh)"
                    .into(),
            ));
        }
        self.leader_dim = leader.obs_dim();
        self.leader = Some(Box::new(leader));
        Ok(self)
    }

    /// (leader block present, followers) of a joint observation of length `obs_dim`.
    fn split(&self, obs_dim: usize) -> Result<(bool, usize)> {
        let (f, l) = (self.blocks.len, self.leader_dim);
        if obs_dim > 0 && obs_dim.is_multiple_of(f) {
            Ok((false, obs_dim / f))
        } else if self.leader.is_some() && obs_dim > l && (obs_dim - l).is_multiple_of(f) {
            Ok((true, (obs_dim - l) / f))
        } else {
            Err(Error::Action(format!(
                "not a formation observation: {obs_dim} values is neither K x {f} (followers) \
                 nor {l} + K x {f} (leader and followers)"
            )))
        }
    }
}

impl Controller for LeaderFollowerPolicy {
    const NAME: &'static str = "leader_follower";
    const READS: &'static str = "formation";
    type Params = LeaderFollowerParams;

    /// `layout` is one follower's block.
    fn new(params: &LeaderFollowerParams, layout: &ObsLayout) -> Result<Self> {
        let position = PositionParams {
            vmax: params.vmax,
            wmax: params.wmax,
            kr: params.kr,
            stop_radius: params.stop_radius,
            axle_length: params.axle_length,
            max_wheel_speed: params.max_wheel_speed,
        };
        let (control, wheels) = position.law(Self::NAME)?;
        let avoidance = if params.avoidance {
            let block = super::braitenberg::BraitenbergParams {
                weights: params.weights.clone(),
                smax: params.smax,
                threshold: params.threshold,
                ..Default::default()
            };
            Some(block.block(Self::NAME)?)
        } else {
            None
        };
        if params
            .offsets
            .iter()
            .any(|[r, b]| !r.is_finite() || !b.is_finite() || *r < 0.0)
        {
            return Err(Error::Param(
                "leader_follower: offsets must be finite (r >= 0, beta) pairs".into(),
            ));
        }
        let make = |offset| LeaderFollower {
            offset,
            control,
            feedforward: params.feedforward,
            avoidance,
        };
        let followers = if params.offsets.is_empty() {
            vec![make(None)]
        } else {
            params.offsets.iter().map(|o| make(Some(*o))).collect()
        };
        Ok(Self {
            followers,
            leader: None,
            wheels,
            blocks: FollowerBlocks::find(layout, Self::NAME)?,
            leader_dim: 0,
        })
    }

    fn obs_dim(&self) -> usize {
        self.blocks.len
    }

    fn act_dim(&self, obs_dim: usize) -> Result<usize> {
        let (leader, k) = self.split(obs_dim)?;
        if self.followers.len() > 1 && self.followers.len() != k {
            return Err(Error::Action(format!(
                "the policy has {} follower offsets but the observation has {k} followers",
                self.followers.len()
            )));
        }
        Ok(2 * (k + usize::from(leader)))
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (has_leader, k) = self.split(obs.len()).unwrap_or((false, 0));
        let (mut blocks, mut actions) = (obs, &mut out[..]);
        if let (true, Some(leader)) = (has_leader, &self.leader) {
            leader.act(&blocks[..self.leader_dim], &mut actions[..2]);
            blocks = &blocks[self.leader_dim..];
            actions = &mut actions[2..];
        }
        let f = self.blocks.len;
        for i in 0..k {
            let block = &blocks[i * f..(i + 1) * f];
            let lf = self.followers.get(i).or(self.followers.first());
            let w = lf.map_or([0.0, 0.0], |lf| {
                lf.wheels(
                    block,
                    &self.blocks,
                    self.wheels.axle_length,
                    self.wheels.max_wheel_speed,
                )
            });
            actions[2 * i..2 * i + 2].copy_from_slice(&self.wheels.action(w));
        }
    }
}
