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
}

/// Most cells along a side: bounds the grid's memory whatever the robots' spread.
const MAX_SIDE: usize = 1024;

impl Grid {
    /// Buckets `positions` in cells of side at least `cell` (m, > 0 and finite).
    pub fn build(&mut self, positions: impl Iterator<Item = Vector> + Clone, cell: f32) {
        let mut lo = Vector::splat(f32::INFINITY);
        let mut hi = Vector::splat(f32::NEG_INFINITY);
        for p in positions.clone() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let span = (hi - lo).max(Vector::ZERO);
        let cell = cell
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
        for p in positions.clone() {
            let c = self.cell_index(p);
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
        let mut next: Vec<u32> = self.starts[..cells].to_vec();
        for ((i, &c), p) in self.cell_of.iter().enumerate().zip(positions) {
            let slot = next[c as usize] as usize;
            self.order[slot] = i as u32;
            self.points[slot] = p;
            next[c as usize] += 1;
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
    /// centre lies within `radius` of `p` (squared distances compared: |q − p|² ≤ radius²).
    pub fn near(&self, p: Vector, radius: f32, me: usize, out: &mut Vec<u32>) {
        let start = out.len();
        self.for_each_near(p, radius, me, |j, _| out.push(j));
        out[start..].sort_unstable();
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

    #[test]
    fn finds_exactly_the_robots_a_full_loop_finds_in_index_order() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let positions: Vec<Vector> = (0..500)
            .map(|_| Vector::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0)))
            .collect();
        let mut grid = Grid::default();
        grid.build(positions.iter().copied(), 0.7);
        let mut got = Vec::new();
        for (i, &p) in positions.iter().enumerate() {
            got.clear();
            grid.near(p, 1.5, i, &mut got);
            let want: Vec<u32> = (0..positions.len() as u32)
                .filter(|&j| {
                    j as usize != i && (positions[j as usize] - p).length_squared() <= 2.25
                })
                .collect();
            assert_eq!(got, want);
        }
    }
}
