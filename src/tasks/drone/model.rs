//! The quadcopter of the KH4VREP paper's Fig. 8, as a 2.5-D vehicle (docs/task-design.md §7): it
//! flies above the arena (no contacts), its horizontal motion a double integrator whose
//! commanded acceleration is bounded by its largest tilt, with linear drag, and its altitude
//! held by a first-order autopilot. A camera looks straight down.
//!
//! - Horizontal: v̇ = a_max·sat(u) − c·v, with u the normalised command (its length clamped to
//!   1), a_max = g·tan(tilt_max) the acceleration of the largest tilt, and drag c = a_max/v_max,
//!   so that v_max is the terminal speed. Integrated exactly over a substep (the command held).
//! - Altitude: ż = (z_ref − z)/τ, exact. z_ref follows the search rule of the UNED course on the
//!   KH4VREP model (`AngelJMC/khepera-simulation`, `quadricopter.lua`): the tracking height
//!   while the robot is in view, the search height once it has been out of view for
//!   `search_delay` seconds (a higher camera sees a wider footprint).
//! - Camera: pointing down, a cone of full angle `fov`: a robot is seen when its horizontal
//!   distance is within z·tan(fov/2), the footprint's radius; it reports the robot's offset
//!   in image coordinates, (p_robot − p_drone)/(z·tan(fov/2)) ∈ the unit disc (world axes: the
//!   drone holds its yaw).
//!
//! Units: metres, seconds, radians; world frame (x right, y up), z up from the floor.

use rapier2d::math::Vector;

/// Standard gravity (m/s²).
const GRAVITY: f32 = 9.80665;

/// The drone's parameters (from the `[drone]` table).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DroneParams {
    /// Acceleration at the largest tilt, g·tan(tilt_max) (m/s²).
    pub accel_max: f32,
    /// Terminal horizontal speed (m/s).
    pub speed_max: f32,
    /// Altitude time constant τ (s).
    pub altitude_tau: f32,
    /// Height while tracking (m).
    pub track_altitude: f32,
    /// Height while searching (m).
    pub search_altitude: f32,
    /// Out-of-view time before climbing to search (s).
    pub search_delay: f32,
    /// tan(fov/2) of the downward camera.
    pub tan_half_fov: f32,
}

impl DroneParams {
    /// Parameters from the tilt limit (rad) and the rest.
    pub fn new(
        tilt_max: f32,
        speed_max: f32,
        altitude_tau: f32,
        altitudes: (f32, f32),
        search_delay: f32,
        fov: f32,
    ) -> Self {
        Self {
            accel_max: GRAVITY * tilt_max.tan(),
            speed_max,
            altitude_tau,
            track_altitude: altitudes.0,
            search_altitude: altitudes.1,
            search_delay,
            tan_half_fov: (0.5 * fov).tan(),
        }
    }

    /// Drag coefficient c (1/s): a_max / v_max.
    pub fn drag(&self) -> f32 {
        self.accel_max / self.speed_max
    }
}

/// The drone's state.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Drone {
    /// Horizontal position (m).
    pub position: Vector,
    /// Horizontal velocity (m/s).
    pub velocity: Vector,
    /// Altitude (m).
    pub altitude: f32,
    /// Its autopilot's altitude reference (m).
    pub altitude_ref: f32,
    /// Time since the robot was last in view (s).
    pub unseen_for: f32,
}

impl Drone {
    /// The commanded acceleration of a normalised command `u` (its length clamped to 1), m/s².
    pub fn thrust(u: Vector, p: &DroneParams) -> Vector {
        let u = if u.is_finite() { u } else { Vector::ZERO };
        let n = u.length();
        let u = if n > 1.0 { u / n } else { u };
        u * p.accel_max
    }

    /// Advances `h` seconds with the normalised command `u` held.
    pub fn advance(&mut self, u: Vector, h: f32, p: &DroneParams) {
        let c = p.drag();
        let terminal = Drone::thrust(u, p) / c;
        let decay = (-c * h).exp();
        let gap = self.velocity - terminal;
        self.position += terminal * h + gap * ((1.0 - decay) / c);
        self.velocity = terminal + gap * decay;
        let k = (-h / p.altitude_tau).exp();
        self.altitude = self.altitude_ref + (self.altitude - self.altitude_ref) * k;
    }

    /// Radius of the camera's footprint on the floor (m).
    pub fn footprint(&self, p: &DroneParams) -> f32 {
        self.altitude.max(0.0) * p.tan_half_fov
    }

    /// The image offset of a robot at `target` (the unit disc), or None out of view.
    pub fn sees(&self, target: Vector, p: &DroneParams) -> Option<Vector> {
        let radius = self.footprint(p);
        let offset = target - self.position;
        (radius > 0.0 && offset.length() <= radius).then(|| offset / radius)
    }

    /// Updates the search rule after a frame (`seen` or not) over `dt` seconds.
    pub fn update_search(&mut self, seen: bool, dt: f32, p: &DroneParams) {
        self.unseen_for = if seen { 0.0 } else { self.unseen_for + dt };
        self.altitude_ref = if self.unseen_for >= p.search_delay {
            p.search_altitude
        } else {
            p.track_altitude
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> DroneParams {
        DroneParams::new(
            15f32.to_radians(),
            1.0,
            0.3,
            (0.5, 2.0),
            1.0,
            60f32.to_radians(),
        )
    }

    #[test]
    fn full_command_reaches_the_terminal_speed_and_no_faster() {
        let p = params();
        let mut d = Drone::default();
        for _ in 0..400 {
            d.advance(Vector::new(3.0, 4.0), 0.0125, &p);
        }
        // The command is clamped to length 1: the speed tends to v_max along (0.6, 0.8).
        assert!((d.velocity.length() - 1.0).abs() < 1e-3, "{:?}", d.velocity);
        assert!((d.velocity.y / d.velocity.x - 4.0 / 3.0).abs() < 1e-3);
    }

    #[test]
    fn the_footprint_grows_with_altitude() {
        let p = params();
        let d = Drone {
            altitude: 0.5,
            ..Drone::default()
        };
        // 0.5 m · tan 30° = 0.2887 m.
        assert!(d.sees(Vector::new(0.288, 0.0), &p).is_some());
        assert!(d.sees(Vector::new(0.290, 0.0), &p).is_none());
    }
}
