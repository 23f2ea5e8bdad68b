//! Spawning: the start poses, goals and random obstacles of an episode, drawn from the world's
//! random stream, and always feasible.
//!
//! Feasibility by construction: fixed obstacles are rasterised once into a 2 cm grid of the
//! positions a robot centre can take, labelled into connected components (`geometry/reach.rs`);
//! a start and its goal are drawn in the same component. Random obstacles keep a free gap of at least `min_gap`
//! (validated ≥ the robot's diameter + 1 cm) from the walls, the fixed obstacles and each
//! other, and stay clear of every start and goal; a convex obstacle whose robot-inflated shape
//! touches nothing else cannot disconnect the free space, so the goal stays reachable.
//!
//! Units: metres, radians; world frame, arena centred at the origin.

use rand::Rng;
use rapier2d::math::Vector;

use super::scenery;
use super::spacing::Spacing;
use crate::error::{Error, Result};
use crate::geometry::floor::{Segment, SharedFloor};
use crate::geometry::reach::Grid;
use crate::geometry::scene::{Scene, SceneShape};
use crate::scenario::{ObstacleKind, Placement, Scenario};

/// Whole-layout attempts before keeping the best one.
const LAYOUT_TRIES: usize = 16;
/// Attempts at drawing one point (start, goal) before giving up on a layout attempt.
const POINT_TRIES: usize = 256;
/// Attempts at placing one random obstacle.
const OBSTACLE_TRIES: usize = 40;
/// Seeds tried when checking at load time that random layouts fit.
const CHECK_SEEDS: u64 = 8;

/// Where the robots of a world go relative to one another.
#[derive(Debug, Clone)]
pub enum Spawn {
    /// One robot with its goal.
    Single,
    /// A leader with followers at (r, β) offsets from its pose (eq. 12); the leader has a goal.
    Formation(Vec<[f32; 2]>),
    /// `n` robots, each with its own goal.
    Multi(usize),
}

impl Spawn {
    /// Robots this rule places.
    pub fn n_robots(&self) -> usize {
        match self {
            Spawn::Single => 1,
            Spawn::Formation(offsets) => 1 + offsets.len(),
            Spawn::Multi(n) => *n,
        }
    }

    fn n_goals(&self) -> usize {
        match self {
            Spawn::Multi(n) => *n,
            _ => 1,
        }
    }
}

/// An episode's layout.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// Start pose (position, heading) of every robot.
    pub poses: Vec<(Vector, f32)>,
    /// Goals.
    pub goals: Vec<Vector>,
    /// The random obstacles (the fixed ones are in the spawner's base scene).
    pub obstacles: Vec<SceneShape>,
    /// Marks the task draws on the floor this episode (a line-following track).
    pub floor: Vec<Segment>,
}

/// Draws layouts for one scenario. Built once per batch and shared by its worlds.
#[derive(Debug, Clone)]
pub struct Spawner {
    spawn: Spawn,
    /// The arena with the fixed obstacles.
    pub base: Scene,
    /// The scenario's floor (marks as segments, image decoded), shared by every world.
    pub floor: SharedFloor,
    grid: Option<Grid>,
    radius: f32,
    half: (f32, f32),
}

impl Spawner {
    /// A spawner for `cfg`, with its floor built (the image read first), checking that its
    /// fixed parts are feasible and that its random obstacles fit; errors name `origin` and the
    /// key.
    pub fn new(cfg: &Scenario, spawn: Spawn, origin: &str) -> Result<Self> {
        let floor = SharedFloor::new(scenery::floor(
            &cfg.floor,
            cfg.floor_dir.as_deref(),
            origin,
        )?);
        let mut base = scenery::arena(&cfg.arena);
        for (i, spec) in cfg.obstacles.fixed.iter().enumerate() {
            let shape = scenery::obstacle(spec);
            if shape.wall_gap(cfg.arena.width, cfg.arena.height) < 0.0 {
                return Err(Error::config(
                    origin,
                    &format!("obstacles.fixed[{i}]"),
                    format!(
                        "lies (partly) outside the {}x{} m arena",
                        cfg.arena.width, cfg.arena.height
                    ),
                ));
            }
            base.shapes.push(shape);
        }
        let radius = cfg.robot.radius;
        let margin = radius + cfg.spawn.wall_margin;
        let half = (
            0.5 * cfg.arena.width - margin,
            0.5 * cfg.arena.height - margin,
        );
        let grid = if base.shapes.is_empty() {
            None
        } else {
            Grid::check_size(&base, origin)?;
            Some(Grid::new(&base, radius))
        };
        let spawner = Self {
            spawn,
            base,
            floor,
            grid,
            radius,
            half,
        };
        spawner.check(cfg, origin)?;
        Ok(spawner)
    }

    /// Robots placed by this spawner.
    pub fn n_robots(&self) -> usize {
        self.spawn.n_robots()
    }

    fn check(&self, cfg: &Scenario, origin: &str) -> Result<()> {
        let (n_robots, n_goals) = (self.spawn.n_robots(), self.spawn.n_goals());
        if !cfg.spawn.start.is_empty() && cfg.spawn.start.len() != 3 * self.start_poses() {
            return Err(Error::config(
                origin,
                "spawn.start",
                format!(
                    "give [] (random) or {} numbers (x, y, heading per started robot), got {}",
                    3 * self.start_poses(),
                    cfg.spawn.start.len()
                ),
            ));
        }
        if !cfg.spawn.goal.is_empty() && cfg.spawn.goal.len() != 2 * n_goals {
            return Err(Error::config(
                origin,
                "spawn.goal",
                format!(
                    "give [] (random) or {} numbers (x, y per goal), got {}",
                    2 * n_goals,
                    cfg.spawn.goal.len()
                ),
            ));
        }
        let mut full = 0;
        for seed in 0..CHECK_SEEDS {
            let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
            let Some(layout) = self.try_generate(cfg, &mut rng) else {
                continue;
            };
            debug_assert_eq!(layout.poses.len(), n_robots);
            if layout.obstacles.len() == cfg.obstacles.count as usize {
                full += 1;
            }
        }
        if full == 0 {
            let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
            let key = if self.try_points(cfg, &mut rng).is_none() {
                if cfg.spawn.start.is_empty() && cfg.spawn.goal.is_empty() {
                    "spawn"
                } else if cfg.spawn.goal.is_empty() {
                    "spawn.start"
                } else {
                    "spawn.goal"
                }
            } else {
                "obstacles.count"
            };
            let message = if key == "obstacles.count" {
                format!(
                    "{} random obstacles of these sizes do not fit with a gap of {} m \
                     (tried {CHECK_SEEDS} layouts); use fewer or smaller ones",
                    cfg.obstacles.count, cfg.obstacles.min_gap
                )
            } else {
                "no feasible start/goal: a start must be free of obstacles, and its goal \
                 reachable and at least spawn.min_goal_distance away"
                    .to_string()
            };
            return Err(Error::config(origin, key, message));
        }
        Ok(())
    }

    /// Number of poses `spawn.start` fixes: every robot's for several robots, else the leader's.
    fn start_poses(&self) -> usize {
        match self.spawn {
            Spawn::Multi(n) => n,
            _ => 1,
        }
    }

    /// A layout for a new episode. Never fails: the load-time check proved layouts exist; in
    /// the unlikely case that every attempt falls short, the best attempt is used.
    pub fn generate<R: Rng>(&self, cfg: &Scenario, rng: &mut R) -> Layout {
        let mut best: Option<Layout> = None;
        for _ in 0..LAYOUT_TRIES {
            if let Some(layout) = self.try_generate(cfg, rng) {
                if layout.obstacles.len() == cfg.obstacles.count as usize {
                    return layout;
                }
                if best
                    .as_ref()
                    .is_none_or(|b| b.obstacles.len() < layout.obstacles.len())
                {
                    best = Some(layout);
                }
            }
        }
        best.unwrap_or_else(|| self.fallback(cfg))
    }

    /// A deterministic layout with no random parts (used only if sampling kept failing).
    fn fallback(&self, cfg: &Scenario) -> Layout {
        let offsets = self.offsets();
        let (lx, ly) = self.half;
        let start = Vector::new(-lx, -ly);
        let poses = offsets.iter().map(|p| (start + *p, 0.0)).collect();
        let goals = (0..self.spawn.n_goals())
            .map(|i| Vector::new(lx, ly - i as f32 * 3.0 * cfg.robot.radius))
            .collect();
        Layout {
            poses,
            goals,
            obstacles: Vec::new(),
            floor: Vec::new(),
        }
    }

    /// Robot positions relative to the (leader's) start, heading 0.
    fn offsets(&self) -> Vec<Vector> {
        match &self.spawn {
            Spawn::Formation(offsets) => std::iter::once(Vector::ZERO)
                .chain(
                    offsets
                        .iter()
                        .map(|[r, b]| Vector::new(r * b.cos(), r * b.sin())),
                )
                .collect(),
            Spawn::Multi(n) => vec![Vector::ZERO; *n],
            Spawn::Single => vec![Vector::ZERO],
        }
    }

    fn try_generate<R: Rng>(&self, cfg: &Scenario, rng: &mut R) -> Option<Layout> {
        let (poses, goals) = self.try_points(cfg, rng)?;
        let obstacles = self.place_obstacles(cfg, &poses, &goals, rng);
        Some(Layout {
            poses,
            goals,
            obstacles,
            floor: Vec::new(),
        })
    }

    #[allow(clippy::type_complexity)]
    fn try_points<R: Rng>(
        &self,
        cfg: &Scenario,
        rng: &mut R,
    ) -> Option<(Vec<(Vector, f32)>, Vec<Vector>)> {
        let clear = self.radius + cfg.obstacles.spawn_clearance;
        let apart = 2.0 * self.radius + cfg.obstacles.spawn_clearance;
        let fixed_start = |k: usize| {
            let s = &cfg.spawn.start;
            (!s.is_empty()).then(|| (Vector::new(s[3 * k], s[3 * k + 1]), s[3 * k + 2]))
        };
        let fixed_goal = |k: usize| {
            let g = &cfg.spawn.goal;
            (!g.is_empty()).then(|| Vector::new(g[2 * k], g[2 * k + 1]))
        };
        let mut poses: Vec<(Vector, f32)> = Vec::new();
        let mut spaced_starts = Spacing::new(self.half, apart);
        let offsets = self.offsets();
        let mut goal_hint: Option<Vector> = None;
        match &self.spawn {
            Spawn::Single | Spawn::Formation(_) => {
                let formation = matches!(self.spawn, Spawn::Formation(_));
                let pose = match fixed_start(0) {
                    Some(p) => p,
                    None => {
                        let mut found = None;
                        for _ in 0..POINT_TRIES {
                            let p = self.sample_point(rng);
                            let mut heading =
                                rng.random_range(-std::f32::consts::PI..std::f32::consts::PI);
                            if formation {
                                // A formation starts facing the leader's goal (the paper's
                                // Fig. 7), so that the followers' targets do not swing round
                                // at the start; the goal is drawn again below.
                                let Some(g) = fixed_goal(0).or_else(|| self.goal_from(p, cfg, rng))
                                else {
                                    continue;
                                };
                                heading = (g - p).y.atan2((g - p).x);
                                goal_hint = Some(g);
                            }
                            if self.formation_fits(p, heading, &offsets, clear) {
                                found = Some((p, heading));
                                break;
                            }
                        }
                        found?
                    }
                };
                let (p, heading) = pose;
                if !self.formation_fits(p, heading, &offsets, clear) {
                    return None;
                }
                let (s, c) = heading.sin_cos();
                for o in &offsets {
                    poses.push((
                        p + Vector::new(c * o.x - s * o.y, s * o.x + c * o.y),
                        heading,
                    ));
                }
            }
            Spawn::Multi(n) => {
                spaced_starts.reset(*n);
                for k in 0..*n {
                    let pose = match fixed_start(k) {
                        Some(p) => p,
                        None => {
                            let mut found = None;
                            for _ in 0..POINT_TRIES {
                                let p = self.sample_point(rng);
                                let h =
                                    rng.random_range(-std::f32::consts::PI..std::f32::consts::PI);
                                if self.free(p, clear) && spaced_starts.all_apart(p) {
                                    found = Some((p, h));
                                    break;
                                }
                            }
                            found?
                        }
                    };
                    if !self.free(pose.0, clear) {
                        return None;
                    }
                    poses.push(pose);
                    spaced_starts.insert(pose.0);
                }
            }
        }
        let mut goals: Vec<Vector> = Vec::new();
        let mut spaced_goals = Spacing::new(self.half, apart);
        spaced_goals.reset(self.spawn.n_goals());
        for (k, (from, _)) in poses.iter().copied().enumerate().take(self.spawn.n_goals()) {
            let ok = |g: Vector, spaced_goals: &Spacing| {
                self.free(g, clear)
                    && (g - from).length() >= cfg.spawn.min_goal_distance
                    && self.same_component(from, g)
                    && spaced_goals.all_apart(g)
            };
            let goal = match fixed_goal(k).or(goal_hint.take()) {
                Some(g) => {
                    // A formation arriving from its start must fit round a fixed goal too.
                    let arrival = (g - from).y.atan2((g - from).x);
                    if !self.inside(g)
                        || !self.free(g, self.radius)
                        || !self.same_component(from, g)
                        || !self.formation_fits(g, arrival, &offsets, self.radius)
                    {
                        return None;
                    }
                    g
                }
                None => {
                    let mut found = None;
                    for _ in 0..POINT_TRIES {
                        let g = self.sample_point(rng);
                        if ok(g, &spaced_goals) {
                            found = Some(g);
                            break;
                        }
                    }
                    found?
                }
            };
            goals.push(goal);
            spaced_goals.insert(goal);
        }
        Some((poses, goals))
    }

    /// A random goal for a robot starting at `from`, or None after many tries. A formation's
    /// goal leaves room for the whole formation arriving from `from`.
    fn goal_from<R: Rng>(&self, from: Vector, cfg: &Scenario, rng: &mut R) -> Option<Vector> {
        let clear = self.radius + cfg.obstacles.spawn_clearance;
        let offsets = self.offsets();
        (0..POINT_TRIES).map(|_| self.sample_point(rng)).find(|g| {
            let arrival = (*g - from).y.atan2((*g - from).x);
            self.free(*g, clear)
                && (*g - from).length() >= cfg.spawn.min_goal_distance
                && self.same_component(from, *g)
                && self.formation_fits(*g, arrival, &offsets, clear)
        })
    }

    fn sample_point<R: Rng>(&self, rng: &mut R) -> Vector {
        let (hx, hy) = self.half;
        Vector::new(rng.random_range(-hx..=hx), rng.random_range(-hy..=hy))
    }

    fn inside(&self, p: Vector) -> bool {
        p.x.abs() <= self.half.0 + 1e-6 && p.y.abs() <= self.half.1 + 1e-6
    }

    /// `p` is inside the spawn region and at least `clear` from walls and fixed obstacles.
    fn free(&self, p: Vector, clear: f32) -> bool {
        self.inside(p) && self.base.clearance(p) >= clear
    }

    fn formation_fits(&self, p: Vector, heading: f32, offsets: &[Vector], clear: f32) -> bool {
        let (s, c) = heading.sin_cos();
        offsets
            .iter()
            .all(|o| self.free(p + Vector::new(c * o.x - s * o.y, s * o.x + c * o.y), clear))
    }

    fn same_component(&self, a: Vector, b: Vector) -> bool {
        match &self.grid {
            None => true,
            Some(grid) => {
                let la = grid.label(a);
                la != 0 && la == grid.label(b)
            }
        }
    }

    fn place_obstacles<R: Rng>(
        &self,
        cfg: &Scenario,
        poses: &[(Vector, f32)],
        goals: &[Vector],
        rng: &mut R,
    ) -> Vec<SceneShape> {
        let oc = &cfg.obstacles;
        let mut placed: Vec<SceneShape> = Vec::new();
        if oc.count == 0 || oc.kinds.is_empty() {
            return placed;
        }
        let clear = self.radius + oc.spawn_clearance;
        let (from, to) = (poses[0].0, goals[0]);
        let (w, h) = (cfg.arena.width, cfg.arena.height);
        for _ in 0..oc.count {
            for _ in 0..OBSTACLE_TRIES {
                let kind = oc.kinds[rng.random_range(0..oc.kinds.len())];
                let angle = rng.random_range(0.0..std::f32::consts::PI);
                let centre = match oc.placement {
                    Placement::Between => {
                        let along = to - from;
                        let normal = Vector::new(-along.y, along.x).normalize_or_zero();
                        let t = rng.random_range(0.15..=0.85);
                        let lateral = 0.5 * oc.corridor_width * rng.random_range(-1.0..=1.0f32);
                        from + t * along + lateral * normal
                    }
                    Placement::Anywhere => Vector::new(
                        rng.random_range(-0.5 * w..=0.5 * w),
                        rng.random_range(-0.5 * h..=0.5 * h),
                    ),
                };
                let shape = match kind {
                    ObstacleKind::Circle => {
                        let [lo, hi] = oc.circle_radius;
                        SceneShape::circle(centre, rng.random_range(lo..=hi))
                    }
                    ObstacleKind::Box => {
                        let [lo, hi] = oc.box_half_extent;
                        let half =
                            Vector::new(rng.random_range(lo..=hi), rng.random_range(lo..=hi));
                        SceneShape::rect(centre, half, angle)
                    }
                    ObstacleKind::Segment => {
                        let [lo, hi] = oc.segment_length;
                        let half = 0.5 * rng.random_range(lo..=hi);
                        let d = Vector::new(angle.cos(), angle.sin()) * half;
                        SceneShape::segment(centre - d, centre + d)
                    }
                };
                let wall_gap = shape.wall_gap(w, h);
                let ok = (if cfg.arena.walls {
                    wall_gap >= oc.min_gap
                } else {
                    wall_gap >= 0.0
                }) && self.base.shapes.iter().all(|f| shape.gap(f) >= oc.min_gap)
                    && placed.iter().all(|f| shape.gap(f) >= oc.min_gap)
                    && poses.iter().all(|(p, _)| shape.distance(*p) >= clear)
                    && goals.iter().all(|g| shape.distance(*g) >= clear);
                if ok {
                    placed.push(shape);
                    break;
                }
            }
        }
        placed
    }
}
