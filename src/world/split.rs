//! Contact substeps robot by robot (`physics.split = "robot"`, traction drive): rapier steps only
//! the robots that can touch something within the substep or whose tyres slip; every other
//! robot rolls on its exact arc, as it would in a world where nothing can be touched. With
//! `split = "world"` (v1's default) one robot that can touch something sends every robot of its
//! world through rapier, which in a swarm is every substep.
//!
//! Which robots go to rapier depends only on the world's state: a robot is left out when it
//! rolls within its tyres' grip, its clearance to the scene exceeds the distance it can travel
//! in the substep (plus [`CONTACT_MARGIN`]), and its gap to every other robot exceeds both
//! robots' reach. So no robot left out can touch anything, or be touched, during the substep.
//!
//! Units: metres, seconds, radians; world frame.

use rayon::prelude::*;

use super::motion::{integrate_arc, set_rolling_velocity, speed_bound, CONTACT_MARGIN, MIN_CELL};
use super::physics::{Grip, TractionBody, GRAVITY};
use super::{Robot, World};
use crate::robot::{wrap_angle, Drive};

/// Robots a thread checks at least at a time.
const MIN_ROBOTS_PER_TASK: usize = 32;

impl World {
    /// One substep of `h` seconds, robot by robot (module doc).
    pub(super) fn split_substep(&mut self, h: f32) {
        let grip = self.tyre_friction * GRAVITY * h;
        let ratio = self.inertia_per_mass() / self.drive.axle_length;
        self.active.clear();
        for r in &mut self.robots {
            (r.wheel_setpoint, r.wheel_speeds) =
                self.drive
                    .motors(r.wheel_setpoint, r.wheel_speeds, r.wheel_command, h);
            r.wheel_travel[0] += (r.wheel_speeds[0] * h) as f64;
            r.wheel_travel[1] += (r.wheel_speeds[1] * h) as f64;
            self.active.push(!grips(&self.drive, r, ratio, grip, h));
        }
        self.mark_reachable(h);
        let mut any = false;
        for (r, &active) in self.robots.iter_mut().zip(&self.active) {
            if active {
                any = true;
                continue;
            }
            let (v, w) = self.drive.twist(r.wheel_speeds);
            integrate_arc(&mut r.position, &mut r.heading, v, w, h);
            r.step_travel += v.abs() * h;
            set_rolling_velocity(r, v, w);
        }
        if any {
            self.split_rapier_substep();
        }
    }

    /// Marks active every robot that could touch the scene or another robot within `h` s.
    fn mark_reachable(&mut self, h: f32) {
        let gain = self.drive.wheel_accel_limit * h;
        let radius = self.drive.radius;
        self.speeds.clear();
        self.speeds
            .extend(self.robots.iter().map(|r| speed_bound(r, gain)));
        let fastest = self.speeds.iter().fold(0.0f32, |a, &b| a.max(b));
        let cutoff = 2.0 * radius + 2.0 * fastest * h + CONTACT_MARGIN + 0.001;
        if !cutoff.is_finite() {
            self.active.iter_mut().for_each(|a| *a = true);
            return;
        }
        let swarm = self.robots.len() > self.grid_min_robots;
        if swarm {
            self.grid
                .build(self.robots.iter().map(|r| r.position), cutoff.max(MIN_CELL));
        }
        self.positions.clear();
        self.positions
            .extend(self.robots.iter().map(|r| r.position));
        let (grid, positions, speeds, scene) =
            (&self.grid, &self.positions, &self.speeds, &self.scene);
        // Robot i can touch robot j when their gap is within both reaches (symmetric, so each
        // robot decides for itself).
        let check = |near: &mut Vec<u32>, (i, active): (usize, &mut bool)| {
            if *active {
                return;
            }
            let p = positions[i];
            let reach = speeds[i] * h + CONTACT_MARGIN;
            if scene.clearance(p) - radius <= reach {
                *active = true;
                return;
            }
            let touches = |j: usize| {
                j != i && (positions[j] - p).length() - 2.0 * radius <= reach + speeds[j] * h
            };
            if swarm {
                near.clear();
                grid.near(p, cutoff, i, near);
                *active = near.iter().any(|&j| touches(j as usize));
            } else {
                *active = (0..positions.len()).any(touches);
            }
        };
        if swarm && rayon::current_thread_index().is_some() {
            self.active
                .par_iter_mut()
                .enumerate()
                .with_min_len(MIN_ROBOTS_PER_TASK)
                .for_each_init(Vec::new, check);
        } else {
            let mut near = Vec::new();
            self.active
                .iter_mut()
                .enumerate()
                .for_each(|item| check(&mut near, item));
        }
    }

    /// Hands the active robots to rapier for one traction substep and marks their contacts.
    fn split_rapier_substep(&mut self) {
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
        self.physics
            .step_traction_some(&mut self.traction, &self.active, grip);
        for ((r, state), &active) in self.robots.iter_mut().zip(&self.traction).zip(&self.active) {
            if !active {
                continue;
            }
            r.step_travel += (state.position - r.position).length();
            r.position = state.position;
            r.heading = wrap_angle(state.heading);
            r.velocity = state.velocity;
            r.spin = state.spin;
        }
        self.mark_contacts();
    }
}

/// Whether robot `r`'s tyres can make its body roll on its wheels' current speeds within this
/// substep of `h` seconds and keep it on the arc: the impulse per unit mass each tyre must give
/// (half the change of the centre's velocity, plus or minus the yaw change's share `ratio`·Δω
/// with `ratio` = (I/m)/axle, plus half the arc's centripetal v·ω·h across) stays inside its
/// friction circle, half of μ·g·h (`grip`: each wheel carries half the weight). For a robot
/// already rolling this is `motion::within_grip`; a robot rapier moved last substep has a small
/// sideways slip (its velocity kept its direction while it turned), which the tyres take up.
#[inline]
fn grips(drive: &Drive, r: &Robot, ratio: f32, grip: f32, h: f32) -> bool {
    let (v, w) = drive.twist(r.wheel_speeds);
    let (s, c) = r.heading.sin_cos();
    let forward = rapier2d::math::Vector::new(c, s);
    let left = rapier2d::math::Vector::new(-s, c);
    let change = v * forward - r.velocity;
    let (along, across) = (change.dot(forward), change.dot(left));
    let dw = w - r.spin;
    let lateral = 0.5 * across.abs() + 0.5 * (v * w * h).abs();
    let cap = 0.5 * grip;
    let fits = |long: f32| long * long + lateral * lateral <= cap * cap;
    fits(0.5 * along - ratio * dw) && fits(0.5 * along + ratio * dw)
}
