//! Pure pursuit (Coulter, "Implementation of the Pure Pursuit Path Tracking Algorithm",
//! CMU-RI-TR-92-01, 1992): steer along the circular arc through the robot and the goal point,
//! the point of the path at the look-ahead distance L_d from the robot.
//!
//! With the goal point at (x_g, y_g) in the robot frame (x forward, y left) and l² = x_g² + y_g²,
//! the arc's curvature is γ = 2·y_g / l² (Coulter's eq., his x being our lateral y), so at speed
//! v the turn rate is ω = v·γ = 2·v·sin α / l, α the goal point's bearing. The speed is the
//! task's desired speed v_d (`desired_speed` block).
//!
//! The goal point is found on the polyline through the closest path point (from
//! `cross_track_error` d and `path_heading_error` e: (d·sin e, −d·cos e) in the robot frame) and
//! the `preview` points: the first point of the polyline at distance L_d from the robot,
//! interpolated; the last preview point when the whole polyline is nearer (a look-ahead longer
//! than the preview). L_d: 0.15 m at Khepera scale [docs/task-design.md §4, E: PythonRobotics uses
//! 0.1·v + 2 m for a 2.9 m car]. Linearised on a straight path, the lateral error obeys
//! ÿ = −(2v²/L_d²)·y − (2v/L_d)·ẏ... (ω_n = √2·v/L_d = 1.4 rad/s, ζ = 1/√2 at 0.15 m/s).
//!
//! Units: metres, m/s, radians, rad/s; robot frame x forward, y left, angles CCW.

use super::{positive, Controller, PathBlocks, WheelMap};
use crate::error::Result;
use crate::obs::ObsLayout;

crate::config_table! {
    /// Parameters of pure pursuit.
    pub struct PurePursuitParams {
        /// look-ahead distance L_d (m) [task-design.md §4: 0.15 m at Khepera scale, E]
        lookahead: f32 = 0.15,
        /// wheel separation (m) turning (v, omega) into wheel speeds
        axle_length: f32 = 0.1054,
        /// wheel speed that an action of 1 stands for (m/s)
        max_wheel_speed: f32 = 0.813,
    }
}

/// Pure pursuit on a path-following observation.
#[derive(Debug, Clone, PartialEq)]
pub struct PurePursuitPolicy {
    /// Look-ahead distance L_d (m).
    pub lookahead: f32,
    /// The drive.
    pub wheels: WheelMap,
    at: PathBlocks,
    obs_dim: usize,
}

impl PurePursuitPolicy {
    /// The goal point (robot frame) on the polyline `points` at distance L_d from the origin.
    fn goal_point(&self, points: &[[f32; 2]]) -> [f32; 2] {
        let ld = self.lookahead;
        let norm = |p: [f32; 2]| p[0].hypot(p[1]);
        for w in points.windows(2) {
            let (a, b) = (w[0], w[1]);
            if norm(a) < ld && norm(b) >= ld {
                // |a + t (b − a)| = L_d, the root in [0, 1].
                let d = [b[0] - a[0], b[1] - a[1]];
                let (qa, qb, qc) = (
                    d[0] * d[0] + d[1] * d[1],
                    2.0 * (a[0] * d[0] + a[1] * d[1]),
                    a[0] * a[0] + a[1] * a[1] - ld * ld,
                );
                let t = if qa > 0.0 {
                    ((-qb + (qb * qb - 4.0 * qa * qc).max(0.0).sqrt()) / (2.0 * qa)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                return [a[0] + t * d[0], a[1] + t * d[1]];
            }
        }
        // Already beyond L_d at the closest point (far off the path), or the preview is
        // shorter than L_d: the first point beyond, else the last.
        points
            .iter()
            .copied()
            .find(|p| norm(*p) >= ld)
            .unwrap_or(points[points.len() - 1])
    }
}

impl Controller for PurePursuitPolicy {
    const NAME: &'static str = "pure_pursuit";
    const READS: &'static str = "pathfollow";
    type Params = PurePursuitParams;

    fn new(params: &PurePursuitParams, layout: &ObsLayout) -> Result<Self> {
        Ok(Self {
            lookahead: positive(Self::NAME, "lookahead", params.lookahead)?,
            wheels: WheelMap::new(Self::NAME, params.axle_length, params.max_wheel_speed)?,
            at: PathBlocks::find(layout, Self::NAME)?,
            obs_dim: layout.len(),
        })
    }

    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    fn act(&self, obs: &[f32], out: &mut [f32]) {
        let mut points = [[0.0f32; 2]; 1 + super::MAX_PATH_PREVIEW];
        points[0] = self.at.closest(obs);
        let n = 1 + self.at.preview_points.min(super::MAX_PATH_PREVIEW);
        for (k, p) in points[1..n].iter_mut().enumerate() {
            *p = [
                obs[self.at.preview + 2 * k],
                obs[self.at.preview + 2 * k + 1],
            ];
        }
        let [x, y] = self.goal_point(&points[..n]);
        let l2 = x * x + y * y;
        let v = obs[self.at.speed] * self.wheels.max_wheel_speed;
        let w = if l2 > 0.0 { 2.0 * v * y / l2 } else { 0.0 };
        out.copy_from_slice(&self.wheels.twist_action(v, w));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn goal_point_is_on_the_polyline_at_the_lookahead() {
        let policy = PurePursuitPolicy {
            lookahead: 0.15,
            wheels: WheelMap::default(),
            at: PathBlocks {
                cross_track: 0,
                heading: 0,
                curvature: 0,
                preview: 0,
                preview_points: 3,
                speed: 0,
            },
            obs_dim: 0,
        };
        // A straight path 5 cm to the left: the goal point is at x = √(0.15² − 0.05²).
        let points = [[0.0, 0.05], [0.1, 0.05], [0.2, 0.05], [0.3, 0.05]];
        let [x, y] = policy.goal_point(&points);
        assert!((x - (0.15f32 * 0.15 - 0.05 * 0.05).sqrt()).abs() < 1e-6 && y == 0.05);
    }
}
