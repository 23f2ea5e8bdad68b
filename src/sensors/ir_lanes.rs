//! The IR ring's eight rays in lanes: one kernel, compiled for each of the CPU's vector paths
//! ([`crate::simd`]), that computes what [`Scene::cast_hit`] and [`IrModel::read_surface`]
//! compute ray after ray, with the same operations in the same order for each ray, so that
//! every path gives the same bits as the scalar code.

use rapier2d::math::Vector;

use super::ir::{IrModel, IrReading, CURVE_MM, IR_COUNT, IR_MAX_RAW};
use super::rotate;
use crate::geometry::rays::may_hit;
use crate::geometry::scene::Scene;

/// What the eight rays see: the robot, its surroundings and the noise already drawn.
pub(super) struct Ring<'a> {
    pub model: &'a IrModel,
    pub dirs: &'a [Vector; IR_COUNT],
    pub position: Vector,
    pub radius: f32,
    pub sin_cos: (f32, f32),
    pub scene: &'a Scene,
    /// Indices in `scene.shapes` of the obstacles within reach.
    pub shapes: &'a [usize],
    /// Centres of the robots within reach, in robot order.
    pub others: &'a [Vector],
    pub robot_reflectance: f32,
    /// One standard normal draw a sensor, in K-Team order.
    pub noise: &'a [f32; IR_COUNT],
}

crate::multiversion! {
    /// Writes the ring's reading: [`super::ir::IrRing`]'s rays, each one as
    /// [`Scene::cast_hit`] casts it and [`IrModel::read_surface`] reads it. The portable path
    /// casts them one after the other (in SSE2's four lanes the kernel costs more than it
    /// saves: 4,931 instructions a Nav env-step against 4,688).
    pub(super) fn read_ring(ring: &Ring, reading: &mut IrReading) = read_ring_body, portable = read_ray_by_ray;
}

/// The ring read ray after ray: [`Scene::cast_hit`] and [`IrModel::read_surface`]'s arithmetic
/// on the noise drawn before (the portable path, and the reference of the lanes).
fn read_ray_by_ray(ring: &Ring, reading: &mut IrReading) {
    let (s, c) = ring.sin_cos;
    for k in 0..IR_COUNT {
        let dir = rotate(ring.dirs[k], c, s);
        let origin = ring.position + ring.radius * dir;
        let near = ring.shapes.iter().map(|&n| &ring.scene.shapes[n]);
        let hit = ring.scene.cast_hit(
            origin,
            dir,
            ring.model.range,
            near,
            ring.others,
            &[],
            ring.radius,
        );
        let reflectance = hit.map_or(1.0, |h| h.reflectance(ring.scene, ring.robot_reflectance));
        let distance = hit.map(|h| h.distance);
        reading.raw[k] = ring.model.surface_raw(distance, reflectance, ring.noise[k]);
        reading.hit[k] = distance.unwrap_or(ring.model.range);
    }
}

// Only the x86-64 paths run the lanes; elsewhere the portable path casts ray by ray.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
#[inline(always)]
fn read_ring_body(ring: &Ring, reading: &mut IrReading) {
    let model = ring.model;
    let scene = ring.scene;
    let (s, c) = ring.sin_cos;
    let mut ox = [0.0f32; IR_COUNT];
    let mut oy = [0.0f32; IR_COUNT];
    let mut dx = [0.0f32; IR_COUNT];
    let mut dy = [0.0f32; IR_COUNT];
    for k in 0..IR_COUNT {
        let dir = rotate(ring.dirs[k], c, s);
        (dx[k], dy[k]) = (dir.x, dir.y);
        ox[k] = ring.position.x + ring.radius * dir.x;
        oy[k] = ring.position.y + ring.radius * dir.y;
    }
    // The nearest hit so far (the range when none) and the reflectance of what it hit. A hit
    // at the range reads as no hit (the floor value), so no flag is kept.
    let mut best = [model.range; IR_COUNT];
    let mut reflectance = [1.0f32; IR_COUNT];
    if scene.walled {
        // Scene::cast_walls, lane by lane.
        let (hw, hh) = (0.5 * scene.arena.0, 0.5 * scene.arena.1);
        for k in 0..IR_COUNT {
            let outside = (ox[k].abs() >= hw) | (oy[k].abs() >= hh);
            let tx = (hw.copysign(dx[k]) - ox[k]) / dx[k];
            let ty = (hh.copysign(dy[k]) - oy[k]) / dy[k];
            let wall = if outside { 0.0 } else { tx.min(ty) };
            let nearer = wall <= best[k];
            best[k] = if nearer { wall } else { best[k] };
            reflectance[k] = if nearer {
                scene.wall_reflectance
            } else {
                reflectance[k]
            };
        }
    }
    for k in 0..IR_COUNT {
        let (o, d) = (Vector::new(ox[k], oy[k]), Vector::new(dx[k], dy[k]));
        for shape in ring.shapes.iter().map(|&n| &scene.shapes[n]) {
            if !may_hit(o, d, shape.center, shape.bound_radius, best[k]) {
                continue;
            }
            if let Some(t) = shape.cast(o, d, best[k]) {
                if t <= best[k] {
                    best[k] = t;
                    reflectance[k] = shape.reflectance;
                }
            }
        }
    }
    let r2 = ring.radius * ring.radius;
    for &centre in ring.others {
        // geometry::rays::ray_disc, lane by lane.
        for k in 0..IR_COUNT {
            let (ocx, ocy) = (ox[k] - centre.x, oy[k] - centre.y);
            let b = ocx * dx[k] + ocy * dy[k];
            let cc = (ocx * ocx + ocy * ocy) - r2;
            let inside = cc <= 0.0;
            let t = -b - (b * b - cc).sqrt();
            let hit = inside | ((b <= 0.0) & (t <= best[k]));
            let at = if inside { 0.0 } else { t.max(0.0) };
            best[k] = if hit { at } else { best[k] };
            reflectance[k] = if hit {
                ring.robot_reflectance
            } else {
                reflectance[k]
            };
        }
    }
    for k in 0..IR_COUNT {
        let white = mean_raw(model, best[k]);
        let mean = if reflectance[k] == 1.0 {
            white
        } else {
            model.floor_value + reflectance[k] * (white - model.floor_value)
        };
        let raw = mean + model.noise_sigma * ring.noise[k];
        // In [0, 1023.5] (or NaN, which both casts take to 0): through i32, which vector
        // units convert, the same integer as the cast to u16.
        reading.raw[k] = ((raw.clamp(0.0, IR_MAX_RAW) + 0.5) as i32) as u16;
        reading.hit[k] = best[k];
    }
}

/// [`IrModel::mean_raw`] of the nearest hit at `distance` (the range or beyond: none), without
/// its binary search: the curve's segment is found by counting the points at or below the
/// distance, which is the same index on a sorted curve and has no branch.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
#[inline(always)]
pub(super) fn mean_raw(model: &IrModel, distance: f32) -> f32 {
    let last = CURVE_MM.len() - 1;
    let within = distance < model.range;
    let d = distance.max(0.0) * 1000.0;
    let span = model.range * 1000.0 - CURVE_MM[last];
    let beyond =
        model.curve[last] + (d - CURVE_MM[last]) / span * (model.floor_value - model.curve[last]);
    let mut i = 0u32;
    for x in CURVE_MM {
        i += u32::from(x <= d);
    }
    let i = (i as usize).clamp(1, last);
    let (x0, x1) = (CURVE_MM[i - 1], CURVE_MM[i]);
    let (y0, y1) = (model.curve[i - 1], model.curve[i]);
    let inside = y0 + (d - x0) / (x1 - x0) * (y1 - y0);
    if !within {
        model.floor_value
    } else if d >= CURVE_MM[last] {
        beyond
    } else {
        inside
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::scene::SceneShape;
    use crate::sensors::ir::{CURVE_RAW, IR_BEARINGS};
    use crate::sensors::unit;
    use crate::simd::{self, PATHS};
    use rand::{Rng, SeedableRng};

    #[test]
    fn every_path_reads_the_ring_as_the_rays_one_by_one_do() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let dirs = IR_BEARINGS.map(unit);
        let model = IrModel {
            range: 0.25,
            floor_value: 100.0,
            noise_sigma: 10.0,
            curve: CURVE_RAW,
        };
        let (mut readings, mut near) = (0usize, 0usize);
        for case in 0..20_000 {
            let mut scene = Scene::arena(0.8, 0.6, 0.02);
            scene.walled = case % 7 != 0;
            scene.wall_reflectance = if case % 3 == 0 { 0.6 } else { 1.0 };
            let spot = |rng: &mut rand_chacha::ChaCha8Rng| {
                Vector::new(rng.random_range(-0.45..0.45), rng.random_range(-0.35..0.35))
            };
            for n in 0..case % 4 {
                let at = spot(&mut rng);
                let shape = if n % 2 == 0 {
                    SceneShape::circle(at, rng.random_range(0.01..0.1))
                } else {
                    let half =
                        Vector::new(rng.random_range(0.01..0.1), rng.random_range(0.01..0.1));
                    SceneShape::rect(at, half, rng.random_range(-3.0..3.0))
                };
                scene
                    .shapes
                    .push(shape.with_reflectance(rng.random_range(0.3..1.2)));
            }
            let position = spot(&mut rng);
            // Other robots near this one (some overlapping it, some touching).
            let others: Vec<Vector> = (0..case % 5)
                .map(|_| {
                    position + Vector::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3))
                })
                .collect();
            let shapes: Vec<usize> = (0..scene.shapes.len()).collect();
            let noise: [f32; IR_COUNT] = std::array::from_fn(|_| rng.random_range(-4.0..4.0));
            let heading: f32 = rng.random_range(-3.2..3.2);
            let ring = Ring {
                model: &model,
                dirs: &dirs,
                position,
                radius: 0.0704,
                sin_cos: heading.sin_cos(),
                scene: &scene,
                shapes: &shapes,
                others: &others,
                robot_reflectance: if case % 2 == 0 { 1.0 } else { 0.8 },
                noise: &noise,
            };
            let mut want = IrReading::default();
            read_ray_by_ray(&ring, &mut want);
            near += want.hit.iter().filter(|&&h| h < model.range).count();
            for path in PATHS.into_iter().filter(|p| p.available()) {
                simd::force(path).expect("available");
                let mut got = IrReading::default();
                read_ring(&ring, &mut got);
                assert_eq!(got.raw, want.raw, "case {case}, {}", path.name());
                assert_eq!(
                    got.hit.map(f32::to_bits),
                    want.hit.map(f32::to_bits),
                    "case {case}, {}",
                    path.name()
                );
                readings += 1;
            }
        }
        simd::force(simd::widest()).expect("the widest");
        assert!(near > 20_000, "only {near} rays met something");
        assert!(readings >= 20_000);
    }

    #[test]
    fn the_counted_curve_is_the_searched_one_bit_for_bit() {
        let mut model = IrModel {
            range: 0.25,
            floor_value: 100.0,
            noise_sigma: 10.0,
            curve: CURVE_RAW,
        };
        let mut distances: Vec<f32> = (0..=300_000).map(|i| i as f32 * 1e-6).collect();
        // The curve's points, either side of each, and what is not a distance.
        for mm in CURVE_MM {
            let m = mm / 1000.0;
            distances.extend([m, m.next_up(), m.next_down()]);
        }
        distances.extend([
            -0.01,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.25,
            0.3,
        ]);
        for (range, floor) in [(0.25, 100.0), (0.21, 111.0), (1.0, 0.0)] {
            (model.range, model.floor_value) = (range, floor);
            for &d in &distances {
                let want = model.mean_raw(Some(d));
                assert_eq!(mean_raw(&model, d).to_bits(), want.to_bits(), "{d}");
            }
        }
    }
}
