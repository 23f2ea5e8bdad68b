//! The front colour camera (Aptina MT9V034, 752 × 480, 131° horizontal field of view; K-Team
//! manual §4.5, docs/robot.md §6) as a scanline: `camera_pixels` pixels (32 [D]:
//! docs/task-design.md §6.2) across the horizontal field, each `camera_rays_per_pixel` rays (4 [E])
//! across its width from the camera 60 mm ahead of the robot's centre, the pixel showing the
//! nearest surface they meet (so that a thin pillar between two pixel centres still shows)
//! (Webots `Khepera4.proto`: (+60, 0, 27.5) mm, fieldOfView 2.287 rad): the colour
//! (RGB in [0, 1]) and the depth of the first surface the ray meets: walls (`arena.wall_color`),
//! obstacles (their `color`), other robots (their top LEDs' colour, `robot.led_color`). A ray
//! that meets nothing within `camera_range` (2 m [E]) sees black at depth `camera_range`.
//! Pixel 0 is the leftmost (the image as the robot sees it, left to right).
//!
//! Optional Gaussian noise on each colour channel (`camera_noise_sigma`, 0 by default: no
//! random draws), clamped to [0, 1].
//!
//! Units: `sensor_readings()["camera_rgb"]` (n_robots, 3·N: r, g, b of pixel 0, then pixel 1,
//! ...), `["camera_depth"]` (n_robots, N), m. The observation block `camera` holds, per pixel,
//! r, g, b and depth / `camera_range` (4·N values in [0, 1]; 3·N without depth,
//! `camera_depth = false`). Not carried by default (`[sensors] carry`).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rapier2d::math::Vector;

use super::{rotate, unit, DrawContext, Readout, SenseContext, Sensor};
use crate::config::Domain;
use crate::draw::Mark;
use crate::geometry::scene::Target;
use crate::obs::Block;

/// Most pixels of a scanline.
pub const MAX_CAMERA_PIXELS: u32 = 256;
/// The camera's position ahead of the robot's centre (m): Webots `Khepera4.proto` (docs/robot.md
/// §6).
pub const CAMERA_AHEAD: f32 = 0.060;

crate::config_table! {
    /// The camera's keys in `[sensors]`.
    pub struct CameraConfig {
        /// pixels of the scanline across the field of view (1..256) [D: docs/task-design.md §6.2]
        camera_pixels: u32 = 32 => Domain::range(1.0, MAX_CAMERA_PIXELS as f64),
        /// rad, horizontal field of view [C: 131 deg, K-Team manual §4.5; Webots 2.287 rad]
        camera_fov: f32 = 2.287 => Domain::POSITIVE.below(std::f64::consts::TAU),
        /// m, farthest surface a pixel sees [E]
        camera_range: f32 = 2.0 => Domain::POSITIVE.at_most(100.0),
        /// per colour channel, Gaussian (0: none) [E]
        camera_noise_sigma: f32 = 0.0 => Domain::range(0.0, 10.0),
        /// whether the observation holds each pixel's depth after its colour
        camera_depth: bool = true,
        /// rays across each pixel's width; the pixel shows the nearest surface they meet (1..16) [E]
        camera_rays_per_pixel: u32 = 4 => Domain::range(1.0, 16.0),
    }
}

/// One robot's scanline.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct CameraReading {
    /// r, g, b of each pixel, left to right.
    pub rgb: Vec<[f32; 3]>,
    /// Depth of each pixel (m).
    pub depth: Vec<f32>,
}

/// The scanline camera as a [`Sensor`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Bearing of each pixel's ray (rad, robot frame, left positive), left to right.
    pub bearings: Vec<f32>,
    /// Field of view (rad).
    pub fov: f32,
    /// Range (m).
    pub range: f32,
    /// Colour noise.
    pub noise_sigma: f32,
    /// Whether the observation holds depth.
    pub depth: bool,
    /// Offsets (rad) of each pixel's rays from its centre.
    pub sub_rays: Vec<f32>,
}

impl Camera {
    /// The colour of what `target` is: a wall, an obstacle or a robot (its LEDs).
    fn color_of(target: &Target, ctx: &SenseContext) -> [f32; 3] {
        match target {
            Target::Wall => ctx.scene.wall_color,
            Target::Shape(shape) => shape.color,
            // The LEDs of the robot of smallest index centred there: `other_ids` holds the
            // others' indices, or is empty when the others come in robot order.
            Target::Disc(c) => {
                let index = |j: usize| ctx.other_ids.get(j).map_or(j, |&id| id as usize);
                ctx.others
                    .iter()
                    .enumerate()
                    .filter(|(_, o)| *o == c)
                    .min_by_key(|(j, _)| index(*j))
                    .and_then(|(j, _)| ctx.other_leds.get(j).copied())
                    .unwrap_or([0.0, 0.0, 0.0])
            }
        }
    }

    fn values_per_pixel(&self) -> usize {
        if self.depth {
            4
        } else {
            3
        }
    }
}

impl Sensor for Camera {
    const NAME: &'static str = "camera";
    type Config = CameraConfig;
    type Reading = CameraReading;

    fn new(cfg: &CameraConfig) -> Self {
        let n = cfg.camera_pixels.max(1) as usize;
        let step = cfg.camera_fov / n as f32;
        Self {
            bearings: (0..n)
                .map(|i| 0.5 * cfg.camera_fov - (i as f32 + 0.5) * step)
                .collect(),
            fov: cfg.camera_fov,
            range: cfg.camera_range,
            noise_sigma: cfg.camera_noise_sigma,
            depth: cfg.camera_depth,
            sub_rays: {
                let k = cfg.camera_rays_per_pixel.max(1) as usize;
                (0..k)
                    .map(|j| step * ((j as f32 + 0.5) / k as f32 - 0.5))
                    .collect()
            },
        }
    }

    fn randomise(&mut self, _cfg: &CameraConfig, _rng: &mut ChaCha8Rng) {}

    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut CameraReading) {
        let (s, c) = ctx.sin_cos;
        let origin = ctx.position + ctx.to_world(Vector::new(CAMERA_AHEAD, 0.0));
        reading.rgb.clear();
        reading.depth.clear();
        for &bearing in &self.bearings {
            // The nearest surface any of the pixel's rays meets.
            let mut nearest: Option<crate::geometry::scene::Hit> = None;
            for &offset in &self.sub_rays {
                let dir = rotate(unit(bearing + offset), c, s);
                let hit = ctx.scene.cast_hit(
                    origin,
                    dir,
                    self.range,
                    ctx.scene.shapes.iter(),
                    ctx.others,
                    ctx.other_ids,
                    ctx.radius,
                );
                if let Some(h) = hit {
                    if nearest.is_none_or(|n| h.distance < n.distance) {
                        nearest = Some(h);
                    }
                }
            }
            let (mut color, depth) = match nearest {
                Some(h) => (Self::color_of(&h.target, ctx), h.distance),
                None => ([0.0; 3], self.range),
            };
            if self.noise_sigma > 0.0 {
                for channel in &mut color {
                    let noise: f32 = rng.sample(StandardNormal);
                    *channel = (*channel + self.noise_sigma * noise).clamp(0.0, 1.0);
                }
            }
            reading.rgb.push(color);
            reading.depth.push(depth);
        }
    }

    fn block(&self) -> Block {
        Block::new(Self::NAME, self.obs_len(), 0.0, 1.0)
    }

    fn obs_len(&self) -> usize {
        self.bearings.len() * self.values_per_pixel()
    }

    #[inline]
    fn observe(&self, reading: &CameraReading, out: &mut [f32]) {
        let per = self.values_per_pixel();
        for ((o, rgb), depth) in out
            .chunks_exact_mut(per)
            .zip(&reading.rgb)
            .zip(&reading.depth)
        {
            o[..3].copy_from_slice(rgb);
            if self.depth {
                o[3] = (depth / self.range).clamp(0.0, 1.0);
            }
        }
    }

    fn readout(&self, reading: &CameraReading, out: &mut Readout) {
        let n = self.bearings.len();
        let rgb: Vec<f32> = reading.rgb.iter().flatten().copied().collect();
        out.reals("camera_rgb", 3 * n, &rgb);
        out.reals("camera_depth", n, &reading.depth);
    }

    fn draw(&self, at: &DrawContext, _reading: &CameraReading, marks: &mut Vec<Mark>) {
        let forward = Vector::new(at.heading.cos(), at.heading.sin());
        let origin = at.position + forward * CAMERA_AHEAD;
        for edge in [0.5 * self.fov, -0.5 * self.fov] {
            marks.push(Mark::Ray {
                from: origin,
                to: origin + unit(at.heading + edge) * 0.25,
                colour: [230, 160, 0],
                alpha: 200,
                width: 0.004,
            });
        }
    }

    fn reach(&self, radius: f32) -> f32 {
        // A ray of `range` from 60 mm ahead of the centre meets discs of `radius`.
        CAMERA_AHEAD + self.range + radius
    }
}
