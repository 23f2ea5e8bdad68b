//! Robots against walls and obstacles without rapier (`physics.scene_solver = "disc"`, traction
//! drive): in a substep in which some robot can touch the scene but no robot can touch another,
//! each robot is moved as a rigid disc meeting the static shapes within its reach. Contacts
//! between robots, and every substep where one is possible, stay with rapier (`physics.rs`).
//!
//! Model, per robot and substep of `h` seconds (mass m, radius R, moment of inertia I = m R²/2,
//! a uniform disc [E] as in `physics.rs`):
//! 1. The tyres' impulses (`tyres::tyre_impulses`), as before a rapier step.
//! 2. One contact per shape within the disc's reach in the substep: the normal n points from the
//!    shape's nearest point to the disc's centre, the gap d is the distance between shell and
//!    shape (negative: overlap), and the contact point lies on the shell, at centre − R n.
//!    - Normal impulse J_n ≥ 0, no restitution, speculative: the centre's velocity along n
//!      stays at least −max(d, 0)/h, so a gap closes by the end of the substep and no faster.
//!      The distance to a convex shape is convex in the centre's position, so holding its
//!      linearisation at or above 0 never lets the disc in (around a curved shape it may hold
//!      the disc off by a hair's breadth within one substep).
//!    - Coulomb friction at the contact point: |J_t| ≤ μ J_n (μ = `physics.friction`), which
//!      also spins the disc (the point's tangential velocity is v·t − ω R).
//!    - A disc meeting several shapes (a corner) has its contacts solved together:
//!      Gauss–Seidel sweeps over the accumulated impulses until they stop changing. One contact
//!      takes one sweep, which is then exact: for a disc the normal and tangential impulses do
//!      not couple (the normal passes through the centre).
//! 3. Integration as rapier integrates a free body: centre + v·h, heading + ω·h.
//! 4. An overlap left by an earlier rapier step (rapier lets shapes sink by up to its allowed
//!    error) is pushed out along its normal, by at most [`MAX_PUSHOUT_SPEED`]·h per substep,
//!    without changing the velocity.
//!
//! Left out: rapier's soft contacts (compliance, allowed penetration): contacts here are rigid;
//! rolling resistance; the shape's motion (the scene is static); contacts between robots.
//!
//! Units: metres, seconds, radians, kg; world frame, arena centred at the origin.

use rapier2d::math::Vector;

use super::motion::{roll_arc, speed_bound, CONTACT_MARGIN};
use super::team::CHUNK;
use super::tyres::{tyre_impulses, Grip, TractionBody, GRAVITY};
use super::{Robot, World};
use crate::geometry::scene::Scene;
use crate::robot::wrap_angle;

// The four constants below are numerical choices of this solver, not properties of the robot
// or of a surface; none of them changes a contact the tests of `tests/dynamics.rs` specify.

/// Most contacts a robot keeps in one substep (the nearest ones; a disc meets at most three or
/// four shapes at a time in any scene of the tasks).
pub const MAX_CONTACTS: usize = 6;
/// Most Gauss–Seidel sweeps over a robot's contacts in one substep (a corner of two walls
/// settles in a few; the cap only bounds the cost of a degenerate pile of shapes).
const MAX_SWEEPS: usize = 16;
/// Sweeps stop once no impulse changed by more than this times the mass (N·s per kg: 0.1 µm/s,
/// far below what a sensor or the observation resolves).
const IMPULSE_TOLERANCE: f32 = 1e-7;
/// Fastest an overlap is pushed out (m/s): 2.5 mm per default substep of 25 ms. An overlap only
/// comes from an earlier rapier step, which lets shapes sink by up to its allowed error
/// (rapier2d 0.36's `normalized_allowed_linear_error`, 5 mm at our 1 m length unit) and corrects
/// at up to its `normalized_max_corrective_velocity` (3 m/s); the slower push here keeps the
/// correction from reading as a jump of the robot.
pub const MAX_PUSHOUT_SPEED: f32 = 0.1;

/// One contact of a disc with a shape of the scene.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Contact {
    /// Unit normal from the shape toward the disc's centre (world frame).
    pub normal: Vector,
    /// Distance between the shell and the shape (m); negative when they overlap.
    pub gap: f32,
}

/// A disc's contacts in one substep: the nearest [`MAX_CONTACTS`], without allocation.
#[derive(Debug, Clone, Copy, Default)]
pub struct Contacts {
    items: [Contact; MAX_CONTACTS],
    len: usize,
}

impl Contacts {
    /// The contacts gathered.
    pub fn as_slice(&self) -> &[Contact] {
        &self.items[..self.len]
    }

    fn clear(&mut self) {
        self.len = 0;
    }

    /// Keeps `contact`, or when full, puts it in place of the farthest if it is nearer.
    fn push(&mut self, contact: Contact) {
        if self.len < MAX_CONTACTS {
            self.items[self.len] = contact;
            self.len += 1;
            return;
        }
        let mut farthest = 0;
        for (k, c) in self.items.iter().enumerate() {
            if c.gap > self.items[farthest].gap {
                farthest = k;
            }
        }
        if contact.gap < self.items[farthest].gap {
            self.items[farthest] = contact;
        }
    }
}

/// The contacts of a disc of `radius` centred at `centre` with every shape of `scene` (the
/// arena's walls as the four sides of its inner rectangle, and the obstacles) whose gap is at
/// most `reach` (m).
pub fn gather(scene: &Scene, centre: Vector, radius: f32, reach: f32, out: &mut Contacts) {
    out.clear();
    if scene.walled {
        let (hw, hh) = (0.5 * scene.arena.0, 0.5 * scene.arena.1);
        let sides = [
            (hw - centre.x, Vector::new(-1.0, 0.0)),
            (hw + centre.x, Vector::new(1.0, 0.0)),
            (hh - centre.y, Vector::new(0.0, -1.0)),
            (hh + centre.y, Vector::new(0.0, 1.0)),
        ];
        for (distance, normal) in sides {
            let gap = distance - radius;
            if gap <= reach {
                out.push(Contact { normal, gap });
            }
        }
    }
    for shape in &scene.shapes {
        // The bounding circle gives a lower bound of the gap.
        if (centre - shape.center).length() - shape.bound_radius - radius > reach {
            continue;
        }
        if let Some((distance, normal)) = shape.surface_normal(centre) {
            let gap = distance - radius;
            if gap <= reach {
                out.push(Contact { normal, gap });
            }
        }
    }
}

/// The body a contact solve moves.
#[derive(Debug, Clone, Copy)]
pub struct Disc {
    /// Mass (kg).
    pub mass: f32,
    /// Moment of inertia about the centre (kg·m²).
    pub inertia: f32,
    /// Radius of the shell (m).
    pub radius: f32,
}

/// Changes a disc's `velocity` (m/s) and `spin` (rad/s) by the impulses of `contacts` over a
/// substep of `h` seconds, with friction coefficient `friction` (module doc, step 2).
pub fn solve_contacts(
    contacts: &[Contact],
    disc: Disc,
    friction: f32,
    h: f32,
    velocity: &mut Vector,
    spin: &mut f32,
) {
    let Disc {
        mass,
        inertia,
        radius,
    } = disc;
    // The impulse along the tangent that changes the contact point's tangential velocity by 1.
    let tangent_mass = 1.0 / (1.0 / mass + radius * radius / inertia);
    let mut normal_impulse = [0.0f32; MAX_CONTACTS];
    let mut friction_impulse = [0.0f32; MAX_CONTACTS];
    let tolerance = IMPULSE_TOLERANCE * mass;
    for _ in 0..MAX_SWEEPS {
        let mut largest = 0.0f32;
        for (k, c) in contacts.iter().enumerate() {
            let n = c.normal;
            let t = Vector::new(-n.y, n.x);
            // Normal: the velocity along n stays at least -max(d, 0)/h.
            let least = -c.gap.max(0.0) / h;
            let total = (normal_impulse[k] + mass * (least - velocity.dot(n))).max(0.0);
            let dn = total - normal_impulse[k];
            normal_impulse[k] = total;
            *velocity += n * (dn / mass);
            // Friction: toward no tangential slip at the contact point, within μ J_n.
            let slip = velocity.dot(t) - *spin * radius;
            let bound = friction * total;
            let total_t = (friction_impulse[k] - tangent_mass * slip)
                .max(-bound)
                .min(bound);
            let dt = total_t - friction_impulse[k];
            friction_impulse[k] = total_t;
            *velocity += t * (dt / mass);
            *spin -= radius * dt / inertia;
            largest = largest.max(dn.abs()).max(dt.abs());
        }
        if contacts.len() <= 1 || largest <= tolerance {
            break;
        }
    }
}

/// What moving a robot's disc through one substep takes besides its state.
#[derive(Debug, Clone, Copy)]
pub struct DiscStep {
    /// The body.
    pub disc: Disc,
    /// The tyres' grip.
    pub grip: Grip,
    /// Shell–scene friction coefficient.
    pub friction: f32,
    /// Substep length (s).
    pub h: f32,
}

/// Moves `body` through one substep against `scene` (module doc, steps 1–4); `contacts` is
/// scratch, left holding the contacts it used.
pub fn move_disc(body: &mut TractionBody, scene: &Scene, step: &DiscStep, contacts: &mut Contacts) {
    let Disc {
        mass,
        inertia,
        radius,
    } = step.disc;
    let h = step.h;
    let cap = step.grip.tyre_friction * 0.5 * mass * GRAVITY * h;
    let (dv, dw) = tyre_impulses(body, step.grip.axle, mass, inertia, cap);
    body.velocity += dv;
    body.spin += dw;
    // No contact impulse adds kinetic energy, so the centre never moves faster than the whole
    // of it in translation would: the shapes within that reach are all the disc can meet.
    let energy_speed =
        (body.velocity.length_squared() + inertia / mass * body.spin * body.spin).sqrt();
    gather(
        scene,
        body.position,
        radius,
        energy_speed * h + CONTACT_MARGIN,
        contacts,
    );
    solve_contacts(
        contacts.as_slice(),
        step.disc,
        step.friction,
        h,
        &mut body.velocity,
        &mut body.spin,
    );
    body.position += body.velocity * h;
    body.heading += body.spin * h;
    for c in contacts.as_slice() {
        if c.gap < 0.0 {
            body.position += c.normal * (-c.gap).min(MAX_PUSHOUT_SPEED * h);
        }
    }
}

impl World {
    /// One substep of `h` seconds in which robots can touch the scene but no robot can touch
    /// another (`physics.scene_solver = "disc"`): a robot that keeps rolling within its tyres'
    /// grip (`self.active`, set by the motors' pass) and cannot reach the scene rolls on its
    /// exact arc; every other one is moved as a disc against the shapes within its reach
    /// ([`move_disc`]). Robot by robot (each depends only on its own state and the scene), so a
    /// swarm shares them among the batch's threads. Then marks the contacts as a rapier
    /// substep does.
    pub(super) fn scene_substep(&mut self, h: f32) {
        let mass = self.physics.mass();
        let step = DiscStep {
            disc: Disc {
                mass,
                inertia: mass * self.inertia_per_mass(),
                radius: self.drive.radius,
            },
            grip: Grip {
                axle: self.drive.axle_length,
                tyre_friction: self.tyre_friction,
            },
            friction: self.physics.wall_friction(),
            h,
        };
        let gain = self.drive.max_speed_change(h);
        let (scene, drive) = (&self.scene, &self.drive);
        let each = |(r, &keeps): (&mut Robot, &bool)| {
            let reach = speed_bound(r, gain) * h + CONTACT_MARGIN;
            if keeps && scene.clearance(r.position) - drive.radius > reach {
                let (v, w) = drive.twist(r.wheel_speeds);
                roll_arc(r, v, w, h);
                r.step_travel += v.abs() * h;
                return;
            }
            let mut body = TractionBody {
                position: r.position,
                heading: r.heading,
                velocity: r.velocity,
                spin: r.spin,
                wheels: r.wheel_speeds,
            };
            let mut contacts = Contacts::default();
            move_disc(&mut body, scene, &step, &mut contacts);
            r.step_travel += (body.position - r.position).length();
            r.position = body.position;
            r.heading = wrap_angle(body.heading);
            r.velocity = body.velocity;
            r.spin = body.spin;
        };
        let chunks = self.robots.chunks_mut(CHUNK).zip(self.active.chunks(CHUNK));
        self.team
            .each(chunks, |_, (r, a): (&mut [Robot], &[bool])| {
                r.iter_mut().zip(a).for_each(each);
            });
        self.mark_contacts(false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::scene::SceneShape;

    const MASS: f32 = 0.54;
    const RADIUS: f32 = 0.0704;
    const H: f32 = 0.025;

    fn disc() -> Disc {
        Disc {
            mass: MASS,
            inertia: 0.5 * MASS * RADIUS * RADIUS,
            radius: RADIUS,
        }
    }

    /// A wall below the disc, touching it: normal +y.
    fn floor_contact(gap: f32) -> Contact {
        Contact {
            normal: Vector::new(0.0, 1.0),
            gap,
        }
    }

    #[test]
    fn an_oblique_impact_follows_rigid_disc_theory_with_coulomb_friction() {
        // A disc meeting a wall at speed v, angle a, with no bounce: the normal velocity goes,
        // friction removes mu J_n = mu m v sin a of tangential momentum while the contact point
        // slides, or leaves 2/3 v cos a once it rolls (tan a >= 1 / (3 mu)).
        let (v, mu) = (0.4f32, 0.7f32);
        for deg in [10.0f32, 20.0, 30.0, 45.0, 60.0, 75.0, 85.0] {
            let a = deg.to_radians();
            let mut velocity = Vector::new(v * a.cos(), -v * a.sin());
            let mut spin = 0.0;
            solve_contacts(
                &[floor_contact(0.0)],
                disc(),
                mu,
                H,
                &mut velocity,
                &mut spin,
            );
            let rolls = a.tan() >= 1.0 / (3.0 * mu);
            let u = if rolls {
                2.0 / 3.0 * v * a.cos()
            } else {
                v * (a.cos() - mu * a.sin())
            };
            assert!(velocity.y.abs() < 1e-6, "{deg}: normal {}", velocity.y);
            assert!(
                (velocity.x - u).abs() < 1e-6,
                "{deg}: {} vs {u}",
                velocity.x
            );
            // Friction at the shell spins the disc toward rolling (clockwise, moving +x above
            // the wall): the angular impulse J_t R over I = m R^2 / 2 gives 2 (v cos a - u) / R.
            let spin_theory = -2.0 * (v * a.cos() - u) / RADIUS;
            assert!((spin - spin_theory).abs() < 1e-4, "{deg}: spin {spin}");
        }
    }

    #[test]
    fn a_frictionless_contact_keeps_the_tangential_speed_and_spin() {
        let mut velocity = Vector::new(0.3, -0.2);
        let mut spin = 1.5;
        solve_contacts(
            &[floor_contact(0.0)],
            disc(),
            0.0,
            H,
            &mut velocity,
            &mut spin,
        );
        assert_eq!((velocity, spin), (Vector::new(0.3, 0.0), 1.5));
    }

    #[test]
    fn a_gap_closes_within_the_substep_and_no_faster() {
        // 1 cm away at 1 m/s (2.5 cm per substep): the disc arrives exactly at the wall.
        let gap = 0.01;
        let mut velocity = Vector::new(0.0, -1.0);
        let mut spin = 0.0;
        solve_contacts(
            &[floor_contact(gap)],
            disc(),
            0.7,
            H,
            &mut velocity,
            &mut spin,
        );
        assert!((velocity.y * H + gap).abs() < 1e-7, "{}", velocity.y);
        // Too slow to arrive: untouched.
        let mut velocity = Vector::new(0.1, -0.2);
        solve_contacts(
            &[floor_contact(gap)],
            disc(),
            0.7,
            H,
            &mut velocity,
            &mut spin,
        );
        assert_eq!(velocity, Vector::new(0.1, -0.2));
        // Leaving: untouched.
        let mut velocity = Vector::new(0.1, 0.2);
        solve_contacts(
            &[floor_contact(0.0)],
            disc(),
            0.7,
            H,
            &mut velocity,
            &mut spin,
        );
        assert_eq!(velocity, Vector::new(0.1, 0.2));
    }

    #[test]
    fn a_disc_driven_into_a_corner_approaches_neither_wall_and_gains_no_energy() {
        // Two walls at right angles (normals +x and +y), the disc moving into the corner,
        // spinning or not: solved together, neither wall is approached and no kinetic energy is
        // made. Without spin, straight into the corner, it stops dead.
        let contacts = [
            Contact {
                normal: Vector::new(1.0, 0.0),
                gap: 0.0,
            },
            floor_contact(0.0),
        ];
        let energy =
            |v: Vector, w: f32| 0.5 * MASS * v.length_squared() + 0.5 * disc().inertia * w * w;
        for (velocity, spin) in [
            (Vector::new(-0.5, -0.5), 0.0),
            (Vector::new(-0.8, -0.1), 3.0),
            (Vector::new(-0.1, -0.6), -4.0),
            (Vector::new(-0.3, 0.2), 8.0),
        ] {
            let (mut v, mut w) = (velocity, spin);
            solve_contacts(&contacts, disc(), 0.7, H, &mut v, &mut w);
            assert!(v.x >= -1e-5 && v.y >= -1e-5, "{velocity:?} {spin}: {v:?}");
            assert!(
                energy(v, w) <= energy(velocity, spin) + 1e-7,
                "{velocity:?} {spin}: {v:?} {w}"
            );
            if spin == 0.0 {
                assert!(v.length() < 1e-5, "{velocity:?}: still moving {v:?}");
            }
        }
    }

    #[test]
    fn gather_finds_walls_and_every_obstacle_kind_within_reach() {
        let mut scene = Scene::arena(2.0, 2.0, 0.05);
        scene
            .shapes
            .push(SceneShape::circle(Vector::new(0.0, 0.3), 0.1));
        scene.shapes.push(SceneShape::rect(
            Vector::new(0.3, 0.0),
            Vector::new(0.1, 0.05),
            std::f32::consts::FRAC_PI_2,
        ));
        scene.shapes.push(SceneShape::segment(
            Vector::new(-0.2, -0.5),
            Vector::new(-0.2, 0.5),
        ));
        let mut contacts = Contacts::default();
        // At the origin: circle 0.2 - R above, box 0.25 - R to the right, segment 0.2 - R left.
        gather(&scene, Vector::ZERO, RADIUS, 0.2, &mut contacts);
        let found = contacts.as_slice();
        assert_eq!(found.len(), 3, "{found:?}");
        let expect = [
            (Vector::new(0.0, -1.0), 0.2 - RADIUS),
            (Vector::new(-1.0, 0.0), 0.25 - RADIUS),
            (Vector::new(1.0, 0.0), 0.2 - RADIUS),
        ];
        for (c, (normal, gap)) in found.iter().zip(expect) {
            assert!((c.normal - normal).length() < 1e-6, "{c:?}");
            assert!((c.gap - gap).abs() < 1e-6, "{c:?}");
        }
        // In the arena's corner: two walls, nothing else.
        gather(&scene, Vector::new(0.92, 0.95), RADIUS, 0.01, &mut contacts);
        let found = contacts.as_slice();
        assert_eq!(found.len(), 2, "{found:?}");
        assert!((found[0].gap - (0.08 - RADIUS)).abs() < 1e-6);
        assert!((found[1].gap - (0.05 - RADIUS)).abs() < 1e-6);
    }

    #[test]
    fn an_overlap_is_pushed_out_at_a_bounded_speed() {
        // 1 cm into the floor wall of an arena, at rest with wheels at rest.
        let scene = Scene::arena(2.0, 2.0, 0.05);
        let mut body = TractionBody {
            position: Vector::new(0.0, -1.0 + RADIUS - 0.01),
            heading: 0.0,
            velocity: Vector::ZERO,
            spin: 0.0,
            wheels: [0.0, 0.0],
        };
        let step = DiscStep {
            disc: disc(),
            grip: Grip {
                axle: 0.1054,
                tyre_friction: 1.0,
            },
            friction: 0.7,
            h: H,
        };
        let mut contacts = Contacts::default();
        move_disc(&mut body, &scene, &step, &mut contacts);
        let pushed = body.position.y - (-1.0 + RADIUS - 0.01);
        assert!((pushed - MAX_PUSHOUT_SPEED * H).abs() < 1e-6, "{pushed}");
        assert_eq!(body.velocity, Vector::ZERO);
    }

    #[test]
    fn a_full_list_keeps_the_nearest_contacts() {
        let mut contacts = Contacts::default();
        for k in 0..MAX_CONTACTS + 3 {
            contacts.push(floor_contact(0.01 * (MAX_CONTACTS + 3 - k) as f32));
        }
        let mut gaps: Vec<f32> = contacts.as_slice().iter().map(|c| c.gap).collect();
        gaps.sort_by(f32::total_cmp);
        let expect: Vec<f32> = (1..=MAX_CONTACTS).map(|k| 0.01 * k as f32).collect();
        assert_eq!(gaps, expect);
    }
}
