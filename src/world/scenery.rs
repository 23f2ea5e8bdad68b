//! The fixed scenery a scenario describes, as the plain geometry the world runs on: its
//! `[arena]` and `obstacles.fixed` as a [`Scene`], its `[floor]` as a [`Floor`] (marks as
//! segments, the image decoded). The spawner builds them once per batch.
//!
//! Units: metres, radians; world frame, arena centred at the origin.

use std::path::Path;

use rapier2d::math::Vector;

use crate::error::Result;
use crate::geometry::floor::{arc_points, polyline, Floor, FloorImage, FloorMarks};
use crate::geometry::scene::{Scene, SceneShape};
use crate::scenario::{ArenaConfig, FloorConfig, ObstacleSpec};

/// The empty arena a scenario's `[arena]` table describes.
pub fn arena(arena: &ArenaConfig) -> Scene {
    Scene {
        walled: arena.walls,
        wall_reflectance: arena.wall_reflectance,
        wall_color: arena.wall_color,
        ..Scene::arena(arena.width, arena.height, arena.wall_thickness)
    }
}

/// A scenario's fixed obstacle (an `obstacles.fixed` entry) as a scene shape.
pub fn obstacle(spec: &ObstacleSpec) -> SceneShape {
    let v = |p: [f32; 2]| Vector::new(p[0], p[1]);
    let (shape, reflectance, color) = match *spec {
        ObstacleSpec::Circle {
            center,
            radius,
            reflectance,
            color,
        } => (SceneShape::circle(v(center), radius), reflectance, color),
        ObstacleSpec::Box {
            center,
            half_extents,
            angle,
            reflectance,
            color,
        } => (
            SceneShape::rect(v(center), v(half_extents), angle),
            reflectance,
            color,
        ),
        ObstacleSpec::Segment {
            a,
            b,
            reflectance,
            color,
        } => (SceneShape::segment(v(a), v(b)), reflectance, color),
    };
    let shape = shape.with_reflectance(reflectance);
    match color {
        Some(color) => shape.with_color(color),
        None => shape,
    }
}

/// The floor a scenario's `[floor]` describes (its marks as segments, its image decoded);
/// `dir` is the scenario file's folder (relative image paths start there). The marks were
/// checked with the scenario ([`FloorConfig::check`]); errors (an image that cannot be
/// read) name `origin` and the key.
pub fn floor(cfg: &FloorConfig, dir: Option<&Path>, origin: &str) -> Result<Floor> {
    cfg.check(origin)?;
    let mut segments = Vec::new();
    for l in &cfg.lines {
        let (a, b) = (Vector::from(l.a), Vector::from(l.b));
        segments.extend(polyline(&[a, b], false, l.width, l.grey));
    }
    for arc in &cfg.arcs {
        let c = Vector::from(arc.center);
        let points = arc_points(c, arc.radius, arc.start, arc.end);
        segments.extend(polyline(&points, false, arc.width, arc.grey));
    }
    for t in &cfg.tracks {
        let points: Vec<Vector> = t.points.iter().map(|p| Vector::from(*p)).collect();
        segments.extend(polyline(&points, t.closed, t.width, t.grey));
    }
    let image = if cfg.image.is_empty() {
        None
    } else {
        let path = Path::new(&cfg.image);
        let path = match dir {
            Some(dir) if path.is_relative() => dir.join(path),
            _ => path.to_path_buf(),
        };
        let origin_m = Vector::from(cfg.image_origin);
        Some(FloorImage::load(&path, cfg.image_scale, origin_m, origin)?)
    };
    Ok(Floor {
        background: cfg.background,
        image,
        marks: FloorMarks::new(segments),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::floor::LineMark;

    #[test]
    fn a_line_covers_exactly_its_width_and_later_marks_paint_over() {
        let cfg = FloorConfig {
            lines: vec![
                LineMark {
                    a: [-1.0, 0.0],
                    b: [1.0, 0.0],
                    width: 0.027,
                    grey: 0.0,
                },
                LineMark {
                    a: [0.5, -1.0],
                    b: [0.5, 1.0],
                    width: 0.1,
                    grey: 0.5,
                },
            ],
            ..FloorConfig::default()
        };
        let floor = floor(&cfg, None, "t").expect("floor");
        let none = FloorMarks::default();
        assert_eq!(floor.grey_at(Vector::new(0.0, 0.0134), &none), 0.0);
        assert_eq!(floor.grey_at(Vector::new(0.0, 0.0136), &none), 1.0);
        assert_eq!(floor.grey_at(Vector::new(0.5, 0.0), &none), 0.5);
    }
}
