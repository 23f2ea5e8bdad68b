//! Scenarios: the TOML tables that describe a world, with every key declared once (default,
//! units, comment) by the module that owns it, merged from those defaults, the task's own
//! defaults, a user file and keyword overrides, and validated. Every error names where the value
//! came from (file, `<override>`) and its key.
//!
//! Sections and their owners: `[robot]` (`robot.rs`), `[sensors]` (each sensor in `sensors/`),
//! `[arena]`, `[obstacles]`, `[spawn]`, `[task]`, `[physics]` (`sections.rs`, re-exported
//! here), `[floor]` (`floor.rs`), and the task's own table when it has one (`[formation]`, `[multinav]`: the task's file
//! in `tasks/`). This file holds the [`Scenario`] they make up, the [`TaskSchema`] a task adds,
//! loading, TOML output, and the checks that relate several sections. It never calls into the
//! world: whether layouts fit is checked, and the floor image read, once, when a batch builds
//! its spawner.
//!
//! Units: metres, seconds, radians, m/s, raw sensor counts where stated. Frame: the world frame,
//! arena centred at the origin.

pub mod floor;
mod scenes;
pub mod sections;
mod versions;

use serde::Serialize;
use toml::{Table, Value};

use crate::config::{self, ConfigTable, KeyDoc, OVERRIDE_ORIGIN};
use crate::error::{Error, Result};
use crate::motors::MotorsConfig;
use crate::odometry::OdometryConfig;
use crate::robot::RobotConfig;
use crate::sensors::SensorsConfig;
pub use floor::FloorConfig;

pub use crate::config::Param;
pub use scenes::{scene, SCENES};
pub use sections::{
    ArenaConfig, DriveModel, Localization, MotionSplit, ObstacleConfig, ObstacleKind, ObstacleSpec,
    PhysicsConfig, Placement, SceneSolver, SlipSolver, SpawnConfig, TaskConfig, MAX_DELAY_STEPS,
    MAX_RANDOM_OBSTACLES,
};
pub use versions::{overlays_down_to, Version, LATEST_VERSION, VERSIONS};

/// What a task adds to the shared schema: its own defaults and its own table.
#[derive(Debug, Clone, Copy)]
pub struct TaskSchema {
    /// The task's name (`"avoid"`), in messages.
    pub name: &'static str,
    /// The first behaviour version with this task (an older one is an error naming `version`).
    pub since: u32,
    /// TOML overlaid on the shared defaults: the values this task changes (`[obstacles] count =
    /// 10`).
    pub defaults: &'static str,
    /// The task's own table, if it has one.
    pub section: Option<Section>,
}

/// A task's own table: its name, keys, and the check of its values.
#[derive(Debug, Clone, Copy)]
pub struct Section {
    /// The table's name (`"formation"`).
    pub name: &'static str,
    /// Its keys with defaults and comments.
    pub keys: &'static [KeyDoc],
    /// Reads and checks the table (`scenario` is the rest, already checked); errors name
    /// `origin` and `name.key`.
    pub check: fn(table: &Table, scenario: &Scenario, origin: &str) -> Result<()>,
}

/// A whole scenario.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub robot: RobotConfig,
    /// `[motors]`, resolved (a named preset replaced by its settings).
    pub motors: MotorsConfig,
    pub arena: ArenaConfig,
    pub obstacles: ObstacleConfig,
    pub spawn: SpawnConfig,
    pub sensors: SensorsConfig,
    pub task: TaskConfig,
    pub physics: PhysicsConfig,
    pub odometry: OdometryConfig,
    /// `[floor]`: what the ground sensors see.
    pub floor: FloorConfig,
    /// The scenario file's folder, where a relative `floor.image` path starts (None: the
    /// working directory).
    pub floor_dir: Option<std::path::PathBuf>,
    /// The task's own table (name, checked values), if it has one.
    pub own: Option<(String, Table)>,
    /// Where the last part of the scenario came from (a file's name, `<override>` or
    /// `<built-in>`), for messages about layouts checked later.
    pub origin: String,
}

/// Where the parts of a scenario come from.
#[derive(Debug, Clone, Default)]
pub struct Source<'a> {
    /// A scenario file's text and its name (path or built-in name), overlaid on the defaults.
    pub file: Option<(&'a str, &'a str)>,
    /// Keyword overrides: leaf names (`goal_radius`), dotted names (`task.goal_radius`) or
    /// section tables (`task = {goal_radius = 0.1}`).
    pub overrides: Table,
    /// The behaviour version whose defaults apply (`KheperaIV-Nav-v0` → 0); None: the latest.
    pub version: Option<u32>,
}

/// Largest arena side (m): positions are float32 metres, which keep millimetre precision well
/// beyond this; far larger arenas overflow distances to infinity.
pub const MAX_ARENA_SIDE: f32 = crate::config::limits::LENGTH as f32;

/// The shared sections in file order: name and keys.
fn shared_sections() -> Vec<(&'static str, Vec<KeyDoc>)> {
    vec![
        ("robot", RobotConfig::KEYS.to_vec()),
        ("motors", MotorsConfig::KEYS.to_vec()),
        ("arena", ArenaConfig::KEYS.to_vec()),
        ("obstacles", ObstacleConfig::KEYS.to_vec()),
        ("spawn", SpawnConfig::KEYS.to_vec()),
        ("sensors", SensorsConfig::keys()),
        ("task", TaskConfig::KEYS.to_vec()),
        ("physics", PhysicsConfig::KEYS.to_vec()),
        ("odometry", OdometryConfig::KEYS.to_vec()),
        ("floor", FloorConfig::KEYS.to_vec()),
    ]
}

impl TaskSchema {
    /// The sections of this task's scenario in file order: name and keys.
    pub fn sections(&self) -> Vec<(&'static str, Vec<KeyDoc>)> {
        let mut sections = shared_sections();
        if let Some(s) = &self.section {
            sections.push((s.name, s.keys.to_vec()));
        }
        sections
    }

    /// Every key of the task's scenario with its default: the shared defaults, the task's own
    /// table, then the task's defaults overlaid.
    pub fn defaults_table(&self, version: Option<u32>) -> Result<Table> {
        let mut table = Table::new();
        for (name, keys) in self.sections() {
            table.insert(name.to_string(), Value::Table(config::keys_table(&keys)));
        }
        let origin = format!("<built-in:{}>", self.name);
        let own = config::parse(self.defaults, &origin)?;
        config::overlay(&mut table, &own, "", &origin)?;
        let version = version.unwrap_or(LATEST_VERSION);
        if version < self.since {
            let msg = format!(
                "the {} task exists from version {} on",
                self.name, self.since
            );
            return Err(Error::config("<built-in>", "version", msg));
        }
        if version > LATEST_VERSION {
            return Err(Error::config(
                "<built-in>",
                "version",
                format!(
                    "behaviour version {version} does not exist; the latest is {LATEST_VERSION}"
                ),
            ));
        }
        for v in overlays_down_to(VERSIONS, version) {
            // The origin names the version whose values these are.
            let origin = format!("<built-in:v{}>", v.number - 1);
            config::overlay(&mut table, &config::parse(v.before, &origin)?, "", &origin)?;
        }
        Ok(table)
    }

    /// The task's default scenario file: every key with its default and comment.
    pub fn render_defaults(&self, header: &str, version: Option<u32>) -> Result<String> {
        let table = self.defaults_table(version)?;
        let mut out = String::new();
        for line in header.lines() {
            out.push_str(&format!("# {line}\n").replace("# \n", "#\n"));
        }
        out.push('\n');
        for (name, keys) in self.sections() {
            if let Some(Value::Table(section)) = table.get(name) {
                config::render_section(&mut out, name, &keys, section, true);
            }
        }
        Ok(out)
    }

    /// Loads the task's scenario: its defaults, then the file, then the overrides. Values are
    /// validated; layouts are checked when a batch builds its spawner.
    pub fn load(&self, source: &Source) -> Result<Scenario> {
        let defaults = self.defaults_table(source.version)?;
        let mut table = defaults.clone();
        let origin = format!("<built-in:{}>", self.name);
        let mut scenario = Scenario::from_table(&table, &defaults, self, &origin)?;
        if let Some((text, name)) = source.file {
            let file = config::parse(text, name)?;
            config::overlay(&mut table, &file, "", name).map_err(|e| at_line(e, text))?;
            scenario = Scenario::from_table(&table, &defaults, self, name)?;
        }
        if !source.overrides.is_empty() {
            let over = config::expand_overrides(&table, &source.overrides)?;
            config::overlay(&mut table, &over, "", OVERRIDE_ORIGIN)?;
            scenario = Scenario::from_table(&table, &defaults, self, OVERRIDE_ORIGIN)?;
        }
        // The floor's marks are checked once the scenario is whole; the image is read when a
        // batch builds its floor. A relative image path starts at the scenario file's folder.
        scenario.floor.check(&scenario.origin)?;
        scenario.floor_dir = source
            .file
            .map(|(_, name)| std::path::Path::new(name))
            .filter(|path| path.is_file())
            .and_then(|path| path.parent())
            .map(std::path::Path::to_path_buf);
        Ok(scenario)
    }
}

/// An unknown key's error from a scenario file, with the line of `text` that sets it.
fn at_line(error: Error, text: &str) -> Error {
    match error {
        Error::Config {
            origin,
            key,
            message,
        } if message.starts_with("unknown key") => {
            let message = match config::line_of(text, &key) {
                Some(line) => {
                    message.replacen("unknown key", &format!("unknown key (line {line})"), 1)
                }
                None => message,
            };
            Error::Config {
                origin,
                key,
                message,
            }
        }
        other => other,
    }
}

impl Scenario {
    /// Reads and checks a whole scenario `table`; `defaults` is the version's default table (a
    /// drive key the mode does not use may not differ from it).
    fn from_table(
        table: &Table,
        defaults: &Table,
        schema: &TaskSchema,
        origin: &str,
    ) -> Result<Self> {
        let section = |name: &str| -> Table {
            match table.get(name) {
                Some(Value::Table(t)) => t.clone(),
                _ => Table::new(),
            }
        };
        // Every key's declared domain, used by this scenario or not, before anything is read.
        for (name, keys) in schema.sections() {
            config::check_keys(&section(name), &keys, origin, name)?;
        }
        // Entries of `obstacles.fixed` are checked one by one first, so that a message says
        // which entry.
        if let Some(Value::Array(fixed)) = table.get("obstacles").and_then(|o| o.get("fixed")) {
            ObstacleConfig::check_fixed_entries(fixed, origin)?;
        }
        let scenario = Scenario {
            robot: RobotConfig::from_table(&section("robot"), origin, "robot")?,
            motors: MotorsConfig::resolve(table, defaults, origin)?,
            arena: ArenaConfig::from_table(&section("arena"), origin, "arena")?,
            obstacles: ObstacleConfig::from_table(&section("obstacles"), origin, "obstacles")?,
            spawn: SpawnConfig::from_table(&section("spawn"), origin, "spawn")?,
            sensors: SensorsConfig::from_table(&section("sensors"), origin)?,
            task: TaskConfig::from_table(&section("task"), origin, "task")?,
            physics: PhysicsConfig::from_table(&section("physics"), origin, "physics")?,
            odometry: OdometryConfig::from_table(&section("odometry"), origin, "odometry")?,
            floor: FloorConfig::from_table(&section("floor"), origin, "floor")?,
            floor_dir: None,
            own: schema
                .section
                .map(|s| (s.name.to_string(), section(s.name))),
            origin: origin.to_string(),
        };
        scenario.validate(origin)?;
        if let Some(s) = &schema.section {
            (s.check)(&section(s.name), &scenario, origin)?;
        }
        Ok(scenario)
    }

    /// The task's own table as `T` (it was checked at load).
    pub fn own<T: serde::de::DeserializeOwned>(&self) -> Result<T> {
        match &self.own {
            Some((name, table)) => config::read_table(table, &self.origin, name),
            None => Err(Error::config(
                &self.origin,
                "<task>",
                "this scenario has no task table",
            )),
        }
    }

    /// The scenario as TOML text (every key, in file order; no comments).
    pub fn to_toml(&self) -> String {
        let mut out = String::new();
        let mut sections: Vec<(&str, Vec<KeyDoc>, Table)> = vec![
            ("robot", RobotConfig::KEYS.to_vec(), as_table(&self.robot)),
            (
                "motors",
                MotorsConfig::KEYS.to_vec(),
                as_table(&self.motors),
            ),
            ("arena", ArenaConfig::KEYS.to_vec(), as_table(&self.arena)),
            (
                "obstacles",
                ObstacleConfig::KEYS.to_vec(),
                as_table(&self.obstacles),
            ),
            ("spawn", SpawnConfig::KEYS.to_vec(), as_table(&self.spawn)),
            ("sensors", SensorsConfig::keys(), self.sensors.to_table()),
            ("task", TaskConfig::KEYS.to_vec(), as_table(&self.task)),
            (
                "physics",
                PhysicsConfig::KEYS.to_vec(),
                as_table(&self.physics),
            ),
            (
                "odometry",
                OdometryConfig::KEYS.to_vec(),
                as_table(&self.odometry),
            ),
            ("floor", FloorConfig::KEYS.to_vec(), as_table(&self.floor)),
        ];
        if let Some((name, table)) = &self.own {
            sections.push((name.as_str(), Vec::new(), table.clone()));
        }
        for (name, keys, table) in sections {
            config::render_section(&mut out, name, &keys, &table, false);
        }
        out
    }

    /// Checks what the keys' domains cannot (each value alone is checked by its declaration,
    /// [`config::check_keys`]): values that relate keys within a section or across sections.
    /// The error names the first offending key. Whether layouts fit (start, goal, obstacles)
    /// is checked by `world::layout::Spawner::new`.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        self.robot.validate(origin)?;
        self.sensors.validate(origin)?;
        if self.physics.split == MotionSplit::Robot && self.physics.drive != DriveModel::Traction {
            return bad(
                "physics.split",
                "\"robot\" needs physics.drive = \"traction\" (the kinematic drive steps its world whole)"
                    .to_string(),
            );
        }
        let (hw, hh) = self.spawn_half_extent();
        if hw <= 0.0 || hh <= 0.0 {
            return bad(
                "arena.width",
                format!(
                    "a {}x{} m arena leaves no room to spawn a robot of radius {} with wall margin {}",
                    self.arena.width,
                    self.arena.height,
                    self.robot.radius,
                    self.spawn.wall_margin
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
        self.obstacles.validate(origin, self.robot.radius)
    }

    /// Half extents of the region where robot centres and goals are spawned.
    pub fn spawn_half_extent(&self) -> (f32, f32) {
        let m = self.robot.radius + self.spawn.wall_margin;
        (0.5 * self.arena.width - m, 0.5 * self.arena.height - m)
    }

    /// The arena's diagonal (m): the largest distance between two points in it.
    pub fn diagonal(&self) -> f32 {
        (self.arena.width * self.arena.width + self.arena.height * self.arena.height).sqrt()
    }

    /// The wheels' acceleration limit (m/s²) of this scenario's drive, a range when randomised:
    /// [`MotorsConfig::accel`](crate::motors::MotorsConfig::accel) with `robot.wheel_accel_limit`
    /// as ramp mode's limit.
    pub fn wheel_accel(&self) -> Param {
        self.motors.accel(self.robot.wheel_accel_limit)
    }
}

/// A section struct as a TOML table, its numbers written as their shortest text (so f32 values
/// read back as written: 0.0704, not 0.07040000259876251).
fn as_table<T: Serialize>(section: &T) -> Table {
    toml::to_string(section)
        .ok()
        .and_then(|text| text.parse::<Table>().ok())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests;
