//! The rapier2d side of a world: fixed colliders for the scene, one dynamic disc per robot.
//!
//! Robots are dynamic bodies whose planar velocity is set from the wheel commands before each
//! rapier step; rapier's solver then resolves robot–wall, robot–obstacle and robot–robot
//! contacts (a robot pushed into a wall stops or slides). The world is built once and bodies
//! are teleported (set_position) rather than rebuilt. Gravity is zero (the plane is the floor);
//! sleeping and CCD are off, so a step depends only on the state we set.
//!
//! Units: metres, seconds, radians, m/s, rad/s; world frame, arena centred at the origin.

use rapier2d::math::{Pose, Vector};
use rapier2d::prelude::{
    ColliderBuilder, ColliderHandle, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
};

use super::scene::{Geometry, Scene};

/// Rapier state of one world. It serialises whole (bodies, colliders, broad phase, contact
/// manifolds with their warm-start impulses), so a restored world steps bit for bit as the
/// original.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Physics {
    world: PhysicsWorld,
    robots: Vec<RigidBodyHandle>,
    /// What the world was built with, to build it again for a new scene.
    params: PhysicsParams,
}

#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct PhysicsParams {
    n_robots: usize,
    radius: f32,
    mass: f32,
    friction: f32,
    substep_dt: f32,
    solver_iterations: usize,
}

/// A robot's planar state as the physics step sees it.
#[derive(Debug, Clone, Copy)]
pub struct BodyState {
    /// Centre (m).
    pub position: Vector,
    /// Heading (rad).
    pub heading: f32,
    /// Forward speed (m/s) and yaw rate (rad/s) commanded for this substep.
    pub twist: (f32, f32),
}

impl Physics {
    /// Builds the rapier world for `scene` with `n_robots` discs of `radius` and `mass`.
    pub fn new(
        scene: &Scene,
        n_robots: usize,
        radius: f32,
        mass: f32,
        friction: f32,
        substep_dt: f32,
        solver_iterations: usize,
    ) -> Self {
        Self::build(
            scene,
            PhysicsParams {
                n_robots,
                radius,
                mass,
                friction,
                substep_dt,
                solver_iterations,
            },
        )
    }

    fn build(scene: &Scene, params: PhysicsParams) -> Self {
        let mut world = PhysicsWorld {
            gravity: Vector::ZERO,
            ..PhysicsWorld::default()
        };
        world.integration_parameters.dt = params.substep_dt;
        world.integration_parameters.num_solver_iterations = params.solver_iterations;
        let robots = (0..params.n_robots)
            .map(|i| {
                let body = RigidBodyBuilder::dynamic()
                    .translation(Vector::new(i as f32, 0.0))
                    .can_sleep(false)
                    .ccd_enabled(false);
                let collider = ColliderBuilder::ball(params.radius)
                    .mass(params.mass)
                    .friction(params.friction)
                    .restitution(0.0);
                world.insert(body, collider).0
            })
            .collect();
        for shape in scene.walls().iter().chain(&scene.shapes) {
            let builder = match shape.geometry {
                Geometry::Circle(b) => ColliderBuilder::ball(b.radius),
                Geometry::Box(c) => ColliderBuilder::cuboid(c.half_extents.x, c.half_extents.y),
                Geometry::Segment(s) => ColliderBuilder::segment(s.a, s.b),
            };
            let collider = builder
                .position(Pose::new(shape.center, shape.angle))
                .friction(params.friction)
                .restitution(0.0);
            world.colliders.insert(collider);
        }
        Self {
            world,
            robots,
            params,
        }
    }

    /// Sets every robot's mass (kg).
    pub fn set_mass(&mut self, mass: f32) {
        self.params.mass = mass;
        for handle in &self.robots {
            let colliders: Vec<ColliderHandle> = self
                .world
                .bodies
                .get(*handle)
                .map(|b| b.colliders().to_vec())
                .unwrap_or_default();
            for c in colliders {
                if let Some(collider) = self.world.colliders.get_mut(c) {
                    collider.set_mass(mass);
                }
            }
        }
    }

    /// Replaces the fixed colliders with `scene`'s shapes. The rapier world is built anew (robots
    /// included; the caller places them): removing and inserting colliders in place left rapier's
    /// pending-removal lists and broad phase growing by ~35 bytes per episode, since the removals
    /// are only processed by a rapier step, which an episode without contacts never takes.
    pub fn set_scene(&mut self, scene: &Scene) {
        *self = Self::build(scene, self.params);
    }

    /// One rapier substep: sets every robot's pose and velocity, steps, and writes the resolved
    /// poses back into `states`.
    pub fn step(&mut self, states: &mut [BodyState]) {
        for (state, handle) in states.iter().zip(&self.robots) {
            if let Some(body) = self.world.bodies.get_mut(*handle) {
                let (v, w) = state.twist;
                let (s, c) = state.heading.sin_cos();
                body.set_position(Pose::new(state.position, state.heading), true);
                body.set_linvel(Vector::new(v * c, v * s), true);
                body.set_angvel(w, true);
            }
        }
        self.world.step();
        for (state, handle) in states.iter_mut().zip(&self.robots) {
            if let Some(body) = self.world.bodies.get(*handle) {
                let pose = body.position();
                state.position = pose.translation;
                state.heading = pose.rotation.angle();
            }
        }
    }
}
