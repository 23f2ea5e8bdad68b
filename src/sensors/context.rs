//! What a sensor sees of its world when one robot reads it ([`SenseContext`]), built in one
//! place from the world's side ([`Surroundings`]) and the robot's own motion; and the test
//! fixture the sensors' tests read in.
//!
//! Units: metres, seconds, radians; positions in the world frame, the acceleration in the robot
//! frame (x forward, y left).

use rapier2d::math::Vector;

use crate::geometry::floor::{Floor, FloorMarks};
use crate::geometry::scene::Scene;

/// What a sensor sees of its world when one robot reads it.
pub struct SenseContext<'a> {
    /// The static scene (walls and obstacles).
    pub scene: &'a Scene,
    /// The robot's centre (m).
    pub position: Vector,
    /// sin and cos of its heading.
    pub sin_cos: (f32, f32),
    /// Body radius of every robot (m); sensors sit on the rim.
    pub radius: f32,
    /// Centres of the other robots of the world (m): all of them in robot order, or in a
    /// world of many robots those within the suite's [`Sensor::reach`], in any order.
    pub others: &'a [Vector],
    /// Their LED colours (RGB in [0, 1]), in the same order: what a camera sees of them.
    pub other_leds: &'a [[f32; 3]],
    /// Their indices in the world, in the same order, when `others` is not in robot order (a
    /// swarm's grid finds them cell by cell); empty when it is. Readings must not depend on
    /// the order: where two robots are met at exactly the same distance, the one of larger
    /// index is hit, as a scan in robot order gives ([`Scene::cast_hit`]).
    pub other_ids: &'a [u32],
    /// Infrared reflectance of the robots' shells (relative to white paper).
    pub robot_reflectance: f32,
    /// The robot's yaw rate over the last step (rad/s).
    pub yaw_rate: f32,
    /// The body's planar acceleration around the start of the last step, in the robot frame
    /// (m/s²); kept only while the robot carries the IMU, else zero.
    pub acceleration: Vector,
    /// The scenario's floor (for the ground sensors).
    pub floor: &'a Floor,
    /// The task's marks on it this episode.
    pub floor_marks: &'a FloorMarks,
    /// The control step (s): the time since the sensors were last read.
    pub dt: f32,
    /// A new episode: every sensor takes a new reading, whatever its refresh period.
    pub fresh: bool,
}

/// What every robot of a world sees alike when it reads its sensors: the world's side of a
/// [`SenseContext`].
#[derive(Clone, Copy)]
pub struct Surroundings<'a> {
    /// The static scene (walls and obstacles).
    pub scene: &'a Scene,
    /// The scenario's floor (for the ground sensors).
    pub floor: &'a Floor,
    /// The task's marks on it this episode.
    pub floor_marks: &'a FloorMarks,
    /// Body radius of every robot (m).
    pub radius: f32,
    /// Infrared reflectance of the robots' shells (relative to white paper).
    pub robot_reflectance: f32,
    /// The control step (s).
    pub dt: f32,
    /// A new episode: every sensor takes a new reading.
    pub fresh: bool,
}

impl<'a> SenseContext<'a> {
    /// The context of one robot of `world` at `position` (m) heading `heading` (rad), which
    /// turned at `yaw_rate` (rad/s) and accelerated by `acceleration` (m/s², robot frame) over
    /// the last step; it sees no other robot until [`SenseContext::seeing`].
    #[inline]
    pub fn new(
        world: Surroundings<'a>,
        position: Vector,
        heading: f32,
        yaw_rate: f32,
        acceleration: Vector,
    ) -> Self {
        Self {
            scene: world.scene,
            position,
            sin_cos: heading.sin_cos(),
            radius: world.radius,
            others: &[],
            other_leds: &[],
            other_ids: &[],
            robot_reflectance: world.robot_reflectance,
            yaw_rate,
            acceleration,
            floor: world.floor,
            floor_marks: world.floor_marks,
            dt: world.dt,
            fresh: world.fresh,
        }
    }

    /// The same context seeing the other robots centred at `others` with LEDs `leds`, whose
    /// indices are `ids` (empty when `others` is in robot order; see the fields).
    #[inline]
    pub fn seeing(self, others: &'a [Vector], leds: &'a [[f32; 3]], ids: &'a [u32]) -> Self {
        Self {
            others,
            other_leds: leds,
            other_ids: ids,
            ..self
        }
    }
}

impl SenseContext<'_> {
    /// `v` (robot frame) rotated into the world frame.
    #[inline]
    pub fn to_world(&self, v: Vector) -> Vector {
        let (s, c) = self.sin_cos;
        Vector::new(c * v.x - s * v.y, s * v.x + c * v.y)
    }
}

/// A sensor test's surroundings: an empty 2 m × 2 m arena (walls 0.05 m thick), a plain
/// floor, robots of radius 0.07 m with white shells, a 0.05 s step, no new episode.
#[cfg(test)]
pub(crate) struct TestSurroundings {
    scene: Scene,
    floor: Floor,
    floor_marks: FloorMarks,
}

#[cfg(test)]
impl TestSurroundings {
    /// The fixture.
    pub(crate) fn new() -> Self {
        Self {
            scene: Scene::arena(2.0, 2.0, 0.05),
            floor: Floor::default(),
            floor_marks: FloorMarks::default(),
        }
    }

    /// The context of a robot at the arena's centre heading along x, turning at `yaw_rate`
    /// (rad/s) and accelerating by `acceleration` (m/s², robot frame), alone in the arena.
    pub(crate) fn context(&self, yaw_rate: f32, acceleration: Vector) -> SenseContext<'_> {
        let world = Surroundings {
            scene: &self.scene,
            floor: &self.floor,
            floor_marks: &self.floor_marks,
            radius: 0.07,
            robot_reflectance: 1.0,
            dt: 0.05,
            fresh: false,
        };
        SenseContext::new(world, Vector::ZERO, 0.0, yaw_rate, acceleration)
    }
}
