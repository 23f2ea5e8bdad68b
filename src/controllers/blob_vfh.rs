//! Seek among obstacles: the Vector Field Histogram (paper eqs. 8–11, with VFH+'s enlargement
//! and direction choice, [`super::vfh`]) driving to the coloured pillar the camera sees, its
//! histogram built from the IR ring and the camera's depth.
//!
//! The camera gives what Nav's observation gives from a tracker: the pillar's bearing and its
//! distance. A pixel is of the target colour when each channel is within `tolerance` of it;
//! pixel i looks along φ_i = fov/2 − (i + ½)·fov/N (pixel 0 leftmost, as the camera's
//! scanline) and its depth is the range (`camera_range` × the observed depth) from the camera,
//! `camera_ahead` in front of the robot's centre, to the nearest surface its rays meet. The
//! pillar's centre lies along the ray through the middle of the target pixels, `pillar_radius`
//! beyond the nearest surface they show. The robot drives to the point `standoff` short of that
//! centre (it cannot reach the centre of a pillar; Seek succeeds within 0.1704 m of it).
//!
//! The histogram: every other pixel is a range reading (the surface it shows, in the robot
//! frame, with the pixel's width as its beam; a sector keeps the nearest surface its pixels
//! show, since many pixels on one wall are one obstacle), the IR ring adds its proximities, and
//! both are enlarged by VFH+'s r_r + d_s. The camera sees what the IR ring's eight rays miss in
//! front: a thin wall between two rays, against which the IR-only controllers stall on v2
//! (position control and Braitenberg on the pillar the camera sees reached 68–72% of the
//! targets, over half of its failures pressed against walls its IR ring did not see). Pixels
//! count within `range_window` of the rim, about the IR ring's reach: with vfh's 0.45 m window
//! for the sonars, 32 pixels fill the histogram in Seek's clutter. The IR sensors within
//! `target_cone` of the pillar's bearing are left out once the pillar is within IR range: they
//! see the target, not an obstacle.
//!
//! With no target pixel in view it explores toward the most open direction: the farthest
//! surface the camera shows (of several, the one nearest straight ahead), avoiding obstacles with
//! the same histogram. It drives into open space, turns where the arena closes in, and so sweeps
//! the view over the arena and leaves a place from which the pillar is hidden. The controller is
//! stateless, as every baseline: it acts on the current observation only (its previous direction
//! it reads from its wheel speeds, as [`super::vfh`]).
//!
//! Units: metres, m/s, radians, rad/s; robot frame x forward, y left, angles CCW.

use super::blob_servo::TargetColour;
use super::vfh::{Vfh, VfhParams};
use super::{non_negative, positive, Controller, WheelMap};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;
use crate::sensors::{IR_BEARINGS, IR_COUNT};

crate::config_table! {
    /// Parameters of VFH on the pillar the camera sees.
    pub struct BlobVfhParams {
        /// RGB in [0, 1] of the target (Seek's red pillar: the scenario's seek.pillar_color)
        target: [f32; 3] = [1.0, 0.0, 0.0],
        /// largest difference per channel of a target pixel
        tolerance: f32 = 0.3,
        /// m, the pillar's radius: the scenario's seek.pillar_radius
        pillar_radius: f32 = 0.05,
        /// m, distance from the pillar's centre where the robot stops [D: robot radius 0.0704 + pillar 0.05 + 1 cm; Seek succeeds within 0.1704]
        standoff: f32 = 0.13,
        /// rad, half-width of the cone round the pillar's bearing whose IR sensors see the target, not an obstacle [D: 45°, the ring's spacing]
        target_cone: f32 = 0.7853981633974483,
        /// rad, the camera's horizontal field of view: the scenario's sensors.camera_fov
        camera_fov: f32 = 2.287,
        /// m, the camera's depth full scale: the scenario's sensors.camera_range
        camera_range: f32 = 2.0,
        /// m, the camera's position ahead of the robot's centre [S: Webots Khepera4.proto]
        camera_ahead: f32 = 0.06,
        /// values per pixel in the camera block: 4 (with depth; this controller needs it)
        values_per_pixel: u32 = 4,
        /// histogram sectors around the robot, as vfh's
        sectors: usize = 36,
        /// smoothed density under which a sector is free, as vfh's
        threshold: f32 = 0.15,
        /// h_m of eqs. 10-11, as vfh's
        hm: f32 = 0.6,
        /// v_max (m/s), as vfh's
        vmax: f32 = 0.3,
        /// ω_max (rad/s), as vfh's
        wmax: f32 = 3.0,
        /// docking radius k_r of eq. 3 (m), as vfh's
        kr: f32 = 0.15,
        /// m, camera pixels showing a surface farther than this from the rim add nothing (vfh's us_range for the sonars) [D: docs/notes/controllers-v2.md: 0.45 m, vfh's, fills the histogram in Seek's clutter (42% of targets); 0.15 m, about the IR ring's useful reach, 84%]
        range_window: f32 = 0.15,
        /// angular width an IR reading fills before enlargement (rad), as vfh's beam_width
        beam_width: f32 = 0.7853981633974483,
        /// narrowest free valley the robot steers into (rad), as vfh's
        min_valley: f32 = 0.5235987755982988,
        /// VFH+'s μ2/μ1, as vfh's
        heading_weight: f32 = 0.4,
        /// VFH+'s μ3/μ1, as vfh's
        previous_weight: f32 = 0.4,
        /// extra cost (rad) of a candidate on the other side of the current turn, as vfh's
        switch_penalty: f32 = 0.6,
        /// r_r of VFH+'s enlargement (m), as vfh's
        robot_radius: f32 = 0.0704,
        /// d_s of VFH+'s enlargement (m), as vfh's
        safety_distance: f32 = 0.015,
        /// the IR observation's floor (raw count with nothing seen), as vfh's
        ir_floor_value: f32 = 100.0,
        /// the IR range (m), as vfh's
        ir_range: f32 = 0.25,
        /// wheel separation (m)
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// VFH on a Seek observation (`camera` with depth, `ir`, `wheel_speeds`).
#[derive(Debug, Clone, PartialEq)]
pub struct BlobVfhPolicy {
    colour: TargetColour,
    pillar_radius: f32,
    standoff: f32,
    target_cone: f32,
    camera_fov: f32,
    camera_range: f32,
    camera_ahead: f32,
    vfh: Vfh,
    wheels: WheelMap,
    camera: usize,
    pixels: usize,
    ir: usize,
    wheel_speeds: usize,
    obs_dim: usize,
}

impl Controller for BlobVfhPolicy {
    const NAME: &'static str = "blob_vfh";
    const READS: &'static str = "seek";
    type Params = BlobVfhParams;

    fn new(params: &BlobVfhParams, layout: &ObsLayout) -> Result<Self> {
        let who = Self::NAME;
        if params.values_per_pixel != 4 {
            return Err(Error::Param(format!(
                "{who}: reads each pixel's depth: values_per_pixel must be 4 (sensors.camera_depth \
                 = true), got {}",
                params.values_per_pixel
            )));
        }
        let camera = layout
            .find("camera")
            .ok_or_else(|| Error::Param(format!("{who}: the observation has no `camera` block")))?;
        if camera.is_empty() || camera.len() % 4 != 0 {
            return Err(Error::Param(format!(
                "{who}: a camera block of {} values is not whole pixels of r, g, b, depth",
                camera.len()
            )));
        }
        let camera_fov = positive(who, "camera_fov", params.camera_fov)?;
        if camera_fov >= std::f32::consts::TAU {
            return Err(Error::Param(format!(
                "{who}: camera_fov must be below 2 pi, got {camera_fov}"
            )));
        }
        let vfh = VfhParams {
            sectors: params.sectors,
            threshold: params.threshold,
            hm: params.hm,
            vmax: params.vmax,
            wmax: params.wmax,
            kr: params.kr,
            stop_radius: 0.0,
            us_range: params.range_window,
            beam_width: params.beam_width,
            us_beam_width: 0.0,
            min_valley: params.min_valley,
            heading_weight: params.heading_weight,
            previous_weight: params.previous_weight,
            switch_penalty: params.switch_penalty,
            robot_radius: params.robot_radius,
            safety_distance: params.safety_distance,
            ir_floor_value: params.ir_floor_value,
            ir_range: params.ir_range,
            axle_length: params.axle_length,
            max_wheel_speed: params.max_wheel_speed,
            ..Default::default()
        }
        .law(who)?;
        Ok(Self {
            colour: TargetColour::new(who, params.target, params.tolerance)?,
            pillar_radius: non_negative(who, "pillar_radius", params.pillar_radius)?,
            standoff: non_negative(who, "standoff", params.standoff)?,
            target_cone: non_negative(who, "target_cone", params.target_cone)?,
            camera_fov,
            camera_range: positive(who, "camera_range", params.camera_range)?,
            camera_ahead: non_negative(who, "camera_ahead", params.camera_ahead)?,
            vfh,
            wheels: WheelMap::new(who, params.axle_length, params.max_wheel_speed)?,
            camera: camera.start,
            pixels: camera.len() / 4,
            ir: layout.require("ir", IR_COUNT, who)?,
            wheel_speeds: layout.require("wheel_speeds", 2, who)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let pillar = self.pillar(obs);
        let step = self.camera_fov / self.pixels as f32;
        let mut h = vec![0.0f32; self.vfh.sectors];
        let mut seen = vec![0.0f32; self.vfh.sectors];
        // The camera's pixels other than the target's: range readings in the robot frame.
        for i in 0..self.pixels {
            let px = &obs[self.camera + 4 * i..self.camera + 4 * i + 4];
            let range = px[3] * self.camera_range;
            if self.colour.matches(&px[..3]) || range >= 0.999 * self.camera_range {
                continue; // the target, or nothing within the camera's range
            }
            let ray = 0.5 * self.camera_fov - (i as f32 + 0.5) * step;
            let (x, y) = (self.camera_ahead + range * ray.cos(), range * ray.sin());
            let rim_distance = (x * x + y * y).sqrt() - self.vfh.robot_radius;
            let magnitude = self.vfh.range_magnitude(rim_distance);
            if magnitude > 0.0 {
                // A sector holds the nearest surface the pixels show in it: many pixels on one
                // wall are one obstacle, not many.
                self.vfh
                    .fill(&mut seen, y.atan2(x), rim_distance, step, |slot| {
                        *slot = slot.max(magnitude)
                    });
            }
        }
        for (slot, camera) in h.iter_mut().zip(&seen) {
            *slot += camera;
        }
        // The IR ring, but for the sensors that see the pillar.
        let pillar_near = pillar.map(|(d, b)| {
            (
                d - self.pillar_radius - self.vfh.robot_radius <= self.vfh.ir_range,
                b,
            )
        });
        for (k, bearing) in IR_BEARINGS.iter().enumerate() {
            if let Some((true, b)) = pillar_near {
                if crate::robot::wrap_angle(bearing - b).abs() <= self.target_cone {
                    continue;
                }
            }
            self.vfh.add_ir(&mut h, *bearing, obs[self.ir + k]);
        }
        let h = self.vfh.smooth(&h);
        let wheels = &obs[self.wheel_speeds..self.wheel_speeds + 2];
        let turn_rate =
            (wheels[1] - wheels[0]) * self.wheels.max_wheel_speed / self.wheels.axle_length;
        let (v, w) = match pillar {
            Some((distance, bearing)) => {
                let to_go = (distance - self.standoff).max(0.0);
                if to_go <= 0.0 {
                    (0.0, 0.0)
                } else {
                    self.vfh.twist_in(&h, to_go, bearing, turn_rate)
                }
            }
            // Exploring: toward the most open direction, a goal far away.
            None => self
                .vfh
                .twist_in(&h, f32::INFINITY, self.most_open(obs), turn_rate),
        };
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

impl BlobVfhPolicy {
    /// The bearing (rad, robot frame) of the farthest surface the camera shows, of several the
    /// one nearest straight ahead: where it explores while the pillar is out of view.
    fn most_open(&self, obs: &[f32]) -> f32 {
        let step = self.camera_fov / self.pixels as f32;
        let ray = |i: usize| 0.5 * self.camera_fov - (i as f32 + 0.5) * step;
        let depth = |i: usize| obs[self.camera + 4 * i + 3];
        let far = (0..self.pixels).map(depth).fold(0.0f32, f32::max);
        (0..self.pixels)
            .filter(|&i| depth(i) >= far - 0.01)
            .map(ray)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(0.0)
    }

    /// Distance (m) and bearing (rad) from the robot's centre to the pillar's centre, from the
    /// target pixels of the scanline (None: none in view).
    fn pillar(&self, obs: &[f32]) -> Option<(f32, f32)> {
        let step = self.camera_fov / self.pixels as f32;
        let (mut first, mut last) = (None, 0usize);
        let mut nearest = f32::INFINITY; // range from the camera (m)
        for i in 0..self.pixels {
            let px = &obs[self.camera + 4 * i..self.camera + 4 * i + 4];
            if self.colour.matches(&px[..3]) {
                first.get_or_insert(i);
                last = i;
                nearest = nearest.min(px[3] * self.camera_range);
            }
        }
        let first = first?;
        // Along the ray through the middle of the target pixels (the blob's centre),
        // `pillar_radius` beyond the nearest surface they show, from the camera.
        let middle = 0.5 * (first + last) as f32;
        let ray = 0.5 * self.camera_fov - (middle + 0.5) * step;
        let reach = nearest + self.pillar_radius;
        let (x, y) = (self.camera_ahead + reach * ray.cos(), reach * ray.sin());
        Some(((x * x + y * y).sqrt(), y.atan2(x)))
    }
}
