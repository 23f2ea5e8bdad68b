//! Leader–follower formation control (paper §3.5, eq. 12) on a follower's observation.
//!
//! The follower computes its target from the leader's pose in its own frame (observation
//! `leader_offset`, `leader_heading`) and its (r, β): target = leader + R(θ_L − θ)·(r cos β,
//! r sin β), which is eq. 12 written in the follower's frame. It drives there with position
//! control (eqs. 1–4) plus the leader's forward speed projected on its own heading
//! (feed-forward, so it does not trail behind a moving target), then Braitenberg avoidance.

use super::position::twist_to_wheels;
use super::{Braitenberg, PositionControl};

/// Observation indices of a follower block (see `tasks::formation::FOLLOWER_LAYOUT`).
pub mod index {
    /// IR proximities.
    pub const IR: usize = 0;
    /// Target offset (x, y) in the follower frame.
    pub const TARGET: usize = 13;
    /// Leader position (x, y) in the follower frame.
    pub const LEADER: usize = 15;
    /// sin, cos of the leader's heading relative to the follower's.
    pub const LEADER_HEADING: usize = 17;
    /// Leader (v / v_max, ω / ω_max).
    pub const LEADER_VELOCITY: usize = 19;
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
    /// Wheel speeds (m/s) for one follower block; `max_wheel_speed` scales the leader's
    /// normalised speed back to m/s.
    pub fn wheels(&self, block: &[f32], axle: f32, max_wheel_speed: f32) -> [f32; 2] {
        let (tx, ty) = match self.offset {
            None => (block[index::TARGET], block[index::TARGET + 1]),
            Some([r, beta]) => {
                let (s, c) = (
                    block[index::LEADER_HEADING],
                    block[index::LEADER_HEADING + 1],
                );
                let (ox, oy) = (r * beta.cos(), r * beta.sin());
                (
                    block[index::LEADER] + c * ox - s * oy,
                    block[index::LEADER + 1] + s * ox + c * oy,
                )
            }
        };
        let distance = (tx * tx + ty * ty).sqrt();
        let bearing = ty.atan2(tx);
        let (mut v, w) = self.control.twist(distance, bearing);
        if self.feedforward {
            let leader_v = block[index::LEADER_VELOCITY] * max_wheel_speed;
            v += leader_v * block[index::LEADER_HEADING + 1] * bearing.cos().max(0.0);
        }
        let wheels = twist_to_wheels(v, w, axle);
        match &self.avoidance {
            None => wheels,
            Some(b) => {
                let mut p = [0.0f32; 8];
                p.copy_from_slice(&block[index::IR..index::IR + 8]);
                b.apply(wheels, &p)
            }
        }
    }
}
