//! Software rendering of a world to an RGB frame with tiny-skia: no display, no OpenGL.
//!
//! Drawn in world coordinates (metres, y up) through one transform to pixels (y down), so sizes
//! below are in metres: floor, walls, obstacles, then what the task asks for (goals, targets),
//! fading trails, what each robot's sensors ask for (the IR rays, green when nothing is seen and
//! toward red as an obstacle nears; the ultrasonic beams, blue, solid to an echo and dashed when
//! they report nothing), and the robots as discs with a heading mark. Tasks and sensors describe
//! themselves as [`Mark`]s; this file is the only one that turns marks into pixels.
//!
//! A frame shows the whole arena, or part of it ([`View`]: a zoom factor about a centre). Where
//! a robot is drawn smaller than [`DETAIL_MIN_PIXELS`] across (a swarm's arena in a small frame),
//! its sensors' rays and its LEDs are left out: they would only be noise at that size.

use rapier2d::math::Vector;
use tiny_skia::{
    Color, FillRule, LineCap, Paint, PathBuilder, Pixmap, Stroke, StrokeDash, Transform,
};

use crate::draw::{Mark, PALETTE};
use crate::geometry::scene::Geometry;
use crate::sensors::DrawContext;
use crate::tasks::Env;

fn paint(rgb: [u8; 3], alpha: u8) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(rgb[0], rgb[1], rgb[2], alpha);
    p.anti_alias = true;
    p
}

fn stroke(width: f32) -> Stroke {
    Stroke {
        width,
        line_cap: LineCap::Round,
        ..Stroke::default()
    }
}

fn line(a: Vector, b: Vector) -> Option<tiny_skia::Path> {
    let mut pb = PathBuilder::new();
    pb.move_to(a.x, a.y);
    pb.line_to(b.x, b.y);
    pb.finish()
}

/// Smallest diameter (pixels) at which a robot's sensor rays and LEDs are drawn.
pub const DETAIL_MIN_PIXELS: f32 = 12.0;

/// The part of the world a frame shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Magnification: 1 fits the whole arena (with its walls) in the frame; 4 shows a quarter
    /// of its width and height.
    pub zoom: f32,
    /// The world point (m) at the frame's centre: the arena's centre (the origin) by default.
    pub centre: Vector,
}

impl Default for View {
    fn default() -> Self {
        Self {
            zoom: 1.0,
            centre: Vector::ZERO,
        }
    }
}

/// Renders `env`'s whole arena into a `width` × `height` RGB frame (row-major, 3 bytes a
/// pixel).
pub fn render(env: &Env, width: u32, height: u32) -> Vec<u8> {
    render_view(env, width, height, View::default())
}

/// Renders the part `view` of `env` into a `width` × `height` RGB frame (row-major, 3 bytes a
/// pixel).
pub fn render_view(env: &Env, width: u32, height: u32, view: View) -> Vec<u8> {
    let Some(mut pixmap) = Pixmap::new(width.max(1), height.max(1)) else {
        return vec![0; (width * height * 3) as usize];
    };
    pixmap.fill(Color::from_rgba8(250, 250, 247, 255));
    let scene = &env.world.scene;
    let (aw, ah) = scene.arena;
    let t = if scene.walled {
        scene.wall_thickness
    } else {
        0.02
    };
    let fit = (width as f32 / (aw + 2.0 * t)).min(height as f32 / (ah + 2.0 * t));
    let scale = fit * view.zoom;
    let transform = Transform::from_row(
        scale,
        0.0,
        0.0,
        -scale,
        0.5 * width as f32 - scale * view.centre.x,
        0.5 * height as f32 + scale * view.centre.y,
    );
    // Walls (or the outline of an open floor).
    if scene.walled {
        for wall in scene.walls() {
            fill_shape(&mut pixmap, &wall, paint([70, 70, 70], 255), transform);
        }
    } else if let Some(rect) = tiny_skia::Rect::from_xywh(-0.5 * aw, -0.5 * ah, aw, ah) {
        let path = PathBuilder::from_rect(rect);
        pixmap.stroke_path(
            &path,
            &paint([160, 160, 160], 255),
            &stroke(0.01),
            transform,
            None,
        );
    }
    draw_floor(&mut pixmap, env, transform);
    for shape in &scene.shapes {
        // Grey as always, or the colour the camera sees when the scenario gives one.
        let colour = if shape.color == crate::geometry::scene::OBSTACLE_GREY {
            [120, 120, 120]
        } else {
            shape.color.map(|c| (c.clamp(0.0, 1.0) * 255.0) as u8)
        };
        fill_shape(&mut pixmap, shape, paint(colour, 255), transform);
    }
    // What the task draws: goals, targets.
    let mut marks = Vec::new();
    env.task_marks(&mut marks);
    for mark in &marks {
        draw_mark(&mut pixmap, mark, transform);
    }
    // Trails, fading toward the past.
    for (k, trail) in env.trails().iter().enumerate() {
        let colour = PALETTE[k % 8];
        let n = trail.len();
        for (i, pair) in trail.windows(2).enumerate() {
            let alpha = (40.0 + 200.0 * (i + 1) as f32 / n.max(1) as f32) as u8;
            if let Some(l) = line(pair[0], pair[1]) {
                pixmap.stroke_path(&l, &paint(colour, alpha), &stroke(0.006), transform, None);
            }
        }
    }
    // Sensor rays and robots.
    let radius = env.world.drive.radius;
    let detailed = 2.0 * radius * scale >= DETAIL_MIN_PIXELS;
    for (k, robot) in env.world.robots.iter().enumerate() {
        let (s, c) = robot.heading.sin_cos();
        let dir = |bearing: f32| {
            let (bs, bc) = bearing.sin_cos();
            Vector::new(c * bc - s * bs, s * bc + c * bs)
        };
        marks.clear();
        let at = DrawContext {
            position: robot.position,
            heading: robot.heading,
            radius,
        };
        if detailed {
            env.world.sensors.draw(&at, &robot.readings, &mut marks);
        }
        // Rays under the body; markers (the ground sensors' spots, under the body's front) on
        // top of it.
        let on_top = |m: &Mark| matches!(m, Mark::Cross { .. });
        for mark in marks.iter().filter(|m| !on_top(m)) {
            draw_mark(&mut pixmap, mark, transform);
        }
        let colour = PALETTE[k % 8];
        if let Some(body) = PathBuilder::from_circle(robot.position.x, robot.position.y, radius) {
            pixmap.fill_path(
                &body,
                &paint(colour, 235),
                FillRule::Winding,
                transform,
                None,
            );
            let rim = if robot.in_contact {
                [214, 39, 40]
            } else {
                [30, 30, 30]
            };
            pixmap.stroke_path(&body, &paint(rim, 255), &stroke(0.006), transform, None);
        }
        if let Some(l) = line(robot.position, robot.position + 0.9 * radius * dir(0.0)) {
            pixmap.stroke_path(
                &l,
                &paint([255, 255, 255], 255),
                &stroke(0.012),
                transform,
                None,
            );
        }
        if env.cfg.task.led_action && detailed {
            // The three top LEDs where the real robot has them: a front pair at (39, ±24) mm, one
            // at (−48, 0) mm (Webots' Khepera IV model; docs/robot.md §6), in the colour its agent
            // set.
            let rgb = robot.led.map(|c| (c * 255.0).round() as u8);
            for (x, y) in [(0.039, 0.024), (0.039, -0.024), (-0.048, 0.0)] {
                let at = robot.position + x * dir(0.0) + y * dir(std::f32::consts::FRAC_PI_2);
                if let Some(dot) = PathBuilder::from_circle(at.x, at.y, 0.011) {
                    pixmap.fill_path(&dot, &paint(rgb, 255), FillRule::Winding, transform, None);
                    let rim = paint([30, 30, 30], 255);
                    pixmap.stroke_path(&dot, &rim, &stroke(0.003), transform, None);
                }
            }
        }
        for mark in marks.iter().filter(|m| on_top(m)) {
            draw_mark(&mut pixmap, mark, transform);
        }
    }
    // Premultiplied RGBA over an opaque background is plain RGB.
    pixmap
        .data()
        .chunks_exact(4)
        .flat_map(|px| [px[0], px[1], px[2]])
        .collect()
}

fn draw_mark(pixmap: &mut Pixmap, mark: &Mark, transform: Transform) {
    match mark {
        Mark::Goal {
            position,
            radius,
            colour,
        } => {
            if let Some(c) = PathBuilder::from_circle(position.x, position.y, *radius) {
                pixmap.fill_path(&c, &paint(*colour, 70), FillRule::Winding, transform, None);
                pixmap.stroke_path(&c, &paint(*colour, 255), &stroke(0.006), transform, None);
            }
        }
        Mark::Cross {
            position,
            size,
            colour,
        } => {
            let d = *size;
            for (a, b) in [
                (Vector::new(-d, -d), Vector::new(d, d)),
                (Vector::new(-d, d), Vector::new(d, -d)),
            ] {
                if let Some(l) = line(*position + a, *position + b) {
                    pixmap.stroke_path(&l, &paint(*colour, 220), &stroke(0.008), transform, None);
                }
            }
        }
        Mark::Ray {
            from,
            to,
            colour,
            alpha,
            width,
        } => {
            if let Some(l) = line(*from, *to) {
                pixmap.stroke_path(
                    &l,
                    &paint(*colour, *alpha),
                    &stroke(*width),
                    transform,
                    None,
                );
            }
        }
        Mark::Dashed {
            from,
            to,
            colour,
            alpha,
            width,
            dash,
        } => {
            if let Some(l) = line(*from, *to) {
                let mut pen = stroke(*width);
                pen.line_cap = LineCap::Butt;
                pen.dash = StrokeDash::new(vec![*dash, *dash], 0.0);
                pixmap.stroke_path(&l, &paint(*colour, *alpha), &pen, transform, None);
            }
        }
        Mark::Path {
            points,
            colour,
            alpha,
            width,
            closed,
        } => {
            let mut pb = PathBuilder::new();
            if let Some(first) = points.first() {
                pb.move_to(first.x, first.y);
                for p in &points[1..] {
                    pb.line_to(p.x, p.y);
                }
                if *closed {
                    pb.close();
                }
            }
            if let Some(path) = pb.finish() {
                pixmap.stroke_path(
                    &path,
                    &paint(*colour, *alpha),
                    &stroke(*width),
                    transform,
                    None,
                );
            }
        }
    }
}

fn fill_shape(
    pixmap: &mut Pixmap,
    shape: &crate::geometry::scene::SceneShape,
    paint: Paint,
    transform: Transform,
) {
    let (s, c) = shape.angle.sin_cos();
    let at = |x: f32, y: f32| shape.center + Vector::new(c * x - s * y, s * x + c * y);
    match shape.geometry {
        Geometry::Circle(b) => {
            if let Some(p) = PathBuilder::from_circle(shape.center.x, shape.center.y, b.radius) {
                pixmap.fill_path(&p, &paint, FillRule::Winding, transform, None);
            }
        }
        Geometry::Box(b) => {
            let (hx, hy) = (b.half_extents.x, b.half_extents.y);
            let mut pb = PathBuilder::new();
            let corners = [at(-hx, -hy), at(hx, -hy), at(hx, hy), at(-hx, hy)];
            pb.move_to(corners[0].x, corners[0].y);
            for p in &corners[1..] {
                pb.line_to(p.x, p.y);
            }
            pb.close();
            if let Some(p) = pb.finish() {
                pixmap.fill_path(&p, &paint, FillRule::Winding, transform, None);
            }
        }
        Geometry::Segment(g) => {
            if let Some(l) = line(shape.center + g.a, shape.center + g.b) {
                pixmap.stroke_path(&l, &paint, &stroke(0.02), transform, None);
            }
        }
    }
}

/// The floor's image and marks (grey levels as greys), under everything else.
fn draw_floor(pixmap: &mut Pixmap, env: &Env, transform: Transform) {
    let floor = &env.world.floor;
    let grey = |g: f32| {
        let v = (g.clamp(0.0, 1.0) * 255.0) as u8;
        [v, v, v]
    };
    if let Some(image) = &floor.image {
        let (w, h) = image.size;
        if let Some(mut pixels) = Pixmap::new(w, h) {
            for (px, g) in pixels.pixels_mut().iter_mut().zip(&image.grey) {
                let v = (g.clamp(0.0, 1.0) * 255.0) as u8;
                *px = tiny_skia::PremultipliedColorU8::from_rgba(v, v, v, 255)
                    .unwrap_or(tiny_skia::PremultipliedColorU8::TRANSPARENT);
            }
            // Pixel (column, row) covers origin + (column, h − 1 − row) · scale.
            let s = image.scale;
            let place = Transform::from_row(
                s,
                0.0,
                0.0,
                -s,
                image.origin.x,
                image.origin.y + h as f32 * s,
            );
            pixmap.draw_pixmap(
                0,
                0,
                pixels.as_ref(),
                &tiny_skia::PixmapPaint::default(),
                transform.pre_concat(place),
                None,
            );
        }
    }
    let segments = floor
        .marks
        .segments()
        .iter()
        .chain(env.world.floor_marks.segments());
    for segment in segments {
        if let Some(l) = line(segment.a, segment.b) {
            let mut pen = stroke(2.0 * segment.half_width);
            pen.line_cap = tiny_skia::LineCap::Round;
            pixmap.stroke_path(&l, &paint(grey(segment.grey), 255), &pen, transform, None);
        }
    }
}
