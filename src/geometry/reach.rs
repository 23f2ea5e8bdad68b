//! The reachability map of a scenario's fixed scene: the positions a robot centre can take
//! (a 2 cm grid, clear of the walls and fixed obstacles by the robot's radius), labelled into
//! connected components, so that the spawner draws a start and its goal in the same one. Built
//! once per batch, its size checked against documented limits before anything is allocated.
//!
//! Units: metres; world frame, arena centred at the origin.

use rapier2d::math::Vector;

use super::scene::Scene;
use crate::error::{Error, Result};

/// Grid cell size for the reachability map (m).
const CELL: f32 = 0.02;
/// Most cells of the reachability map (an arena of about 41 m x 41 m with fixed obstacles):
/// each costs at most 13 bytes while it is built (free flag, component label, search stack),
/// 54.5 MB at most, shared by every world of a batch.
pub const MAX_GRID_CELLS: usize = 1 << 22;
/// Bytes a cell of the reachability map may cost while it is built.
const GRID_CELL_BYTES: usize = 13;
/// Most clearance evaluations (cells x fixed obstacles) when the map is built: about a second.
pub const MAX_GRID_WORK: usize = 1 << 28;
/// Components of the free space left by the walls and fixed obstacles.
#[derive(Debug, Clone)]
pub struct Grid {
    nx: usize,
    ny: usize,
    origin: Vector,
    labels: Vec<u32>,
}

impl Grid {
    /// Cells of the map of an arena `w` x `h` (m).
    fn cells(w: f32, h: f32) -> (usize, usize) {
        ((w / CELL).ceil() as usize, (h / CELL).ceil() as usize)
    }

    /// Checks that the map of `scene` stays within [`MAX_GRID_CELLS`] and [`MAX_GRID_WORK`]
    /// before anything is allocated; errors name `origin` and the key to change.
    pub fn check_size(scene: &Scene, origin: &str) -> Result<()> {
        let (nx, ny) = Self::cells(scene.arena.0, scene.arena.1);
        let cells = nx.saturating_mul(ny);
        if cells > MAX_GRID_CELLS {
            return Err(Error::config(
                origin,
                "arena.width",
                format!(
                    "with fixed obstacles, a {} m x {} m arena needs a reachability map of \
                     {cells} cells of {CELL} m ({:.0} MB); the limit is {MAX_GRID_CELLS} cells \
                     ({:.1} MB, about a 41 m x 41 m arena): a smaller arena, or no \
                     obstacles.fixed",
                    scene.arena.0,
                    scene.arena.1,
                    (cells as f64) * GRID_CELL_BYTES as f64 / 1e6,
                    (MAX_GRID_CELLS * GRID_CELL_BYTES) as f64 / 1e6
                ),
            ));
        }
        let work = cells.saturating_mul(scene.shapes.len());
        if work > MAX_GRID_WORK {
            return Err(Error::config(
                origin,
                "obstacles.fixed",
                format!(
                    "{} fixed obstacles over a map of {cells} cells need {work} clearance \
                     evaluations; the limit is {MAX_GRID_WORK}: fewer fixed obstacles or a \
                     smaller arena",
                    scene.shapes.len()
                ),
            ));
        }
        Ok(())
    }

    /// The map of `scene` for a robot of `radius` (m): the cells whose centre is clear of the
    /// walls and obstacles by `radius` + 5 mm, labelled into 4-connected components.
    pub fn new(scene: &Scene, radius: f32) -> Self {
        let (w, h) = scene.arena;
        let (nx, ny) = Self::cells(w, h);
        let origin = Vector::new(-0.5 * w, -0.5 * h);
        let centre = |i: usize, j: usize| {
            origin + Vector::new((i as f32 + 0.5) * CELL, (j as f32 + 0.5) * CELL)
        };
        let free: Vec<bool> = (0..nx * ny)
            .map(|k| scene.clearance(centre(k % nx, k / nx)) > radius + 0.005)
            .collect();
        let mut labels = vec![0u32; nx * ny];
        let mut next = 0;
        let mut stack = Vec::new();
        for seed in 0..nx * ny {
            if !free[seed] || labels[seed] != 0 {
                continue;
            }
            next += 1;
            labels[seed] = next;
            stack.push(seed);
            while let Some(k) = stack.pop() {
                let (i, j) = (k % nx, k / nx);
                let mut visit = |n: usize| {
                    if free[n] && labels[n] == 0 {
                        labels[n] = next;
                        stack.push(n);
                    }
                };
                if i > 0 {
                    visit(k - 1);
                }
                if i + 1 < nx {
                    visit(k + 1);
                }
                if j > 0 {
                    visit(k - nx);
                }
                if j + 1 < ny {
                    visit(k + nx);
                }
            }
        }
        Self {
            nx,
            ny,
            origin,
            labels,
        }
    }

    /// Component of the cell holding `p` (0: blocked or outside).
    pub fn label(&self, p: Vector) -> u32 {
        let q = (p - self.origin) / CELL;
        if q.x < 0.0 || q.y < 0.0 {
            return 0;
        }
        let (i, j) = (q.x as usize, q.y as usize);
        if i >= self.nx || j >= self.ny {
            return 0;
        }
        self.labels[j * self.nx + i]
    }
}
