//! Reference trajectories of the tracking task: closed curves centred at the arena's origin,
//! travelled once per period. A [`Curve`] is a closed curve p(s) over the phase s ∈ [0, 1) with
//! its first two derivatives; a [`Reference`] puts it in time, s(t) = s₀ + σ·t/T (σ = ±1 the
//! direction, T the period), and gives the reference posture and feed-forward at any time:
//!
//! * position p_r(t) = p(s(t)), velocity ṗ_r = p'(s)·ṡ with ṡ = σ/T;
//! * heading θ_r = atan2(ṗ_r), speed v_r = |p'|/T (always ≥ 0: the robot drives forwards);
//! * turn rate ω_r = (ẋ ÿ − ẏ ẍ)/|ṗ|² = (p' × p'')·ṡ / |p'|² (ṡ constant).
//!
//! Curves: `circle` (radius = size), `lemniscate` (Gerono's figure eight, x = A sin 2πs,
//! y = A sin 2πs cos 2πs, A = size; docs/task-design.md §3), `square` (half-side = size, corners
//! where the heading jumps by 90° and ω_r is an impulse the feed-forward does not carry: the
//! limit of smooth controllers) and `spline` (a random smooth star-shaped closed curve,
//! r(φ) = size·(1 + Σₖ aₖ cos(kφ + ψₖ)), k = 2..4, with Σ aₖ ≤ the irregularity < 1, so r > 0
//! and the curve never crosses itself), or `waypoints` (a scenario's own: points with times,
//! joined by a periodic cubic Hermite curve in time whose tangents are the central differences
//! of the neighbouring points, Catmull–Rom style: C¹, so v_r is continuous and ω_r jumps at
//! most at the points).
//!
//! Units: metres, seconds, radians; world frame, arena centred at the origin. Computed in f64
//! (phases over long episodes), returned in f32.

use std::f64::consts::TAU;

use rapier2d::math::Vector;

/// Harmonics of a random spline curve (k = 2, 3, 4).
pub const SPLINE_HARMONICS: usize = 3;

/// Samples of a curve used for its length and limits.
const SAMPLES: usize = 720;

/// A closed reference curve family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shape {
    /// A circle of radius `size`.
    Circle,
    /// Gerono's lemniscate (figure eight) of half-width `size`.
    Lemniscate,
    /// A square of half-side `size`, corners included.
    Square,
    /// A random smooth star-shaped curve of mean radius `size`.
    Spline,
    /// A scenario's points with times.
    Waypoints,
}

/// A closed curve p(s), s ∈ [0, 1).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Curve {
    /// Its family.
    pub shape: Shape,
    /// Radius, half-width or half-side (m).
    pub size: f64,
    /// Spline only: (a_k, ψ_k) of the harmonics k = 2, 3, 4.
    pub harmonics: [(f64, f64); SPLINE_HARMONICS],
    /// Waypoints only: (s, x, y) of each point but the closing one, s = t / period rising
    /// from 0.
    pub knots: Vec<[f64; 3]>,
}

/// What a curve travelled in a period asks of the robot, from [`SAMPLES`] samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Largest |x| and |y| of the curve (m).
    pub extent: [f32; 2],
    /// Largest wheel speed |v_r| + |ω_r|·axle/2 (m/s).
    pub wheel_speed: f32,
    /// Largest wheel acceleration between samples (m/s²), excluding the square's corners.
    pub wheel_accel: f32,
}

impl Curve {
    /// A curve of `shape` and `size` (a spline with no harmonics is a circle).
    pub fn new(shape: Shape, size: f32) -> Self {
        Self {
            shape,
            size: size as f64,
            harmonics: [(0.0, 0.0); SPLINE_HARMONICS],
            knots: Vec::new(),
        }
    }

    /// The curve through `points` ([t, x, y]: s, m, m; times rising from 0, the last point
    /// closing the loop at the period) and its period (s). Checked by the caller: at least 4
    /// points, finite, times strictly rising from 0.
    pub fn waypoints(points: &[[f32; 3]]) -> (Self, f64) {
        let period = points.last().map_or(1.0, |p| p[0] as f64);
        let knots = points[..points.len().saturating_sub(1)]
            .iter()
            .map(|[t, x, y]| [*t as f64 / period, *x as f64, *y as f64])
            .collect();
        let curve = Self {
            knots,
            ..Self::new(Shape::Waypoints, 0.0)
        };
        (curve, period)
    }

    /// The tangent dp/ds at knot `k` (central difference of its neighbours, periodic).
    fn knot_tangent(&self, k: usize) -> [f64; 2] {
        let m = self.knots.len();
        let (prev, next) = (&self.knots[(k + m - 1) % m], &self.knots[(k + 1) % m]);
        let s_prev = prev[0] - if k == 0 { 1.0 } else { 0.0 };
        let s_next = next[0] + if k + 1 == m { 1.0 } else { 0.0 };
        let ds = s_next - s_prev;
        [(next[1] - prev[1]) / ds, (next[2] - prev[2]) / ds]
    }

    /// p, p', p'' of the waypoint curve: cubic Hermite between knots i and i + 1.
    fn eval_waypoints(&self, s: f64) -> [[f64; 2]; 3] {
        let m = self.knots.len();
        if m < 3 {
            return [[0.0; 2]; 3];
        }
        let i = self.knots.partition_point(|k| k[0] <= s).saturating_sub(1);
        let j = (i + 1) % m;
        let s_j = if i + 1 == m { 1.0 } else { self.knots[j][0] };
        let h = s_j - self.knots[i][0];
        let u = (s - self.knots[i][0]) / h;
        let (ti, tj) = (
            self.knots_tangent_scaled(i, h),
            self.knots_tangent_scaled(j, h),
        );
        let (pi, pj) = (&self.knots[i], &self.knots[j]);
        let (u2, u3) = (u * u, u * u * u);
        let basis = [
            [
                2.0 * u3 - 3.0 * u2 + 1.0,
                u3 - 2.0 * u2 + u,
                -2.0 * u3 + 3.0 * u2,
                u3 - u2,
            ],
            [
                6.0 * u2 - 6.0 * u,
                3.0 * u2 - 4.0 * u + 1.0,
                -6.0 * u2 + 6.0 * u,
                3.0 * u2 - 2.0 * u,
            ],
            [
                12.0 * u - 6.0,
                6.0 * u - 4.0,
                -12.0 * u + 6.0,
                6.0 * u - 2.0,
            ],
        ];
        let mut out = [[0.0; 2]; 3];
        for (order, b) in basis.iter().enumerate() {
            let scale = h.powi(-(order as i32));
            for axis in 0..2 {
                out[order][axis] = scale
                    * (b[0] * pi[axis + 1]
                        + b[1] * ti[axis]
                        + b[2] * pj[axis + 1]
                        + b[3] * tj[axis]);
            }
        }
        out
    }

    /// The tangent at knot `k` times the segment length `h` (Hermite's scaled tangent).
    fn knots_tangent_scaled(&self, k: usize, h: f64) -> [f64; 2] {
        let t = self.knot_tangent(k);
        [t[0] * h, t[1] * h]
    }

    /// p(s), p'(s), p''(s) (m, per unit phase).
    pub fn eval(&self, s: f64) -> [[f64; 2]; 3] {
        let s = s.rem_euclid(1.0);
        let a = self.size;
        match self.shape {
            Shape::Circle => {
                let (sn, cs) = (TAU * s).sin_cos();
                [
                    [a * cs, a * sn],
                    [-a * TAU * sn, a * TAU * cs],
                    [-a * TAU * TAU * cs, -a * TAU * TAU * sn],
                ]
            }
            Shape::Lemniscate => {
                // x = A sin φ, y = (A/2) sin 2φ, φ = 2πs.
                let (s1, c1) = (TAU * s).sin_cos();
                let (s2, c2) = (2.0 * TAU * s).sin_cos();
                [
                    [a * s1, 0.5 * a * s2],
                    [a * TAU * c1, a * TAU * c2],
                    [-a * TAU * TAU * s1, -2.0 * a * TAU * TAU * s2],
                ]
            }
            Shape::Square => {
                // Counter-clockwise from the middle of the right edge (a, 0); perimeter 8a, so
                // the arc length travelled is 8a·s. Legs: up a, left 2a, down 2a, right 2a, up a.
                const LEGS: [([f64; 2], [f64; 2], f64); 5] = [
                    ([1.0, 0.0], [0.0, 1.0], 1.0),
                    ([1.0, 1.0], [-1.0, 0.0], 2.0),
                    ([-1.0, 1.0], [0.0, -1.0], 2.0),
                    ([-1.0, -1.0], [1.0, 0.0], 2.0),
                    ([1.0, -1.0], [0.0, 1.0], 1.0),
                ];
                let mut along = 8.0 * s; // in units of a
                let mut leg = LEGS[4];
                for l in LEGS {
                    if along < l.2 {
                        leg = l;
                        break;
                    }
                    along -= l.2;
                }
                let along = along.min(leg.2);
                let (start, dir) = (leg.0, leg.1);
                let speed = 8.0 * a; // perimeter per unit phase
                [
                    [
                        a * (start[0] + dir[0] * along),
                        a * (start[1] + dir[1] * along),
                    ],
                    [dir[0] * speed, dir[1] * speed],
                    [0.0, 0.0],
                ]
            }
            Shape::Waypoints => self.eval_waypoints(s),
            Shape::Spline => {
                let phi = TAU * s;
                let (mut r, mut r1, mut r2) = (1.0, 0.0, 0.0);
                for (i, (amp, psi)) in self.harmonics.iter().enumerate() {
                    let k = (i + 2) as f64;
                    let (sn, cs) = (k * phi + psi).sin_cos();
                    r += amp * cs;
                    r1 -= amp * k * sn;
                    r2 -= amp * k * k * cs;
                }
                let (r, r1, r2) = (a * r, a * r1, a * r2);
                let (sn, cs) = phi.sin_cos();
                // d/dφ of r (cos φ, sin φ), then ×2π per unit phase.
                let d1 = [r1 * cs - r * sn, r1 * sn + r * cs];
                let d2 = [(r2 - r) * cs - 2.0 * r1 * sn, (r2 - r) * sn + 2.0 * r1 * cs];
                [
                    [r * cs, r * sn],
                    [TAU * d1[0], TAU * d1[1]],
                    [TAU * TAU * d2[0], TAU * TAU * d2[1]],
                ]
            }
        }
    }

    /// Length of the curve (m).
    pub fn length(&self) -> f64 {
        match self.shape {
            Shape::Circle => TAU * self.size,
            Shape::Square => 8.0 * self.size,
            _ => {
                (0..SAMPLES)
                    .map(|i| {
                        let [_, d, _] = self.eval((i as f64 + 0.5) / SAMPLES as f64);
                        d[0].hypot(d[1])
                    })
                    .sum::<f64>()
                    / SAMPLES as f64
            }
        }
    }
}

/// Times a random spline's harmonics are halved, at most, to bring it within limits (then it is
/// its mean circle, which the scenario's validation checked).
pub const SPLINE_SHRINKS: usize = 8;

/// A random spline around `base` (a spline curve, its mean circle): relative amplitudes aₖ =
/// `irregularity`·wₖ/3 (wₖ uniform in [0, 1)) and phases ψₖ uniform, drawn from `rng` in the
/// order w₂, ψ₂, w₃, ψ₃, w₄, ψ₄; then, while the curve does not `fit`, every aₖ is halved, and
/// after [`SPLINE_SHRINKS`] halvings dropped (the mean circle).
pub fn random_spline<R: rand::Rng>(
    base: &Curve,
    irregularity: f32,
    rng: &mut R,
    fits: impl Fn(&Curve) -> bool,
) -> Curve {
    let mut curve = base.clone();
    for h in curve.harmonics.iter_mut() {
        let weight: f64 = rng.random();
        let psi: f64 = rng.random::<f64>() * TAU;
        *h = (irregularity as f64 * weight / SPLINE_HARMONICS as f64, psi);
    }
    let mut shrinks = 0;
    while !fits(&curve) {
        shrinks += 1;
        for h in curve.harmonics.iter_mut() {
            h.0 = if shrinks >= SPLINE_SHRINKS {
                0.0
            } else {
                0.5 * h.0
            };
        }
        if shrinks >= SPLINE_SHRINKS {
            break;
        }
    }
    curve
}

/// A curve put in time: period, starting phase and direction.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Reference {
    /// The curve.
    pub curve: Curve,
    /// Time of one lap T (s).
    pub period: f64,
    /// Phase s₀ at t = 0.
    pub phase: f64,
    /// +1 in the curve's own direction (counter-clockwise for the circle), −1 against it.
    pub direction: f64,
}

/// The reference posture and feed-forward at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Posture {
    /// p_r (m, world frame).
    pub position: Vector,
    /// θ_r (rad, CCW from +x), the direction of travel.
    pub heading: f32,
    /// v_r (m/s), ≥ 0.
    pub speed: f32,
    /// ω_r (rad/s, CCW positive).
    pub turn_rate: f32,
}

impl Reference {
    /// `curve` travelled at mean speed `speed` (m/s) from phase `phase` in `direction` (±1).
    pub fn new(curve: Curve, speed: f32, phase: f64, direction: f64) -> Self {
        let period = curve.length() / speed as f64;
        Self::timed(curve, period, phase, direction)
    }

    /// `curve` travelled once in `period` (s) from phase `phase` in `direction` (±1).
    pub fn timed(curve: Curve, period: f64, phase: f64, direction: f64) -> Self {
        Self {
            curve,
            period,
            phase,
            direction,
        }
    }

    /// The posture at time `t` (s) since the start.
    pub fn at(&self, t: f64) -> Posture {
        let rate = self.direction / self.period; // ṡ
        let [p, d1, d2] = self.curve.eval(self.phase + rate * t);
        let speed2 = d1[0] * d1[0] + d1[1] * d1[1];
        let speed = speed2.sqrt() / self.period;
        let heading = (rate * d1[1]).atan2(rate * d1[0]);
        let turn_rate = if speed2 > 0.0 {
            (d1[0] * d2[1] - d1[1] * d2[0]) * rate / speed2
        } else {
            0.0
        };
        Posture {
            position: Vector::new(p[0] as f32, p[1] as f32),
            heading: heading as f32,
            speed: speed as f32,
            turn_rate: turn_rate as f32,
        }
    }

    /// Extent, peak wheel speed and peak wheel acceleration of one lap, for a robot with wheel
    /// separation `axle` (m).
    pub fn limits(&self, axle: f32) -> Limits {
        let axle = axle as f64;
        let dt = self.period / SAMPLES as f64;
        let mut out = Limits {
            extent: [0.0; 2],
            wheel_speed: 0.0,
            wheel_accel: 0.0,
        };
        let wheels = |p: &Posture| {
            let half = 0.5 * p.turn_rate as f64 * axle;
            [p.speed as f64 - half, p.speed as f64 + half]
        };
        let mut previous = wheels(&self.at(-dt));
        for i in 0..SAMPLES {
            let p = self.at(i as f64 * dt);
            out.extent[0] = out.extent[0].max(p.position.x.abs());
            out.extent[1] = out.extent[1].max(p.position.y.abs());
            let w = wheels(&p);
            let peak = w[0].abs().max(w[1].abs());
            out.wheel_speed = out.wheel_speed.max(peak as f32);
            let accel = (w[0] - previous[0]).abs().max((w[1] - previous[1]).abs()) / dt;
            out.wheel_accel = out.wheel_accel.max(accel as f32);
            previous = w;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curves() -> Vec<Curve> {
        let mut spline = Curve::new(Shape::Spline, 0.5);
        spline.harmonics = [(0.1, 0.3), (0.05, 1.0), (0.08, 2.0)];
        let points: Vec<[f32; 3]> = (0..=6)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / 6.0;
                [3.0 * k as f32, 0.5 * a.cos(), 0.3 * a.sin()]
            })
            .collect();
        vec![
            Curve::new(Shape::Circle, 0.6),
            Curve::new(Shape::Lemniscate, 0.6),
            Curve::new(Shape::Square, 0.6),
            spline,
            Curve::waypoints(&points).0,
        ]
    }

    #[test]
    fn derivatives_match_finite_differences_and_curves_close() {
        let h = 1e-6;
        for curve in curves() {
            for i in 0..97 {
                let s = (i as f64 + 0.37) / 97.0;
                let [p, d1, d2] = curve.eval(s);
                let ([pa, da, _], [pb, db, _]) = (curve.eval(s - h), curve.eval(s + h));
                for axis in 0..2 {
                    let fd1 = (pb[axis] - pa[axis]) / (2.0 * h);
                    let fd2 = (db[axis] - da[axis]) / (2.0 * h);
                    assert!(
                        (fd1 - d1[axis]).abs() < 1e-4 * (1.0 + d1[axis].abs()),
                        "{curve:?} p' at {s}"
                    );
                    assert!(
                        (fd2 - d2[axis]).abs() < 1e-3 * (1.0 + d2[axis].abs()),
                        "{curve:?} p'' at {s}"
                    );
                }
                assert!(p.iter().all(|v| v.is_finite()));
            }
            let (start, end) = (curve.eval(0.0)[0], curve.eval(1.0 - 1e-12)[0]);
            assert!((start[0] - end[0]).abs() < 1e-6 && (start[1] - end[1]).abs() < 1e-6);
        }
    }

    #[test]
    fn circle_feed_forward_is_speed_over_radius() {
        // R = 0.6 m at 0.15 m/s: T = 2π·0.6/0.15 = 25.13 s, ω_r = 0.25 rad/s (docs/task-design.md
        // §3).
        for direction in [1.0, -1.0] {
            let r = Reference::new(Curve::new(Shape::Circle, 0.6), 0.15, 0.1, direction);
            assert!((r.period - 25.132741).abs() < 1e-4);
            let p = r.at(3.0);
            assert!((p.speed - 0.15).abs() < 1e-6);
            assert!((p.turn_rate - 0.25 * direction as f32).abs() < 1e-5);
        }
    }

    #[test]
    fn waypoints_pass_through_their_points_at_their_times() {
        let points = [
            [0.0, 0.4, 0.0],
            [4.0, 0.0, 0.4],
            [8.0, -0.4, 0.0],
            [12.0, 0.0, -0.4],
            [16.0, 0.4, 0.0],
        ];
        let (curve, period) = Curve::waypoints(&points);
        let r = Reference::timed(curve, period, 0.0, 1.0);
        for [t, x, y] in points {
            let p = r.at(t as f64).position;
            assert!(
                (p.x - x).abs() < 1e-6 && (p.y - y).abs() < 1e-6,
                "{t}: {p:?}"
            );
        }
    }
}
