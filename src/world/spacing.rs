//! Spacing of the robots a layout places: whether a new start or goal keeps the least distance
//! from every one placed so far, in about one comparison a point (a swarm places thousands).
//!
//! Units: metres; world frame, arena centred at the origin.

use rapier2d::math::Vector;

/// The points placed so far (starts, or goals), bucketed in square cells of at least twice the
/// least spacing `apart`, so that whether a new point keeps `apart` from every one of them is
/// decided by the few in the 3 x 3 cells around it: a point in any other cell is more than
/// `2 apart` away along x or y, so farther than `apart` whatever the rounding, and the answer
/// is the very one of comparing with every point (`|q - p| >= apart` for each, the same
/// arithmetic). Placing n robots then costs about n comparisons, not n².
pub(super) struct Spacing {
    apart: f32,
    cell: f32,
    /// Lower corner of the cells (m): the spawn region's; points outside it (fixed starts are
    /// checked only later) fall in the border cells, which only adds candidates.
    origin: Vector,
    columns: usize,
    rows: usize,
    /// Each cell's last point (`NONE` if empty), and each point's previous one in its cell.
    head: Vec<u32>,
    next: Vec<u32>,
    points: Vec<Vector>,
}

/// An empty cell or the end of a cell's list.
const NONE: u32 = u32::MAX;
/// Most cells along a side of a [`Spacing`] (bounds its memory whatever the arena).
const SPACING_MAX_SIDE: usize = 512;
/// Points a [`Spacing`] compares one by one before it builds its cells (a Nav or Formation
/// layout never builds them).
const SPACING_PLAIN: usize = 32;

impl Spacing {
    /// Cells over the spawn region of half extents `half` (m) for points `apart` (m) apart.
    pub(super) fn new(half: (f32, f32), apart: f32) -> Self {
        let (w, h) = ((2.0 * half.0).max(0.0), (2.0 * half.1).max(0.0));
        let cell = (2.0 * apart)
            .max(w / SPACING_MAX_SIDE as f32)
            .max(h / SPACING_MAX_SIDE as f32)
            .max(1e-3);
        let side = |length: f32| ((length / cell) as usize + 1).min(SPACING_MAX_SIDE);
        Self {
            apart,
            cell,
            origin: Vector::new(-half.0, -half.1),
            columns: side(w),
            rows: side(h),
            head: Vec::new(),
            next: Vec::new(),
            points: Vec::new(),
        }
    }

    /// Empties it, with room for `n` points.
    pub(super) fn reset(&mut self, n: usize) {
        self.head.clear();
        self.next.clear();
        self.points.clear();
        self.points.reserve(n);
    }

    /// Column and row of `p`'s cell (clamped to the grid; NaN goes to 0).
    fn coords(&self, p: Vector) -> (usize, usize) {
        let q = (p - self.origin) / self.cell;
        let clamp = |v: f32, n: usize| (v.max(0.0) as usize).min(n - 1);
        (clamp(q.x, self.columns), clamp(q.y, self.rows))
    }

    /// Adds `p`. The first [`SPACING_PLAIN`] points are compared one by one; past them, the
    /// cells are built (once) and kept up to date.
    pub(super) fn insert(&mut self, p: Vector) {
        self.points.push(p);
        if !self.head.is_empty() {
            self.link(self.points.len() - 1);
        } else if self.points.len() > SPACING_PLAIN {
            self.head.resize(self.columns * self.rows, NONE);
            self.next.reserve(self.points.capacity());
            for i in 0..self.points.len() {
                self.link(i);
            }
        }
    }

    /// Puts point `i` at the head of its cell's list.
    fn link(&mut self, i: usize) {
        let (x, y) = self.coords(self.points[i]);
        let c = y * self.columns + x;
        self.next.push(self.head[c]);
        self.head[c] = i as u32;
    }

    /// Whether `p` is at least `apart` from every point inserted (`|q - p| >= apart`).
    pub(super) fn all_apart(&self, p: Vector) -> bool {
        if self.head.is_empty() || !p.is_finite() {
            // Few points (or, never reached, a point off the map): compare with each.
            return self.points.iter().all(|q| (*q - p).length() >= self.apart);
        }
        let (x, y) = self.coords(p);
        for row in y.saturating_sub(1)..(y + 2).min(self.rows) {
            for column in x.saturating_sub(1)..(x + 2).min(self.columns) {
                let mut i = self.head[row * self.columns + column];
                while i != NONE {
                    if (self.points[i as usize] - p).length() < self.apart {
                        return false;
                    }
                    i = self.next[i as usize];
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn spacing_answers_as_comparing_with_every_point() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (half, apart) = ((3.0, 2.0), 0.19);
        let mut spacing = Spacing::new(half, apart);
        spacing.reset(400);
        let mut placed: Vec<Vector> = Vec::new();
        let (mut kept, mut refused) = (0, 0);
        for _ in 0..4000 {
            // Some points off the region (fixed starts may lie anywhere).
            let p = Vector::new(
                rng.random_range(-3.5..3.5f32),
                rng.random_range(-2.5..2.5f32),
            );
            let plain = placed.iter().all(|q| (*q - p).length() >= apart);
            assert_eq!(spacing.all_apart(p), plain, "{p:?} after {}", placed.len());
            if plain {
                kept += 1;
                placed.push(p);
                spacing.insert(p);
            } else {
                refused += 1;
            }
        }
        assert!(kept > SPACING_PLAIN && refused > 0, "{kept} {refused}");
    }
}
