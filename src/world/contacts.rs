//! Contacts after a rapier substep: which robots ended it touching the scene or another robot,
//! and (split by robot) which robots left out of rapier one of its robots met. One pass serves
//! every world: a world of few robots compares every pair; a swarm finds each robot's
//! neighbours through the contact grid, which is kept over substeps and steps while the robots
//! stay near the centres it holds (a query widened by that drift finds every robot in reach).
//!
//! Units: metres; world frame.

use rapier2d::math::Vector;

use super::motion::{CONTACT_TOLERANCE, MIN_CELL};
use super::team::CHUNK;
use super::{Robot, World};
use crate::geometry::grid::Grid;

/// Farthest a robot may move from the centre the contact grid holds for it before the grid is
/// built anew (m; about four control steps' travel at full speed). While a query widened by the
/// drift still spans only the cells next to a robot's own (the other condition of
/// `refresh_contact_grid`), it reads the same cells, and the wider radius only lets a few more
/// robots through to the pair checks: in a 1,000-robot world (2026-12-08) a new grid cost about
/// 16 µs, and with 0.04 m it was built 0.58 times a step, with 0.15 m 0.15 times, the contact
/// checks taking no longer.
const REBUILD_DRIFT: f32 = 0.15;

impl World {
    /// Makes the contact grid fit for queries of `cutoff` (m) around the robots' centres now,
    /// which `self.positions` holds (`gather_positions`): kept when every robot lies within
    /// [`REBUILD_DRIFT`] of its centre in the grid and a query widened by that drift spans only
    /// the cells next to a robot's own; built anew on `self.positions` otherwise. Returns the
    /// drift to widen queries by: a robot within `cutoff` of a point now was within
    /// `cutoff + drift` of it when the grid was built, so the widened query finds every robot a
    /// grid built now would.
    pub(super) fn refresh_contact_grid(&mut self, cutoff: f32) -> f32 {
        let drift = self.contact_grid.drift(self.positions.iter().copied());
        if drift <= REBUILD_DRIFT && cutoff + drift <= self.contact_grid.cell() {
            return drift;
        }
        self.contact_grid
            .build(self.positions.iter().copied(), cutoff.max(MIN_CELL));
        0.0
    }

    /// Copies every robot's centre into `self.positions` (robot order), which the contact
    /// grid and the pair checks read instead of the robots' large structs.
    pub(super) fn gather_positions(&mut self) {
        self.positions.clear();
        self.positions
            .extend(self.robots.iter().map(|r| r.position));
    }

    /// Marks in contact every robot rapier moved in the last substep that ended it within
    /// [`CONTACT_TOLERANCE`] of the scene or another robot: every robot, or split by robot
    /// (`split`) those `self.active` marks, since the others kept clear of everything by their
    /// speed bounds. Split by robot, also marks active every robot left out that one of them
    /// met (it was pushed faster than its bound) and returns whether there was any.
    pub(super) fn mark_contacts(&mut self, split: bool) -> bool {
        let radius = self.drive.radius;
        // A robot farther than this cannot be within the tolerance.
        let cutoff = 2.0 * radius + CONTACT_TOLERANCE + 0.001;
        if !split {
            // Split by robot, the substep wrote each robot's centre as it moved it.
            self.gather_positions();
        }
        let swarm = self.robots.len() > self.grid_min_robots;
        let reach = if swarm {
            cutoff + self.refresh_contact_grid(cutoff)
        } else {
            f32::INFINITY
        };
        let near = Near {
            grid: swarm.then_some(&self.contact_grid),
            positions: &self.positions,
            reach,
            radius,
        };
        let scene = &self.scene;
        let scene_gap = |i: usize| scene.clearance(near.positions[i]) - radius;
        if split {
            // Few robots (those rapier moved), one after another.
            let (active, missed) = (&self.active, &mut self.missed);
            self.touching.clear();
            for i in (0..active.len()).filter(|&i| active[i]) {
                let mut gap = scene_gap(i);
                near.gaps(i, |j, other| {
                    gap = gap.min(other);
                    if !active[j] && other < CONTACT_TOLERANCE {
                        missed.push(j as u32);
                    }
                });
                if gap < CONTACT_TOLERANCE {
                    self.touching.push(i as u32);
                }
            }
            for &i in &self.touching {
                self.robots[i as usize].in_contact = true;
            }
            let any = !self.missed.is_empty();
            for j in self.missed.drain(..) {
                self.active[j as usize] = true;
            }
            return any;
        }
        let mark = |(i, robot): (usize, &mut Robot)| {
            let mut gap = scene_gap(i);
            near.gaps(i, |_, other| gap = gap.min(other));
            if gap < CONTACT_TOLERANCE {
                robot.in_contact = true;
            }
        };
        // Robot by robot, so a swarm shares it among its team.
        let chunks = self.robots.chunks_mut(CHUNK);
        self.team.each(chunks, |first, robots: &mut [Robot]| {
            for (i, robot) in robots.iter_mut().enumerate() {
                mark((first + i, robot));
            }
        });
        false
    }
}

/// The robots near a robot: through the contact grid (a swarm) or all of them.
struct Near<'a> {
    grid: Option<&'a Grid>,
    positions: &'a [Vector],
    /// Query radius (m) through the grid: the cutoff widened by the grid's drift.
    reach: f32,
    radius: f32,
}

impl Near<'_> {
    /// Calls `f(j, gap)` with the gap (m) between robot `i`'s body and robot `j`'s, for every
    /// robot `j` other than `i` that can be within the cutoff (a swarm) or every other robot.
    #[inline]
    fn gaps(&self, i: usize, mut f: impl FnMut(usize, f32)) {
        let p = self.positions[i];
        let gap = |q: Vector| (q - p).length() - 2.0 * self.radius;
        match self.grid {
            Some(grid) => grid.for_each_near(p, self.reach, i, |j, _| {
                f(j as usize, gap(self.positions[j as usize]));
            }),
            None => {
                for (j, q) in self.positions.iter().enumerate() {
                    if j != i {
                        f(j, gap(*q));
                    }
                }
            }
        }
    }
}
