//! Static scene geometry (arena walls and obstacles) and the exact queries on it: ray casts for
//! the range sensors and point distances for contact checks. Shapes are parry2d shapes (rapier's
//! geometry crate), queried one by one in their local frames after a cheap bounding-circle test;
//! for scenes of a few dozen shapes that is several times faster than a query pipeline. Built
//! from plain sizes and shapes: the world turns a scenario's `[arena]` and `obstacles.fixed`
//! into them (`world/scenery.rs`).
//!
//! Frame: world frame, metres, the arena's centre at the origin, angles CCW in radians.

use rapier2d::math::{Pose, Vector};
use rapier2d::parry::query::{PointQuery, Ray, RayCast};
use rapier2d::parry::shape::{Ball, Cuboid, Segment, Shape};

use super::rays::{may_hit, ray_disc};

/// One of the scene's shapes, as parry2d knows it, in its local frame.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub enum Geometry {
    /// A disc (cylindrical obstacle).
    Circle(Ball),
    /// A rectangle (box obstacle or a wall slab).
    Box(Cuboid),
    /// A thin wall segment.
    Segment(Segment),
}

/// A static shape placed in the world.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct SceneShape {
    /// The shape in its local frame.
    pub geometry: Geometry,
    /// Position of the local frame's origin (m).
    pub center: Vector,
    /// Rotation of the local frame (rad).
    pub angle: f32,
    cos: f32,
    sin: f32,
    /// Radius of a circle around `center` that contains the shape (m).
    pub bound_radius: f32,
    /// Infrared reflectance relative to white paper (1 = K-Team's response curve).
    #[serde(default = "white")]
    pub reflectance: f32,
    /// Colour the camera sees, RGB in [0, 1].
    pub color: [f32; 3],
}

fn white() -> f32 {
    1.0
}

/// The colour of obstacles that give none (a mid grey).
pub const OBSTACLE_GREY: [f32; 3] = [0.5, 0.5, 0.5];
/// The colour of walls that give none (a light grey).
pub const WALL_GREY: [f32; 3] = [0.8, 0.8, 0.8];

impl SceneShape {
    /// Places `geometry` at `center`, rotated by `angle`.
    pub fn new(geometry: Geometry, center: Vector, angle: f32) -> Self {
        let bound_radius = match geometry {
            Geometry::Circle(b) => b.radius,
            Geometry::Box(c) => c.half_extents.length(),
            Geometry::Segment(s) => s.a.length().max(s.b.length()),
        };
        Self {
            geometry,
            center,
            angle,
            cos: angle.cos(),
            sin: angle.sin(),
            bound_radius,
            reflectance: 1.0,
            color: OBSTACLE_GREY,
        }
    }

    /// The same shape with the camera colour `color` (RGB in [0, 1]).
    pub fn with_color(mut self, color: [f32; 3]) -> Self {
        self.color = color;
        self
    }

    /// The same shape with infrared `reflectance` (relative to white paper).
    pub fn with_reflectance(mut self, reflectance: f32) -> Self {
        self.reflectance = reflectance;
        self
    }

    /// A disc of `radius` at `center`.
    pub fn circle(center: Vector, radius: f32) -> Self {
        Self::new(Geometry::Circle(Ball::new(radius)), center, 0.0)
    }

    /// A rectangle with half extents `half`, centred at `center`, rotated by `angle`.
    pub fn rect(center: Vector, half: Vector, angle: f32) -> Self {
        Self::new(Geometry::Box(Cuboid::new(half)), center, angle)
    }

    /// Free distance between this shape and `other` (0 when they touch or overlap).
    pub fn gap(&self, other: &SceneShape) -> f32 {
        if (self.center - other.center).length() - self.bound_radius - other.bound_radius > 1.0 {
            return (self.center - other.center).length() - self.bound_radius - other.bound_radius;
        }
        let d = rapier2d::parry::query::distance(
            &Pose::new(self.center, self.angle),
            self.parry_shape(),
            &Pose::new(other.center, other.angle),
            other.parry_shape(),
        );
        // Every pair of these convex primitives is supported; fall back to the bounding circles.
        d.map(|d| d.distance).unwrap_or_else(|_| {
            ((self.center - other.center).length() - self.bound_radius - other.bound_radius)
                .max(0.0)
        })
    }

    fn parry_shape(&self) -> &dyn Shape {
        match &self.geometry {
            Geometry::Circle(s) => s,
            Geometry::Box(s) => s,
            Geometry::Segment(s) => s,
        }
    }

    /// Smallest gap between the shape and the walls of an arena `width` × `height` centred at
    /// the origin (negative when it sticks out).
    pub fn wall_gap(&self, width: f32, height: f32) -> f32 {
        let (hw, hh) = (0.5 * width, 0.5 * height);
        let (ex, ey) = self.extent();
        (hw - (self.center.x.abs() + ex)).min(hh - (self.center.y.abs() + ey))
    }

    /// Half extents of the shape's axis-aligned bounding box.
    pub fn extent(&self) -> (f32, f32) {
        let (c, s) = (self.cos.abs(), self.sin.abs());
        match self.geometry {
            Geometry::Circle(b) => (b.radius, b.radius),
            Geometry::Box(b) => (
                c * b.half_extents.x + s * b.half_extents.y,
                s * b.half_extents.x + c * b.half_extents.y,
            ),
            Geometry::Segment(g) => (g.a.x.abs().max(g.b.x.abs()), g.a.y.abs().max(g.b.y.abs())),
        }
    }

    /// A segment from `a` to `b` (world coordinates).
    pub fn segment(a: Vector, b: Vector) -> Self {
        let mid = 0.5 * (a + b);
        Self::new(Geometry::Segment(Segment::new(a - mid, b - mid)), mid, 0.0)
    }

    #[inline]
    fn point_to_local(&self, p: Vector) -> Vector {
        let d = p - self.center;
        Vector::new(
            self.cos * d.x + self.sin * d.y,
            -self.sin * d.x + self.cos * d.y,
        )
    }

    #[inline]
    fn dir_to_local(&self, d: Vector) -> Vector {
        Vector::new(
            self.cos * d.x + self.sin * d.y,
            -self.sin * d.x + self.cos * d.y,
        )
    }

    /// Distance along the unit ray (`origin`, `dir`) to the shape's surface, if within `max`.
    /// A ray starting inside a solid shape hits at 0.
    #[inline]
    pub fn cast(&self, origin: Vector, dir: Vector, max: f32) -> Option<f32> {
        let ray = Ray::new(self.point_to_local(origin), self.dir_to_local(dir));
        match &self.geometry {
            Geometry::Circle(s) => s.cast_local_ray(&ray, max, true),
            Geometry::Box(s) => s.cast_local_ray(&ray, max, true),
            Geometry::Segment(s) => s.cast_local_ray(&ray, max, true),
        }
    }

    /// Signed distance from `point` to the shape's surface (negative inside a solid shape) and
    /// the unit normal of the surface toward `point` (world frame): the direction a disc centred
    /// at `point` is pushed out along. None when `point` lies on the surface or, for a segment,
    /// on it (no direction).
    #[inline]
    pub fn surface_normal(&self, point: Vector) -> Option<(f32, Vector)> {
        let p = self.point_to_local(point);
        let (distance, local) = match &self.geometry {
            Geometry::Circle(s) => {
                let l = p.length();
                (l > 0.0).then(|| (l - s.radius, p / l))?
            }
            Geometry::Box(s) => {
                let projection = s.project_local_point(p, false);
                let away = p - projection.point;
                let l = away.length();
                if l <= 0.0 {
                    return None;
                }
                if projection.is_inside {
                    (-l, -away / l)
                } else {
                    (l, away / l)
                }
            }
            Geometry::Segment(s) => {
                let away = p - s.project_local_point(p, true).point;
                let l = away.length();
                (l > 0.0).then(|| (l, away / l))?
            }
        };
        let normal = Vector::new(
            self.cos * local.x - self.sin * local.y,
            self.sin * local.x + self.cos * local.y,
        );
        Some((distance, normal))
    }

    /// Distance from `point` to the shape (0 inside it).
    #[inline]
    pub fn distance(&self, point: Vector) -> f32 {
        let p = self.point_to_local(point);
        match &self.geometry {
            Geometry::Circle(s) => (p.length() - s.radius).max(0.0),
            Geometry::Box(s) => s.distance_to_local_point(p, true),
            Geometry::Segment(s) => s.distance_to_local_point(p, true),
        }
    }
}

/// The static geometry of one world: a walled rectangular arena centred at the origin and the
/// obstacles inside it. The walls are slabs lying outside the inner rectangle; queries against
/// them are answered in closed form (the inside of an axis-aligned rectangle), which gives the
/// same distances as casting on the slabs.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Scene {
    /// Arena inner width and height (m).
    pub arena: (f32, f32),
    /// Thickness of the wall slabs (m).
    pub wall_thickness: f32,
    /// Whether the arena is walled (an open arena only bounds spawning).
    pub walled: bool,
    /// Infrared reflectance of the walls relative to white paper.
    #[serde(default = "white")]
    pub wall_reflectance: f32,
    /// Colour of the walls for the camera (RGB in [0, 1]).
    pub wall_color: [f32; 3],
    /// Obstacles (not the walls).
    pub shapes: Vec<SceneShape>,
}

impl Scene {
    /// An empty arena of inner size `width` × `height`, walled by slabs `thickness` thick.
    pub fn arena(width: f32, height: f32, thickness: f32) -> Self {
        Self {
            arena: (width, height),
            wall_thickness: thickness,
            walled: true,
            wall_reflectance: 1.0,
            wall_color: WALL_GREY,
            shapes: Vec::new(),
        }
    }

    /// The four wall slabs as shapes (for the physics world).
    pub fn walls(&self) -> [SceneShape; 4] {
        let (hw, hh, t) = (
            0.5 * self.arena.0,
            0.5 * self.arena.1,
            0.5 * self.wall_thickness,
        );
        [
            SceneShape::rect(Vector::new(hw + t, 0.0), Vector::new(t, hh + 2.0 * t), 0.0),
            SceneShape::rect(Vector::new(-hw - t, 0.0), Vector::new(t, hh + 2.0 * t), 0.0),
            SceneShape::rect(Vector::new(0.0, hh + t), Vector::new(hw + 2.0 * t, t), 0.0),
            SceneShape::rect(Vector::new(0.0, -hh - t), Vector::new(hw + 2.0 * t, t), 0.0),
        ]
    }

    /// Nearest hit along the unit ray (`origin`, `dir`) within `max` metres, against the walls,
    /// the obstacles and the discs of radius `disc_radius` at `discs` (other robots).
    #[inline]
    pub fn cast(
        &self,
        origin: Vector,
        dir: Vector,
        max: f32,
        discs: &[Vector],
        disc_radius: f32,
    ) -> Option<f32> {
        self.cast_among(origin, dir, max, self.shapes.iter(), discs, disc_radius)
    }

    /// Like [`Scene::cast`], against only the obstacles `shapes` (a pre-culled subset).
    #[inline]
    pub fn cast_among<'a>(
        &self,
        origin: Vector,
        dir: Vector,
        max: f32,
        shapes: impl Iterator<Item = &'a SceneShape>,
        discs: &[Vector],
        disc_radius: f32,
    ) -> Option<f32> {
        self.cast_hit(origin, dir, max, shapes, discs, &[], disc_radius)
            .map(|hit| hit.distance)
    }

    /// Like [`Scene::cast_among`], also saying what was hit (for its surface normal and
    /// reflectance). `ids` are the discs' robot indices when `discs` are not in robot order,
    /// or empty when they are: of two discs met at exactly the same distance the hit is the
    /// one of larger index, as a scan in robot order gives, whatever the order of `discs`.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn cast_hit<'a>(
        &self,
        origin: Vector,
        dir: Vector,
        max: f32,
        shapes: impl Iterator<Item = &'a SceneShape>,
        discs: &[Vector],
        ids: &[u32],
        disc_radius: f32,
    ) -> Option<Hit<'a>> {
        let mut best = max;
        let mut target = None;
        let wall = self.cast_walls(origin, dir);
        if wall <= best {
            best = wall;
            target = Some(Target::Wall);
        }
        for shape in shapes {
            if !may_hit(origin, dir, shape.center, shape.bound_radius, best) {
                continue;
            }
            if let Some(t) = shape.cast(origin, dir, best) {
                if t <= best {
                    best = t;
                    target = Some(Target::Shape(shape));
                }
            }
        }
        if ids.is_empty() {
            // In robot order a disc met at the distance so far (`t == best`) comes later: it
            // takes the hit, over a shape or an earlier disc.
            for &c in discs {
                if let Some(t) = ray_disc(origin, dir, c, disc_radius, best) {
                    best = t;
                    target = Some(Target::Disc(c));
                }
            }
        } else {
            // In any other order, the same choice: nearer, or as near and of larger index
            // (`key` = index + 1, 0 for a shape, the wall or nothing, which a disc met at the
            // same distance replaces as above).
            debug_assert_eq!(ids.len(), discs.len(), "one index per disc");
            let mut best_key = 0;
            for (&c, &id) in discs.iter().zip(ids) {
                if let Some(t) = ray_disc(origin, dir, c, disc_radius, best) {
                    let key = id + 1;
                    if t < best || key > best_key {
                        best = t;
                        best_key = key;
                        target = Some(Target::Disc(c));
                    }
                }
            }
        }
        target.map(|target| Hit {
            distance: best,
            origin,
            dir,
            target,
        })
    }

    /// Distance along a unit ray to the walls: where it leaves the inner rectangle (0 when it
    /// starts outside it, i.e. inside a wall).
    #[inline(always)]
    pub fn cast_walls(&self, o: Vector, d: Vector) -> f32 {
        if !self.walled {
            return f32::INFINITY;
        }
        let (hw, hh) = (0.5 * self.arena.0, 0.5 * self.arena.1);
        if o.x.abs() >= hw || o.y.abs() >= hh {
            return 0.0;
        }
        // The wall the ray heads for along each axis is the one on the side of its direction's
        // sign. Written without branches (rays point every way, so a branch on the sign is
        // mispredicted about half the time): for a component of +0 or -0 the division gives
        // +inf, since the origin lies strictly inside (the numerator has the zero's sign).
        let tx = (hw.copysign(d.x) - o.x) / d.x;
        let ty = (hh.copysign(d.y) - o.y) / d.y;
        tx.min(ty)
    }

    /// Smallest distance from `point` to the walls or any obstacle (0 inside one).
    pub fn clearance(&self, point: Vector) -> f32 {
        let (hw, hh) = (0.5 * self.arena.0, 0.5 * self.arena.1);
        let mut best = if self.walled {
            (hw - point.x.abs()).min(hh - point.y.abs()).max(0.0)
        } else {
            f32::INFINITY
        };
        for shape in &self.shapes {
            // The bounding circle gives a lower bound: skip shapes that cannot be closer.
            if (point - shape.center).length() - shape.bound_radius >= best {
                continue;
            }
            best = best.min(shape.distance(point));
        }
        best
    }
}

/// What a ray hit.
#[derive(Debug, Clone, Copy)]
pub enum Target<'a> {
    /// An arena wall.
    Wall,
    /// An obstacle.
    Shape(&'a SceneShape),
    /// A robot's disc, centred there.
    Disc(Vector),
}

/// A ray's nearest hit.
#[derive(Debug, Clone, Copy)]
pub struct Hit<'a> {
    /// Distance along the ray (m).
    pub distance: f32,
    /// The ray's origin (m).
    pub origin: Vector,
    /// The ray's unit direction.
    pub dir: Vector,
    /// What it hit.
    pub target: Target<'a>,
}

impl Hit<'_> {
    /// The cosine of the angle between the ray and the surface's normal at the hit (1 head-on,
    /// 0 grazing); 1 when the ray starts inside what it hits.
    pub fn incidence_cos(&self, scene: &Scene, disc_radius: f32) -> f32 {
        let point = self.origin + self.distance * self.dir;
        let normal = match self.target {
            Target::Wall => {
                let (hw, hh) = (0.5 * scene.arena.0, 0.5 * scene.arena.1);
                // The face the ray leaves the inner rectangle through.
                if (hw - point.x.abs()) < (hh - point.y.abs()) {
                    Vector::new(-point.x.signum(), 0.0)
                } else {
                    Vector::new(0.0, -point.y.signum())
                }
            }
            Target::Shape(shape) => {
                let ray = Ray::new(
                    shape.point_to_local(self.origin),
                    shape.dir_to_local(self.dir),
                );
                let local = match &shape.geometry {
                    Geometry::Circle(g) => {
                        g.cast_local_ray_and_get_normal(&ray, self.distance + 1e-3, true)
                    }
                    Geometry::Box(g) => {
                        g.cast_local_ray_and_get_normal(&ray, self.distance + 1e-3, true)
                    }
                    Geometry::Segment(g) => {
                        g.cast_local_ray_and_get_normal(&ray, self.distance + 1e-3, true)
                    }
                };
                match local {
                    Some(i) => Vector::new(
                        shape.cos * i.normal.x - shape.sin * i.normal.y,
                        shape.sin * i.normal.x + shape.cos * i.normal.y,
                    ),
                    None => return 1.0,
                }
            }
            Target::Disc(centre) => (point - centre) / disc_radius.max(f32::EPSILON),
        };
        if self.distance <= 0.0 {
            return 1.0;
        }
        (-self.dir.dot(normal)).abs().min(1.0)
    }

    /// The infrared reflectance of what was hit, relative to white paper; `disc` is the robots'.
    pub fn reflectance(&self, scene: &Scene, disc: f32) -> f32 {
        match self.target {
            Target::Wall => scene.wall_reflectance,
            Target::Shape(shape) => shape.reflectance,
            Target::Disc(_) => disc,
        }
    }
}

#[cfg(test)]
mod tests;
