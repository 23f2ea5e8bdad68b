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
//! y = A sin 2πs cos 2πs, A = size; research/tasks.md §3), `square` (half-side = size, corners
//! where the heading jumps by 90° and ω_r is an impulse the feed-forward does not carry: the
//! limit of smooth controllers) and `spline` (a random smooth star-shaped closed curve,
//! r(φ) = size·(1 + Σₖ aₖ cos(kφ + ψₖ)), k = 2..4, with Σ aₖ ≤ the irregularity < 1, so r > 0
//! and the curve never crosses itself).
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
}

/// A closed curve p(s), s ∈ [0, 1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Curve {
    /// Its family.
    pub shape: Shape,
    /// Radius, half-width or half-side (m).
    pub size: f64,
    /// Spline only: (a_k, ψ_k) of the harmonics k = 2, 3, 4.
    pub harmonics: [(f64, f64); SPLINE_HARMONICS],
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
        }
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

/// A curve put in time: period, starting phase and direction.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
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
        Self {
            curve,
            period: curve.length() / speed as f64,
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
