//! The shared sections of a scenario that belong to no other module: `[arena]`, `[obstacles]`,
//! `[spawn]`, `[task]` and `[physics]`, each declared once with [`crate::config_table!`] (key,
//! default, units, comment), and the checks of `[obstacles]`. The other shared sections are
//! declared by their owners (`[robot]` in `robot.rs`, `[sensors]` by each sensor in `sensors/`);
//! the checks that relate several sections are in `scenario/mod.rs`. They are plain data: the
//! world turns `[arena]` and `obstacles.fixed` into geometry (`world/scenery.rs`).
//!
//! Units: metres, seconds, radians, m/s. Frame: the world frame, origin at the arena's centre,
//! x right, y up, angles CCW from +x.

use serde::{Deserialize, Serialize};
use toml::Value;

use crate::config::{limits, Domain, Field, Param};
use crate::error::{Error, Result};

crate::config_table! {
    /// `[arena]`: the rectangle, centred at the origin, walled or open.
    pub struct ArenaConfig {
        /// m, inner size along x (arena centred at the origin)
        width: f32 = 2.0 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, inner size along y
        height: f32 = 2.0 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, walls lie outside the inner rectangle
        wall_thickness: f32 = 0.05 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// false: an open floor (the size then only bounds spawning)
        walls: bool = true,
        /// infrared reflectance of the walls relative to white paper (1 = K-Team's curve) [E]
        wall_reflectance: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::REFLECTANCE),
        /// RGB in [0, 1] of the walls for the camera (a light grey)
        wall_color: [f32; 3] = [0.8, 0.8, 0.8] => Domain::UNIT,
    }
}

/// Most random obstacles (`obstacles.count`).
pub const MAX_RANDOM_OBSTACLES: u32 = 64;

/// Largest action or observation delay (control steps): 5 s at the default 50 ms, far beyond
/// the real robot's latencies; each pending step keeps an observation per world.
pub const MAX_DELAY_STEPS: u32 = 100;

/// A coordinate (m): finite and within [`limits::LENGTH`] of the origin.
const COORDINATE: Domain = Domain::range(-limits::LENGTH, limits::LENGTH);

/// The fields of an `obstacles.fixed` entry and their domains.
const OBSTACLE_FIELDS: &[Field] = &[
    Field::new("center", "[f32; 2]", COORDINATE),
    Field::new("radius", "f32", Domain::POSITIVE.at_most(limits::LENGTH)),
    Field::new(
        "half_extents",
        "[f32; 2]",
        Domain::POSITIVE.at_most(limits::LENGTH),
    ),
    Field::new("angle", "f32", Domain::FINITE),
    Field::new("a", "[f32; 2]", COORDINATE),
    Field::new("b", "[f32; 2]", COORDINATE),
    Field::new(
        "reflectance",
        "f32",
        Domain::NON_NEGATIVE.at_most(limits::REFLECTANCE),
    ),
    Field::new("color", "[f32; 3]", Domain::UNIT),
];

/// A fixed obstacle of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObstacleSpec {
    /// A disc.
    Circle {
        center: [f32; 2],
        radius: f32,
        #[serde(default = "white", skip_serializing_if = "is_white")]
        reflectance: f32,
        /// RGB in [0, 1] for the camera; grey when not given.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        color: Option<[f32; 3]>,
    },
    /// A rectangle rotated by `angle` (rad).
    Box {
        center: [f32; 2],
        half_extents: [f32; 2],
        #[serde(default)]
        angle: f32,
        #[serde(default = "white", skip_serializing_if = "is_white")]
        reflectance: f32,
        /// RGB in [0, 1] for the camera; grey when not given.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        color: Option<[f32; 3]>,
    },
    /// A thin wall from `a` to `b`.
    Segment {
        a: [f32; 2],
        b: [f32; 2],
        #[serde(default = "white", skip_serializing_if = "is_white")]
        reflectance: f32,
        /// RGB in [0, 1] for the camera; grey when not given.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        color: Option<[f32; 3]>,
    },
}

/// The infrared reflectance of white paper, the surface of K-Team's response curve.
fn white() -> f32 {
    1.0
}

fn is_white(reflectance: &f32) -> bool {
    *reflectance == 1.0
}

impl ObstacleSpec {
    /// Its colour, if given.
    pub fn color(&self) -> Option<[f32; 3]> {
        match *self {
            ObstacleSpec::Circle { color, .. }
            | ObstacleSpec::Box { color, .. }
            | ObstacleSpec::Segment { color, .. } => color,
        }
    }
}

/// Shapes the random obstacle generator draws from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ObstacleKind {
    Circle,
    Box,
    Segment,
}

/// Where random obstacles go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Placement {
    /// Centred in a corridor along the start–goal segment.
    Between,
    /// Anywhere in the arena.
    Anywhere,
}

crate::config_table! {
    /// `[obstacles]`: a fixed list and/or a random generator run at every reset. Fixed ones are
    /// e.g. `{kind = "circle", center = [0.3, 0.0], radius = 0.1}`,
    /// `{kind = "box", center = [x, y], half_extents = [hx, hy], angle = 0.0}`,
    /// `{kind = "segment", a = [x0, y0], b = [x1, y1]}`.
    pub struct ObstacleConfig {
        /// fixed obstacles: circle {center, radius}, box {center, half_extents, angle}, segment {a, b}
        fixed: Vec<ObstacleSpec> = [] => Domain::tables(OBSTACLE_FIELDS),
        /// random obstacles drawn at every reset
        count: u32 = 0 => Domain::range(0.0, MAX_RANDOM_OBSTACLES as f64),
        /// shapes the random ones are drawn from
        kinds: Vec<ObstacleKind> = ["circle", "box", "segment"],
        /// m, range of random circle radii
        circle_radius: [f32; 2] = [0.04, 0.10] => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, range of random box half sides
        box_half_extent: [f32; 2] = [0.03, 0.10] => Domain::POSITIVE.at_most(limits::LENGTH),
        /// m, range of random wall-segment lengths
        segment_length: [f32; 2] = [0.20, 0.45] => Domain::POSITIVE.at_most(limits::LENGTH),
        /// "between" start and goal, or "anywhere"
        placement: Placement = "between",
        /// m, width of the band around start->goal used by "between"
        corridor_width: f32 = 0.8 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// m, free gap between random obstacles, walls and fixed obstacles (>= robot diameter + 1 cm keeps every goal reachable)
        min_gap: f32 = 0.16 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// m, free gap between obstacles and robots at their start and goals
        spawn_clearance: f32 = 0.05 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
    }
}

impl ObstacleConfig {
    /// Checks the entries of the raw `obstacles.fixed` list one by one, before the table is read
    /// whole: serde's errors inside a tagged list entry carry no position, and the message should
    /// say which entry.
    pub(super) fn check_fixed_entries(fixed: &[Value], origin: &str) -> Result<()> {
        for (i, entry) in fixed.iter().enumerate() {
            entry.clone().try_into::<ObstacleSpec>().map_err(|e| {
                Error::config(origin, &format!("obstacles.fixed[{i}]"), e.message().trim())
            })?;
        }
        Ok(())
    }

    /// Checks what the keys' domains cannot (each number alone is checked by its declaration):
    /// a fixed segment's length, the order of the size ranges, the shapes and the gap of the
    /// generator; the error names the first offending key. `robot_radius` (m) bounds `min_gap`
    /// from below, so that random obstacles never wall off a goal. Whether layouts fit is
    /// checked by `world::layout::Spawner::new`.
    pub fn validate(&self, origin: &str, robot_radius: f32) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        let o = self;
        for (i, spec) in o.fixed.iter().enumerate() {
            if let ObstacleSpec::Segment { a, b, .. } = spec {
                if ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt() <= 0.0 {
                    return bad(
                        &format!("obstacles.fixed[{i}]"),
                        format!("a segment needs two different ends: {spec:?}"),
                    );
                }
            }
        }
        for (key, [lo, hi]) in [
            ("obstacles.circle_radius", o.circle_radius),
            ("obstacles.box_half_extent", o.box_half_extent),
            ("obstacles.segment_length", o.segment_length),
        ] {
            if lo > hi {
                return bad(
                    key,
                    format!("must be a range [low, high] with low <= high, got [{lo}, {hi}]"),
                );
            }
        }
        if o.count > 0 {
            if o.kinds.is_empty() {
                return bad(
                    "obstacles.kinds",
                    "must name at least one shape when count > 0".into(),
                );
            }
            let needed = 2.0 * robot_radius + 0.01;
            if o.min_gap < needed {
                return bad(
                    "obstacles.min_gap",
                    format!(
                        "must be >= the robot's diameter + 1 cm ({needed:.3} m) so that random \
                         obstacles never wall off a goal, got {}",
                        o.min_gap
                    ),
                );
            }
        }
        Ok(())
    }
}

crate::config_table! {
    /// `[spawn]`: where robots start and goals lie.
    pub struct SpawnConfig {
        /// m, gap between a spawned robot (or goal) and the walls
        wall_margin: f32 = 0.05 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// m, start-goal distance at reset is at least this
        min_goal_distance: f32 = 0.5 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// [] random, or [x, y, heading] (m, m, rad) to fix it
        start: Vec<f32> = [] => Domain::range(-limits::LENGTH, limits::LENGTH),
        /// [] random, or [x, y] (m) to fix it
        goal: Vec<f32> = [] => Domain::range(-limits::LENGTH, limits::LENGTH),
    }
}

crate::config_table! {
    /// `[task]`: goal, reward weights, episode length.
    pub struct TaskConfig {
        /// m, success when the robot centre is this close to the goal
        goal_radius: f32 = 0.05 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// control steps before truncation (20 s at dt = 0.05)
        max_steps: u32 = 400 => Domain::at_least(1.0),
        /// reward per metre of progress toward the goal
        progress_weight: f32 = 10.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward subtracted every step
        time_cost: f32 = 0.01 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward on reaching the goal
        success_bonus: f32 = 10.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// reward subtracted per step in contact with a wall or obstacle
        collision_penalty: f32 = 0.1 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
        /// end the episode at the first contact
        terminate_on_collision: bool = false,
        /// where the goal's distance and bearing come from: "ground_truth" (an external tracker) or "odometry" (the robot's dead reckoning from its encoders and gyroscope, what it can compute on board)
        localization: Localization = "ground_truth",
        /// control steps between an action and the wheels receiving it (0 = none)
        action_delay: u32 = 0 => Domain::range(0.0, MAX_DELAY_STEPS as f64),
        /// control steps between the world and the observation showing it (0 = none)
        observation_delay: u32 = 0 => Domain::range(0.0, MAX_DELAY_STEPS as f64),
        /// whether each agent also sets its robot's top LEDs: three more action values (red, green, blue in [-1, 1], to 0..63 per colour, the real LEDs' 6 bits, robot.md §6) after its two wheel values; the camera sees the colour from the next observation on
        led_action: bool = false,
    }
}

/// Where a robot's idea of its own pose comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Localization {
    /// The true pose (an external tracker, as in the KH4VREP paper's V-REP scenes).
    GroundTruth,
    /// Dead reckoning from the wheel encoders and the gyroscope, with calibration errors.
    Odometry,
}

crate::config_table! {
    /// `[physics]`: control step and rapier settings.
    pub struct PhysicsConfig {
        /// s per control step (V-REP's default)
        dt: f32 = 0.05 => Domain::POSITIVE.at_most(1.0),
        /// physics substeps per control step: 2 (25 ms) keeps poses within millimetres of 16 substeps over a second of wall contact (tests/dynamics.rs); v0: 4
        substeps: u32 = 2 => Domain::range(1.0, 64.0),
        /// rapier solver iterations for contact steps
        solver_iterations: u32 = 4 => Domain::range(1.0, 64.0),
        /// "traction": the body is driven by its tyres' grip (bounded force) and resisted by friction in contacts; "kinematic": its velocity is imposed (v0)
        drive: DriveModel = "traction",
        /// shell-wall and shell-obstacle friction coefficient [S: ARGoS's Khepera IV model, 0.7]; 0 lets a robot slide along walls; may be a range
        friction: Param = 0.7 => Domain::NON_NEGATIVE.at_most(limits::FRICTION),
        /// shell-shell friction coefficient between robots [S: ARGoS, 0.7]; may be a range
        robot_friction: Param = 0.7 => Domain::NON_NEGATIVE.at_most(limits::FRICTION),
        /// which robots rapier steps while something can be touched or a tyre slips (traction drive): "world" steps them all (v1); "robot" only those that can touch something or slip, the others rolling on exact arcs (faster in swarms, and exact for them)
        split: MotionSplit = "world",
        /// split = "robot" only: true lets a world whose robots all keep their wheel speeds, grip and can touch nothing roll each one arc over the whole step (v1; a free robot's path then depends in its last bits on whether other robots were in contact); false rolls them substep by substep, each robot's path its own
        whole_step_arc: bool = false,
        /// m: rapier makes a contact when two shapes come this close, before they touch; 0 = 1.25 x what two robots at full speed close in one substep (2 x 0.813 m/s x 25 ms: 5.1 cm at the defaults), at least rapier's default 0.02, so that such an impact meets its contact before the robots overlap (v1: 0.02, and head-on impacts at full speed overlapped by up to 1 cm)
        contact_prediction: f32 = 0.0 => Domain::range(0.0, 1.0),
        /// traction drive: a world where a robot slips (its body not yet rolling on its wheels, after a contact) but nothing can be touched: "tyres" moves each slipping robot by its tyres' impulses directly, as rapier moves a free body (v2); "rapier" hands the whole world to rapier's step as for a contact (v1; the same motion at rapier's cost)
        slip_solver: SlipSolver = "tyres",
        /// traction drive, split = "world": a substep in which robots can touch walls or obstacles but no robot can touch another: "disc" solves each robot's contacts with the scene directly, as a rigid disc with Coulomb friction and no restitution (src/world/scene_contacts.rs, docs/dynamics.md; v3); "rapier" hands the whole world to rapier's step (v0 to v2). Contacts between robots always go to rapier, and so do a split = "robot" world's robots that can touch anything
        scene_solver: SceneSolver = "disc",
    }
}

/// Who solves a robot's contacts with the scene while no robot can touch another.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneSolver {
    /// Each robot as a rigid disc against the shapes within its reach (v3).
    Disc,
    /// Rapier's step of the whole world (v0 to v2).
    Rapier,
}

/// Who moves a slipping robot that can touch nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SlipSolver {
    /// Its tyres' impulses, integrated directly (v2).
    Tyres,
    /// Rapier's step of the whole world (v1).
    Rapier,
}

/// Which robots a contact substep hands to rapier.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MotionSplit {
    /// Every robot of the world, as soon as one can touch something or slips (v1).
    World,
    /// Only the robots that can touch something or slip; the others roll on exact arcs.
    Robot,
}

/// How the drive moves a robot's body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DriveModel {
    /// Wheels grip the floor with bounded force; contacts push back with friction.
    Traction,
    /// The body's velocity is set from the wheels every substep (the v0 model).
    Kinematic,
}
