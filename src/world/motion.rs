//! How robots move over one control step: the exact arc where nothing can be touched, rapier
//! where something can; with the `kinematic` drive (v0, velocity imposed) or the `traction`
//! drive (v1, tyres with bounded grip, contacts with friction; see `physics.rs`).
//!
//! Units: metres, seconds, radians; world frame.

use rapier2d::math::Vector;

use super::physics::BodyState;
use super::team::{Team, CHUNK};
use super::tyres::{slip_freely, Grip, TractionBody, GRAVITY};
use super::{Robot, World};
use crate::robot::{wrap_angle, Drive};
use crate::scenario::DriveModel;

/// Extra clearance (m) kept before deciding a robot cannot touch anything this substep.
pub(super) const CONTACT_MARGIN: f32 = 0.002;
/// A robot whose clearance falls below this (m) after a substep is in contact.
pub(super) const CONTACT_TOLERANCE: f32 = 0.001;
/// Least cell side (m) of the contact checks' grid: cells as small as a contact's reach would
/// cost more to clear and count than the few more robots larger ones hold.
pub(super) const MIN_CELL: f32 = 0.5;
/// Slip (m/s at the centre or the wheels) under which a body counts as rolling on its wheels.
pub(super) const ROLLING_TOLERANCE: f32 = 1e-4;

/// What the robots of a world can touch within a span.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Reach {
    /// Nothing.
    Nothing,
    /// The scene (walls, obstacles), and no robot another.
    Scene,
    /// Some robot another robot (and maybe the scene).
    Robots,
}

impl World {
    /// Whether some robot could touch the scene or another robot within `duration` seconds.
    fn contact_possible(&mut self, duration: f32) -> bool {
        self.contact_reach(duration, false) != Reach::Nothing
    }

    /// What the robots could touch within `duration` seconds. A robot's centre moves no faster
    /// than its fastest wheel, and a ramping wheel never exceeds the larger of its current and
    /// commanded speeds. With `classify` false it answers at the first possible contact of
    /// either kind (`Reach::Scene` or `Reach::Robots`, whichever comes first); with `classify`
    /// it tells a world whose robots can only touch the scene from one where two can meet.
    fn contact_reach(&mut self, duration: f32, classify: bool) -> Reach {
        // (In the traction model a body may also move faster than its wheels, pushed or
        // sliding: its own speed counts too; it is 0 in the kinematic model. There the wheels
        // also follow a speed profile: within `duration` a wheel's speed and setpoint gain at
        // most accel·duration. The kinematic model (v0) keeps its original bound, so that its
        // choice between arcs and rapier, hence its trajectories, stay bit for bit.)
        let gain = match self.drive_model {
            DriveModel::Traction => self.drive.max_speed_change(duration),
            DriveModel::Kinematic => f32::INFINITY,
        };
        let speed = |r: &Robot| speed_bound(r, gain);
        let radius = self.drive.radius;
        if self.robots.len() > self.grid_min_robots {
            // The same test, pairs found through the grid: no pair farther apart than the two
            // fastest robots' reach can pass it.
            self.speeds.clear();
            self.speeds.extend(self.robots.iter().map(speed));
            let fastest = self.speeds.iter().fold(0.0f32, |a, &b| a.max(b));
            let cutoff = 2.0 * radius + 2.0 * fastest * duration + CONTACT_MARGIN + 0.001;
            if !cutoff.is_finite() {
                return Reach::Robots;
            }
            self.gather_positions();
            let widen = self.refresh_contact_grid(cutoff);
            let (grid, positions) = (&self.contact_grid, &self.positions);
            let mut found = Reach::Nothing;
            for (i, &p) in positions.iter().enumerate() {
                let reach = self.speeds[i] * duration + CONTACT_MARGIN;
                if found == Reach::Nothing && self.scene.clearance(p) - radius <= reach {
                    found = Reach::Scene;
                    if !classify {
                        return found;
                    }
                }
                let mut touch = false;
                grid.for_each_near(p, cutoff + widen, i, |j, _| {
                    let j = j as usize;
                    if j > i {
                        let gap = (positions[j] - p).length() - 2.0 * radius;
                        touch |= gap <= reach + self.speeds[j] * duration;
                    }
                });
                if touch {
                    return Reach::Robots;
                }
            }
            return found;
        }
        let mut found = Reach::Nothing;
        for (i, r) in self.robots.iter().enumerate() {
            let reach = speed(r) * duration + CONTACT_MARGIN;
            if found == Reach::Nothing && self.scene.clearance(r.position) - radius <= reach {
                found = Reach::Scene;
                if !classify {
                    return found;
                }
            }
            for other in &self.robots[i + 1..] {
                let gap = (other.position - r.position).length() - 2.0 * radius;
                if gap <= reach + speed(other) * duration {
                    return Reach::Robots;
                }
            }
        }
        found
    }

    /// Advances every robot by one control step toward its `wheel_command`.
    pub fn advance(&mut self) {
        let begin = |r: &mut Robot| {
            r.step_travel = 0.0;
            r.in_contact = false;
            r.step_start_heading = r.heading;
            r.step_start_position = r.position;
        };
        self.each_robot(begin);
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
        let (inertial, dt) = (self.sensors.imu.is_some(), self.dt);
        let finish = |r: &mut Robot| {
            r.heading = wrap_angle(r.heading);
            r.yaw_rate = wrap_angle(r.heading - r.step_start_heading) / dt;
            if inertial {
                // The difference of the mean velocities of the last two steps is the mean
                // acceleration around their boundary, the start of this step: rotated into the
                // robot's frame at that moment.
                let velocity = (r.position - r.step_start_position) / dt;
                let (s, c) = r.step_start_heading.sin_cos();
                let a = (velocity - r.step_velocity) / dt;
                r.acceleration = Vector::new(c * a.x + s * a.y, c * a.y - s * a.x);
                r.step_velocity = velocity;
            }
        };
        self.each_robot(finish);
    }

    /// Runs `f` on every robot, robot by robot, so that a swarm shares the pass among its team
    /// (`team.rs`); in order otherwise.
    fn each_robot(&mut self, f: impl Fn(&mut Robot) + Sync) {
        let chunks = self.robots.chunks_mut(CHUNK);
        self.team
            .each(chunks, |_, r: &mut [Robot]| r.iter_mut().for_each(&f));
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
        self.mark_contacts(false);
    }

    /// The traction model (v1): the motors follow their speed profile; while a robot rolls
    /// without slipping and nothing can be touched, its body follows its wheels exactly (arcs);
    /// otherwise the tyres' bounded grip and rapier's contacts with friction move it.
    fn advance_traction(&mut self) {
        let h = self.dt / self.substeps as f32;
        let steady = self
            .robots
            .iter()
            .all(|r| r.wheel_speeds == r.wheel_command && r.wheel_setpoint == r.wheel_command);
        // Split by robot, `far` only decides the whole-step arc below, which needs `steady`
        // too: a world whose wheels change skips the check (a swarm's grid and pass).
        let far = if self.split_robots && (!steady || !self.whole_step_arc) {
            false
        } else {
            !self.contact_possible(self.dt)
        };
        if far && steady && self.all_rolling() && self.all_grip(self.dt) {
            // The wheels keep their speed and grip: one exact arc over the whole step.
            for r in &mut self.robots {
                r.wheel_travel[0] += (r.wheel_speeds[0] * self.dt) as f64;
                r.wheel_travel[1] += (r.wheel_speeds[1] * self.dt) as f64;
                let (v, w) = self.drive.twist(r.wheel_speeds);
                roll_arc(r, v, w, self.dt);
                r.step_travel = v.abs() * self.dt;
            }
            return;
        }
        for _ in 0..self.substeps {
            if self.split_robots {
                self.split_substep(h);
                continue;
            }
            // Rolling now, and the tyres can give this substep's change of wheel speeds (and the
            // turn's centripetal force) within their grip: the body keeps rolling. Robot by
            // robot in `self.active` (what `slip_substep` reads), and for the whole world.
            let grip = self.tyre_friction * GRAVITY * h;
            let ratio = self.inertia_per_mass() / self.drive.axle_length;
            let (drive, keeps_rolling) = (&self.drive, &mut self.active);
            keeps_rolling.clear();
            keeps_rolling.resize(self.robots.len(), false);
            // Robot by robot, so a swarm shares it among its team.
            let pass = |(r, keeps): (&mut Robot, &mut bool)| {
                let rolling = is_rolling(drive, r);
                let before = r.wheel_speeds;
                (r.wheel_setpoint, r.wheel_speeds) =
                    drive.motors(r.wheel_setpoint, r.wheel_speeds, r.wheel_command, h);
                r.wheel_travel[0] += (r.wheel_speeds[0] * h) as f64;
                r.wheel_travel[1] += (r.wheel_speeds[1] * h) as f64;
                *keeps = rolling && within_grip(drive, before, r.wheel_speeds, ratio, grip, h);
            };
            let chunks = self.robots.chunks_mut(CHUNK);
            let chunks = chunks.zip(keeps_rolling.chunks_mut(CHUNK));
            self.team
                .each(chunks, |_, (r, k): (&mut [Robot], &mut [bool])| {
                    r.iter_mut().zip(k.iter_mut()).for_each(pass);
                });
            let rolls = keeps_rolling.iter().all(|&keeps| keeps);
            let reach = if far {
                Reach::Nothing
            } else {
                self.contact_reach(h, self.scene_by_disc)
            };
            let to_rapier = match reach {
                Reach::Robots => true,
                Reach::Scene => !self.scene_by_disc,
                Reach::Nothing => false,
            };
            if to_rapier || (!rolls && !self.slip_by_tyres) {
                self.traction_substep(None);
            } else if reach == Reach::Scene {
                self.scene_substep(h);
            } else if !rolls {
                self.slip_substep(h);
            } else {
                for r in &mut self.robots {
                    let (v, w) = self.drive.twist(r.wheel_speeds);
                    roll_arc(r, v, w, h);
                    r.step_travel += v.abs() * h;
                }
            }
        }
    }

    /// One substep of `h` seconds in which some robot slips and nothing can be touched
    /// (`physics.slip_solver = "tyres"`): a robot that keeps rolling within its tyres' grip
    /// (`self.active`, set by the motors' pass) rolls on its exact arc; a slipping one is moved
    /// by its tyres' impulses, as rapier moves a body that touches nothing
    /// (`tyres::slip_freely`), without rapier's step.
    fn slip_substep(&mut self, h: f32) {
        let grip = Grip {
            axle: self.drive.axle_length,
            tyre_friction: self.tyre_friction,
        };
        let (mass, radius) = (self.physics.mass(), self.drive.radius);
        for (r, &keeps) in self.robots.iter_mut().zip(&self.active) {
            if keeps {
                let (v, w) = self.drive.twist(r.wheel_speeds);
                roll_arc(r, v, w, h);
                r.step_travel += v.abs() * h;
                continue;
            }
            let mut body = TractionBody {
                position: r.position,
                heading: r.heading,
                velocity: r.velocity,
                spin: r.spin,
                wheels: r.wheel_speeds,
            };
            slip_freely(&mut body, grip, mass, radius, h);
            r.step_travel += (body.position - r.position).length();
            r.position = body.position;
            r.heading = wrap_angle(body.heading);
            r.velocity = body.velocity;
            r.spin = body.spin;
        }
    }

    /// Moment of inertia over mass (m²) of the robots' bodies (uniform discs: R²/2, as rapier's
    /// ball colliders give).
    pub(super) fn inertia_per_mass(&self) -> f32 {
        0.5 * self.drive.radius * self.drive.radius
    }

    /// Whether every robot's tyres give the centripetal force of its steady turn over `h`
    /// seconds within their grip.
    fn all_grip(&self, h: f32) -> bool {
        let grip = self.tyre_friction * GRAVITY * h;
        let ratio = self.inertia_per_mass() / self.drive.axle_length;
        self.robots
            .iter()
            .all(|r| within_grip(&self.drive, r.wheel_speeds, r.wheel_speeds, ratio, grip, h))
    }

    /// Whether every robot's body moves as its wheels roll (no slip, within a tolerance far
    /// below what the sensors or the observation could show).
    fn all_rolling(&self) -> bool {
        self.robots.iter().all(|r| is_rolling(&self.drive, r))
    }

    /// Hands the robots to rapier for one traction substep and marks their contacts. With
    /// `roll_others = Some(h)` (`physics.split = "robot"`) only the robots `self.active` marks
    /// go to rapier, while the others roll on their arcs over `h` seconds: at the same time, on
    /// a swarm's team (neither depends on the other); every robot's centre is then in
    /// `self.positions`.
    pub(super) fn traction_substep(&mut self, roll_others: Option<f32>) {
        let only = roll_others.is_some();
        let body = |r: &Robot| TractionBody {
            position: r.position,
            heading: r.heading,
            velocity: r.velocity,
            spin: r.spin,
            wheels: r.wheel_speeds,
        };
        if only {
            // Only the robots rapier takes are read (a swarm's others are in the cache of the
            // thread that rolls them); the other slots are never read, and keep what they held.
            self.traction
                .resize(self.robots.len(), TractionBody::default());
            for (i, r) in self.robots.iter().enumerate() {
                if self.active[i] {
                    self.traction[i] = body(r);
                }
            }
        } else {
            self.traction.clear();
            self.traction.extend(self.robots.iter().map(body));
        }
        let grip = Grip {
            axle: self.drive.axle_length,
            tyre_friction: self.tyre_friction,
        };
        let active = only.then_some(self.active.as_slice());
        let team = &self.team;
        let (physics, traction) = (&mut self.physics, &mut self.traction);
        let mut step = || physics.step_traction(traction, active, grip, team);
        if let Some(h) = roll_others {
            // The others roll on the team while this thread steps rapier.
            let rolled = (&mut self.robots[..], &mut self.positions[..]);
            roll_left_out(rolled, &self.active, &self.drive, h, team, step);
        } else {
            step();
        }
        let take = |(r, state): (&mut Robot, &TractionBody)| {
            r.step_travel += (state.position - r.position).length();
            r.position = state.position;
            r.heading = wrap_angle(state.heading);
            r.velocity = state.velocity;
            r.spin = state.spin;
        };
        if only {
            // Split by robot, only rapier's robots, whose centres the contact checks then read.
            for (i, state) in self.traction.iter().enumerate() {
                if self.active[i] {
                    take((&mut self.robots[i], state));
                    self.positions[i] = state.position;
                }
            }
        } else {
            // Robot by robot, so a swarm shares it among its team.
            let chunks = self
                .robots
                .chunks_mut(CHUNK)
                .zip(self.traction.chunks(CHUNK));
            self.team
                .each(chunks, |_, (r, t): (&mut [Robot], &[TractionBody])| {
                    r.iter_mut().zip(t).for_each(take);
                });
        }
        // Split by robot, `split_substep` marks the contacts (and checks its bounds held).
        if !only {
            self.mark_contacts(false);
        }
    }
}

/// Rolls every robot `active` does not mark on its exact arc over `h` seconds and writes its
/// centre into `positions`, while this thread runs `beside`; robot by robot, so that a swarm
/// shares it among its `team`, with the same results.
pub(super) fn roll_left_out(
    (robots, positions): (&mut [Robot], &mut [Vector]),
    active: &[bool],
    drive: &Drive,
    h: f32,
    team: &Team,
    beside: impl FnOnce(),
) {
    let roll = |((r, at), &a): ((&mut Robot, &mut Vector), &bool)| {
        if !a {
            let (v, w) = drive.twist(r.wheel_speeds);
            roll_arc(r, v, w, h);
            r.step_travel += v.abs() * h;
            *at = r.position;
        }
    };
    let chunks = robots.chunks_mut(CHUNK).zip(positions.chunks_mut(CHUNK));
    let chunks = chunks.zip(active.chunks(CHUNK));
    let each = |_: &mut (), _, ((r, p), a): ((&mut [Robot], &mut [Vector]), &[bool])| {
        r.iter_mut().zip(p.iter_mut()).zip(a).for_each(roll);
    };
    team.each_beside(chunks, || (), each, beside);
}

/// Whether a robot rolling on wheels at `before` (m/s) keeps rolling when they change to `after`
/// over `h` seconds: the impulse per unit mass each tyre must give (half the change of forward
/// speed, plus or minus the yaw change's share `ratio`·Δω with `ratio` = (I/m)/axle, and half of
/// the turn's centripetal v·ω·h) stays inside its friction circle, half of μ·g·h (`grip`: each
/// wheel carries half the weight).
#[inline]
pub(super) fn within_grip(
    drive: &Drive,
    before: [f32; 2],
    after: [f32; 2],
    ratio: f32,
    grip: f32,
    h: f32,
) -> bool {
    let (v0, w0) = drive.twist(before);
    let (v1, w1) = drive.twist(after);
    let (dv, dw) = (v1 - v0, w1 - w0);
    let lateral = 0.5 * v1 * w1 * h;
    let cap = 0.5 * grip;
    let fits = |long: f32| long * long + lateral * lateral <= cap * cap;
    fits(0.5 * dv - ratio * dw) && fits(0.5 * dv + ratio * dw)
}

/// The fastest a robot's centre can move over a span in which its wheels' speeds and setpoints
/// can gain at most `gain` (m/s): a ramping wheel never exceeds the larger of its current and
/// commanded speeds, and a pushed or sliding body may move faster than its wheels.
#[inline]
pub(super) fn speed_bound(r: &Robot, gain: f32) -> f32 {
    let wheel = |i: usize| {
        let now = r.wheel_speeds[i].abs().max(r.wheel_setpoint[i].abs());
        r.wheel_command[i].abs().max(now).min(now + gain)
    };
    r.velocity.length().max(wheel(0)).max(wheel(1))
}

/// Whether a robot's body moves as its wheels roll (no slip, within [`ROLLING_TOLERANCE`]).
#[inline]
pub(super) fn is_rolling(drive: &Drive, r: &Robot) -> bool {
    let (v, w) = drive.twist(r.wheel_speeds);
    let (s, c) = r.heading.sin_cos();
    (r.velocity - Vector::new(v * c, v * s)).length() <= ROLLING_TOLERANCE
        && (r.spin - w).abs() * drive.axle_length <= ROLLING_TOLERANCE
}

/// Exact differential-drive motion over `h` seconds at constant forward speed `v` and yaw rate
/// `w` (a circular arc; a straight line when `w` is ~0). Returns the sine and cosine of the
/// heading it ends on.
#[inline]
pub fn integrate_arc(
    position: &mut Vector,
    heading: &mut f32,
    v: f32,
    w: f32,
    h: f32,
) -> (f32, f32) {
    let theta = *heading;
    if (w * h).abs() < 1e-6 {
        let (s, c) = theta.sin_cos();
        *position += Vector::new(v * h * c, v * h * s);
        (s, c)
    } else {
        let next = theta + w * h;
        let r = v / w;
        let (s0, c0) = theta.sin_cos();
        let (s1, c1) = next.sin_cos();
        *position += Vector::new(r * (s1 - s0), -r * (c1 - c0));
        *heading = next;
        (s1, c1)
    }
}

/// Rolls robot `r` on its exact arc over `h` seconds at forward speed `v` and yaw rate `w`, and
/// gives its body the rolling velocity at the end: forward speed `v` along the end heading
/// (whose sine and cosine the arc already computed), yaw rate `w`.
#[inline]
pub(super) fn roll_arc(r: &mut Robot, v: f32, w: f32, h: f32) {
    let (s, c) = integrate_arc(&mut r.position, &mut r.heading, v, w, h);
    r.velocity = Vector::new(v * c, v * s);
    r.spin = w;
}
