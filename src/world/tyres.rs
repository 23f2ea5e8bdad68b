//! The tyres of the traction drive (v1 and later): each wheel grips the floor with a bounded
//! impulse, the one that would cancel the wheel's slip, clamped to the tyre's friction circle
//! μ_t·N·h with N half the robot's weight. `physics.rs` applies these impulses before a rapier
//! step, `scene_contacts.rs` before solving a contact with the scene, `motion.rs` to a robot
//! that slips with nothing to touch ([`slip_freely`]).
//!
//! Units: metres, seconds, radians, kg, m/s, rad/s; world frame.

use rapier2d::math::Vector;

/// Standard gravity (m/s²): the robots' weight presses the tyres on the floor.
pub const GRAVITY: f32 = 9.81;

/// A robot as the traction substep sees it: its planar state and its wheels' speeds.
#[derive(Debug, Clone, Copy, Default)]
pub struct TractionBody {
    /// Centre (m).
    pub position: Vector,
    /// Heading (rad).
    pub heading: f32,
    /// Velocity of the centre (m/s, world frame).
    pub velocity: Vector,
    /// Yaw rate (rad/s).
    pub spin: f32,
    /// Wheel speeds (left, right; m/s at the tyre).
    pub wheels: [f32; 2],
}

/// The tyres' grip.
#[derive(Debug, Clone, Copy)]
pub struct Grip {
    /// Wheel separation (m).
    pub axle: f32,
    /// Tyre–floor friction coefficient.
    pub tyre_friction: f32,
}

/// One substep of `h` seconds of a body that slips and touches nothing, without rapier: the
/// tyres' impulses change its velocity and yaw rate, then it moves at them over the substep
/// (rapier's integration of a free body: position + v·h, heading + ω·h). `mass` (kg) and
/// `inertia` (kg·m²) are the body's; `grip` the tyres'.
pub fn slip_freely(body: &mut TractionBody, grip: Grip, mass: f32, radius: f32, h: f32) {
    let inertia = 0.5 * mass * radius * radius;
    let cap = grip.tyre_friction * 0.5 * mass * GRAVITY * h;
    let (dv, dw) = tyre_impulses(body, grip.axle, mass, inertia, cap);
    body.velocity += dv;
    body.spin += dw;
    body.position += body.velocity * h;
    body.heading += body.spin * h;
}

/// The change of velocity and yaw rate the two tyres give a robot in one substep: the impulses
/// that would make both wheels roll without slipping, each clamped to `cap` (its friction
/// circle). Wheels at ±axle/2 along the robot's left axis; the body's mass `mass` (kg) and
/// moment of inertia `inertia` (kg·m²).
pub(super) fn tyre_impulses(
    body: &TractionBody,
    axle: f32,
    mass: f32,
    inertia: f32,
    cap: f32,
) -> (Vector, f32) {
    let (s, c) = body.heading.sin_cos();
    let forward = Vector::new(c, s);
    let left = Vector::new(-s, c);
    let half = 0.5 * axle;
    // Ground velocity at each wheel: v + ω × r, with r = ±half·left and ω × left = −forward.
    let at_left = body.velocity - body.spin * half * forward;
    let at_right = body.velocity + body.spin * half * forward;
    let slip_left = at_left - body.wheels[0] * forward;
    let slip_right = at_right - body.wheels[1] * forward;
    // The impulse that cancels both slips: a linear part for their mean, a torque for their
    // difference (the lateral slips are equal, so this is exact).
    let linear = -0.5 * mass * (slip_left + slip_right);
    let torque = inertia * (slip_left - slip_right).dot(forward) / axle;
    // Split between the wheels: the same lateral share, and longitudinal shares whose
    // difference makes the torque (torque = half·(J_right − J_left)·forward).
    let along = linear.dot(forward);
    let across = 0.5 * linear.dot(left) * left;
    let clamp = |j: Vector| {
        let norm = j.length();
        if norm > cap && norm > 0.0 {
            j * (cap / norm)
        } else {
            j
        }
    };
    let j_left = clamp((0.5 * along - torque / axle) * forward + across);
    let j_right = clamp((0.5 * along + torque / axle) * forward + across);
    let dv = (j_left + j_right) / mass;
    let dw = half * (j_right - j_left).dot(forward) / inertia;
    (dv, dw)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(wheels: [f32; 2], velocity: Vector, spin: f32) -> TractionBody {
        TractionBody {
            position: Vector::ZERO,
            heading: 0.3,
            velocity,
            spin,
            wheels,
        }
    }

    #[test]
    fn unclamped_impulses_make_both_wheels_roll() {
        let (axle, mass, inertia) = (0.1054, 0.54, 0.5 * 0.54 * 0.0704 * 0.0704);
        let b = body([0.2, 0.35], Vector::new(0.05, -0.1), 0.7);
        let (dv, dw) = tyre_impulses(&b, axle, mass, inertia, f32::INFINITY);
        let after = body(b.wheels, b.velocity + dv, b.spin + dw);
        let (s, c) = after.heading.sin_cos();
        let forward = Vector::new(c, s);
        let v_left = after.velocity - after.spin * 0.5 * axle * forward;
        let v_right = after.velocity + after.spin * 0.5 * axle * forward;
        assert!((v_left - 0.2 * forward).length() < 1e-5, "{v_left:?}");
        assert!((v_right - 0.35 * forward).length() < 1e-5, "{v_right:?}");
    }

    #[test]
    fn clamped_impulses_bound_the_acceleration_by_the_grip() {
        let (axle, mass, inertia) = (0.1054, 0.54, 0.5 * 0.54 * 0.0704 * 0.0704);
        let h = 0.0125;
        let cap = 1.0 * 0.5 * mass * GRAVITY * h;
        // Wheels at full speed, body at rest: at most μ·g of acceleration.
        let (dv, _) = tyre_impulses(
            &body([0.8, 0.8], Vector::ZERO, 0.0),
            axle,
            mass,
            inertia,
            cap,
        );
        assert!((dv.length() - GRAVITY * h).abs() < 1e-5, "{}", dv.length());
    }
}
