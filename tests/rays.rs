//! A ray's hit among other robots does not depend on the order they are listed in: a swarm's
//! grid lists them cell by cell, with their indices, and must find what a scan in robot order
//! finds, down to which of two robots met at exactly the same distance is hit (the one of
//! larger index: the later in robot order).

use _core::geometry::scene::{Hit, Scene, SceneShape, Target};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rapier2d::math::Vector;

/// Khepera IV body radius (m), docs/robot.md.
const RADIUS: f32 = 0.0704;

/// (distance bits, centre of the robot hit, if a robot) of a hit.
fn key(hit: Option<Hit>) -> Option<(u32, Option<(u32, u32)>)> {
    hit.map(|h| {
        let disc = match h.target {
            Target::Disc(c) => Some((c.x.to_bits(), c.y.to_bits())),
            _ => None,
        };
        (h.distance.to_bits(), disc)
    })
}

/// `v` turned by `quarter` quarter turns, exactly (coordinates swapped and negated).
fn turn(v: Vector, quarter: u32) -> Vector {
    match quarter % 4 {
        0 => v,
        1 => Vector::new(-v.y, v.x),
        2 => Vector::new(-v.x, -v.y),
        _ => Vector::new(v.y, -v.x),
    }
}

#[test]
fn of_two_robots_met_at_the_same_distance_the_later_in_robot_order_is_hit() {
    let scene = Scene::arena(10.0, 10.0, 0.05);
    // Two discs mirrored about the ray's line: the ray enters both at the same point.
    let (a, b) = (Vector::new(1.0, 0.03), Vector::new(1.0, -0.03));
    let cast = |discs: &[Vector], ids: &[u32]| {
        scene.cast_hit(
            Vector::ZERO,
            Vector::X,
            3.0,
            scene.shapes.iter(),
            discs,
            ids,
            RADIUS,
        )
    };
    let in_order = cast(&[a, b], &[]).expect("a hit");
    assert!(
        matches!(in_order.target, Target::Disc(c) if c == b),
        "{in_order:?}"
    );
    assert!((in_order.distance - (1.0 - (RADIUS * RADIUS - 0.0009f32).sqrt())).abs() < 1e-6);
    // Listed the other way round, with their indices (a is robot 0, b robot 1): still b.
    let listed = cast(&[b, a], &[1, 0]).expect("a hit");
    assert!(
        matches!(listed.target, Target::Disc(c) if c == b),
        "{listed:?}"
    );
    assert_eq!(key(Some(listed)), key(Some(in_order)));
    // And a, when a is the later robot.
    let swapped = cast(&[b, a], &[0, 1]).expect("a hit");
    assert!(
        matches!(swapped.target, Target::Disc(c) if c == a),
        "{swapped:?}"
    );
}

#[test]
fn any_order_with_indices_gives_the_hit_of_robot_order() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut scene = Scene::arena(6.0, 6.0, 0.05);
    scene
        .shapes
        .push(SceneShape::circle(Vector::new(0.5, 0.5), 0.2));
    let (mut ties, mut hits) = (0, 0);
    for case in 0..20_000 {
        // Rays along an axis through a point on it, from the rim-sized neighbourhood of the
        // origin; robots scattered ahead, some in pairs mirrored about the ray's line (hit at
        // exactly the same distance), some twice at the same place.
        let quarter = rng.random_range(0..4u32);
        let origin = turn(Vector::new(rng.random_range(-0.3..0.3), 0.0), quarter);
        let dir = turn(Vector::X, quarter);
        let mut discs = Vec::new();
        for _ in 0..rng.random_range(1..12) {
            let c = Vector::new(rng.random_range(-0.5..2.0), rng.random_range(-0.3..0.3));
            discs.push(turn(c, quarter));
            match rng.random_range(0..4) {
                0 => discs.push(turn(Vector::new(c.x, -c.y), quarter)),
                1 => discs.push(turn(c, quarter)),
                _ => {}
            }
        }
        let max = rng.random_range(0.1..3.0);
        let cast = |d: &[Vector], ids: &[u32]| {
            scene.cast_hit(origin, dir, max, scene.shapes.iter(), d, ids, RADIUS)
        };
        let want = cast(&discs, &[]);
        let mut order: Vec<u32> = (0..discs.len() as u32).collect();
        order.shuffle(&mut rng);
        let listed: Vec<Vector> = order.iter().map(|&j| discs[j as usize]).collect();
        let got = cast(&listed, &order);
        assert_eq!(key(got), key(want), "case {case}: {discs:?} as {order:?}");
        if let Some(h) = want {
            hits += 1;
            let same = discs
                .iter()
                .filter(|&&c| {
                    scene
                        .cast_hit(origin, dir, max, std::iter::empty(), &[c], &[], RADIUS)
                        .is_some_and(|o| o.distance == h.distance)
                })
                .count();
            ties += usize::from(same > 1);
        }
    }
    // The mirrored pairs must have made exact ties, else this test shows nothing about them.
    assert!(hits > 5_000 && ties > 1_000, "{hits} hits, {ties} ties");
}
