//! What tasks and sensors ask the renderer to draw, in world coordinates (metres, y up): a small
//! vocabulary of marks, so that `render.rs` is the only code that knows how pixels are made and
//! a new task or sensor draws itself by pushing marks.

use rapier2d::math::Vector;

/// An RGB colour.
pub type Rgb = [u8; 3];

/// Robot and agent colours, first robot first (matplotlib's tab10, also used by the plots).
pub const PALETTE: [Rgb; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [148, 103, 189],
    [214, 39, 40],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
];

/// One thing to draw.
#[derive(Debug, Clone, PartialEq)]
pub enum Mark {
    /// A goal: a translucent disc with an outline.
    Goal {
        /// Centre (m).
        position: Vector,
        /// Radius (m).
        radius: f32,
        /// Colour.
        colour: Rgb,
    },
    /// A target point: a cross.
    Cross {
        /// Centre (m).
        position: Vector,
        /// Half the length of an arm (m).
        size: f32,
        /// Colour.
        colour: Rgb,
    },
    /// A sensor ray from `from` to `to`.
    Ray {
        /// Start (m).
        from: Vector,
        /// End (m).
        to: Vector,
        /// Colour.
        colour: Rgb,
        /// Opacity 0..255.
        alpha: u8,
        /// Line width (m).
        width: f32,
    },
    /// A dashed line from `from` to `to`: a sensor beam that reports nothing (an ultrasonic
    /// beam without echo).
    Dashed {
        /// Start (m).
        from: Vector,
        /// End (m).
        to: Vector,
        /// Colour.
        colour: Rgb,
        /// Opacity 0..255.
        alpha: u8,
        /// Line width (m).
        width: f32,
        /// Length of a dash, and of the gap after it (m).
        dash: f32,
    },
    /// A polyline (a reference path, a track).
    Path {
        /// Its points (m).
        points: Vec<Vector>,
        /// Colour.
        colour: Rgb,
        /// Opacity 0..255.
        alpha: u8,
        /// Line width (m).
        width: f32,
        /// Join the last point to the first.
        closed: bool,
    },
}
