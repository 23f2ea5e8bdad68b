//! The floor the ground sensors look at: a background grey level, an optional grey-scale image,
//! and marks drawn over it (lines, arcs and polylines with a width and a grey level), such as
//! the black tape of a line-following track. Grey levels run from 0 (black) to 1 (white paper).
//!
//! Built from plain values (segments, an image file, a grey level): the world builds a
//! scenario's `[floor]` into a [`Floor`] once, shared by every world of a batch
//! (`world::scenery`); a task may add marks of its own per episode ([`FloorMarks`], part
//! of the world's state: a line-following track drawn from the world's seed). Marks are painted
//! in order (scenario marks, then the task's), each over the image, the image over the
//! background. Every mark is stored as segments of a polyline (arcs as chords within 1 mm of the
//! arc, [`arc_points`]), found near a point through a uniform grid.
//!
//! Image: a PNG file (grey, grey + alpha, RGB or RGBA, 8 or 16 bits; colours become luminance,
//! ITU-R BT.709), `image_scale` metres per pixel, its lower-left corner at `image_origin`; row 0
//! of the file is the top of the picture (+y), as any paint program draws it.
//!
//! Units: metres, radians; world frame (x right, y up).

use std::path::Path;
use std::sync::Arc;

use rapier2d::math::Vector;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Most points of a polyline mark, and most chords of an arc.
pub const MAX_MARK_POINTS: usize = 100_000;
/// Bytes of one [`Segment`] (a test ties the two): what a scenario's check counts its marks in.
pub const SEGMENT_BYTES: usize = 24;
/// Largest sagitta (m) between an arc and the chords that stand for it.
const ARC_SAGITTA: f32 = 0.001;
/// Largest image side (pixels): a 4096 x 4096 image costs 64 MiB while it is decoded (RGBA,
/// 8 bits a channel) and 64 MiB of grey levels (f32) once built, shared by every world.
pub const MAX_IMAGE_SIDE: u32 = 4096;
/// Most entries of the grid that finds marks near a point (a segment is listed in every cell
/// its bounding box touches): 4 bytes each, 16 MiB at most; above it the cells grow (the
/// grid only finds candidates, so the floor reads the same).
const MAX_GRID_MEMBERS: usize = 1 << 22;
/// Side (m) of the cells of the grid that finds marks near a point.
const CELL: f32 = 0.05;
/// Most cells along a side of that grid.
const MAX_CELLS_PER_SIDE: usize = 1024;

/// One segment of a mark, with half its width and its grey level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Start (m).
    pub a: Vector,
    /// End (m).
    pub b: Vector,
    /// Half the mark's width (m).
    pub half_width: f32,
    /// Grey level.
    pub grey: f32,
}

impl Segment {
    fn distance(&self, p: Vector) -> f32 {
        let ab = self.b - self.a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 {
            ((p - self.a).dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p - (self.a + ab * t)).length()
    }
}

/// Marks as segments, with a grid of the segments near each cell (built with them).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FloorMarks {
    segments: Vec<Segment>,
    origin: Vector,
    cell: Vector,
    columns: usize,
    rows: usize,
    /// `starts[c]..starts[c + 1]` indexes `members` for cell `c`.
    starts: Vec<u32>,
    members: Vec<u32>,
}

impl FloorMarks {
    /// Marks made of `segments`, painted in their order.
    pub fn new(segments: Vec<Segment>) -> Self {
        let mut marks = Self {
            segments,
            ..Self::default()
        };
        if marks.segments.is_empty() {
            return marks;
        }
        let mut lo = Vector::splat(f32::INFINITY);
        let mut hi = Vector::splat(f32::NEG_INFINITY);
        for s in &marks.segments {
            let r = Vector::splat(s.half_width);
            lo = lo.min(s.a.min(s.b) - r);
            hi = hi.max(s.a.max(s.b) + r);
        }
        let cells = |span: f32| ((span / CELL).ceil() as usize).clamp(1, MAX_CELLS_PER_SIDE);
        marks.origin = lo;
        marks.columns = cells(hi.x - lo.x);
        marks.rows = cells(hi.y - lo.y);
        let cell_of = |marks: &Self| {
            Vector::new(
                (hi.x - lo.x).max(CELL) / marks.columns as f32,
                (hi.y - lo.y).max(CELL) / marks.rows as f32,
            )
        };
        // Long marks over a fine grid would be listed in very many cells: coarser cells then.
        while marks.columns * marks.rows > 1
            && marks.members_needed(cell_of(&marks)) > MAX_GRID_MEMBERS
        {
            marks.columns = marks.columns.div_ceil(2);
            marks.rows = marks.rows.div_ceil(2);
        }
        let cell = cell_of(&marks);
        marks.cell = cell;
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); marks.columns * marks.rows];
        for (k, s) in marks.segments.iter().enumerate() {
            let r = Vector::splat(s.half_width);
            let (x0, y0) = marks.coords_in(s.a.min(s.b) - r, cell);
            let (x1, y1) = marks.coords_in(s.a.max(s.b) + r, cell);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    lists[y * marks.columns + x].push(k as u32);
                }
            }
        }
        marks.starts.push(0);
        for list in &lists {
            marks.members.extend_from_slice(list);
            marks.starts.push(marks.members.len() as u32);
        }
        marks
    }

    /// Entries of the grid with cells of `cell`: each segment once per cell its bounding box
    /// touches.
    fn members_needed(&self, cell: Vector) -> usize {
        self.segments
            .iter()
            .map(|s| {
                let r = Vector::splat(s.half_width);
                let (x0, y0) = self.coords_in(s.a.min(s.b) - r, cell);
                let (x1, y1) = self.coords_in(s.a.max(s.b) + r, cell);
                (x1 - x0 + 1) * (y1 - y0 + 1)
            })
            .fold(0usize, usize::saturating_add)
    }

    fn coords_in(&self, p: Vector, cell: Vector) -> (usize, usize) {
        let q = (p - self.origin) / cell;
        let clamp = |v: f32, n: usize| (v.max(0.0) as usize).min(n.saturating_sub(1));
        (clamp(q.x, self.columns), clamp(q.y, self.rows))
    }

    /// The grey level of the last mark covering `p`, if any.
    pub fn grey_at(&self, p: Vector) -> Option<f32> {
        if self.segments.is_empty() {
            return None;
        }
        let q = p - self.origin;
        if q.x < 0.0 || q.y < 0.0 {
            return None;
        }
        let (x, y) = self.coords_in(p, self.cell);
        let c = y * self.columns + x;
        let members = &self.members[self.starts[c] as usize..self.starts[c + 1] as usize];
        // The last one painted wins: members are in painting order.
        members
            .iter()
            .rev()
            .map(|&k| &self.segments[k as usize])
            .find(|s| s.distance(p) <= s.half_width)
            .map(|s| s.grey)
    }

    /// The distance (m) from `p` to the nearest edge of a mark near it (infinite when no mark
    /// is near): a spot of smaller radius around `p` lies wholly on one side of every edge.
    pub fn edge_margin(&self, p: Vector) -> f32 {
        if self.segments.is_empty() {
            return f32::INFINITY;
        }
        let (x, y) = self.coords_in(p, self.cell);
        let c = y * self.columns + x;
        let q = p - self.origin;
        let inside = q.x >= 0.0 && q.y >= 0.0;
        // Outside the grid, or near its border, a mark of a neighbouring cell may be close: only
        // the cell's own members are known to be the marks within its bounds.
        let members = &self.members[self.starts[c] as usize..self.starts[c + 1] as usize];
        let cell_lo = self.origin + Vector::new(x as f32 * self.cell.x, y as f32 * self.cell.y);
        let border = (p.x - cell_lo.x)
            .min(cell_lo.x + self.cell.x - p.x)
            .min(p.y - cell_lo.y)
            .min(cell_lo.y + self.cell.y - p.y);
        if !inside || border <= 0.0 {
            return 0.0;
        }
        members
            .iter()
            .map(|&k| {
                let s = &self.segments[k as usize];
                (s.distance(p) - s.half_width).abs()
            })
            .fold(border, f32::min)
    }

    /// The segments, in painting order (for drawing).
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }
}

/// A grey-scale image on the floor.
#[derive(Debug, Clone, PartialEq)]
pub struct FloorImage {
    /// Pixels, row 0 at the top, grey levels 0..1.
    pub grey: Vec<f32>,
    /// Width and height (pixels).
    pub size: (u32, u32),
    /// m per pixel.
    pub scale: f32,
    /// World position of the lower-left corner (m).
    pub origin: Vector,
}

impl FloorImage {
    /// The grey level of the pixel under `p`, or None outside the image.
    pub fn grey_at(&self, p: Vector) -> Option<f32> {
        let q = (p - self.origin) / self.scale;
        let (w, h) = (self.size.0 as f32, self.size.1 as f32);
        if !(q.x >= 0.0 && q.y >= 0.0 && q.x < w && q.y < h) {
            return None;
        }
        // Row 0 is the top of the picture: +y.
        let column = q.x as usize;
        let row = (h - 1.0 - q.y.floor()) as usize;
        self.grey.get(row * self.size.0 as usize + column).copied()
    }

    /// Decodes the PNG at `path`; errors name `floor.image`.
    pub fn load(path: &Path, scale: f32, origin: Vector, from: &str) -> Result<Self> {
        let bad = |message: String| Error::config(from, "floor.image", message);
        let file = std::fs::File::open(path)
            .map_err(|e| bad(format!("cannot open {}: {e}", path.display())))?;
        let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
        decoder.set_transformations(png::Transformations::normalize_to_color8());
        let mut reader = decoder
            .read_info()
            .map_err(|e| bad(format!("{} is not a PNG image: {e}", path.display())))?;
        let (width, height) = (reader.info().width, reader.info().height);
        if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(bad(format!(
                "{} is {width} x {height} pixels; sides of 1 to {MAX_IMAGE_SIDE} are accepted",
                path.display()
            )));
        }
        let mut buffer = vec![0; reader.output_buffer_size()];
        let frame = reader
            .next_frame(&mut buffer)
            .map_err(|e| bad(format!("cannot decode {}: {e}", path.display())))?;
        let channels = frame.color_type.samples();
        let pixels = &buffer[..frame.buffer_size()];
        let grey = pixels
            .chunks_exact(channels)
            .map(|px| match px.len() {
                1 | 2 => f32::from(px[0]) / 255.0,
                _ => {
                    let [r, g, b] = [px[0], px[1], px[2]].map(|c| f32::from(c) / 255.0);
                    0.2126 * r + 0.7152 * g + 0.0722 * b
                }
            })
            .collect();
        Ok(Self {
            grey,
            size: (width, height),
            scale,
            origin,
        })
    }
}

/// A scenario's floor: background, image and marks.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Floor {
    /// Grey level of the bare floor.
    pub background: f32,
    /// The image, if any.
    pub image: Option<FloorImage>,
    /// The scenario's marks.
    pub marks: FloorMarks,
}

impl Floor {
    /// The grey level at `p`, with the task's marks `task` painted last.
    pub fn grey_at(&self, p: Vector, task: &FloorMarks) -> f32 {
        task.grey_at(p)
            .or_else(|| self.marks.grey_at(p))
            .or_else(|| self.image.as_ref().and_then(|i| i.grey_at(p)))
            .unwrap_or(self.background)
    }

    /// The mean grey level over a spot of radius `r` around `p`: the centre and 8 points at
    /// 0.7·r; the centre's alone when no image is drawn and no mark's edge crosses the spot
    /// (the same value, found 9 times faster).
    pub fn spot_grey(&self, p: Vector, r: f32, task: &FloorMarks) -> f32 {
        let centre = self.grey_at(p, task);
        if self.image.is_none() && self.marks.edge_margin(p) > r && task.edge_margin(p) > r {
            return centre;
        }
        let mut sum = centre;
        for j in 0..8 {
            let a = j as f32 * std::f32::consts::FRAC_PI_4;
            sum += self.grey_at(p + Vector::new(a.cos(), a.sin()) * (0.7 * r), task);
        }
        sum / 9.0
    }

    /// Whether nothing is drawn on it (the ground sensors then read the background).
    pub fn is_plain(&self, task: &FloorMarks) -> bool {
        self.image.is_none() && self.marks.segments.is_empty() && task.segments.is_empty()
    }
}

/// Shared floors, for a scenario (cloned into every world).
pub type SharedFloor = Arc<Floor>;

/// The segments of a polyline of `points` (m), closed or not.
pub fn polyline(points: &[Vector], closed: bool, width: f32, grey: f32) -> Vec<Segment> {
    let mut out: Vec<Segment> = points
        .windows(2)
        .map(|w| Segment {
            a: w[0],
            b: w[1],
            half_width: 0.5 * width,
            grey,
        })
        .collect();
    if closed && points.len() > 2 {
        out.push(Segment {
            a: points[points.len() - 1],
            b: points[0],
            half_width: 0.5 * width,
            grey,
        });
    }
    out
}

/// Chords (at least 2, at most [`MAX_MARK_POINTS`]) that stand within [`ARC_SAGITTA`] for an
/// arc of `radius` (m), counter-clockwise from `start` to `end` (rad).
pub fn arc_chords(radius: f32, start: f32, end: f32) -> usize {
    let sweep = (end - start).min(std::f32::consts::TAU);
    // A chord of angle φ lies r(1 − cos(φ/2)) ≈ rφ²/8 from its arc.
    let step = (8.0 * ARC_SAGITTA / radius).sqrt().min(0.5);
    ((sweep / step).ceil() as usize).clamp(2, MAX_MARK_POINTS)
}

/// The ends of the [`arc_chords`] chords that stand for an arc of `radius` (m) around `center`,
/// counter-clockwise from `start` to `end` (rad); `end − start` of 2π or more is the whole
/// circle.
pub fn arc_points(center: Vector, radius: f32, start: f32, end: f32) -> Vec<Vector> {
    let sweep = (end - start).min(std::f32::consts::TAU);
    let n = arc_chords(radius, start, end);
    (0..=n)
        .map(|k| {
            let a = start + sweep * k as f32 / n as f32;
            center + Vector::new(a.cos(), a.sin()) * radius
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segment_costs_what_the_scenario_check_counts() {
        assert_eq!(std::mem::size_of::<Segment>(), SEGMENT_BYTES);
    }
}
