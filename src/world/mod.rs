//! One simulated world: the scene, its rapier physics, the robots and their sensors, and the
//! world's own random stream. A control step is: wheel commands → substeps of motion → sensors.
//!
//! Motion: a substep in which no robot can touch anything (its clearance exceeds the distance it
//! can travel) integrates the differential drive exactly (circular arc) without calling rapier;
//! otherwise rapier2d steps the world and resolves the contacts. The choice depends only on this
//! world's state, so worlds stay independent and bit-for-bit reproducible.
//!
//! Units: metres, seconds, radians; world frame with the arena centred at the origin.

pub mod layout;
pub mod physics;
pub mod scene;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use crate::robot::{wrap_angle, Drive};
use crate::scenario::Scenario;
use crate::sensors::{Readings, SenseContext, Suite};
use physics::{BodyState, Physics};
pub use scene::{Scene, SceneShape};

/// Extra clearance (m) kept before deciding a robot cannot touch anything this substep.
const CONTACT_MARGIN: f32 = 0.002;
/// A robot whose clearance falls below this (m) after a substep is in contact.
const CONTACT_TOLERANCE: f32 = 0.001;

/// State of one robot.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Robot {
    /// Centre (m).
    pub position: Vector,
    /// Heading (rad, (-π, π]).
    pub heading: f32,
    /// Actual wheel speeds (left, right), m/s.
    pub wheel_speeds: [f32; 2],
    /// Commanded wheel speeds (left, right), m/s.
    pub wheel_command: [f32; 2],
    /// Distance rolled by each wheel since reset (m), for the encoders.
    pub wheel_travel: [f64; 2],
    /// Yaw rate over the last step (rad/s), as the gyro reads it.
    pub yaw_rate: f32,
    /// Distance the centre moved during the last step (m).
    pub step_travel: f32,
    /// Whether the robot touched a wall, obstacle or robot during the last step.
    pub in_contact: bool,
    /// Its sensors' last readings, in the real robot's units.
    pub readings: Readings,
    step_start_heading: f32,
}

/// A world: scene, physics, robots, sensors and random stream. It serialises whole (scratch
/// buffers aside), which is how an env's state is saved and restored.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct World {
    /// Drive parameters shared by the robots.
    pub drive: Drive,
    /// The sensors every robot carries (the models; each robot keeps its own readings).
    pub sensors: Suite,
    /// Static geometry.
    pub scene: Scene,
    /// The robots.
    pub robots: Vec<Robot>,
    /// The world's random stream (ChaCha8), the only randomness it uses.
    pub rng: ChaCha8Rng,
    physics: Physics,
    dt: f32,
    substeps: u32,
    // Scratch buffers and constants: not state.
    #[serde(skip)]
    bodies: Vec<BodyState>,
    #[serde(skip)]
    others: Vec<Vector>,
}

impl World {
    /// A world of `n_robots` robots in `scene`, configured by `cfg`.
    pub fn new(cfg: &Scenario, scene: Scene, n_robots: usize) -> Self {
        let drive = Drive::from_config(&cfg.robot);
        let physics = Physics::new(
            &scene,
            n_robots,
            drive.radius,
            cfg.robot.mass.bounds().0,
            cfg.physics.friction,
            cfg.physics.dt / cfg.physics.substeps as f32,
            cfg.physics.solver_iterations as usize,
        );
        Self {
            drive,
            sensors: Suite::new(&cfg.sensors),
            scene,
            robots: vec![Robot::default(); n_robots],
            rng: ChaCha8Rng::seed_from_u64(0),
            physics,
            dt: cfg.physics.dt,
            substeps: cfg.physics.substeps,
            bodies: Vec::with_capacity(n_robots),
            others: Vec::with_capacity(n_robots),
        }
    }

    /// Draws this episode's robot and sensor parameters: values given as `[low, high]` ranges in
    /// the scenario (domain randomisation) are sampled from the world's stream; fixed values
    /// draw nothing.
    pub fn randomise(&mut self, cfg: &Scenario) {
        let r = &cfg.robot;
        let rng = &mut self.rng;
        self.drive.axle_length = r.axle_length.sample(rng);
        self.drive.max_wheel_speed = r.max_wheel_speed.sample(rng);
        self.drive.wheel_accel_limit = r.wheel_accel_limit.sample(rng);
        self.sensors.randomise(&cfg.sensors, rng);
        if r.mass.is_random() {
            let mass = r.mass.sample(rng);
            self.physics.set_mass(mass);
        }
    }

    /// Replaces the static geometry (rebuilds the fixed colliders).
    pub fn set_scene(&mut self, scene: Scene) {
        self.physics.set_scene(&scene);
        self.scene = scene;
    }

    /// Puts robot `i` at rest at `position` with `heading`, clearing its odometry.
    pub fn place_robot(&mut self, i: usize, position: Vector, heading: f32) {
        self.robots[i] = Robot {
            position,
            heading: wrap_angle(heading),
            ..Robot::default()
        };
    }

    /// Control step length (s).
    pub fn dt(&self) -> f32 {
        self.dt
    }

    /// Smallest gap (m) between robot `i`'s body and the scene or another robot.
    pub fn clearance(&self, i: usize) -> f32 {
        let p = self.robots[i].position;
        let mut gap = self.scene.clearance(p) - self.drive.radius;
        for (j, other) in self.robots.iter().enumerate() {
            if j != i {
                gap = gap.min((other.position - p).length() - 2.0 * self.drive.radius);
            }
        }
        gap
    }

    /// Whether some robot could touch the scene or another robot within `duration` seconds.
    /// A robot's centre moves no faster than its fastest wheel, and a ramping wheel never
    /// exceeds the larger of its current and commanded speeds.
    fn contact_possible(&self, duration: f32) -> bool {
        let speed = |r: &Robot| {
            r.wheel_speeds
                .iter()
                .chain(&r.wheel_command)
                .fold(0.0f32, |m, w| m.max(w.abs()))
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
        let h = self.dt / self.substeps as f32;
        for r in &mut self.robots {
            r.step_travel = 0.0;
            r.in_contact = false;
            r.step_start_heading = r.heading;
        }
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
            self.finish_step();
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
        self.finish_step();
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
        for i in 0..self.robots.len() {
            if self.clearance(i) < CONTACT_TOLERANCE {
                self.robots[i].in_contact = true;
            }
        }
    }

    /// Reads every robot's sensors (with noise from the world's stream), robot after robot.
    pub fn sense(&mut self) {
        for i in 0..self.robots.len() {
            self.others.clear();
            for (j, other) in self.robots.iter().enumerate() {
                if j != i {
                    self.others.push(other.position);
                }
            }
            let robot = &mut self.robots[i];
            let ctx = SenseContext {
                scene: &self.scene,
                position: robot.position,
                sin_cos: robot.heading.sin_cos(),
                radius: self.drive.radius,
                others: &self.others,
            };
            self.sensors.read(&ctx, &mut self.rng, &mut robot.readings);
        }
    }
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
