//! Contact substeps robot by robot (`physics.split = "robot"`, traction drive): rapier steps only
//! the robots that can touch something within the substep or whose tyres slip; every other
//! robot rolls on its exact arc, as it would in a world where nothing can be touched. With
//! `split = "world"` (v1's default) one robot that can touch something sends every robot of its
//! world through rapier, which in a swarm is every substep.
//!
//! Which robots go to rapier depends only on the world's state: a robot is left out when it
//! rolls within its tyres' grip, its clearance to the scene exceeds the distance it can travel
//! in the substep (plus [`CONTACT_MARGIN`]), and its gap to every other robot exceeds both
//! robots' reach at their speed bounds. So no robot left out can touch anything, or be touched
//! by a robot keeping to its bound. A robot struck within the substep could in principle be
//! pushed past its bound; the ends are checked, and a robot left out that one met is taken in
//! and the substep done again (`World::mark_contacts` in `contacts.rs`; not seen to happen in
//! any run so far, since rapier hands an impact's impulse over at the end of a substep).
//!
//! Units: metres, seconds, radians; world frame.

use rapier2d::math::Vector;

use super::motion::{roll_left_out, speed_bound, CONTACT_MARGIN};
use super::team::CHUNK;
use super::tyres::GRAVITY;
use super::{Robot, World};
use crate::robot::Drive;

/// A chunk of the robots and of their slots in the motors' pass of `split_substep`.
type Chunk<'a> = (
    ((&'a mut [Robot], &'a mut [bool]), &'a mut [f32]),
    (&'a mut [Vector], &'a mut [Start]),
);

/// Tries of a substep with more robots taken in before every robot is.
const MAX_RETRIES: usize = 3;

/// A robot's state at the start of a substep.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Start {
    position: Vector,
    heading: f32,
    velocity: Vector,
    spin: f32,
    step_travel: f32,
    in_contact: bool,
}

impl Start {
    fn of(r: &Robot) -> Self {
        Self {
            position: r.position,
            heading: r.heading,
            velocity: r.velocity,
            spin: r.spin,
            step_travel: r.step_travel,
            in_contact: r.in_contact,
        }
    }

    fn restore(&self, r: &mut Robot) {
        r.position = self.position;
        r.heading = self.heading;
        r.velocity = self.velocity;
        r.spin = self.spin;
        r.step_travel = self.step_travel;
        r.in_contact = self.in_contact;
    }
}

impl World {
    /// One substep of `h` seconds, robot by robot (module doc).
    pub(super) fn split_substep(&mut self, h: f32) {
        let grip = self.tyre_friction * GRAVITY * h;
        let ratio = self.inertia_per_mass() / self.drive.axle_length;
        let gain = self.drive.max_speed_change(h);
        // One slot per robot, each written by the pass below.
        let n = self.robots.len();
        self.active.resize(n, false);
        self.speeds.resize(n, 0.0);
        self.positions.resize(n, Vector::ZERO);
        self.start.resize(n, Start::default());
        // One pass over the robots: motors, grip, the speed bound `mark_reachable` needs, each
        // robot's centre for the contact checks and its state at the substep's start, to go
        // back to should rapier push a robot into one left out. Robot by robot, so a swarm
        // shares it among the batch's threads (which then read each robot once a pass, in the
        // core whose cache holds it).
        let drive = &self.drive;
        let pass = |r: &mut Robot,
                    (active, speed): (&mut bool, &mut f32),
                    at: &mut Vector,
                    start: &mut Start| {
            (r.wheel_setpoint, r.wheel_speeds) =
                drive.motors(r.wheel_setpoint, r.wheel_speeds, r.wheel_command, h);
            r.wheel_travel[0] += (r.wheel_speeds[0] * h) as f64;
            r.wheel_travel[1] += (r.wheel_speeds[1] * h) as f64;
            *active = !grips(drive, r, ratio, grip, h);
            *speed = speed_bound(r, gain);
            *at = r.position;
            *start = Start::of(r);
        };
        let each = |(((r, a), s), (p, st)): Chunk<'_>| {
            for ((((r, a), s), p), st) in r.iter_mut().zip(a).zip(s).zip(p).zip(st) {
                pass(r, (a, s), p, st);
            }
        };
        let robots = self
            .robots
            .chunks_mut(CHUNK)
            .zip(self.active.chunks_mut(CHUNK));
        let robots = robots.zip(self.speeds.chunks_mut(CHUNK));
        let slots = self
            .positions
            .chunks_mut(CHUNK)
            .zip(self.start.chunks_mut(CHUNK));
        self.team.each(robots.zip(slots), |_, chunk| each(chunk));
        self.mark_reachable(h);
        for round in 0.. {
            if !self.active.contains(&true) {
                let rolled = (&mut self.robots[..], &mut self.positions[..]);
                roll_left_out(rolled, &self.active, &self.drive, h, &self.team, || ());
                return;
            }
            self.traction_substep(Some(h));
            // Only robots rapier moved can be in contact: the others kept clear of everything
            // by their bounds. A robot rapier moved may yet have been pushed faster than its
            // bound (by a third robot) and met one left out: take that one in too and do the
            // substep again (from the same start; rapier's contacts keep what the first try
            // learnt, so the result is still a function of the world's state). After a few
            // tries, take every robot.
            if !self.mark_contacts(true) {
                return;
            }
            for (r, start) in self.robots.iter_mut().zip(&self.start) {
                start.restore(r);
            }
            if round >= MAX_RETRIES {
                self.active.iter_mut().for_each(|a| *a = true);
            }
        }
    }

    /// Marks active every robot that could touch the scene or another robot within `h` s, given
    /// every robot's speed bound over the substep in `self.speeds`.
    fn mark_reachable(&mut self, h: f32) {
        let radius = self.drive.radius;
        let fastest = self.speeds.iter().fold(0.0f32, |a, &b| a.max(b));
        let cutoff = 2.0 * radius + 2.0 * fastest * h + CONTACT_MARGIN + 0.001;
        if !cutoff.is_finite() {
            self.active.iter_mut().for_each(|a| *a = true);
            return;
        }
        let swarm = self.robots.len() > self.grid_min_robots;
        // `self.positions` holds every robot's centre (the motors' pass wrote it).
        let drift = if swarm {
            self.refresh_contact_grid(cutoff)
        } else {
            0.0
        };
        let positions = &self.positions;
        let (grid, speeds, scene) = (&self.contact_grid, &self.speeds, &self.scene);
        // Robot i can touch robot j when their gap is within both reaches (symmetric, so each
        // robot decides for itself).
        let check = |i: usize, active: &mut bool| {
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
                let mut touch = false;
                grid.for_each_near(p, cutoff + drift, i, |j, _| touch |= touches(j as usize));
                *active = touch;
            } else {
                *active = (0..positions.len()).any(touches);
            }
        };
        // Robot by robot, so a swarm shares it among its team.
        let chunks = self.active.chunks_mut(CHUNK);
        self.team.each(chunks, |first, active: &mut [bool]| {
            for (i, a) in active.iter_mut().enumerate() {
                check(first + i, a);
            }
        });
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
