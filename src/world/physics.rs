//! The rapier2d side of a world: fixed colliders for the scene, one dynamic disc per robot.
//!
//! Two drive models. `kinematic` (v0): each robot's planar velocity is set from its wheels
//! before each rapier step, and the solver resolves the contacts (a robot pushed into a wall
//! stops or slides). `traction` (v1): each wheel grips the floor with a bounded impulse — the one
//! that would cancel the wheel's slip, clamped to the tyre's friction circle μ_t·N·h with N half
//! the robot's weight — so the drive force is finite; rapier then resolves the contacts with
//! Coulomb friction (shell–wall and shell–shell coefficients set per pair by a contact hook).
//! Pushing into a wall slows the robot by friction and turns it, a blocked robot's wheels slip,
//! a robot at rest resists being shoved with its tyres' grip. The world is built once and bodies
//! are teleported (set_position) rather than rebuilt. Gravity is zero (the plane is the floor;
//! the weight only sets the tyres' grip); sleeping and CCD are off, so a step depends only on
//! the state we set.
//!
//! Units: metres, seconds, radians, m/s, rad/s; world frame, arena centred at the origin.

use std::cell::RefCell;

use rapier2d::math::{Pose, Vector};
use rapier2d::prelude::{
    ActiveHooks, ColliderBuilder, ColliderHandle, ContactModificationContext, PhysicsHooks,
    PhysicsPipeline, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle,
};

use super::team::{Team, CHUNK};
use super::tyres::{tyre_impulses, Grip, TractionBody, GRAVITY};
use crate::geometry::scene::{Geometry, Scene};

/// Rapier state of one world. It serialises whole (bodies, colliders, broad phase, contact
/// manifolds with their warm-start impulses), so a restored world steps bit for bit as the
/// original.
///
/// The rapier world is built at the first substep that needs it, not with the world: a Nav
/// world of v3 never needs it (one robot, its contacts with the scene solved as a disc's), and
/// its rapier sets were two thirds of a world's memory (21 KiB of 31; issue 54). Building it
/// then is building it at construction: nothing reads or changes a rapier world before its
/// first step but `set_mass` and `set_friction`, whose values the build takes from `params`
/// (a collider built with a mass and friction is one given them later: rapier stores them
/// and derives the body's mass at the step), and `set_scene`, which builds anew. Saved, an
/// unbuilt world is written as the world it would build, so the state's format is unchanged.
pub struct Physics {
    rapier: Rapier,
    /// What the world is built with, to build it (again, for a new scene).
    params: PhysicsParams,
    /// Scratch of `step_traction`: the pose, velocity and yaw rate to hand to rapier of each
    /// body taking part in the substep, in robot order.
    targets: Vec<Target>,
}

/// A body's pose, velocity and yaw rate for rapier's next step.
type Target = (Pose, Vector, f32);

/// A world's rapier side: not built yet (the scene to build it for), or built.
enum Rapier {
    Unbuilt(Scene),
    Built(Box<Built>),
}

/// A built rapier world: the bodies and colliders, and each robot's body.
struct Built {
    world: PhysicsWorld,
    robots: Vec<RigidBodyHandle>,
    /// Whether each robot's body is enabled in rapier, as rapier holds it: a swarm split by
    /// robot leaves most bodies disabled, and reading this costs a byte a robot where asking
    /// rapier reads each body's large struct.
    enabled: Vec<bool>,
}

impl Built {
    /// `world` with the robots' `robots`, as saved.
    fn of(world: PhysicsWorld, robots: Vec<RigidBodyHandle>) -> Self {
        let enabled = robots
            .iter()
            .map(|h| world.bodies.get(*h).is_some_and(|b| b.is_enabled()))
            .collect();
        Self {
            world,
            robots,
            enabled,
        }
    }
}

/// What a [`Physics`] saves (the fields it had when it was built with the world, in the same
/// order, so that states keep their format).
#[derive(serde::Serialize)]
struct SavedRef<'a> {
    world: &'a PhysicsWorld,
    robots: &'a [RigidBodyHandle],
    params: &'a PhysicsParams,
}

/// What a [`Physics`] loads ([`SavedRef`]'s fields).
#[derive(serde::Deserialize)]
struct Saved {
    world: PhysicsWorld,
    robots: Vec<RigidBodyHandle>,
    params: PhysicsParams,
}

impl serde::Serialize for Physics {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let save = |built: &Built| {
            SavedRef {
                world: &built.world,
                robots: &built.robots,
                params: &self.params,
            }
            .serialize(serializer)
        };
        match &self.rapier {
            Rapier::Built(built) => save(built),
            Rapier::Unbuilt(scene) => save(&Built::new(scene, &self.params)),
        }
    }
}

impl<'de> serde::Deserialize<'de> for Physics {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let saved = Saved::deserialize(deserializer)?;
        Ok(Self {
            rapier: Rapier::Built(Box::new(Built::of(saved.world, saved.robots))),
            params: saved.params,
            targets: Vec::new(),
        })
    }
}

thread_local! {
    /// Rapier's pipeline, one per thread for every world stepped on it. It is workspace only
    /// (solver buffers, broad-phase events; rapier does not serialise it, and a restored world,
    /// with a new one, steps bit for bit as the original), so which one steps a world does not
    /// change the results. One per world went cold between a world's contacts: in a batch of
    /// 1,024 worlds each contact step read its world's buffers from memory. The one memo it
    /// keeps across steps, the joint selection, is empty in every world (no joints); a world
    /// with joints would need a pipeline of its own.
    static PIPELINE: RefCell<PhysicsPipeline> = RefCell::new(PhysicsPipeline::new());
}

/// One rapier step of `world` through this thread's pipeline.
fn step_world(world: &mut PhysicsWorld, hooks: &dyn PhysicsHooks) {
    debug_assert!(world.impulse_joints.is_empty());
    PIPELINE.with_borrow_mut(|pipeline| {
        pipeline.step(
            world.gravity,
            &world.integration_parameters,
            &mut world.islands,
            &mut world.broad_phase,
            &mut world.narrow_phase,
            &mut world.bodies,
            &mut world.colliders,
            &mut world.impulse_joints,
            &mut world.multibody_joints,
            &mut world.soft_bodies,
            &mut world.ccd_solver,
            hooks,
            &(),
        );
    });
}

/// What a world's rapier side is built with.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct PhysicsParams {
    /// Robots in the world.
    pub n_robots: usize,
    /// Body radius (m).
    pub radius: f32,
    /// Robot mass (kg).
    pub mass: f32,
    /// Shell–wall and shell–obstacle friction coefficient.
    pub friction: f32,
    /// Shell–shell friction coefficient (traction model).
    pub robot_friction: f32,
    /// Substep length (s).
    pub substep_dt: f32,
    /// Solver iterations per substep.
    pub solver_iterations: usize,
    /// The traction model (else the kinematic one).
    pub traction: bool,
    /// Distance (m) within which rapier makes contacts ahead of touching (its length unit is 1 m).
    pub contact_prediction: f32,
}

/// Sets each contact's friction by what touches: another robot, or a wall or obstacle.
struct PairFriction {
    wall: f32,
    robot: f32,
}

impl PhysicsHooks for PairFriction {
    fn modify_solver_contacts(&self, context: &mut ContactModificationContext) {
        // Robots are the only bodies: a pair of two bodies is two robots.
        let robots = context.rigid_body1.is_some() && context.rigid_body2.is_some();
        if let Some(manifold) = context.rigid_mut() {
            *manifold.friction = if robots { self.robot } else { self.wall };
        }
    }
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

impl Built {
    /// The rapier world for `scene` with `params.n_robots` discs.
    fn new(scene: &Scene, params: &PhysicsParams) -> Self {
        let mut world = PhysicsWorld {
            gravity: Vector::ZERO,
            ..PhysicsWorld::default()
        };
        world.integration_parameters.dt = params.substep_dt;
        world.integration_parameters.num_solver_iterations = params.solver_iterations;
        world.integration_parameters.normalized_prediction_distance = params.contact_prediction;
        let robots = (0..params.n_robots)
            .map(|i| {
                let body = RigidBodyBuilder::dynamic()
                    .translation(Vector::new(i as f32, 0.0))
                    .can_sleep(false)
                    .ccd_enabled(false);
                let mut collider = ColliderBuilder::ball(params.radius)
                    .mass(params.mass)
                    .friction(params.friction)
                    .restitution(0.0);
                if params.traction && params.robot_friction != params.friction {
                    // A different coefficient between robots than against the scene needs the
                    // per-pair hook; rapier never recycles hooked pairs' contacts, so equal
                    // coefficients (the default) go without it.
                    collider = collider.active_hooks(ActiveHooks::MODIFY_SOLVER_CONTACTS);
                }
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
        Self::of(world, robots)
    }
}

impl Physics {
    /// The rapier side of a world of `params.n_robots` discs in `scene` (built at its first
    /// substep: see the type's doc).
    pub fn new(scene: &Scene, params: PhysicsParams) -> Self {
        Self {
            rapier: Rapier::Unbuilt(scene.clone()),
            params,
            targets: Vec::new(),
        }
    }

    /// The built rapier world, built now if it was not.
    fn built(&mut self) -> &mut Built {
        if let Rapier::Unbuilt(scene) = &self.rapier {
            self.rapier = Rapier::Built(Box::new(Built::new(scene, &self.params)));
        }
        match &mut self.rapier {
            Rapier::Built(built) => built,
            Rapier::Unbuilt(_) => unreachable!("built just above"),
        }
    }

    /// Builds the rapier world now if it was not.
    pub fn build_now(&mut self) {
        self.built();
    }

    /// Whether the rapier world has been built (a substep needed it).
    pub fn is_built(&self) -> bool {
        matches!(self.rapier, Rapier::Built(_))
    }

    /// Heap bytes a built rapier world of this one's scene and robots takes (measured by
    /// building one): what a world may grow by when a substep first needs rapier.
    pub fn built_bytes(&self, scene: &Scene) -> u64 {
        let (built, bytes) = crate::memory::measure(|| Built::new(scene, &self.params));
        drop(built);
        bytes + std::mem::size_of::<Built>() as u64
    }

    /// Sets every robot's mass (kg).
    pub fn set_mass(&mut self, mass: f32) {
        self.params.mass = mass;
        // Unbuilt, the build takes it from `params`.
        let Rapier::Built(built) = &mut self.rapier else {
            return;
        };
        for handle in &built.robots {
            let colliders: Vec<ColliderHandle> = built
                .world
                .bodies
                .get(*handle)
                .map(|b| b.colliders().to_vec())
                .unwrap_or_default();
            for c in colliders {
                if let Some(collider) = built.world.colliders.get_mut(c) {
                    collider.set_mass(mass);
                }
            }
        }
    }

    /// Sets the shell friction coefficients of this episode (traction model): every collider's
    /// coefficient, and the robot-robot hook when the two differ.
    pub fn set_friction(&mut self, wall: f32, robot: f32) {
        self.params.friction = wall;
        self.params.robot_friction = robot;
        let hooks = if self.params.traction && robot != wall {
            ActiveHooks::MODIFY_SOLVER_CONTACTS
        } else {
            ActiveHooks::empty()
        };
        // Unbuilt, the build takes them from `params`.
        let Rapier::Built(built) = &mut self.rapier else {
            return;
        };
        let robot_colliders: Vec<ColliderHandle> = built
            .robots
            .iter()
            .filter_map(|h| built.world.bodies.get(*h))
            .flat_map(|b| b.colliders().to_vec())
            .collect();
        for (handle, collider) in built.world.colliders.iter_mut() {
            collider.set_friction(wall);
            if robot_colliders.contains(&handle) {
                collider.set_active_hooks(hooks);
            }
        }
    }

    /// Robot mass of this episode (kg).
    pub fn mass(&self) -> f32 {
        self.params.mass
    }

    /// Shell–wall and shell–obstacle friction coefficient of this episode.
    pub fn wall_friction(&self) -> f32 {
        self.params.friction
    }

    /// Replaces the fixed colliders with `scene`'s shapes. The rapier world is built anew (robots
    /// included; the caller places them), at the next substep that needs it: removing and
    /// inserting colliders in place left rapier's pending-removal lists and broad phase growing
    /// by ~35 bytes per episode, since the removals are only processed by a rapier step, which
    /// an episode without contacts never takes.
    pub fn set_scene(&mut self, scene: &Scene) {
        self.rapier = Rapier::Unbuilt(scene.clone());
    }

    /// One rapier substep: sets every robot's pose and velocity, steps, and writes the resolved
    /// poses back into `states`.
    pub fn step(&mut self, states: &mut [BodyState]) {
        let built = self.built();
        for (state, handle) in states.iter().zip(&built.robots) {
            if let Some(body) = built.world.bodies.get_mut(*handle) {
                let (v, w) = state.twist;
                let (s, c) = state.heading.sin_cos();
                body.set_position(Pose::new(state.position, state.heading), true);
                body.set_linvel(Vector::new(v * c, v * s), true);
                body.set_angvel(w, true);
            }
        }
        step_world(&mut built.world, &());
        for (state, handle) in states.iter_mut().zip(&built.robots) {
            if let Some(body) = built.world.bodies.get(*handle) {
                let pose = body.position();
                state.position = pose.translation;
                state.heading = pose.rotation.angle();
            }
        }
    }

    /// One traction substep: each wheel's grip impulse (the one cancelling its slip, clamped to
    /// the tyre's friction circle), then a rapier step resolving contacts with friction; writes
    /// the resulting poses and velocities back into `bodies`. With `active`
    /// (`physics.split = "robot"`) only the robots it marks take part: the others' bodies are
    /// disabled in rapier (no contacts, no integration, no broad-phase update) and their entries
    /// in `bodies` left as they are; the caller guarantees that none of them can touch anything
    /// during the substep, and their targets are computed and results read on this thread.
    /// Otherwise the world's `team` computes every body's target and reads rapier's results back
    /// (shared among a swarm's threads, in order in any other world; the same results either
    /// way). Rapier's step itself runs on the calling thread.
    pub(super) fn step_traction(
        &mut self,
        bodies: &mut [TractionBody],
        active: Option<&[bool]>,
        grip: Grip,
        team: &Team,
    ) {
        let mass = self.params.mass;
        // A uniform disc [E]: the body's mass spread over the shell's footprint.
        let inertia = 0.5 * mass * self.params.radius * self.params.radius;
        let h = self.params.substep_dt;
        let cap = grip.tyre_friction * 0.5 * mass * GRAVITY * h;
        let takes_part = |i: usize| active.is_none_or(|a| a[i]);
        // Each taking part: its pose, and its velocities after the tyres' impulses. Robot by
        // robot (a sine and cosine each), so a swarm shares it among the batch's threads; rapier
        // is then handed them one after another.
        let target = |state: &TractionBody| {
            let (dv, dw) = tyre_impulses(state, grip.axle, mass, inertia, cap);
            let pose = Pose::new(state.position, state.heading);
            (pose, state.velocity + dv, state.spin + dw)
        };
        self.targets.clear();
        match active {
            Some(active) => {
                // Split by robot: the few robots rapier takes, in robot order, on this thread
                // (sharing them among the team would cost more than reading them).
                let taking = bodies.iter().zip(active).filter(|(_, &a)| a);
                self.targets.extend(taking.map(|(state, _)| target(state)));
            }
            None => {
                let unset = (Pose::new(Vector::ZERO, 0.0), Vector::ZERO, 0.0);
                self.targets.resize(bodies.len(), unset);
                let chunks = self.targets.chunks_mut(CHUNK).zip(bodies.chunks(CHUNK));
                team.each(
                    chunks,
                    |_, (out, each): (&mut [Target], &[TractionBody])| {
                        for (slot, state) in out.iter_mut().zip(each) {
                            *slot = target(state);
                        }
                    },
                );
            }
        }
        let friction = (self.params.friction, self.params.robot_friction);
        let targets = std::mem::take(&mut self.targets);
        let built = self.built();
        let mut next = targets.iter();
        for (i, handle) in built.robots.iter().enumerate() {
            if !takes_part(i) {
                // A body already disabled is left untouched: `get_mut` would put it on rapier's
                // list of modified bodies, which the step then walks for nothing (in a swarm
                // split by robot, most of the bodies every substep).
                if built.enabled[i] {
                    if let Some(body) = built.world.bodies.get_mut(*handle) {
                        body.set_enabled(false);
                    }
                    built.enabled[i] = false;
                }
                continue;
            }
            let Some((pose, velocity, spin)) = next.next() else {
                continue;
            };
            let Some(body) = built.world.bodies.get_mut(*handle) else {
                continue;
            };
            body.set_enabled(true);
            built.enabled[i] = true;
            body.set_position(*pose, true);
            body.set_linvel(*velocity, true);
            body.set_angvel(*spin, true);
        }
        let hooks = PairFriction {
            wall: friction.0,
            robot: friction.1,
        };
        step_world(&mut built.world, &hooks);
        // Reading the poses back (an atan2 each) only reads rapier's bodies: robot by robot, so
        // a swarm shares it among the batch's threads.
        let rapier_bodies = &built.world.bodies;
        let read = |(state, handle): (&mut TractionBody, &RigidBodyHandle)| {
            if let Some(body) = rapier_bodies.get(*handle) {
                let pose = body.position();
                state.position = pose.translation;
                state.heading = pose.rotation.angle();
                state.velocity = body.linvel();
                state.spin = body.angvel();
            }
        };
        match active {
            // Split by robot: the robots rapier took, on this thread.
            Some(active) => {
                let pairs = bodies.iter_mut().zip(&built.robots).zip(active);
                pairs.filter(|(_, &a)| a).for_each(|(pair, _)| read(pair));
            }
            None => {
                let chunks = bodies.chunks_mut(CHUNK).zip(built.robots.chunks(CHUNK));
                team.each(chunks, |_, (each, handles): (&mut [_], &[_])| {
                    each.iter_mut().zip(handles).for_each(read);
                });
            }
        }
        // The scratch goes back, with its capacity.
        self.targets = targets;
    }
}
