//! A uniform grid over the robots' centres, rebuilt when a world of many robots senses or
//! checks for contacts, so that each robot looks only at the robots near it: the cost per robot
//! stays about flat as a swarm grows, instead of growing with the number of robots.
//!
//! Queries return robot indices in increasing order, so a sensor sees its neighbours in the same
//! order as in a plain loop over every robot, and its readings are the same bit for bit.
//!
//! Units: metres; world frame.

use rapier2d::math::Vector;

/// Robots bucketed by square cells (a counting sort by cell, stable in robot index).
#[derive(Debug, Default, Clone)]
pub struct Grid {
    cell: f32,
    origin: Vector,
    columns: usize,
    rows: usize,
    /// `starts[c]..starts[c + 1]` indexes `order` for cell `c`.
    starts: Vec<u32>,
    /// Robot indices, sorted by cell, then by index.
    order: Vec<u32>,
    /// Their centres, in the same order (contiguous for the queries).
    points: Vec<Vector>,
    /// Each robot's cell.
    cell_of: Vec<u32>,
    /// Scratch: the centres in robot order, and each cell's next free slot while filling.
    by_index: Vec<Vector>,
    next: Vec<u32>,
}

/// Most cells along a side: bounds the grid's memory whatever the robots' spread.
const MAX_SIDE: usize = 1024;
/// Most cells per robot over the robots' spread (see [`Grid::build`]).
const CELLS_PER_ROBOT: f32 = 4.0;

impl Grid {
    /// Buckets `positions` in cells of side at least `cell` (m, > 0 and finite), and at least
    /// as wide as [`CELLS_PER_ROBOT`] cells per robot over the robots' spread allow: a query's
    /// result does not depend on the cells (only its cost does), and cells far smaller than
    /// the space per robot cost more to clear and count than the few robots they spare a query.
    pub fn build(&mut self, positions: impl Iterator<Item = Vector>, cell: f32) {
        // One pass over the robots (a robot's struct is large; their centres are copied).
        let mut lo = Vector::splat(f32::INFINITY);
        let mut hi = Vector::splat(f32::NEG_INFINITY);
        self.by_index.clear();
        for p in positions {
            lo = lo.min(p);
            hi = hi.max(p);
            self.by_index.push(p);
        }
        let span = (hi - lo).max(Vector::ZERO);
        let robots = self.by_index.len().max(1) as f32;
        let per_robot = (span.x * span.y / (CELLS_PER_ROBOT * robots)).sqrt();
        let cell = cell
            .max(per_robot)
            .max(span.x / MAX_SIDE as f32)
            .max(span.y / MAX_SIDE as f32);
        self.cell = cell;
        self.origin = lo;
        self.columns = ((span.x / cell) as usize + 1).min(MAX_SIDE);
        self.rows = ((span.y / cell) as usize + 1).min(MAX_SIDE);
        let cells = self.columns * self.rows;
        self.starts.clear();
        self.starts.resize(cells + 1, 0);
        self.cell_of.clear();
        for i in 0..self.by_index.len() {
            let c = self.cell_index(self.by_index[i]);
            self.cell_of.push(c as u32);
            self.starts[c + 1] += 1;
        }
        for c in 0..cells {
            self.starts[c + 1] += self.starts[c];
        }
        self.order.clear();
        self.order.resize(self.cell_of.len(), 0);
        self.points.clear();
        self.points.resize(self.cell_of.len(), Vector::ZERO);
        self.next.clear();
        self.next.extend_from_slice(&self.starts[..cells]);
        for (i, (&c, &p)) in self.cell_of.iter().zip(&self.by_index).enumerate() {
            let slot = self.next[c as usize] as usize;
            self.order[slot] = i as u32;
            self.points[slot] = p;
            self.next[c as usize] += 1;
        }
    }

    fn coords(&self, p: Vector) -> (usize, usize) {
        let q = (p - self.origin) / self.cell;
        let clamp = |v: f32, n: usize| (v.max(0.0) as usize).min(n - 1);
        (clamp(q.x, self.columns), clamp(q.y, self.rows))
    }

    fn cell_index(&self, p: Vector) -> usize {
        let (x, y) = self.coords(p);
        y * self.columns + x
    }

    /// Calls `f` with the index of every robot other than `me` whose centre lies within
    /// `radius` of `p` (squared distances compared: |q − p|² ≤ radius²) and its centre, in
    /// cell order (not index order): for queries whose result does not depend on the order.
    #[inline]
    pub fn for_each_near(&self, p: Vector, radius: f32, me: usize, mut f: impl FnMut(u32, Vector)) {
        let (x, y) = self.coords(p);
        // Cells within `rings` of the robot's cover every point within `radius` of it.
        let rings = ((radius / self.cell).ceil() as usize).max(1);
        let limit = radius * radius;
        for row in y.saturating_sub(rings)..(y + rings + 1).min(self.rows) {
            // The cells of a row are contiguous in `order`.
            let first = row * self.columns + x.saturating_sub(rings);
            let last = row * self.columns + (x + rings + 1).min(self.columns);
            let span = self.starts[first] as usize..self.starts[last] as usize;
            for (&j, q) in self.order[span.clone()].iter().zip(&self.points[span]) {
                if j as usize != me && (*q - p).length_squared() <= limit {
                    f(j, *q);
                }
            }
        }
    }

    /// Appends to `out`, in increasing order, the indices of the robots other than `me` whose
    /// centre lies within `radius` of `p` (squared distances compared: |q − p|² ≤ radius²):
    /// what a full loop in index order finds, for the tests to compare.
    #[cfg(test)]
    pub fn near(&self, p: Vector, radius: f32, me: usize, out: &mut Vec<u32>) {
        let start = out.len();
        self.for_each_near(p, radius, me, |j, _| out.push(j));
        out[start..].sort_unstable();
    }

    /// The farthest any of `positions` (robot order) lies from the centre the grid holds for
    /// that robot (m): a query widened by it finds every robot near its position now. Infinite
    /// when the grid holds another number of robots (or a position is not finite).
    pub fn drift(&self, positions: impl ExactSizeIterator<Item = Vector>) -> f32 {
        if positions.len() != self.by_index.len() {
            return f32::INFINITY;
        }
        // A NaN distance (`max` would skip it) counts as infinitely far.
        let farthest = positions
            .zip(&self.by_index)
            .map(|(p, c)| (p - *c).length_squared())
            .fold(
                0.0f32,
                |a, d| if d.is_nan() { f32::INFINITY } else { a.max(d) },
            );
        farthest.sqrt()
    }

    /// The cell side (m).
    pub fn cell(&self) -> f32 {
        self.cell
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every robot within `radius` of every robot, in index order, by a plain loop.
    fn brute(positions: &[Vector], i: usize, radius: f32) -> Vec<u32> {
        let p = positions[i];
        (0..positions.len() as u32)
            .filter(|&j| {
                j as usize != i && (positions[j as usize] - p).length_squared() <= radius * radius
            })
            .collect()
    }

    #[test]
    fn finds_exactly_the_robots_a_full_loop_finds_in_index_order() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let positions: Vec<Vector> = (0..500)
            .map(|_| Vector::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0)))
            .collect();
        let mut grid = Grid::default();
        // Cells as asked (0.7 m), then far smaller than the space per robot (widened), for
        // radii below, about and above a cell.
        for cell in [0.7, 0.01] {
            grid.build(positions.iter().copied(), cell);
            for radius in [0.3, 1.5, 4.0] {
                let mut got = Vec::new();
                for i in 0..positions.len() {
                    got.clear();
                    grid.near(positions[i], radius, i, &mut got);
                    assert_eq!(
                        got,
                        brute(&positions, i, radius),
                        "cell {cell}, radius {radius}"
                    );
                }
            }
        }
        assert!(
            grid.cell() > 0.2,
            "cells of 0.01 m widened to {}",
            grid.cell()
        );
    }

    #[test]
    fn a_crowd_in_a_corner_of_a_wide_spread_is_found_whole() {
        // Most robots packed in 1 m², one far away: the spread is wide, the cells sized for it
        // hold the whole crowd, and every query still returns exactly the robots in reach.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let mut positions: Vec<Vector> = (0..300)
            .map(|_| Vector::new(rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)))
            .collect();
        positions.push(Vector::new(50.0, 50.0));
        let mut grid = Grid::default();
        grid.build(positions.iter().copied(), 0.05);
        let mut got = Vec::new();
        for i in 0..positions.len() {
            got.clear();
            grid.near(positions[i], 0.2, i, &mut got);
            assert_eq!(got, brute(&positions, i, 0.2));
        }
    }

    #[test]
    fn drift_is_the_farthest_any_robot_moved_and_infinite_for_another_grid() {
        let start = [
            Vector::new(0.0, 0.0),
            Vector::new(1.0, 1.0),
            Vector::new(2.0, 0.0),
        ];
        let mut grid = Grid::default();
        assert_eq!(
            grid.drift(start.iter().copied()),
            f32::INFINITY,
            "empty grid"
        );
        grid.build(start.iter().copied(), 0.5);
        assert_eq!(grid.drift(start.iter().copied()), 0.0);
        // Robot 1 moved 5 cm (a 3-4-5 triangle), robot 2 moved 3 cm.
        let moved = [
            start[0],
            start[1] + Vector::new(0.03, 0.04),
            start[2] + Vector::new(0.0, -0.03),
        ];
        assert!((grid.drift(moved.iter().copied()) - 0.05).abs() < 1e-6);
        assert_eq!(
            grid.drift(start[..2].iter().copied()),
            f32::INFINITY,
            "fewer robots"
        );
        let lost = [start[0], Vector::new(f32::NAN, 0.0), start[2]];
        assert_eq!(
            grid.drift(lost.iter().copied()),
            f32::INFINITY,
            "a position not finite"
        );
    }
}
