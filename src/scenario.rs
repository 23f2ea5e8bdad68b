//! Scenario configuration: the TOML tables that describe a world, parsed with serde
//! (`deny_unknown_fields`), merged from built-in defaults, a user file and keyword overrides, and
//! validated. Every error names where the value came from (file, `<override>`) and its key.
//!
//! Units: metres, seconds, radians, m/s, raw sensor counts where stated.

use serde::{Deserialize, Serialize};
use toml::{Table, Value};

use crate::error::{Error, Result};

/// Built-in scenario files, embedded so an installed wheel has them: (name, text).
pub const BUILTIN: &[(&str, &str)] = &[("nav", include_str!("../configs/nav.toml"))];

/// Returns the text of a built-in scenario.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// `[robot]`: the Khepera IV's body and drive (spec §1).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    pub radius: f32,
    pub wheel_radius: f32,
    pub axle_length: f32,
    pub max_wheel_speed: f32,
    pub min_wheel_speed: f32,
    pub wheel_accel_limit: f32,
    pub mass: f32,
}

/// `[arena]`: the walled rectangle, centred at the origin.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArenaConfig {
    pub width: f32,
    pub height: f32,
    pub wall_thickness: f32,
}

/// `[sensors]`: IR ring and ultrasonic models (spec §3, §5).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    pub ir_range: f32,
    pub ir_floor_value: f32,
    pub ir_noise_sigma: f32,
    pub us_min_range: f32,
    pub us_max_range: f32,
    pub us_noise_sigma: f32,
    pub us_enabled: [bool; 5],
}

/// `[task]`: goal, reward weights, episode length.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskConfig {
    pub goal_radius: f32,
    pub min_goal_distance: f32,
    pub spawn_margin: f32,
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

/// A whole scenario.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub robot: RobotConfig,
    pub arena: ArenaConfig,
    pub sensors: SensorConfig,
    pub task: TaskConfig,
    pub physics: PhysicsConfig,
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

/// Name used in messages for keyword overrides.
pub const OVERRIDE_ORIGIN: &str = "<override>";

impl Scenario {
    /// Loads the scenario of `task`: its built-in defaults, then the file, then the overrides.
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
        if let Some((text, origin)) = source.file {
            let file = parse(text, origin)?;
            overlay(&mut table, &file, "", origin)?;
            scenario = Self::from_table(&table, origin)?;
        }
        if !source.overrides.is_empty() {
            let over = expand_overrides(&table, &source.overrides)?;
            overlay(&mut table, &over, "", OVERRIDE_ORIGIN)?;
            scenario = Self::from_table(&table, OVERRIDE_ORIGIN)?;
        }
        Ok(scenario)
    }

    fn from_table(table: &Table, origin: &str) -> Result<Self> {
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

    /// Checks that every value is possible; the error names the first offending key.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        let positive = [
            ("robot.radius", self.robot.radius),
            ("robot.wheel_radius", self.robot.wheel_radius),
            ("robot.axle_length", self.robot.axle_length),
            ("robot.max_wheel_speed", self.robot.max_wheel_speed),
            ("robot.wheel_accel_limit", self.robot.wheel_accel_limit),
            ("robot.mass", self.robot.mass),
            ("arena.width", self.arena.width),
            ("arena.height", self.arena.height),
            ("arena.wall_thickness", self.arena.wall_thickness),
            ("sensors.ir_range", self.sensors.ir_range),
            ("sensors.us_min_range", self.sensors.us_min_range),
            ("sensors.us_max_range", self.sensors.us_max_range),
            ("task.goal_radius", self.task.goal_radius),
            ("physics.dt", self.physics.dt),
        ];
        for (key, v) in positive {
            // NaN fails `v > 0`; wheel_accel_limit alone may be infinite.
            let finite_or_allowed = v.is_finite() || key == "robot.wheel_accel_limit";
            if v.is_nan() || v <= 0.0 || !finite_or_allowed {
                return bad(key, format!("must be a finite number > 0, got {v}"));
            }
        }
        let non_negative = [
            ("robot.min_wheel_speed", self.robot.min_wheel_speed),
            ("sensors.ir_noise_sigma", self.sensors.ir_noise_sigma),
            ("sensors.us_noise_sigma", self.sensors.us_noise_sigma),
            ("task.min_goal_distance", self.task.min_goal_distance),
            ("task.spawn_margin", self.task.spawn_margin),
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
        if self.robot.min_wheel_speed >= self.robot.max_wheel_speed {
            return bad(
                "robot.min_wheel_speed",
                format!(
                    "must be below robot.max_wheel_speed ({}), got {}",
                    self.robot.max_wheel_speed, self.robot.min_wheel_speed
                ),
            );
        }
        if !(0.0..=111.0).contains(&self.sensors.ir_floor_value) {
            return bad(
                "sensors.ir_floor_value",
                format!(
                    "must be in [0, 111] (the response curve reads 111 at 0.2 m), got {}",
                    self.sensors.ir_floor_value
                ),
            );
        }
        if self.sensors.ir_range <= 0.2 || self.sensors.ir_range > 1.0 {
            return bad(
                "sensors.ir_range",
                format!("must be in (0.2, 1.0] m, got {}", self.sensors.ir_range),
            );
        }
        if self.sensors.us_min_range >= self.sensors.us_max_range {
            return bad(
                "sensors.us_min_range",
                format!(
                    "must be below sensors.us_max_range ({}), got {}",
                    self.sensors.us_max_range, self.sensors.us_min_range
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
        // Spawn feasibility: robot and goal must fit, and the goal distance must be reachable
        // from any start (half the spawn region's diagonal is always available).
        let (hw, hh) = self.spawn_half_extent();
        if hw <= 0.0 || hh <= 0.0 {
            return bad(
                "arena.width",
                format!(
                    "arena {}x{} m leaves no room to spawn a robot of radius {} with margin {}",
                    self.arena.width, self.arena.height, self.robot.radius, self.task.spawn_margin
                ),
            );
        }
        let half_diagonal = (hw * hw + hh * hh).sqrt();
        if self.task.min_goal_distance > half_diagonal {
            return bad(
                "task.min_goal_distance",
                format!(
                    "{} m cannot be guaranteed in this arena: at most {half_diagonal:.3} m",
                    self.task.min_goal_distance
                ),
            );
        }
        if self.task.goal_radius >= half_diagonal {
            return bad(
                "task.goal_radius",
                format!("{} m covers the whole arena", self.task.goal_radius),
            );
        }
        Ok(())
    }

    /// Half extents of the region where robot centres and goals are spawned.
    pub fn spawn_half_extent(&self) -> (f32, f32) {
        let m = self.robot.radius + self.task.spawn_margin;
        (0.5 * self.arena.width - m, 0.5 * self.arena.height - m)
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
        Some((key, _)) if !line.trim_start().starts_with('[') => {
            let key = key.trim().trim_matches('"');
            match section_at(text, offset) {
                Some(section) => format!("{section}.{key}"),
                None => key.to_string(),
            }
        }
        _ => format!("line {line_no}"),
    }
}

/// The name of the last `[section]` header at or before `offset`.
fn section_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    // A span on a header line itself belongs to that header.
    let line_end = text[offset..].find('\n').map_or(text.len(), |i| offset + i);
    text[..line_end]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && l.ends_with(']'))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string())
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
            Some(slot) => *slot = value.clone(),
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
        assert!(s.robot.wheel_accel_limit.is_infinite());
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
        assert_eq!(s.robot.mass, 0.6);
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
        assert!(e.contains("task.min_goal_distance"), "{e}");
        let src = Source {
            file: Some(("[task\n", "broken.toml")),
            overrides: Table::new(),
        };
        let e = Scenario::load("nav", &src).unwrap_err().to_string();
        assert!(e.starts_with("broken.toml: "), "{e}");
    }
}
