//! How robots move over one control step: the exact arc where nothing can be touched, rapier
//! where something can; with the `kinematic` drive (v0, velocity imposed) or the `traction`
//! drive (v1, tyres with bounded grip, contacts with friction; see `physics.rs`).
//!
//! Units: metres, seconds, radians; world frame.

use rapier2d::math::Vector;

use super::physics::{BodyState, Grip, TractionBody};
use super::{Robot, World};
use crate::robot::wrap_angle;
use crate::scenario::DriveModel;

/// Extra clearance (m) kept before deciding a robot cannot touch anything this substep.
const CONTACT_MARGIN: f32 = 0.002;
/// A robot whose clearance falls below this (m) after a substep is in contact.
const CONTACT_TOLERANCE: f32 = 0.001;
/// Slip (m/s at the centre or the wheels) under which a body counts as rolling on its wheels.
const ROLLING_TOLERANCE: f32 = 1e-4;

impl World {
    /// Whether some robot could touch the scene or another robot within `duration` seconds.
    /// A robot's centre moves no faster than its fastest wheel, and a ramping wheel never
    /// exceeds the larger of its current and commanded speeds.
    fn contact_possible(&self, duration: f32) -> bool {
        // (In the traction model a body may also move faster than its wheels, pushed or
        // sliding: its own speed counts too; it is 0 in the kinematic model.)
        let speed = |r: &Robot| {
            r.wheel_speeds
                .iter()
                .chain(&r.wheel_command)
                .fold(r.velocity.length(), |m, w| m.max(w.abs()))
        };
        let radius = self.drive.radius;
        for (i, r) in self.robots.iter().enumerate() {
            let reach = speed(r) * duration + CONTACT_MARGIN;
            if self.scene.clearance(r.position) - radius <= reach {
                return true;
            }
            for other in &self.robots[i + 1..] {
                let gap = (other.position - r.position).length() - 2.0 * radius;
                if gap <= reach + speed(other) * duration {
                    return true;
                }
            }
        }
        false
    }

    /// Advances every robot by one control step toward its `wheel_command`.
    pub fn advance(&mut self) {
        for r in &mut self.robots {
            r.step_travel = 0.0;
            r.in_contact = false;
            r.step_start_heading = r.heading;
        }
        match self.drive_model {
            DriveModel::Kinematic => self.advance_kinematic(),
            DriveModel::Traction => self.advance_traction(),
        }
        self.finish_step();
    }

    /// The kinematic model (v0): the body moves as its wheels say, contacts aside.
    fn advance_kinematic(&mut self) {
        let h = self.dt / self.substeps as f32;
        let far = !self.contact_possible(self.dt);
        let steady = !self.drive.wheel_accel_limit.is_finite()
            || self
                .robots
                .iter()
                .all(|r| r.wheel_speeds == r.wheel_command);
        if far && steady {
            // Nothing can be touched and the wheels keep their speed: the substeps compose into
            // one exact arc over the whole step.
            for r in &mut self.robots {
                r.wheel_speeds = r.wheel_command;
                r.wheel_travel[0] += (r.wheel_speeds[0] * self.dt) as f64;
                r.wheel_travel[1] += (r.wheel_speeds[1] * self.dt) as f64;
                let (v, w) = self.drive.twist(r.wheel_speeds);
                integrate_arc(&mut r.position, &mut r.heading, v, w, self.dt);
                r.step_travel = v.abs() * self.dt;
            }
            return;
        }
        for _ in 0..self.substeps {
            for r in &mut self.robots {
                r.wheel_speeds = self.drive.ramp(r.wheel_speeds, r.wheel_command, h);
                r.wheel_travel[0] += (r.wheel_speeds[0] * h) as f64;
                r.wheel_travel[1] += (r.wheel_speeds[1] * h) as f64;
            }
            if !far && self.contact_possible(h) {
                self.physics_substep();
            } else {
                for r in &mut self.robots {
                    let (v, w) = self.drive.twist(r.wheel_speeds);
                    integrate_arc(&mut r.position, &mut r.heading, v, w, h);
                    r.step_travel += v.abs() * h;
                }
            }
        }
    }

    fn finish_step(&mut self) {
        for r in &mut self.robots {
            r.heading = wrap_angle(r.heading);
            r.yaw_rate = wrap_angle(r.heading - r.step_start_heading) / self.dt;
        }
    }

    fn physics_substep(&mut self) {
        self.bodies.clear();
        for r in &self.robots {
            self.bodies.push(BodyState {
                position: r.position,
                heading: r.heading,
                twist: self.drive.twist(r.wheel_speeds),
            });
        }
        self.physics.step(&mut self.bodies);
        for i in 0..self.robots.len() {
            let state = self.bodies[i];
            let r = &mut self.robots[i];
            r.step_travel += (state.position - r.position).length();
            r.position = state.position;
            r.heading = wrap_angle(state.heading);
        }
        self.mark_contacts();
    }

    fn mark_contacts(&mut self) {
        for i in 0..self.robots.len() {
            if self.clearance(i) < CONTACT_TOLERANCE {
                self.robots[i].in_contact = true;
            }
        }
    }

    /// The traction model (v1): the motors follow their speed profile; while a robot rolls
    /// without slipping and nothing can be touched, its body follows its wheels exactly (arcs);
    /// otherwise the tyres' bounded grip and rapier's contacts with friction move it.
    fn advance_traction(&mut self) {
        let h = self.dt / self.substeps as f32;
        let far = !self.contact_possible(self.dt);
        let steady = self
            .robots
            .iter()
            .all(|r| r.wheel_speeds == r.wheel_command && r.wheel_setpoint == r.wheel_command);
        if far && steady && self.all_rolling() {
            // The wheels keep their speed and grip: one exact arc over the whole step.
            for r in &mut self.robots {
                r.wheel_travel[0] += (r.wheel_speeds[0] * self.dt) as f64;
                r.wheel_travel[1] += (r.wheel_speeds[1] * self.dt) as f64;
                let (v, w) = self.drive.twist(r.wheel_speeds);
                integrate_arc(&mut r.position, &mut r.heading, v, w, self.dt);
                r.step_travel = v.abs() * self.dt;
                set_rolling_velocity(r, v, w);
            }
            return;
        }
        for _ in 0..self.substeps {
            for r in &mut self.robots {
                (r.wheel_setpoint, r.wheel_speeds) =
                    self.drive
                        .motors(r.wheel_setpoint, r.wheel_speeds, r.wheel_command, h);
                r.wheel_travel[0] += (r.wheel_speeds[0] * h) as f64;
                r.wheel_travel[1] += (r.wheel_speeds[1] * h) as f64;
            }
            if (!far && self.contact_possible(h)) || !self.all_rolling() {
                self.traction_substep();
            } else {
                for r in &mut self.robots {
                    let (v, w) = self.drive.twist(r.wheel_speeds);
                    integrate_arc(&mut r.position, &mut r.heading, v, w, h);
                    r.step_travel += v.abs() * h;
                    set_rolling_velocity(r, v, w);
                }
            }
        }
    }

    /// Whether every robot's body moves as its wheels roll (no slip, within a tolerance far
    /// below what the sensors or the observation could show).
    fn all_rolling(&self) -> bool {
        self.robots.iter().all(|r| {
            let (v, w) = self.drive.twist(r.wheel_speeds);
            let (s, c) = r.heading.sin_cos();
            (r.velocity - Vector::new(v * c, v * s)).length() <= ROLLING_TOLERANCE
                && (r.spin - w).abs() * self.drive.axle_length <= ROLLING_TOLERANCE
        })
    }

    fn traction_substep(&mut self) {
        self.traction.clear();
        for r in &self.robots {
            self.traction.push(TractionBody {
                position: r.position,
                heading: r.heading,
                velocity: r.velocity,
                spin: r.spin,
                wheels: r.wheel_speeds,
            });
        }
        let grip = Grip {
            axle: self.drive.axle_length,
            tyre_friction: self.tyre_friction,
        };
        self.physics.step_traction(&mut self.traction, grip);
        for (r, state) in self.robots.iter_mut().zip(&self.traction) {
            r.step_travel += (state.position - r.position).length();
            r.position = state.position;
            r.heading = wrap_angle(state.heading);
            r.velocity = state.velocity;
            r.spin = state.spin;
        }
        self.mark_contacts();
    }
}

/// A rolling robot's body velocity: forward speed `v` (m/s) along its heading, yaw rate `w`.
fn set_rolling_velocity(r: &mut Robot, v: f32, w: f32) {
    let (s, c) = r.heading.sin_cos();
    r.velocity = Vector::new(v * c, v * s);
    r.spin = w;
}

/// Exact differential-drive motion over `h` seconds at constant forward speed `v` and yaw rate
/// `w` (a circular arc; a straight line when `w` is ~0).
#[inline]
pub fn integrate_arc(position: &mut Vector, heading: &mut f32, v: f32, w: f32, h: f32) {
    let theta = *heading;
    if (w * h).abs() < 1e-6 {
        let (s, c) = theta.sin_cos();
        *position += Vector::new(v * h * c, v * h * s);
    } else {
        let next = theta + w * h;
        let r = v / w;
        let (s0, c0) = theta.sin_cos();
        let (s1, c1) = next.sin_cos();
        *position += Vector::new(r * (s1 - s0), -r * (c1 - c0));
        *heading = next;
    }
}
