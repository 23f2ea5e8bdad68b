//! A path for path following: a closed [`Curve`] travelled in one direction, with no clock.
//!
//! The curve's phase u ∈ [0, 1) is not arc length for most curves (it is for the circle and the
//! square), so arc lengths are integrated: a step of Δu covers |p'(u)|·|Δu| metres, evaluated at
//! the step's midpoint, in steps of at most [`ARC_STEP`]. The closest path point to the robot is
//! tracked, not searched for over the whole curve: from the last closest phase, the curve is
//! sampled over ±[`WINDOW`] of arc and the best sample refined by Newton steps on
//! g(u) = (p(u) − q)·p'(u) = 0. Tracking keeps the projection on its branch where the path
//! crosses itself (the lemniscate's centre) and costs the same on every curve. The robot moves at
//! most 0.813 m/s · 50 ms = 4 cm per step, so the window holds the new closest point whenever the
//! robot is closer to the path than its radius of curvature allows the projection to jump.
//!
//! Frenet quantities at the closest point p_c (direction of travel t, left normal n):
//! cross-track error d = (p − p_c)·n (left of the path positive), path heading θ_p = atan2(t),
//! signed curvature κ = σ·(p' × p'')/|p'|³ (left turns positive, σ = ±1 the direction).
//!
//! Units: metres, radians, 1/m; world frame.

use rapier2d::math::Vector;

use crate::tasks::reference::Curve;

/// Half-width of the closest-point search window (m of arc).
pub const WINDOW: f64 = 0.15;
/// Samples on each side of the last closest phase (every 5 cm of arc; Newton refines).
const SAMPLES_PER_SIDE: i32 = 3;
/// Newton refinements after sampling.
const NEWTON_STEPS: usize = 3;
/// Halvings of a Newton step that does not bring the point closer.
const BACKTRACKS: i32 = 4;
/// (q − p_c)·n below this fraction of |q − p_c|: p_c is a corner, not a foot of the
/// perpendicular.
const CORNER_COSINE: f32 = 0.999;
/// Arc length (m) either side of a corner where its legs' normals are taken.
const CORNER_PROBE: f64 = 1.0e-4;
/// Longest step of arc-length integration (m): the preview's spacing, one midpoint step per
/// previewed point (relative error about (step·κ)²/24, 0.1 mm per 0.1 m on the 0.6 m circle).
pub const ARC_STEP: f64 = 0.1;

/// A point of the path with its Frenet frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// Phase u on the curve.
    pub phase: f64,
    /// Position (m).
    pub position: Vector,
    /// Heading of travel θ_p (rad).
    pub heading: f32,
    /// Signed curvature κ (1/m, left turns positive); 0 on the square's legs.
    pub curvature: f32,
}

/// A closed curve travelled in one direction.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Path {
    /// The curve.
    pub curve: Curve,
    /// +1 in the curve's own direction, −1 against it.
    pub direction: f64,
    /// Length of one lap (m).
    pub length: f64,
}

impl Path {
    /// `curve` travelled in `direction` (±1).
    pub fn new(curve: Curve, direction: f64) -> Self {
        let length = curve.length();
        Self {
            curve,
            direction,
            length,
        }
    }

    /// |p'(u)|: metres of arc per unit phase.
    fn rate(&self, u: f64) -> f64 {
        let [_, d1, _] = self.curve.eval(u);
        // √(x² + y²): no overflow to guard against here, and libm's hypot is several times
        // slower (it was 14% of a PathFollow step).
        (d1[0] * d1[0] + d1[1] * d1[1]).sqrt()
    }

    /// The path point at phase `u`.
    pub fn at(&self, u: f64) -> PathPoint {
        let [p, d1, d2] = self.curve.eval(u);
        let sigma = self.direction;
        let speed2 = d1[0] * d1[0] + d1[1] * d1[1];
        let curvature = if speed2 > 0.0 {
            sigma * (d1[0] * d2[1] - d1[1] * d2[0]) / (speed2 * speed2.sqrt())
        } else {
            0.0
        };
        PathPoint {
            phase: u.rem_euclid(1.0),
            position: Vector::new(p[0] as f32, p[1] as f32),
            heading: (sigma * d1[1]).atan2(sigma * d1[0]) as f32,
            curvature: curvature as f32,
        }
    }

    /// The phase reached from `u` after `distance` m along the direction of travel (backwards
    /// if negative), integrated in midpoint steps of at most [`ARC_STEP`].
    pub fn advance(&self, u: f64, distance: f64) -> f64 {
        let steps = (distance.abs() / ARC_STEP).ceil().max(1.0);
        let ds = self.direction * distance / steps;
        let mut u = u;
        for _ in 0..steps as usize {
            let first = ds / self.rate(u).max(1e-9);
            u += ds / self.rate(u + 0.5 * first).max(1e-9);
        }
        u.rem_euclid(1.0)
    }

    /// Metres of arc from phase `from` to phase `to` along the direction of travel, for phases
    /// less than half a lap apart (negative: backwards).
    pub fn progress(&self, from: f64, to: f64) -> f64 {
        let du = (to - from + 0.5).rem_euclid(1.0) - 0.5;
        self.direction * du * self.rate(from + 0.5 * du)
    }

    /// The phase of the path point closest to `q` near phase `u` (within ±[`WINDOW`] m of arc).
    pub fn project(&self, q: Vector, u: f64) -> f64 {
        let (qx, qy) = (q.x as f64, q.y as f64);
        let dist2 = |u: f64| {
            let [p, _, _] = self.curve.eval(u);
            (p[0] - qx).powi(2) + (p[1] - qy).powi(2)
        };
        let h = WINDOW / SAMPLES_PER_SIDE as f64 / self.rate(u).max(1e-9);
        let (mut best, mut best_d2) = (u, dist2(u));
        for k in (-SAMPLES_PER_SIDE..=SAMPLES_PER_SIDE).filter(|k| *k != 0) {
            let v = u + k as f64 * h;
            let d2 = dist2(v);
            if d2 < best_d2 {
                (best, best_d2) = (v, d2);
            }
        }
        // Newton on g(u) = (p − q)·p' = 0, each step within the sampling interval and kept only
        // if it (or its half, quarter, eighth) brings the point closer.
        for _ in 0..NEWTON_STEPS {
            let [p, d1, d2] = self.curve.eval(best);
            let (ex, ey) = (p[0] - qx, p[1] - qy);
            let g = ex * d1[0] + ey * d1[1];
            let dg = d1[0] * d1[0] + d1[1] * d1[1] + ex * d2[0] + ey * d2[1];
            if dg <= 0.0 {
                break;
            }
            // Backtracking: a full step may cross a corner onto a leg farther away.
            let step = (g / dg).clamp(-h, h);
            let Some((v, d2v)) = (0..BACKTRACKS)
                .map(|k| best - step * 0.5f64.powi(k))
                .map(|v| (v, dist2(v)))
                .find(|(_, d2v)| *d2v < best_d2)
            else {
                break;
            };
            (best, best_d2) = (v, d2v);
        }
        best.rem_euclid(1.0)
    }

    /// The cross-track error of `q` whose closest path point is `c` (m, left of the path
    /// positive) and the path's heading there (rad). At a foot of the perpendicular they are
    /// (q − p_c)·n and θ_p. At a corner (the square's), where q − p_c is not along n, the
    /// points at distance |q − p_c| from the path form an arc around the corner: the error is
    /// that distance, signed by the side of the corner's bisector, and the heading the arc's,
    /// perpendicular to q − p_c (so a robot overshooting a corner sees the turn it missed).
    pub fn frame(&self, c: &PathPoint, q: Vector) -> (f32, f32) {
        let r = q - c.position;
        let distance = r.length();
        let normal = |heading: f32| Vector::new(-heading.sin(), heading.cos());
        let side = r.dot(normal(c.heading));
        if side.abs() >= CORNER_COSINE * distance || distance == 0.0 {
            return (side, c.heading);
        }
        let du = CORNER_PROBE / self.rate(c.phase).max(1e-9);
        let (before, after) = (self.at(c.phase - du), self.at(c.phase + du));
        let sign = if r.dot(normal(before.heading) + normal(after.heading)) < 0.0 {
            -1.0
        } else {
            1.0
        };
        // n = sign·r/|r| is the left normal of the tangent t: t = (n_y, −n_x).
        let n = r * (sign / distance);
        (sign * distance, (-n.x).atan2(n.y))
    }

    /// The cross-track error of `q` whose closest path point is `c` (see [`Path::frame`]).
    pub fn cross_track(&self, c: &PathPoint, q: Vector) -> f32 {
        self.frame(c, q).0
    }

    /// Largest |κ| over the lap (1/m), from [`SAMPLES`] phases.
    pub fn max_curvature(&self) -> f32 {
        (0..SAMPLES)
            .map(|i| self.at((i as f64 + 0.5) / SAMPLES as f64).curvature.abs())
            .fold(0.0, f32::max)
    }
}

/// Phases sampled for the curvature bound.
const SAMPLES: usize = 720;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tasks::reference::Shape;
    use std::f64::consts::TAU;

    #[test]
    fn circle_frenet_quantities_and_arc_lengths() {
        for direction in [1.0, -1.0] {
            let path = Path::new(Curve::new(Shape::Circle, 0.5), direction);
            assert!((path.length - TAU * 0.5).abs() < 1e-9);
            let c = path.at(0.0);
            assert!((c.curvature - 2.0 * direction as f32).abs() < 1e-5);
            // At (0.5, 0) travelling +y (ccw) or −y (cw).
            assert!((c.heading - (direction as f32) * std::f32::consts::FRAC_PI_2).abs() < 1e-6);
            // Inside the circle is left of a ccw path.
            let inside = path.cross_track(&c, Vector::new(0.4, 0.0));
            assert!((inside - 0.1 * direction as f32).abs() < 1e-6);
            let u = path.advance(0.1, 0.5);
            assert!((path.progress(0.1, u) - 0.5).abs() < 1e-6);
            assert!((path.progress(u, 0.1) + 0.5).abs() < 1e-6);
        }
    }

    #[test]
    fn projection_finds_the_foot_of_the_perpendicular_and_stays_on_its_branch() {
        let path = Path::new(Curve::new(Shape::Circle, 0.5), 1.0);
        let q = Vector::new(0.3 * 0.9f32.cos(), 0.3 * 0.9f32.sin());
        let u = path.project(q, 0.9 / TAU + 0.02);
        assert!((u - 0.9 / TAU).abs() < 1e-6, "{u}");
        // The lemniscate crosses itself at the origin: a point there projects on the branch
        // the search started from (heading up-right from phase 0, up-left from phase 0.5).
        let lem = Path::new(Curve::new(Shape::Lemniscate, 0.6), 1.0);
        for start in [0.0, 0.5] {
            let u = lem.project(Vector::new(0.0, 0.0), start + 0.01);
            assert!((u - start).abs() < 1e-4 || (u - 1.0).abs() < 1e-4, "{u}");
        }
        // The square's legs: the foot of the perpendicular, exactly.
        let sq = Path::new(Curve::new(Shape::Square, 0.5), 1.0);
        let u = sq.project(Vector::new(0.45, 0.2), 0.01);
        let c = sq.at(u);
        assert!((c.position.x - 0.5).abs() < 1e-6 && (c.position.y - 0.2).abs() < 1e-5);
        assert!((sq.cross_track(&c, Vector::new(0.45, 0.2)) - 0.05).abs() < 1e-5);
        // Beyond the corner (0.5, 0.5) on the right edge's line: outside, on the right.
        let u = sq.project(Vector::new(0.5, 0.55), 0.125 - 0.001);
        let c = sq.at(u);
        assert!(
            (c.position - Vector::new(0.5, 0.5)).length() < 1e-5,
            "{c:?}"
        );
        let (d, heading) = sq.frame(&c, Vector::new(0.5, 0.55));
        assert!((d + 0.05).abs() < 1e-5);
        // Its heading is the arc's around the corner: leftwards, along the next edge.
        assert!(
            (heading.abs() - std::f32::consts::PI).abs() < 1e-5,
            "{heading}"
        );
    }

    #[test]
    fn lemniscate_length_integrates_to_the_curve_length() {
        let path = Path::new(Curve::new(Shape::Lemniscate, 0.6), -1.0);
        let (mut u, mut travelled) = (0.3, 0.0);
        for _ in 0..200 {
            let next = path.advance(u, path.length / 200.0);
            travelled += path.progress(u, next);
            u = next;
        }
        // Both integrations are midpoint rules, of relative error ~(Δφ)²/24 per step (Δφ =
        // 0.03 rad here): after a lap in 200 steps, back at the start and the lap's length
        // summed within 1 mm.
        assert!((u - 0.3).abs() * path.length < 1e-3, "{u}");
        assert!(
            (travelled - path.length).abs() < 1e-3,
            "{travelled} vs {}",
            path.length
        );
    }
}
