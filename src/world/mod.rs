//! One simulated world: the scene, its rapier physics, the robots and their sensors, and the
//! world's own random stream. A control step is: wheel commands → substeps of motion → sensors.
//!
//! Motion: a substep in which no robot can touch anything (its clearance exceeds the distance it
//! can travel) integrates the differential drive exactly (circular arc) without calling rapier;
//! otherwise rapier2d steps the world and resolves the contacts. The choice depends only on this
//! world's state, so worlds stay independent and bit-for-bit reproducible.
//!
//! Units: metres, seconds, radians; world frame with the arena centred at the origin.

/// The world's side of its robots' [`SenseContext`]s for a reading (`fresh` at a reset): a
/// macro rather than a method, so that it borrows only the fields it names and the robots, the
/// sensors and the random stream stay free to change while it is held.
macro_rules! surroundings {
    ($world:expr, $fresh:expr) => {
        $crate::sensors::Surroundings {
            scene: &$world.scene,
            floor: &$world.floor,
            floor_marks: &$world.floor_marks,
            radius: $world.drive.radius,
            robot_reflectance: $world.robot_reflectance,
            dt: $world.dt,
            fresh: $fresh,
        }
    };
}

mod contacts;
pub mod layout;
mod motion;
pub mod physics;
pub mod scene_contacts;
pub mod scenery;
mod spacing;
mod split;
mod swarm;
mod team;
pub mod tyres;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use crate::geometry::floor::{FloorMarks, SharedFloor};
use crate::geometry::grid::Grid;
use crate::geometry::scene::Scene;
use crate::odometry::Odometry;
use crate::robot::{wrap_angle, Drive};
use crate::scenario::{DriveModel, Localization, MotionSplit, Scenario, SceneSolver, SlipSolver};
use crate::sensors::{Readings, SenseContext, Suite};
pub use motion::integrate_arc;
use physics::{BodyState, Physics, PhysicsParams};
pub use team::StepTeam;
pub(crate) use team::CHUNK as ROBOT_CHUNK;
use tyres::TractionBody;

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
    /// Setpoints of the wheels' speed profile (left, right), m/s (traction model).
    pub wheel_setpoint: [f32; 2],
    /// Distance rolled by each wheel since reset (m), for the encoders: what the wheels turned,
    /// slip included.
    pub wheel_travel: [f64; 2],
    /// Velocity of the centre (m/s, world frame; traction model).
    pub velocity: Vector,
    /// Yaw rate of the body (rad/s; traction model).
    pub spin: f32,
    /// The robot's own estimate of its pose, by dead reckoning (`localization = "odometry"`).
    pub odometry: Odometry,
    /// Yaw rate over the last step (rad/s), as the gyro reads it.
    pub yaw_rate: f32,
    /// Distance the centre moved during the last step (m).
    pub step_travel: f32,
    /// Mean velocity of the centre over the last step (m/s, world frame), kept only while the
    /// robot carries the IMU.
    pub step_velocity: Vector,
    /// Acceleration of the centre around the start of the last step (m/s², robot frame): the
    /// change of `step_velocity` over the last two steps; kept only while it carries the IMU.
    pub acceleration: Vector,
    /// Whether the robot touched a wall, obstacle or robot during the last step.
    pub in_contact: bool,
    /// Its sensors' last readings, in the real robot's units.
    pub readings: Readings,
    /// The colour of its top LEDs (RGB in [0, 1]): what cameras see of it.
    pub led: [f32; 3],
    step_start_heading: f32,
    step_start_position: Vector,
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
    /// The scenario's floor (not state: a loaded state keeps its env's).
    #[serde(skip)]
    pub floor: SharedFloor,
    /// Marks the task draws on the floor this episode (a line-following track).
    pub floor_marks: FloorMarks,
    /// The robots.
    pub robots: Vec<Robot>,
    /// The world's random stream (ChaCha8), the only randomness it uses.
    pub rng: ChaCha8Rng,
    physics: Physics,
    dt: f32,
    substeps: u32,
    drive_model: DriveModel,
    /// Whether a contact substep steps only the robots that can touch something or slip
    /// (`physics.split = "robot"`; traction drive).
    split_robots: bool,
    /// Whether a world split by robot may roll one arc over the whole step (`physics.whole_step_arc`).
    whole_step_arc: bool,
    /// Whether a slipping robot that can touch nothing moves by its tyres without rapier
    /// (`physics.slip_solver = "tyres"`).
    slip_by_tyres: bool,
    /// Whether robots that can touch the scene but no other robot are moved as discs against it
    /// without rapier (`physics.scene_solver = "disc"`).
    scene_by_disc: bool,
    /// Tyre–floor friction coefficient of this episode (traction model).
    tyre_friction: f32,
    /// Infrared reflectance of the robots' shells.
    robot_reflectance: f32,
    /// The robots' LED colour at placement (`robot.led_color`).
    robot_led: [f32; 3],
    /// Whether robots keep an odometry estimate (`localization = "odometry"`).
    odometry: bool,
    // Scratch buffers and constants: not state.
    #[serde(skip)]
    bodies: Vec<BodyState>,
    #[serde(skip)]
    traction: Vec<TractionBody>,
    #[serde(skip)]
    others: Vec<Vector>,
    #[serde(skip)]
    other_leds: Vec<[f32; 3]>,
    #[serde(skip)]
    grid: Grid,
    /// The grid a swarm finds contacts through (which robots can touch within a substep, which
    /// ended it touching), kept over substeps and steps while the robots stay near the centres
    /// it holds (`contacts::World::refresh_contact_grid`).
    #[serde(skip)]
    contact_grid: Grid,
    #[serde(skip)]
    speeds: Vec<f32>,
    #[serde(skip)]
    positions: Vec<Vector>,
    /// Which robots the current substep hands to rapier (`physics.split = "robot"`).
    #[serde(skip)]
    active: Vec<bool>,
    /// Robots' states at the start of the current substep (`physics.split = "robot"`).
    #[serde(skip)]
    start: Vec<split::Start>,
    /// Robots left out of a substep that rapier's robots met (`physics.split = "robot"`).
    #[serde(skip)]
    missed: Vec<u32>,
    /// Robots rapier moved that ended a substep in contact (`physics.split = "robot"`).
    #[serde(skip)]
    touching: Vec<u32>,
    /// The threads sharing a swarm's passes over one step (`team.rs`).
    #[serde(skip)]
    team: team::Team,
    /// Worlds of more robots than this find neighbours through the grid ([`GRID_MIN_ROBOTS`];
    /// tests set it to compare both ways).
    #[serde(skip, default = "grid_min_robots")]
    pub grid_min_robots: usize,
}

fn grid_min_robots() -> usize {
    GRID_MIN_ROBOTS
}

/// Worlds of more robots than this are swarms: they find each robot's neighbours through a
/// [`Grid`] (smaller ones loop over every robot; both ways give the same results) and read
/// their sensors in parallel, each robot with its own random stream (`swarm.rs`). 32 was the
/// largest world before swarms, so every earlier scenario keeps its random stream.
pub const GRID_MIN_ROBOTS: usize = 32;

/// Rapier's contact prediction distance (m) for `cfg`: `physics.contact_prediction`, or when it
/// is 0, 1.25 × the distance two robots at full speed close in one substep, at least rapier's
/// default 0.02 m.
fn contact_prediction(cfg: &Scenario) -> f32 {
    let given = cfg.physics.contact_prediction;
    if given > 0.0 {
        return given;
    }
    let substep = cfg.physics.dt / cfg.physics.substeps as f32;
    (1.25 * 2.0 * cfg.robot.max_wheel_speed.max() * substep).max(0.02)
}

impl World {
    /// A world of `n_robots` robots in `scene` on `floor`, configured by `cfg`.
    pub fn new(cfg: &Scenario, scene: Scene, floor: SharedFloor, n_robots: usize) -> Self {
        let drive = Drive::from_config(&cfg.robot, &cfg.motors);
        let physics = Physics::new(
            &scene,
            PhysicsParams {
                n_robots,
                radius: drive.radius,
                mass: cfg.robot.mass.bounds().0,
                friction: cfg.physics.friction.bounds().0,
                robot_friction: cfg.physics.robot_friction.bounds().0,
                substep_dt: cfg.physics.dt / cfg.physics.substeps as f32,
                solver_iterations: cfg.physics.solver_iterations as usize,
                traction: cfg.physics.drive == DriveModel::Traction,
                contact_prediction: contact_prediction(cfg),
            },
        );
        Self {
            drive,
            sensors: Suite::new(&cfg.sensors),
            scene,
            floor,
            floor_marks: FloorMarks::default(),
            robots: vec![Robot::default(); n_robots],
            rng: ChaCha8Rng::seed_from_u64(0),
            physics,
            dt: cfg.physics.dt,
            substeps: cfg.physics.substeps,
            drive_model: cfg.physics.drive,
            split_robots: cfg.physics.split == MotionSplit::Robot,
            whole_step_arc: cfg.physics.whole_step_arc,
            slip_by_tyres: cfg.physics.slip_solver == SlipSolver::Tyres,
            scene_by_disc: cfg.physics.scene_solver == SceneSolver::Disc,
            tyre_friction: cfg.robot.tyre_friction.bounds().0,
            robot_reflectance: cfg.robot.shell_reflectance,
            robot_led: cfg.robot.led_color,
            odometry: cfg.task.localization == Localization::Odometry,
            bodies: Vec::with_capacity(n_robots),
            traction: Vec::with_capacity(n_robots),
            others: Vec::with_capacity(n_robots),
            other_leds: Vec::with_capacity(n_robots),
            grid: Grid::default(),
            contact_grid: Grid::default(),
            speeds: Vec::new(),
            positions: Vec::new(),
            active: Vec::new(),
            start: Vec::new(),
            missed: Vec::new(),
            touching: Vec::new(),
            team: team::Team::default(),
            grid_min_robots: GRID_MIN_ROBOTS,
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
        self.drive.wheel_accel_limit = cfg.wheel_accel().sample(rng);
        self.sensors.randomise(&cfg.sensors, rng);
        if r.mass.is_random() {
            let mass = r.mass.sample(rng);
            self.physics.set_mass(mass);
        }
        if self.drive_model == DriveModel::Traction {
            // Drawn only by the traction model, so that v0 scenarios keep their random streams.
            self.tyre_friction = r.tyre_friction.sample(rng);
            let wall = cfg.physics.friction.sample(rng);
            let robot = cfg.physics.robot_friction.sample(rng);
            self.physics.set_friction(wall, robot);
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
            led: self.robot_led,
            ..Robot::default()
        };
    }

    /// Starts every robot's dead reckoning from its true pose, with this episode's calibration
    /// errors (drawn from the world's stream only when the scenario uses odometry).
    pub fn start_odometry(&mut self, cfg: &Scenario) {
        if !self.odometry {
            return;
        }
        let axle = self.drive.axle_length;
        for r in &mut self.robots {
            r.odometry = Odometry::start(r.position, r.heading, axle, &cfg.odometry, &mut self.rng);
        }
    }

    /// Advances every robot's dead reckoning by the last step: its encoders' travel and, when
    /// it carries one, its gyroscope's reading.
    pub fn update_odometry(&mut self, cfg: &Scenario) {
        if !self.odometry {
            return;
        }
        for r in &mut self.robots {
            let gyro = self.sensors.gyro.as_ref().map(|_| r.readings.gyro.rate);
            r.odometry
                .update(r.wheel_travel, gyro, self.dt, &cfg.odometry, &mut self.rng);
        }
    }

    /// Where robot `i` believes it is (centre, heading): its dead reckoning with
    /// `localization = "odometry"`, else its true pose (an external tracker).
    #[inline]
    pub fn believed_pose(&self, i: usize) -> (Vector, f32) {
        let r = &self.robots[i];
        if self.odometry {
            (r.odometry.position, r.odometry.heading)
        } else {
            (r.position, r.heading)
        }
    }

    /// Builds this world's rapier side now rather than at the first substep that needs it
    /// (what worlds did before issue 54; the tests compare both ways).
    pub fn build_physics_now(&mut self) {
        self.physics.build_now();
    }

    /// Whether this world's rapier side has been built (some substep needed it).
    pub fn physics_built(&self) -> bool {
        self.physics.is_built()
    }

    /// Heap bytes this world's rapier side would still take if a substep needed it: 0 once
    /// built (see [`Physics`]).
    pub fn unbuilt_physics_bytes(&self) -> u64 {
        if self.physics.is_built() {
            0
        } else {
            self.physics.built_bytes(&self.scene)
        }
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

    /// Whether to share this world's robots among the threads of the rayon pool it runs in: a
    /// swarm (more than `grid_min_robots` robots) stepped inside a batch's pool. The results are
    /// the same either way, since each robot's share of the work depends only on the world's
    /// state.
    pub(super) fn share_robots(&self) -> bool {
        self.robots.len() > self.grid_min_robots && rayon::current_thread_index().is_some()
    }

    /// The team a step of this world runs in ([`StepTeam::scope`]): a swarm inside a batch's
    /// pool keeps the pool's other threads for its passes meanwhile (`team.rs`), instead of
    /// waking them pass by pass; any other world runs on its caller's thread alone. The
    /// results are the same either way.
    pub fn step_team(&self) -> StepTeam {
        StepTeam {
            team: self.share_robots().then(|| self.team.share()),
            robots: self.robots.len(),
        }
    }

    /// Reads every robot's sensors (with noise from the world's stream), robot after robot; a
    /// swarm (more than [`GRID_MIN_ROBOTS`] robots) reads them as [`World::sense_swarm`] says.
    /// `fresh` (at reset) makes every sensor take a new reading, whatever its refresh period.
    pub fn sense(&mut self, fresh: bool) {
        if self.robots.len() > GRID_MIN_ROBOTS {
            self.sense_swarm(fresh);
            return;
        }
        let world = surroundings!(self, fresh);
        for i in 0..self.robots.len() {
            self.others.clear();
            self.other_leds.clear();
            for (j, other) in self.robots.iter().enumerate() {
                if j != i {
                    self.others.push(other.position);
                    self.other_leds.push(other.led);
                }
            }
            let robot = &mut self.robots[i];
            let ctx = SenseContext::new(
                world,
                robot.position,
                robot.heading,
                robot.yaw_rate,
                robot.acceleration,
            )
            .seeing(&self.others, &self.other_leds, &[]);
            self.sensors.read(&ctx, &mut self.rng, &mut robot.readings);
        }
    }
}
