//! Exact tests of a unit ray against circles, which every range-sensor ray runs against the
//! scene's shapes (their bounding circles) and the other robots (their discs).
//!
//! Frame: any, as long as the ray and the circle share it; metres.

use rapier2d::math::Vector;

/// Whether a unit ray can come within `radius` of `center` before distance `max`.
#[inline]
pub fn may_hit(origin: Vector, dir: Vector, center: Vector, radius: f32, max: f32) -> bool {
    let oc = center - origin;
    let along = oc.dot(dir);
    let dist2 = oc.length_squared();
    let r2 = radius * radius;
    if dist2 <= r2 {
        return true; // starts inside the bounding circle
    }
    if along < 0.0 || along - radius > max {
        return false;
    }
    dist2 - along * along <= r2
}

/// Exact hit distance of a unit ray on a solid disc, if within `max`.
#[inline]
pub fn ray_disc(origin: Vector, dir: Vector, center: Vector, radius: f32, max: f32) -> Option<f32> {
    let oc = origin - center;
    let b = oc.dot(dir);
    let c = oc.length_squared() - radius * radius;
    // Starting inside, it hits at once. Else it hits when the disc does not lie behind (b ≤ 0;
    // over the rays that is as good as random, so it is not a branch) and the line meets the
    // circle within `max`: when it misses the circle (disc < 0) the root is NaN and fails
    // `t <= max`, as does anything computed from a NaN.
    let inside = c <= 0.0;
    let disc = b * b - c;
    let t = -b - disc.sqrt();
    let hit = inside | ((b <= 0.0) & (t <= max));
    hit.then_some(if inside { 0.0 } else { t.max(0.0) })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `ray_disc` as the geometry reads, one case after the other.
    fn ray_disc_plain(o: Vector, d: Vector, center: Vector, radius: f32, max: f32) -> Option<f32> {
        let oc = o - center;
        let (b, c) = (oc.dot(d), oc.length_squared() - radius * radius);
        if c <= 0.0 {
            return Some(0.0);
        }
        if b > 0.0 {
            return None;
        }
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t <= max).then_some(t.max(0.0))
    }

    #[test]
    fn ray_disc_without_branches_is_the_plain_cases_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let r = 0.0704;
        let mut hits = 0;
        let mut cases = Vec::new();
        for _ in 0..100_000 {
            let a: f32 = rng.random_range(-3.2..3.2);
            let o = Vector::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let center = Vector::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            cases.push((
                o,
                Vector::new(a.cos(), a.sin()),
                center,
                rng.random_range(0.0..2.0),
            ));
        }
        // Inside, on the rim, tangent, just short of `max`, and not finite.
        let x = Vector::new(1.0, 0.0);
        cases.extend([
            (Vector::ZERO, x, Vector::new(0.01, 0.0), 1.0),
            (Vector::ZERO, x, Vector::new(r, 0.0), 1.0),
            (Vector::ZERO, x, Vector::new(0.5, r), 1.0),
            (Vector::ZERO, x, Vector::new(0.5, 0.0), 0.5 - r),
            (Vector::ZERO, x, Vector::new(0.5, 0.0), 0.5 - r - 1e-4),
            (Vector::ZERO, -x, Vector::new(0.5, 0.0), 1.0),
            (Vector::new(f32::NAN, 0.0), x, Vector::ZERO, 1.0),
            (Vector::ZERO, x, Vector::new(f32::INFINITY, 0.0), 1.0),
        ]);
        for (o, d, center, max) in cases {
            let (got, want) = (
                ray_disc(o, d, center, r, max),
                ray_disc_plain(o, d, center, r, max),
            );
            assert_eq!(
                got.map(f32::to_bits),
                want.map(f32::to_bits),
                "{o:?} {d:?} {center:?} {max}"
            );
            hits += usize::from(want.is_some());
        }
        assert!(hits > 1_000, "only {hits} rays hit");
    }
}
