//! Tests of the scene's shapes and queries.

use super::*;

#[test]
fn rays_hit_each_shape_kind_exactly() {
    let mut scene = Scene::arena(2.0, 2.0, 0.05);
    let x = Vector::new(1.0, 0.0);
    // The closed-form walls agree with casting on the wall slabs.
    for k in 0..64 {
        let a = k as f32 * 0.1;
        let (dir, o) = (Vector::new(a.cos(), a.sin()), Vector::new(0.3, -0.6));
        let slabs = scene
            .walls()
            .iter()
            .filter_map(|w| w.cast(o, dir, 9.0))
            .fold(9.0, f32::min);
        let t = scene.cast(o, dir, 9.0, &[], 0.0).expect("wall");
        assert!((t - slabs).abs() < 1e-5, "{a}: {t} vs {slabs}");
        let p = o + 0.37 * dir;
        let slab_gap = scene
            .walls()
            .iter()
            .map(|w| w.distance(p))
            .fold(9.0, f32::min);
        assert!((scene.clearance(p) - slab_gap).abs() < 1e-5);
    }
    // arena wall at x = 1
    let t = scene.cast(Vector::ZERO, x, 5.0, &[], 0.0).expect("wall");
    assert!((t - 1.0).abs() < 1e-6);
    // Rays along an axis, their other component +0 or -0, meet the wall ahead of them
    // (from (0.3, -0.6) in the 2 m × 2 m arena), not one at infinity nor behind.
    let o = Vector::new(0.3, -0.6);
    for (dir, wall) in [
        (Vector::new(1.0, 0.0), 0.7),
        (Vector::new(1.0, -0.0), 0.7),
        (Vector::new(-1.0, 0.0), 1.3),
        (Vector::new(-1.0, -0.0), 1.3),
        (Vector::new(0.0, 1.0), 1.6),
        (Vector::new(-0.0, 1.0), 1.6),
        (Vector::new(0.0, -1.0), 0.4),
        (Vector::new(-0.0, -1.0), 0.4),
    ] {
        let t = scene.cast_walls(o, dir);
        assert!((t - wall).abs() < 1e-6, "{dir:?}: {t}");
    }
    scene
        .shapes
        .push(SceneShape::circle(Vector::new(0.5, 0.0), 0.1));
    let t = scene.cast(Vector::ZERO, x, 5.0, &[], 0.0).expect("circle");
    assert!((t - 0.4).abs() < 1e-6);
    scene.shapes.push(SceneShape::rect(
        Vector::new(0.2, 0.0),
        Vector::new(0.05, 0.05),
        std::f32::consts::FRAC_PI_4,
    ));
    let t = scene
        .cast(Vector::ZERO, x, 5.0, &[], 0.0)
        .expect("rotated box");
    assert!((t - (0.2 - 0.05 * 2f32.sqrt())).abs() < 1e-6);
    scene.shapes.push(SceneShape::segment(
        Vector::new(0.1, -0.5),
        Vector::new(0.1, 0.5),
    ));
    let t = scene.cast(Vector::ZERO, x, 5.0, &[], 0.0).expect("segment");
    assert!((t - 0.1).abs() < 1e-6);
    let t = scene.cast(Vector::ZERO, x, 5.0, &[Vector::new(0.06, 0.0)], 0.01);
    assert!((t.expect("disc") - 0.05).abs() < 1e-6);
    assert_eq!(scene.cast(Vector::ZERO, x, 0.04, &[], 0.0), None);
}

#[test]
fn clearance_to_walls_and_obstacles() {
    let mut scene = Scene::arena(2.0, 2.0, 0.05);
    assert!((scene.clearance(Vector::new(0.7, 0.0)) - 0.3).abs() < 1e-6);
    scene
        .shapes
        .push(SceneShape::circle(Vector::new(0.0, 0.5), 0.1));
    assert!((scene.clearance(Vector::ZERO) - 0.4).abs() < 1e-6);
}
