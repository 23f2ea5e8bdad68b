//! Sensing in a swarm (a world of more than [`GRID_MIN_ROBOTS`](super::GRID_MIN_ROBOTS) robots): every robot reads its
//! sensors seeing only the robots within the sensors' reach, found through the world's grid, and
//! with noise from its own random stream: ChaCha8 seeded by one number the world's stream draws
//! per reading, on stream `robot index`. A robot's readings then depend only on the world's state
//! and its index, so the robots are read in parallel (inside a batch's thread pool, when the
//! world runs in one) with the same results whatever the number of threads.
//!
//! Units: metres; world frame.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;

use super::team::CHUNK;
use super::{Robot, World};
use crate::sensors::{SenseContext, Suite};

impl World {
    /// Reads every robot's sensors, a swarm's way (module doc).
    pub(super) fn sense_swarm(&mut self, fresh: bool) {
        // How far from a robot's centre another robot's centre can change its coming readings
        // (1 mm more, so that rounding never drops a robot a sensor could just reach): the
        // sonars look 2.15 m away when their sweep comes round (every 0.1 s) and not at all in
        // between, when only the IR ring's 0.39 m matter.
        let (sensors, radius, dt) = (&self.sensors, self.drive.radius, self.dt);
        let reach_of =
            |robot: &Robot| sensors.reach_now(radius, &robot.readings, dt, fresh) + 0.001;
        // One pass over the robots: the farthest reach, every centre and LED colour.
        let mut reach = 0.0f32;
        self.positions.clear();
        self.other_leds.clear();
        for robot in &self.robots {
            reach = reach.max(reach_of(robot));
            self.positions.push(robot.position);
            self.other_leds.push(robot.led);
        }
        let use_grid = self.robots.len() > self.grid_min_robots && reach.is_finite();
        if use_grid {
            // Cells of half the reach: the 5 × 5 cells around a robot hold fewer robots than
            // the 3 × 3 of cells as wide as the reach.
            let cell = (0.5 * reach).max(0.01);
            self.grid.build(self.positions.iter().copied(), cell);
        }
        let leds = &self.other_leds;
        let base: u64 = self.rng.random();
        // Every robot's stream has the same key: seeded once, each a copy on its own stream
        // (the same state as seeding it anew, since nothing was drawn).
        let seeded = ChaCha8Rng::seed_from_u64(base);
        let (grid, positions) = (&self.grid, &self.positions);
        let world = surroundings!(self, fresh);
        let read = |scratch: &mut Scratch, (i, robot): (usize, &mut Robot)| {
            scratch.others.clear();
            scratch.leds.clear();
            scratch.near.clear();
            if use_grid {
                // In the grid's cell order, with their indices: sorting them into robot order
                // cost a seventh of the mispredicted branches of a step, and the readings do
                // not depend on the order (`SenseContext::other_ids`).
                grid.for_each_near(robot.position, reach_of(robot), i, |j, q| {
                    scratch.near.push(j);
                    scratch.others.push(q);
                    scratch.leds.push(leds[j as usize]);
                });
            } else {
                let all = positions.iter().enumerate().filter(|(j, _)| *j != i);
                scratch.others.extend(all.map(|(_, p)| *p));
                let all = leds.iter().enumerate().filter(|(j, _)| *j != i);
                scratch.leds.extend(all.map(|(_, c)| *c));
            }
            let mut rng = seeded.clone();
            rng.set_stream(i as u64);
            let ctx = SenseContext::new(
                world,
                robot.position,
                robot.heading,
                robot.yaw_rate,
                robot.acceleration,
            )
            .seeing(&scratch.others, &scratch.leds, &scratch.near);
            scratch.suite.read(&ctx, &mut rng, &mut robot.readings);
        };
        let scratch = || Scratch {
            suite: sensors.clone(),
            others: Vec::new(),
            leds: Vec::new(),
            near: Vec::new(),
        };
        // Robot by robot, so that inside a batch's pool the team shares them.
        let each = |scratch: &mut Scratch, first: usize, robots: &mut [Robot]| {
            for (i, robot) in robots.iter_mut().enumerate() {
                read(scratch, (first + i, robot));
            }
        };
        let chunks = self.robots.chunks_mut(CHUNK);
        self.team.each_beside(chunks, scratch, each, || ());
    }
}

/// A thread's copy of the sensor models (whose `read` uses scratch buffers) and its buffers.
struct Scratch {
    suite: Suite,
    others: Vec<Vector>,
    leds: Vec<[f32; 3]>,
    near: Vec<u32>,
}
