//! Position control (paper eqs. 1–4, after Vilella et al. 2004): drive toward a target point.
//!
//! d = distance to the target (eq. 1), α − θ = its bearing in the robot frame (eq. 2);
//! v = v_max if d > k_r else d·v_max/k_r (eq. 3); ω = ω_max·sin(α − θ) (eq. 4);
//! both 0 once d < stop_radius (the library's 0.05 m).

/// The position controller's parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PositionControl {
    /// Cruise speed v_max (m/s).
    pub vmax: f32,
    /// Largest turn rate ω_max (rad/s), reached at a bearing of ±90°.
    pub wmax: f32,
    /// Radius k_r of the docking area where the speed falls linearly (m).
    pub kr: f32,
    /// Distance under which the robot stops (m).
    pub stop_radius: f32,
}

impl PositionControl {
    /// (v, ω) toward a target at `distance` (m) and `bearing` (rad, robot frame).
    pub fn twist(&self, distance: f32, bearing: f32) -> (f32, f32) {
        if distance < self.stop_radius {
            return (0.0, 0.0);
        }
        let v = if distance > self.kr {
            self.vmax
        } else {
            distance * self.vmax / self.kr
        };
        (v, self.wmax * bearing.sin())
    }
}

/// Wheel speeds (left, right, m/s) of a twist for a robot with wheel separation `axle`.
pub fn twist_to_wheels(v: f32, w: f32, axle: f32) -> [f32; 2] {
    [v - 0.5 * w * axle, v + 0.5 * w * axle]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equations_three_and_four() {
        let pc = PositionControl {
            vmax: 0.2,
            wmax: 1.0,
            kr: 0.1,
            stop_radius: 0.05,
        };
        assert_eq!(pc.twist(1.0, 0.0), (0.2, 0.0));
        let (v, w) = pc.twist(0.08, std::f32::consts::FRAC_PI_2);
        assert!((v - 0.16).abs() < 1e-6 && (w - 1.0).abs() < 1e-6);
        assert_eq!(pc.twist(0.04, 1.0), (0.0, 0.0));
    }
}
