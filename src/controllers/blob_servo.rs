//! Colour-blob servoing for Seek (docs/task-design.md §6.3): steer toward the camera pixels of the
//! target colour and slow down as they fill the view.
//!
//! With the blob's centroid x̄ ∈ [−1, 1] (positive to the right: pixel 0 is the leftmost) and
//! its width w as a share of the scanline, ω = −k·ω_max·x̄ and v = v_max·(1 − |x̄|)·(1 − w/w*),
//! never below 0; with no target pixel in view it searches, driving a circle (`search_speed`,
//! `search`·ω_max) that sweeps the view across the arena.
//! While the blob is narrower than w*/2 (or unseen), Braitenberg avoidance (the paper's eqs. 5–7,
//! K-Team-style weights) is added on the IR ring, as in `avoid_heuristic`; near the target it is
//! not, or the target itself would push the robot away.
//!
//! A pixel is of the target colour when each channel is within `tolerance` of it. Units: m/s,
//! rad/s; robot frame x forward, y left.

use super::braitenberg::Braitenberg;
use super::position::twist_to_wheels;
use super::{non_negative, positive, Controller, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::IR_COUNT;

crate::config_table! {
    /// Parameters of the blob servo.
    pub struct BlobServoParams {
        /// RGB in [0, 1] of the target (Seek's red pillar)
        target: [f32; 3] = [1.0, 0.0, 0.0],
        /// largest difference per channel of a target pixel
        tolerance: f32 = 0.3,
        /// k, gain on the centroid's offset [E]
        k: f32 = 1.0,
        /// m/s, v_max [E: as the paper's position control, 0.3 m/s would brake too late; task-design.md §6.3]
        vmax: f32 = 0.2,
        /// rad/s, omega_max [E]
        wmax: f32 = 2.0,
        /// w*, share of the scanline the target fills where the robot stops [D: the 5 cm pillar 11 cm ahead of the camera spans 54 of 131 degrees, 0.41; a little more]
        stop_width: f32 = 0.5,
        /// share of omega_max turning while searching
        search: f32 = 0.5,
        /// m/s, forward speed while searching: a wide circle, not a turn on the spot, so that an obstacle hiding the target from the start does not hide it for ever [E]
        search_speed: f32 = 0.1,
        /// values per pixel in the camera block: 4 with depth, 3 without
        values_per_pixel: u32 = 4,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// A colour to find in the camera's pixels: each channel within `tolerance` of `target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetColour {
    target: [f32; 3],
    tolerance: f32,
}

impl TargetColour {
    /// The colour `target` (RGB in [0, 1]) with a `tolerance` >= 0 per channel; `who` names the
    /// controller in errors.
    pub fn new(who: &str, target: [f32; 3], tolerance: f32) -> Result<Self> {
        if target.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(Error::Param(format!(
                "{who}: target must be [r, g, b] in [0, 1], got {target:?}"
            )));
        }
        Ok(Self {
            target,
            tolerance: non_negative(who, "tolerance", tolerance)?,
        })
    }

    /// Whether a pixel's r, g, b is of this colour.
    #[inline]
    pub fn matches(&self, rgb: &[f32]) -> bool {
        rgb.iter()
            .zip(self.target)
            .all(|(c, t)| (c - t).abs() <= self.tolerance)
    }
}

/// The blob servo on a Seek observation.
#[derive(Debug, Clone, PartialEq)]
pub struct BlobServoPolicy {
    colour: TargetColour,
    k: f32,
    vmax: f32,
    wmax: f32,
    stop_width: f32,
    search: f32,
    search_speed: f32,
    per: usize,
    pixels: usize,
    camera: usize,
    ir: usize,
    avoidance: Braitenberg,
    wheels: WheelMap,
    obs_dim: usize,
}

impl Controller for BlobServoPolicy {
    const NAME: &'static str = "blob_servo";
    const READS: &'static str = "seek";
    type Params = BlobServoParams;

    fn new(params: &BlobServoParams, layout: &ObsLayout) -> Result<Self> {
        let who = Self::NAME;
        let per = params.values_per_pixel as usize;
        if per != 3 && per != 4 {
            return Err(Error::Param(format!(
                "{who}: values_per_pixel must be 3 or 4, got {per}"
            )));
        }
        let camera = layout
            .find("camera")
            .ok_or_else(|| Error::Param(format!("{who}: the observation has no `camera` block")))?;
        if camera.len() % per != 0 {
            return Err(Error::Param(format!(
                "{who}: a camera block of {} values is not whole pixels of {per}",
                camera.len()
            )));
        }
        Ok(Self {
            colour: TargetColour::new(who, params.target, params.tolerance)?,
            k: non_negative(who, "k", params.k)?,
            vmax: positive(who, "vmax", params.vmax)?,
            wmax: positive(who, "wmax", params.wmax)?,
            stop_width: positive(who, "stop_width", params.stop_width)?,
            search: non_negative(who, "search", params.search)?,
            search_speed: non_negative(who, "search_speed", params.search_speed)?,
            per,
            pixels: camera.len() / per,
            camera: camera.start,
            ir: layout.require("ir", IR_COUNT, who)?,
            avoidance: Braitenberg::default(),
            wheels: WheelMap::new(who, params.axle_length, params.max_wheel_speed)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let (mut count, mut sum) = (0usize, 0.0f32);
        for i in 0..self.pixels {
            let px = &obs[self.camera + i * self.per..self.camera + i * self.per + 3];
            if self.colour.matches(px) {
                count += 1;
                // Pixel centres from −1 (left edge) to 1 (right edge).
                sum += 2.0 * (i as f32 + 0.5) / self.pixels as f32 - 1.0;
            }
        }
        let width = count as f32 / self.pixels as f32;
        let (v, w) = if count == 0 {
            (self.search_speed, self.search * self.wmax)
        } else {
            let x = sum / count as f32;
            let v = self.vmax * (1.0 - x.abs()) * (1.0 - width / self.stop_width);
            (v.max(0.0), -self.k * self.wmax * x)
        };
        let mut wheels = twist_to_wheels(v, w, self.wheels.axle_length);
        if width < 0.5 * self.stop_width {
            let mut proximity = [0.0f32; IR_COUNT];
            proximity.copy_from_slice(&obs[self.ir..self.ir + IR_COUNT]);
            wheels = self.avoidance.apply(wheels, &proximity);
        }
        out.copy_from_slice(&self.wheels.action(wheels));
    }
}
