//! `[floor]`: what the ground sensors see, as plain data: a background grey level, an optional
//! grey-scale image (a path), and marks drawn over it (lines, arcs and polylines with a width
//! and a grey level). [`FloorConfig::check`] checks what the keys' domains cannot; the world
//! builds the floor from it (`world::scenery::floor`: marks as segments, image decoded), once
//! per batch. Grey levels run from 0 (black) to 1 (white paper).
//!
//! Units: metres, radians; world frame (x right, y up).

use serde::{Deserialize, Serialize};

use crate::config::{limits, Domain, Field};
use crate::error::{Error, Result};
use crate::geometry::floor::{arc_chords, MAX_MARK_POINTS, SEGMENT_BYTES};

/// Most segments of a scenario's floor marks (lines, arcs' chords and polylines' sides
/// together): [`SEGMENT_BYTES`] each, 24 MB at most, shared by every world.
pub const MAX_FLOOR_SEGMENTS: usize = 1_000_000;
/// Widest mark (m).
const MAX_MARK_WIDTH: f64 = 10.0;
/// A floor coordinate or angle: finite and within [`limits::LENGTH`].
const COORDINATE: Domain = Domain::range(-limits::LENGTH, limits::LENGTH);
/// A mark's width (m).
const WIDTH: Domain = Domain::POSITIVE.at_most(MAX_MARK_WIDTH);

/// The fields of a `floor.lines` entry.
const LINE_FIELDS: &[Field] = &[
    Field::new("a", "[f32; 2]", COORDINATE),
    Field::new("b", "[f32; 2]", COORDINATE),
    Field::new("width", "f32", WIDTH),
    Field::new("grey", "f32", Domain::UNIT),
];
/// The fields of a `floor.arcs` entry.
const ARC_FIELDS: &[Field] = &[
    Field::new("center", "[f32; 2]", COORDINATE),
    Field::new("radius", "f32", Domain::POSITIVE.at_most(limits::LENGTH)),
    Field::new("start", "f32", COORDINATE),
    Field::new("end", "f32", COORDINATE),
    Field::new("width", "f32", WIDTH),
    Field::new("grey", "f32", Domain::UNIT),
];
/// The fields of a `floor.tracks` entry.
const TRACK_FIELDS: &[Field] = &[
    Field::new(
        "points",
        "Vec<[f32; 2]>",
        COORDINATE.between_entries(2, MAX_MARK_POINTS),
    ),
    Field::new("width", "f32", WIDTH),
    Field::new("grey", "f32", Domain::UNIT),
];

/// A straight mark.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LineMark {
    /// One end (m).
    pub a: [f32; 2],
    /// The other end (m).
    pub b: [f32; 2],
    /// Width (m).
    pub width: f32,
    /// Grey level, 0 black .. 1 white.
    #[serde(default)]
    pub grey: f32,
}

/// An arc of a circle, counter-clockwise from `start` to `end` (rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArcMark {
    /// Centre (m).
    pub center: [f32; 2],
    /// Radius (m).
    pub radius: f32,
    /// Start angle (rad, from +x).
    pub start: f32,
    /// End angle (rad); `end − start` of 2π or more draws the whole circle.
    pub end: f32,
    /// Width (m).
    pub width: f32,
    /// Grey level.
    #[serde(default)]
    pub grey: f32,
}

/// A polyline; a closed one is a track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackMark {
    /// Its points (m).
    pub points: Vec<[f32; 2]>,
    /// Whether the last point joins the first.
    #[serde(default)]
    pub closed: bool,
    /// Width (m).
    pub width: f32,
    /// Grey level.
    #[serde(default)]
    pub grey: f32,
}

crate::config_table! {
    /// `[floor]`: what the ground sensors see.
    pub struct FloorConfig {
        /// grey level of the bare floor, 0 black .. 1 white paper
        background: f32 = 1.0 => Domain::UNIT,
        /// straight marks {a = [x, y], b = [x, y], width (m), grey (0 black, the default)}
        lines: Vec<LineMark> = [] => Domain::tables(LINE_FIELDS),
        /// arcs {center = [x, y], radius, start, end (rad, counter-clockwise), width, grey}
        arcs: Vec<ArcMark> = [] => Domain::tables(ARC_FIELDS),
        /// polylines {points = [[x, y], ...], closed (a track), width, grey}
        tracks: Vec<TrackMark> = [] => Domain::tables(TRACK_FIELDS),
        /// grey-scale PNG under the marks ("" = none), a path relative to the scenario file
        image: String = "",
        /// m per pixel of the image
        image_scale: f32 = 0.01 => Domain::POSITIVE.at_most(1.0),
        /// m, world position of the image's lower-left corner
        image_origin: [f32; 2] = [-1.0, -1.0] => COORDINATE,
    }
}

impl FloorConfig {
    /// Checks what the keys' domains cannot: an arc's direction, and the number of segments
    /// all marks make together. Errors name `origin` and the key.
    pub fn check(&self, origin: &str) -> Result<()> {
        let bad =
            |key: &str, message: String| -> Result<()> { Err(Error::config(origin, key, message)) };
        if let Some(i) = self.arcs.iter().position(|arc| arc.end <= arc.start) {
            return bad(
                "floor.arcs",
                format!("entry {i}: needs end > start (counter-clockwise)"),
            );
        }
        let counts = [
            ("floor.lines", self.lines.len()),
            (
                "floor.arcs",
                self.arcs
                    .iter()
                    .map(|arc| arc_chords(arc.radius, arc.start, arc.end))
                    .sum(),
            ),
            (
                "floor.tracks",
                self.tracks.iter().map(|t| t.points.len()).sum(),
            ),
        ];
        let total: usize = counts.iter().map(|(_, n)| n).sum();
        if total > MAX_FLOOR_SEGMENTS {
            let (key, _) = counts
                .iter()
                .max_by_key(|(_, n)| *n)
                .copied()
                .unwrap_or(counts[0]);
            let bytes = total * SEGMENT_BYTES;
            return bad(
                key,
                format!(
                    "the floor's marks make {total} segments ({:.0} MB), more than the limit of \
                     {MAX_FLOOR_SEGMENTS} ({:.0} MB): fewer or shorter marks, or arcs of a \
                     smaller radius",
                    bytes as f64 / 1e6,
                    (MAX_FLOOR_SEGMENTS * SEGMENT_BYTES) as f64 / 1e6
                ),
            );
        }
        Ok(())
    }
}
