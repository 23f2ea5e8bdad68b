//! Scenario configuration: the TOML tables that describe a world, parsed with serde
//! (`deny_unknown_fields`), merged from built-in defaults, a user file and keyword overrides, and
//! validated. Every error names where the value came from (file, `<override>`) and its key.
//!
//! Units: metres, seconds, radians, m/s, raw sensor counts where stated.

use serde::{Deserialize, Serialize};
use toml::{Table, Value};

use crate::error::{Error, Result};
use crate::world::layout::{Spawn, Spawner};

/// Built-in scenario files, embedded so an installed wheel has them: (name, text). The first
/// three are the tasks' defaults; the others are scenes overlaid on a task's defaults.
pub const BUILTIN: &[(&str, &str)] = &[
    ("nav", include_str!("../configs/nav.toml")),
    ("avoid", include_str!("../configs/avoid.toml")),
    ("formation", include_str!("../configs/formation.toml")),
    ("multinav", include_str!("../configs/multinav.toml")),
    ("paper_fig6", include_str!("../configs/paper_fig6.toml")),
    ("paper_fig7", include_str!("../configs/paper_fig7.toml")),
];

/// Returns the text of a built-in scenario.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// A number, or a `[low, high]` range from which a value is drawn at every reset (domain
/// randomisation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Param {
    /// A fixed value.
    Value(f32),
    /// Uniform in [low, high].
    Range([f32; 2]),
}

impl Param {
    /// The value for an episode, drawn from `rng` when a range.
    pub fn sample<R: rand::Rng>(&self, rng: &mut R) -> f32 {
        match *self {
            Param::Value(v) => v,
            // Validation keeps ranges finite (Scenario::validate); a range that is not
            // (possible only by building a Scenario by hand) gives its low end, never a panic.
            Param::Range([lo, hi]) if hi > lo && (hi - lo).is_finite() => rng.random_range(lo..=hi),
            Param::Range([lo, _]) => lo,
        }
    }

    /// Smallest and largest possible values.
    pub fn bounds(&self) -> (f32, f32) {
        match *self {
            Param::Value(v) => (v, v),
            Param::Range([lo, hi]) => (lo, hi),
        }
    }

    /// Largest possible value.
    pub fn max(&self) -> f32 {
        self.bounds().1
    }

    /// Whether the value changes between episodes.
    pub fn is_random(&self) -> bool {
        matches!(self, Param::Range([lo, hi]) if hi > lo)
    }
}

/// `[robot]`: the Khepera IV's body and drive (spec §1). Entries typed [`Param`] may be ranges.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    pub radius: f32,
    pub wheel_radius: f32,
    pub axle_length: Param,
    pub max_wheel_speed: Param,
    pub min_wheel_speed: f32,
    pub wheel_accel_limit: Param,
    pub mass: Param,
}

/// `[arena]`: the rectangle, centred at the origin, walled or open.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArenaConfig {
    pub width: f32,
    pub height: f32,
    pub wall_thickness: f32,
    pub walls: bool,
}

/// A fixed obstacle of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObstacleSpec {
    /// A disc.
    Circle { center: [f32; 2], radius: f32 },
    /// A rectangle rotated by `angle` (rad).
    Box {
        center: [f32; 2],
        half_extents: [f32; 2],
        #[serde(default)]
        angle: f32,
    },
    /// A thin wall from `a` to `b`.
    Segment { a: [f32; 2], b: [f32; 2] },
}

/// Shapes the random obstacle generator draws from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ObstacleKind {
    Circle,
    Box,
    Segment,
}

/// Where random obstacles go.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Placement {
    /// Centred in a corridor along the start–goal segment.
    Between,
    /// Anywhere in the arena.
    Anywhere,
}

/// `[obstacles]`: a fixed list and/or a random generator run at every reset.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleConfig {
    pub fixed: Vec<ObstacleSpec>,
    pub count: u32,
    pub kinds: Vec<ObstacleKind>,
    pub circle_radius: [f32; 2],
    pub box_half_extent: [f32; 2],
    pub segment_length: [f32; 2],
    pub placement: Placement,
    pub corridor_width: f32,
    pub min_gap: f32,
    pub spawn_clearance: f32,
}

/// `[spawn]`: where robots start and goals lie.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpawnConfig {
    pub wall_margin: f32,
    pub min_goal_distance: f32,
    pub start: Vec<f32>,
    pub goal: Vec<f32>,
}

/// `[sensors]`: IR ring and ultrasonic models (spec §3, §5).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    pub ir_range: f32,
    pub ir_floor_value: Param,
    pub ir_noise_sigma: Param,
    pub us_min_range: f32,
    pub us_max_range: f32,
    pub us_noise_sigma: Param,
    pub us_enabled: [bool; 5],
}

/// `[task]`: goal, reward weights, episode length.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskConfig {
    pub goal_radius: f32,
    pub max_steps: u32,
    pub progress_weight: f32,
    pub time_cost: f32,
    pub success_bonus: f32,
    pub collision_penalty: f32,
    pub terminate_on_collision: bool,
}

/// `[physics]`: control step and rapier settings.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsConfig {
    pub dt: f32,
    pub substeps: u32,
    pub solver_iterations: u32,
    pub friction: f32,
}

/// Formation shapes: offsets (r, β) of the followers relative to the leader's pose (eq. 12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FormationShape {
    /// Arms ahead, left, behind, right of the leader (the paper's Fig. 7).
    Cross,
    /// Abreast, alternating left and right of the leader.
    Line,
    /// A V behind the leader.
    Wedge,
    /// Evenly round the leader.
    Circle,
    /// The `offsets` list.
    Custom,
}

/// Who drives the leader.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LeaderMode {
    /// Position control with Braitenberg avoidance, in Rust.
    Scripted,
    /// A learning agent's actions.
    Agent,
}

/// `[formation]`: leader–follower formation (paper §3.5).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FormationConfig {
    pub shape: FormationShape,
    pub n_followers: u32,
    pub spacing: f32,
    pub offsets: Vec<[f32; 2]>,
    pub leader: LeaderMode,
    pub leader_vmax: f32,
    pub leader_wmax: f32,
    pub leader_kr: f32,
    pub error_weight: f32,
    pub team_weight: f32,
}

/// A whole scenario.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub robot: RobotConfig,
    pub arena: ArenaConfig,
    pub obstacles: ObstacleConfig,
    pub spawn: SpawnConfig,
    pub sensors: SensorConfig,
    pub task: TaskConfig,
    pub physics: PhysicsConfig,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub formation: Option<FormationConfig>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub multinav: Option<MultiNavConfig>,
}

/// `[multinav]`: several robots, each with its own goal.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MultiNavConfig {
    pub n_robots: u32,
}

/// Where the parts of a scenario come from.
#[derive(Debug, Clone, Default)]
pub struct Source<'a> {
    /// A scenario file's text and its name (path or built-in name), overlaid on the defaults.
    pub file: Option<(&'a str, &'a str)>,
    /// Keyword overrides: leaf names (`goal_radius`), dotted names (`task.goal_radius`) or
    /// section tables (`task = {goal_radius = 0.1}`).
    pub overrides: Table,
}

/// Largest arena side (m): positions are float32 metres, which keep millimetre precision well
/// beyond this; far larger arenas overflow distances to infinity.
pub const MAX_ARENA_SIDE: f32 = 1000.0;

/// Name used in messages for keyword overrides.
pub const OVERRIDE_ORIGIN: &str = "<override>";

impl Scenario {
    /// Loads the scenario of `task`: its built-in defaults, then the file, then the overrides.
    /// Values are validated; layouts are checked by `world::layout::Spawner::new`.
    pub fn load(task: &str, source: &Source) -> Result<Self> {
        let base_text = builtin(task).ok_or_else(|| {
            let known: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
            Error::config(
                "<built-in>",
                "task",
                format!("unknown task {task:?}; known: {known:?}"),
            )
        })?;
        let mut table = parse(base_text, task)?;
        let mut scenario = Self::from_table(&table, task)?;
        let mut origin = task;
        if let Some((text, name)) = source.file {
            let file = parse(text, name)?;
            overlay(&mut table, &file, "", name)?;
            scenario = Self::from_table(&table, name)?;
            origin = name;
        }
        if !source.overrides.is_empty() {
            let over = expand_overrides(&table, &source.overrides)?;
            overlay(&mut table, &over, "", OVERRIDE_ORIGIN)?;
            scenario = Self::from_table(&table, OVERRIDE_ORIGIN)?;
            origin = OVERRIDE_ORIGIN;
        }
        let spawn = Spawn::for_task(task, &scenario, origin)?;
        Spawner::new(&scenario, spawn, origin)?;
        Ok(scenario)
    }

    fn from_table(table: &Table, origin: &str) -> Result<Self> {
        // Entries of `obstacles.fixed` are checked one by one first: serde's errors inside a
        // tagged list entry carry no position, and the message should say which entry.
        if let Some(Value::Array(fixed)) = table.get("obstacles").and_then(|o| o.get("fixed")) {
            for (i, entry) in fixed.iter().enumerate() {
                entry.clone().try_into::<ObstacleSpec>().map_err(|e| {
                    Error::config(origin, &format!("obstacles.fixed[{i}]"), e.message().trim())
                })?;
            }
        }
        // Deserialise from text so that serde's errors carry a span we can map to a key.
        let text = toml::to_string(table)
            .map_err(|e| Error::config(origin, "<table>", format!("cannot serialise: {e}")))?;
        let scenario: Scenario = toml::from_str(&text).map_err(|e: toml::de::Error| {
            Error::config(
                origin,
                &error_key(&e, &text),
                e.message().trim().to_string(),
            )
        })?;
        scenario.validate(origin)?;
        Ok(scenario)
    }

    /// The scenario as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# cannot serialise scenario: {e}\n"))
    }

    /// Checks that every value is possible; the error names the first offending key. Whether
    /// layouts fit (start, goal, obstacles) is checked by `world::layout::Spawner::new`.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        let r = &self.robot;
        let sn = &self.sensors;
        let positive = [
            ("robot.radius", r.radius),
            ("robot.wheel_radius", r.wheel_radius),
            ("arena.width", self.arena.width),
            ("arena.height", self.arena.height),
            ("arena.wall_thickness", self.arena.wall_thickness),
            ("sensors.ir_range", sn.ir_range),
            ("sensors.us_min_range", sn.us_min_range),
            ("sensors.us_max_range", sn.us_max_range),
            ("task.goal_radius", self.task.goal_radius),
            ("physics.dt", self.physics.dt),
        ];
        for (key, v) in positive {
            if !v.is_finite() || v <= 0.0 {
                return bad(key, format!("must be a finite number > 0, got {v}"));
            }
        }
        for (key, v) in [
            ("arena.width", self.arena.width),
            ("arena.height", self.arena.height),
        ] {
            if v > MAX_ARENA_SIDE {
                return bad(
                    key,
                    format!(
                        "must be at most {MAX_ARENA_SIDE} m (positions are float32 metres), \
                         got {v}"
                    ),
                );
            }
        }
        let params = [
            ("robot.axle_length", r.axle_length, true),
            ("robot.max_wheel_speed", r.max_wheel_speed, true),
            ("robot.mass", r.mass, true),
            ("sensors.ir_floor_value", sn.ir_floor_value, false),
            ("sensors.ir_noise_sigma", sn.ir_noise_sigma, false),
            ("sensors.us_noise_sigma", sn.us_noise_sigma, false),
        ];
        for (key, p, strictly) in params {
            let (lo, hi) = p.bounds();
            if !lo.is_finite() || !hi.is_finite() || lo > hi {
                return bad(
                    key,
                    format!("must be a finite number or a [low, high] range, got {p:?}"),
                );
            }
            if lo < 0.0 || (strictly && lo <= 0.0) {
                let op = if strictly { ">" } else { ">=" };
                return bad(key, format!("must be {op} 0, got {p:?}"));
            }
        }
        let (alo, ahi) = r.wheel_accel_limit.bounds();
        let infinite_range = r.wheel_accel_limit.is_random() && !ahi.is_finite();
        if alo.is_nan() || ahi.is_nan() || alo <= 0.0 || alo > ahi || infinite_range {
            return bad(
                "robot.wheel_accel_limit",
                format!(
                    "must be > 0 (inf for no limit) or a finite [low, high] range, got {:?}",
                    r.wheel_accel_limit
                ),
            );
        }
        let non_negative = [
            ("robot.min_wheel_speed", r.min_wheel_speed),
            ("spawn.wall_margin", self.spawn.wall_margin),
            ("spawn.min_goal_distance", self.spawn.min_goal_distance),
            ("obstacles.corridor_width", self.obstacles.corridor_width),
            ("obstacles.min_gap", self.obstacles.min_gap),
            ("obstacles.spawn_clearance", self.obstacles.spawn_clearance),
            ("task.time_cost", self.task.time_cost),
            ("task.success_bonus", self.task.success_bonus),
            ("task.collision_penalty", self.task.collision_penalty),
            ("task.progress_weight", self.task.progress_weight),
            ("physics.friction", self.physics.friction),
        ];
        for (key, v) in non_negative {
            if !v.is_finite() || v < 0.0 {
                return bad(key, format!("must be a finite number >= 0, got {v}"));
            }
        }
        if r.min_wheel_speed >= r.max_wheel_speed.bounds().0 {
            return bad(
                "robot.min_wheel_speed",
                format!(
                    "must be below robot.max_wheel_speed ({:?}), got {}",
                    r.max_wheel_speed, r.min_wheel_speed
                ),
            );
        }
        if sn.ir_floor_value.max() > 111.0 {
            return bad(
                "sensors.ir_floor_value",
                format!(
                    "must be in [0, 111] (the response curve reads 111 at 0.2 m), got {:?}",
                    sn.ir_floor_value
                ),
            );
        }
        if sn.ir_range <= 0.2 || sn.ir_range > 1.0 {
            return bad(
                "sensors.ir_range",
                format!("must be in (0.2, 1.0] m, got {}", sn.ir_range),
            );
        }
        if sn.us_min_range >= sn.us_max_range {
            return bad(
                "sensors.us_min_range",
                format!(
                    "must be below sensors.us_max_range ({}), got {}",
                    sn.us_max_range, sn.us_min_range
                ),
            );
        }
        if self.task.max_steps == 0 {
            return bad("task.max_steps", "must be >= 1, got 0".into());
        }
        if self.physics.substeps == 0 || self.physics.substeps > 64 {
            return bad(
                "physics.substeps",
                format!("must be in 1..=64, got {}", self.physics.substeps),
            );
        }
        if self.physics.solver_iterations == 0 || self.physics.solver_iterations > 64 {
            return bad(
                "physics.solver_iterations",
                format!("must be in 1..=64, got {}", self.physics.solver_iterations),
            );
        }
        if self.physics.dt > 1.0 {
            return bad(
                "physics.dt",
                format!("must be <= 1 s, got {}", self.physics.dt),
            );
        }
        let (hw, hh) = self.spawn_half_extent();
        if hw <= 0.0 || hh <= 0.0 {
            return bad(
                "arena.width",
                format!(
                    "a {}x{} m arena leaves no room to spawn a robot of radius {} with wall margin {}",
                    self.arena.width, self.arena.height, r.radius, self.spawn.wall_margin
                ),
            );
        }
        let half_diagonal = (hw * hw + hh * hh).sqrt();
        if self.spawn.min_goal_distance > half_diagonal && self.spawn.goal.is_empty() {
            return bad(
                "spawn.min_goal_distance",
                format!(
                    "{} m cannot be guaranteed in this arena: at most {half_diagonal:.3} m",
                    self.spawn.min_goal_distance
                ),
            );
        }
        self.validate_obstacles(origin)?;
        if let Some(f) = &self.formation {
            f.validate(origin, r.radius)?;
        }
        if let Some(m) = &self.multinav {
            if m.n_robots == 0 || m.n_robots > 32 {
                return bad(
                    "multinav.n_robots",
                    format!("must be in 1..=32, got {}", m.n_robots),
                );
            }
        }
        Ok(())
    }

    fn validate_obstacles(&self, origin: &str) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        let o = &self.obstacles;
        for (i, spec) in o.fixed.iter().enumerate() {
            let key = format!("obstacles.fixed[{i}]");
            let sizes: Vec<f32> = match spec {
                ObstacleSpec::Circle { center, radius } => vec![center[0], center[1], *radius],
                ObstacleSpec::Box {
                    center,
                    half_extents,
                    angle,
                } => {
                    vec![
                        center[0],
                        center[1],
                        half_extents[0],
                        half_extents[1],
                        angle + 1.0,
                    ]
                }
                ObstacleSpec::Segment { a, b } => {
                    let length = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
                    vec![a[0], a[1], b[0], b[1], length]
                }
            };
            if sizes.iter().any(|v| !v.is_finite()) {
                return bad(&key, format!("has a non-finite number: {spec:?}"));
            }
            let size_ok = match spec {
                ObstacleSpec::Circle { radius, .. } => *radius > 0.0,
                ObstacleSpec::Box { half_extents, .. } => half_extents.iter().all(|h| *h > 0.0),
                ObstacleSpec::Segment { .. } => sizes[4] > 0.0,
            };
            if !size_ok {
                return bad(&key, format!("sizes must be > 0: {spec:?}"));
            }
        }
        if o.count > 64 {
            return bad("obstacles.count", format!("must be <= 64, got {}", o.count));
        }
        for (key, [lo, hi]) in [
            ("obstacles.circle_radius", o.circle_radius),
            ("obstacles.box_half_extent", o.box_half_extent),
            ("obstacles.segment_length", o.segment_length),
        ] {
            if !(lo.is_finite() && hi.is_finite()) || lo <= 0.0 || lo > hi {
                return bad(
                    key,
                    format!("must be a range [low, high] with 0 < low <= high, got [{lo}, {hi}]"),
                );
            }
        }
        if o.count > 0 {
            if o.kinds.is_empty() {
                return bad(
                    "obstacles.kinds",
                    "must name at least one shape when count > 0".into(),
                );
            }
            let needed = 2.0 * self.robot.radius + 0.01;
            if o.min_gap < needed {
                return bad(
                    "obstacles.min_gap",
                    format!(
                        "must be >= the robot's diameter + 1 cm ({needed:.3} m) so that random \
                         obstacles never wall off a goal, got {}",
                        o.min_gap
                    ),
                );
            }
        }
        Ok(())
    }

    /// Half extents of the region where robot centres and goals are spawned.
    pub fn spawn_half_extent(&self) -> (f32, f32) {
        let m = self.robot.radius + self.spawn.wall_margin;
        (0.5 * self.arena.width - m, 0.5 * self.arena.height - m)
    }
}

impl FormationConfig {
    /// The followers' (r, β) offsets from the leader (β in radians, CCW from its heading).
    pub fn offsets(&self) -> Vec<[f32; 2]> {
        use std::f32::consts::{FRAC_PI_2, PI};
        let k = self.n_followers as usize;
        let r = self.spacing;
        match self.shape {
            // Arms ahead, left, behind, right; further followers go one spacing further out.
            FormationShape::Cross => (0..k)
                .map(|i| [r * (1 + i / 4) as f32, FRAC_PI_2 * (i % 4) as f32])
                .collect(),
            FormationShape::Line => (0..k)
                .map(|i| {
                    let side = if i % 2 == 0 { FRAC_PI_2 } else { -FRAC_PI_2 };
                    [r * (1 + i / 2) as f32, side]
                })
                .collect(),
            FormationShape::Wedge => (0..k)
                .map(|i| {
                    let side = if i % 2 == 0 { 0.75 * PI } else { -0.75 * PI };
                    [r * (1 + i / 2) as f32, side]
                })
                .collect(),
            FormationShape::Circle => (0..k)
                .map(|i| [r, 2.0 * PI * i as f32 / k as f32])
                .collect(),
            FormationShape::Custom => self.offsets.clone(),
        }
    }

    fn validate(&self, origin: &str, radius: f32) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        if self.shape == FormationShape::Custom {
            if self.offsets.is_empty() || self.offsets.len() > 16 {
                return bad(
                    "formation.offsets",
                    format!(
                        "a custom shape needs 1 to 16 [r, beta] offsets, got {}",
                        self.offsets.len()
                    ),
                );
            }
        } else if self.n_followers == 0 || self.n_followers > 16 {
            return bad(
                "formation.n_followers",
                format!("must be in 1..=16, got {}", self.n_followers),
            );
        }
        for (key, v) in [
            ("formation.spacing", self.spacing),
            ("formation.leader_vmax", self.leader_vmax),
            ("formation.leader_wmax", self.leader_wmax),
            ("formation.leader_kr", self.leader_kr),
        ] {
            if !v.is_finite() || v <= 0.0 {
                return bad(key, format!("must be a finite number > 0, got {v}"));
            }
        }
        for (key, v) in [
            ("formation.error_weight", self.error_weight),
            ("formation.team_weight", self.team_weight),
        ] {
            if !v.is_finite() || v < 0.0 {
                return bad(key, format!("must be a finite number >= 0, got {v}"));
            }
        }
        // Robots in formation must not overlap one another (the leader sits at the origin).
        let points: Vec<(f32, f32)> = std::iter::once((0.0, 0.0))
            .chain(
                self.offsets()
                    .iter()
                    .map(|[r, b]| (r * b.cos(), r * b.sin())),
            )
            .collect();
        for (i, a) in points.iter().enumerate() {
            for b in &points[i + 1..] {
                let d = ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
                if !d.is_finite() || d < 2.0 * radius + 0.01 {
                    let key = if self.shape == FormationShape::Custom {
                        "formation.offsets"
                    } else {
                        "formation.spacing"
                    };
                    return bad(key, format!("robots in formation would be {d:.3} m apart, closer than a robot's diameter + 1 cm"));
                }
            }
        }
        Ok(())
    }
}

fn parse(text: &str, origin: &str) -> Result<Table> {
    text.parse::<Table>().map_err(|e| {
        let key = error_key(&e, text);
        Error::config(origin, &key, e.message().trim().to_string())
    })
}

/// The dotted key a toml error is about: found from the error's span in `text` (the key on that
/// line, under the last `[section]` header above it), else `line N`.
fn error_key(e: &toml::de::Error, text: &str) -> String {
    if let Some(start) = e.message().find("unknown field `") {
        let rest = &e.message()[start + 15..];
        if let Some(end) = rest.find('`') {
            if let Some(section) = e.span().and_then(|s| section_at(text, s.start)) {
                return format!("{section}.{}", &rest[..end]);
            }
            return rest[..end].to_string();
        }
    }
    let Some(span) = e.span() else {
        return "<syntax>".to_string();
    };
    let offset = span.start.min(text.len());
    let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let line = &text[line_start..line_end];
    let line_no = text[..offset].matches('\n').count() + 1;
    match line.split_once('=') {
        Some((key, _)) if !line.trim_start().starts_with('[') && is_plain_key(key.trim()) => {
            let key = key.trim().trim_matches('"');
            match section_at(text, offset) {
                Some(section) => format!("{section}.{key}"),
                None => key.to_string(),
            }
        }
        _ => format!("line {line_no}"),
    }
}

/// Whether `key` is a dotted key of bare words (`task.goal_radius`): the only keys a scenario
/// has, so anything else in a message is better said as its line number.
fn is_plain_key(key: &str) -> bool {
    !key.is_empty()
        && key.split('.').all(|part| {
            let part = part.trim().trim_matches('"');
            !part.is_empty()
                && part
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        })
}

/// The name of the last `[section]` header at or before `offset`; for an array of tables
/// (`[[obstacles.fixed]]`) the entry's index is appended (`obstacles.fixed[1]`).
fn section_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    // A span on a header line itself belongs to that header.
    let line_end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    let before = &text[..line_end];
    let header = before
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && l.ends_with(']'))?;
    let name = header.trim_matches(|c| c == '[' || c == ']').trim();
    if header.starts_with("[[") {
        let index = before.lines().filter(|l| l.trim() == header).count() - 1;
        Some(format!("{name}[{index}]"))
    } else {
        Some(name.to_string())
    }
}

/// Overlays `over` on `base`. Every key of `over` must exist in `base` (so a typo is an error
/// naming the key, not a silently ignored setting).
fn overlay(base: &mut Table, over: &Table, prefix: &str, origin: &str) -> Result<()> {
    for (key, value) in over {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match base.get_mut(key) {
            None => {
                let known: Vec<&String> = base.keys().collect();
                return Err(Error::config(
                    origin,
                    &path,
                    format!("unknown key; known keys here: {known:?}"),
                ));
            }
            Some(Value::Table(sub)) => match value {
                Value::Table(over_sub) => overlay(sub, over_sub, &path, origin)?,
                _ => {
                    return Err(Error::config(
                        origin,
                        &path,
                        "is a table of settings; give a table, not a single value",
                    ))
                }
            },
            Some(slot) => {
                if matches!(value, Value::Table(_)) {
                    return Err(Error::config(
                        origin,
                        &path,
                        "is a single setting; give a value, not a table",
                    ));
                }
                *slot = value.clone();
            }
        }
    }
    Ok(())
}

/// Turns keyword overrides into a table shaped like the scenario: `task.goal_radius = x` and
/// leaf names that occur in exactly one section (`goal_radius = x`) become `[task] goal_radius`.
fn expand_overrides(base: &Table, overrides: &Table) -> Result<Table> {
    let mut out = Table::new();
    for (key, value) in overrides {
        let path: Vec<String> = if key.contains('.') {
            key.split('.').map(str::to_string).collect()
        } else if base.contains_key(key) {
            vec![key.clone()]
        } else {
            let sections: Vec<&String> = base
                .iter()
                .filter(|(_, v)| matches!(v, Value::Table(t) if t.contains_key(key)))
                .map(|(k, _)| k)
                .collect();
            match sections.as_slice() {
                [one] => vec![(*one).clone(), key.clone()],
                [] => {
                    return Err(Error::config(
                        OVERRIDE_ORIGIN,
                        key,
                        "unknown key: no scenario section has it".to_string(),
                    ))
                }
                many => {
                    return Err(Error::config(
                        OVERRIDE_ORIGIN,
                        key,
                        format!("ambiguous: it is in sections {many:?}; write section.{key}"),
                    ))
                }
            }
        };
        insert_path(&mut out, &path, value.clone());
    }
    Ok(out)
}

fn insert_path(table: &mut Table, path: &[String], value: Value) {
    match path {
        [] => {}
        [last] => {
            match (table.get_mut(last), value) {
                (Some(Value::Table(existing)), Value::Table(new)) => {
                    for (k, v) in new {
                        existing.insert(k, v);
                    }
                }
                (_, value) => {
                    table.insert(last.clone(), value);
                }
            };
        }
        [first, rest @ ..] => {
            let entry = table
                .entry(first.clone())
                .or_insert_with(|| Value::Table(Table::new()));
            if !entry.is_table() {
                *entry = Value::Table(Table::new());
            }
            if let Value::Table(sub) = entry {
                insert_path(sub, rest, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn overrides(text: &str) -> Table {
        text.parse().expect("test override")
    }

    #[test]
    fn builtin_nav_loads_and_round_trips() {
        let s = Scenario::load("nav", &Source::default()).expect("nav");
        assert_eq!(s.task.max_steps, 400);
        assert!(s.robot.wheel_accel_limit.max().is_infinite());
        let again: Scenario = toml::from_str(&s.to_toml()).expect("round trip");
        assert_eq!(again.task.goal_radius, s.task.goal_radius);
    }

    #[test]
    fn leaf_dotted_and_section_overrides() {
        let src = Source {
            file: None,
            overrides: overrides(
                "goal_radius = 0.1\n\"robot.mass\" = 0.6\nphysics = { substeps = 2 }",
            ),
        };
        let s = Scenario::load("nav", &src).expect("overrides");
        assert_eq!(s.task.goal_radius, 0.1);
        assert_eq!(s.robot.mass, Param::Value(0.6));
        assert_eq!(s.physics.substeps, 2);
        assert_eq!(s.physics.dt, 0.05);
    }

    #[test]
    fn unknown_keys_are_named() {
        let src = Source {
            file: Some(("[task]\ngoal_radios = 0.1\n", "my.toml")),
            overrides: Table::new(),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(
            e.starts_with("my.toml: task.goal_radios: unknown key"),
            "{e}"
        );
        let src = Source {
            file: None,
            overrides: overrides("goal_radios = 0.1"),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.contains("<override>: goal_radios"), "{e}");
    }

    #[test]
    fn wrong_types_and_impossible_values_are_named() {
        let src = Source {
            file: Some(("[robot]\nradius = \"big\"\n", "f.toml")),
            overrides: Table::new(),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.starts_with("f.toml: robot.radius"), "{e}");
        let src = Source {
            file: None,
            overrides: overrides("radius = -1.0"),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.contains("robot.radius: must be"), "{e}");
        let src = Source {
            file: None,
            overrides: overrides("min_goal_distance = 5.0"),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.contains("spawn.min_goal_distance"), "{e}");
        let src = Source {
            file: Some(("[task\n", "broken.toml")),
            overrides: Table::new(),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.starts_with("broken.toml: "), "{e}");
    }

    #[test]
    fn every_builtin_scenario_loads_on_its_task() {
        for task in ["nav", "avoid", "formation", "multinav"] {
            Scenario::load(task, &Source::default()).unwrap_or_else(|e| panic!("{task}: {e}"));
        }
        for (scene, task) in [
            ("paper_fig6", "avoid"),
            ("paper_fig6", "nav"),
            ("paper_fig7", "formation"),
        ] {
            let text = builtin(scene).expect("scene");
            let src = Source {
                file: Some((text, scene)),
                overrides: Table::new(),
            };
            Scenario::load(task, &src).unwrap_or_else(|e| panic!("{scene} on {task}: {e}"));
        }
    }

    #[test]
    fn ranges_are_parameters_and_checked() {
        let src = Source {
            file: None,
            overrides: overrides("mass = [0.5, 0.6]\nir_noise_sigma = [0.0, 20.0]"),
        };
        let s = Scenario::load("nav", &src).expect("ranges");
        assert_eq!(s.robot.mass, Param::Range([0.5, 0.6]));
        let src = Source {
            file: None,
            overrides: overrides("mass = [0.6, 0.5]"),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.contains("robot.mass"), "{e}");
    }

    #[test]
    fn impossible_layouts_are_config_errors_naming_the_key() {
        let cases = [
            ("[obstacles]\nfixed = [{kind = \"circle\", center = [1.5, 0.0], radius = 0.1}]\n", "obstacles.fixed[0]"),
            ("[obstacles]\nfixed = [{kind = \"circle\", center = [0.0, 0.0], radius = -0.1}]\n", "obstacles.fixed[0]"),
            ("[obstacles]\ncount = 60\ncircle_radius = [0.3, 0.4]\nkinds = [\"circle\"]\n", "obstacles.count"),
            ("[obstacles]\ncount = 2\nmin_gap = 0.05\n", "obstacles.min_gap"),
            ("[obstacles]\nfixed = [{kind = \"triangle\", center = [0.0, 0.0]}]\n", "obstacles.fixed[0]"),
            (
                "[obstacles]\nfixed = [{kind = \"circle\", center = [0.5, 0.5], radius = 0.1}, \
                 {kind = \"circle\", center = [0.0, 0.0], radius = 0.1, colour = 1}]\n",
                "obstacles.fixed[1]",
            ),
            // A wall across the whole arena leaves the fixed goal unreachable.
            ("[obstacles]\nfixed = [{kind = \"box\", center = [0.0, 0.0], half_extents = [0.05, 1.0]}]\n\
              [spawn]\nstart = [-0.5, 0.0, 0.0]\ngoal = [0.5, 0.0]\n", "spawn.goal"),
            ("[spawn]\nstart = [0.0, 0.0]\n", "spawn.start"),
        ];
        for (text, key) in cases {
            let src = Source {
                file: Some((text, "bad.toml")),
                overrides: Table::new(),
            };
            let e = Scenario::load("avoid", &src).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("bad.toml: {key}")),
                "expected {key}: {e}"
            );
        }
    }
}
