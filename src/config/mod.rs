//! Scenario schema machinery: how a table of settings is declared once (its keys, their defaults,
//! units and comments), parsed, overlaid and validated. It knows nothing of robots or worlds; the
//! tables themselves are declared by their owners (`robot.rs`, each sensor in `sensors/`, each
//! task in `tasks/`, the world's in `scenario/sections.rs`) with [`crate::config_table!`].
//!
//! A table's defaults are TOML text written next to each key, so the same text is what
//! `default_config(task)` prints, what every scenario file is overlaid on, and what
//! `Default::default()` returns. Overlays are strict: a key that the defaults do not have is an
//! error naming the file and the key, never a silently ignored setting.
//!
//! Each key may declare its domain after its default (`=> Domain::POSITIVE`, see
//! [`domain`]): [`check_keys`] enforces every declaration on a table, whether the key is used
//! or not, and the default file writes it after the key's comment (`allowed: finite, > 0`).
//!
//! Units: whatever each key's comment says (SI throughout: m, s, rad, m/s, kg).

mod domain;
pub mod limits;
mod text;

pub use domain::{Domain, Field};
pub use text::{
    did_you_mean, error_key, expand_overrides, line_of, nearest_key, overlay, parse, render_section,
};

use serde::{de::DeserializeOwned, Deserialize, Serialize};
use toml::{Table, Value};

use crate::error::{Error, Result};

/// Name used in messages for keyword overrides.
pub const OVERRIDE_ORIGIN: &str = "<override>";

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
            // Validation keeps ranges finite (`Param::check`); a range that is not (possible
            // only by building a table by hand) gives its low end, never a panic.
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

    /// Checks a finite value or range, `> 0` when `strictly`, else `>= 0`; the error names
    /// `origin` and `key`.
    pub fn check(&self, origin: &str, key: &str, strictly: bool) -> Result<()> {
        let (lo, hi) = self.bounds();
        if !lo.is_finite() || !hi.is_finite() || lo > hi {
            return Err(Error::config(
                origin,
                key,
                format!("must be a finite number or a [low, high] range, got {self:?}"),
            ));
        }
        if lo < 0.0 || (strictly && lo <= 0.0) {
            let op = if strictly { ">" } else { ">=" };
            return Err(Error::config(
                origin,
                key,
                format!("must be {op} 0, got {self:?}"),
            ));
        }
        Ok(())
    }
}

/// One key of a declared table: its name, its default as TOML text, its comment (units,
/// meaning, source), its Rust type and the values it may take.
#[derive(Debug, Clone, Copy)]
pub struct KeyDoc {
    /// The key.
    pub name: &'static str,
    /// Its default value, as TOML text.
    pub default: &'static str,
    /// What it is, with units and source.
    pub comment: &'static str,
    /// Its Rust type as declared (`"f32"`, `"Param"`, `"[f32; 3]"`): the shape of its value.
    pub ty: &'static str,
    /// The values it may take; None: any value of its type (numbers must still be finite).
    pub domain: Option<Domain>,
}

impl KeyDoc {
    /// A key without a Rust declaration (a table assembled by hand): name, default, comment,
    /// type and domain.
    pub const fn new(
        name: &'static str,
        default: &'static str,
        comment: &'static str,
        ty: &'static str,
        domain: Option<Domain>,
    ) -> Self {
        Self {
            name,
            default,
            comment,
            ty,
            domain,
        }
    }

    /// Its domain, or any finite number of its type when it declares none.
    pub fn domain_or_finite(&self) -> Domain {
        self.domain.unwrap_or(Domain::FINITE)
    }

    /// The values it may take, as the default file writes them after its comment (empty for a
    /// key without numbers or lengths to check).
    pub fn allowed(&self) -> String {
        self.domain_or_finite().describe(self.ty)
    }

    /// Checks `value` of this key against its type's shape and its domain; the error names
    /// `origin` and `section.key` (with the entry below it where one is wrong).
    pub fn check(&self, value: &Value, origin: &str, section: &str) -> Result<()> {
        self.domain_or_finite()
            .check(self.ty, value)
            .map_err(|(message, at)| {
                let key = match section {
                    "" => format!("{}{at}", self.name),
                    _ => format!("{section}.{}{at}", self.name),
                };
                Error::config(origin, &key, message)
            })
    }
}

/// Checks every key of `table` that `keys` declares against its declaration (see
/// [`domain`]); keys `keys` does not list are left to the table's reader. Errors name `origin`
/// and `section.key`.
pub fn check_keys(table: &Table, keys: &[KeyDoc], origin: &str, section: &str) -> Result<()> {
    for key in keys {
        if let Some(value) = table.get(key.name) {
            key.check(value, origin, section)?;
        }
    }
    Ok(())
}

/// A table of settings declared with [`crate::config_table!`].
pub trait ConfigTable: Clone + Serialize + DeserializeOwned {
    /// Its keys in order, with defaults and comments.
    const KEYS: &'static [KeyDoc];

    /// The defaults as a TOML table (parsed from [`ConfigTable::KEYS`]).
    fn defaults_table() -> Table {
        keys_table(Self::KEYS)
    }

    /// Reads a table whose keys are all known (an overlay of the defaults), checking every
    /// key's domain first ([`check_keys`]).
    fn from_table(table: &Table, origin: &str, section: &str) -> Result<Self> {
        check_keys(table, Self::KEYS, origin, section)?;
        read_table(table, origin, section)
    }
}

/// The defaults of `keys` as a TOML table. A default that is not valid TOML is a programming
/// error in a declaration; it is caught by the tests of every table, so here it is skipped.
pub fn keys_table(keys: &[KeyDoc]) -> Table {
    let mut table = Table::new();
    for key in keys {
        if let Ok(parsed) = format!("value = {}", key.default).parse::<Table>() {
            if let Some(value) = parsed.get("value") {
                table.insert(key.name.to_string(), value.clone());
            }
        }
    }
    table
}

/// Deserialises a table (all of whose keys the type knows) into `T`; errors name `origin` and
/// `section.key`.
pub fn read_table<T: DeserializeOwned>(table: &Table, origin: &str, section: &str) -> Result<T> {
    // Deserialise from text so that serde's errors carry a span we can map to a key.
    let text = toml::to_string(table)
        .map_err(|e| Error::config(origin, section, format!("cannot serialise: {e}")))?;
    toml::from_str(&text).map_err(|e: toml::de::Error| {
        let key = error_key(&e, &text);
        let key = if key.starts_with("line ") || key.starts_with('<') {
            section.to_string()
        } else if section.is_empty() {
            key
        } else {
            format!("{section}.{key}")
        };
        Error::config(origin, &key, e.message().trim().to_string())
    })
}

/// Declares a table of settings: a struct with one public field per key, its defaults as TOML
/// text, and its keys' comments, all written once.
///
/// ```
/// use _core::config::{ConfigTable, Domain, Param};
///
/// _core::config_table! {
///     /// `[wheels]`: an example table.
///     pub struct WheelsConfig {
///         /// wheel radius (m): 42 mm diameter
///         radius: f32 = 0.021 => Domain::POSITIVE.at_most(1.0),
///         /// wheel mass (kg), a number or a [low, high] range drawn at every reset
///         mass: Param = [0.010, 0.012],
///         /// upper speed limit (m/s); inf = none
///         max_speed: f32 = inf,
///         /// names of the wheels
///         names: Vec<String> = ["left", "right"],
///     }
/// }
///
/// // `Default::default()` is the declared defaults, read as TOML.
/// let wheels = WheelsConfig::default();
/// assert_eq!(wheels.radius, 0.021);
/// assert_eq!(wheels.mass, Param::Range([0.010, 0.012]));
/// assert!(wheels.max_speed.is_infinite());
/// assert_eq!(wheels.names, ["left", "right"]);
///
/// // `KEYS`: every key in order, with its default as written and its comment.
/// let keys = WheelsConfig::KEYS;
/// let names: Vec<&str> = keys.iter().map(|k| k.name).collect();
/// assert_eq!(names, ["radius", "mass", "max_speed", "names"]);
/// assert_eq!(keys[0].default, "0.021");
/// assert_eq!(keys[0].comment.trim(), "wheel radius (m): 42 mm diameter");
/// assert_eq!(keys[0].allowed(), "finite, > 0, <= 1");
///
/// // `from_table` checks every key's domain (and a `[T; N]` array's length) before reading.
/// let mut table = WheelsConfig::defaults_table();
/// table.insert("radius".into(), toml::Value::Float(f64::NAN));
/// let error = WheelsConfig::from_table(&table, "f.toml", "wheels").unwrap_err();
/// assert_eq!(error.to_string(), "f.toml: wheels.radius: must be finite, > 0, <= 1, got NaN");
/// ```
/// Each default is TOML text (`inf`, `[0.04, 0.10]`, `"between"`, `[]` are all fine) and must
/// deserialise into the field's type; `Default::default()` is that deserialisation. The optional
/// `=> domain` after a default is a `const` [`Domain`]: the values the key may take (a key
/// without one takes any finite number of its type). The expansion names `serde`, which the
/// declaring crate must depend on (with `derive`).
#[macro_export]
macro_rules! config_table {
    (@domain) => {
        None
    };
    (@domain $domain:expr) => {
        Some($domain)
    };
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $field:ident : $ty:ty = $default:expr $(=> $domain:expr)?
            ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            $(
                $(#[doc = $doc])*
                pub $field: $ty,
            )*
        }

        impl $crate::config::ConfigTable for $name {
            const KEYS: &'static [$crate::config::KeyDoc] = &[
                $(
                    $crate::config::KeyDoc {
                        name: stringify!($field),
                        default: stringify!($default),
                        comment: concat!($($doc, " "),*),
                        ty: stringify!($ty),
                        domain: $crate::config_table!(@domain $($domain)?),
                    },
                )*
            ];
        }

        impl Default for $name {
            fn default() -> Self {
                let table = <Self as $crate::config::ConfigTable>::defaults_table();
                // The declared defaults are checked by every table's tests: a failure here is a
                // programming error in this declaration, never the user's input.
                $crate::config::read_table(&table, "<defaults>", stringify!($name))
                    .expect(concat!("the defaults of ", stringify!($name), " deserialise"))
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::config_table! {
        /// A table for these tests.
        pub struct Example {
            /// a length (m)
            length: f32 = 0.25,
            /// an unbounded rate; inf = none
            rate: Param = inf => Domain::POSITIVE.or_inf(),
            /// a list
            names: Vec<String> = ["a", "b"],
            /// a negative default
            offset: f32 = -1.5,
        }
    }

    #[test]
    fn declared_defaults_parse_and_render() {
        let d = Example::default();
        assert_eq!(d.length, 0.25);
        assert!(d.rate.max().is_infinite());
        assert_eq!(d.names, vec!["a".to_string(), "b".to_string()]);
        assert_eq!(d.offset, -1.5);
        let mut text = String::new();
        render_section(
            &mut text,
            "example",
            Example::KEYS,
            &Example::defaults_table(),
            true,
        );
        assert!(text.contains("length = 0.25"), "{text}");
        assert!(text.contains("# a length (m)"), "{text}");
        let back: Table = text.parse().expect("rendered text is TOML");
        assert_eq!(back["example"]["offset"].as_float(), Some(-1.5));
    }

    #[test]
    fn unknown_and_mistyped_keys_are_named() {
        let mut base = Table::new();
        base.insert("example".into(), Value::Table(Example::defaults_table()));
        let over = parse("[example]\nlenght = 1.0\n", "f.toml").expect("toml");
        let e = overlay(&mut base, &over, "", "f.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("f.toml: example.lenght: unknown key"), "{e}");
        assert!(e.contains("did you mean `length`?"), "{e}");
        let mut table = Example::defaults_table();
        table.insert("length".into(), Value::String("long".into()));
        let e = Example::from_table(&table, "f.toml", "example")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("f.toml: example.length"), "{e}");
    }

    #[test]
    fn a_mistyped_keyword_gets_the_nearest_key_suggested() {
        let mut base = Table::new();
        base.insert("example".into(), Value::Table(Example::defaults_table()));
        base.insert("seed".into(), Value::Integer(0));
        let over = parse("lenhgt = 1.0\n", "kw").expect("toml");
        let e = expand_overrides(&base, &over).unwrap_err().to_string();
        assert!(e.contains("lenhgt: unknown key"), "{e}");
        assert!(e.contains("did you mean `length`?"), "{e}");
        let over = parse("seeed = 1\n", "kw").expect("toml");
        let e = expand_overrides(&base, &over).unwrap_err().to_string();
        assert!(e.contains("did you mean `seed`?"), "{e}");
        let over = parse("zzzzzz = 1\n", "kw").expect("toml");
        let e = expand_overrides(&base, &over).unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
    }

    #[test]
    fn two_swapped_letters_are_one_edit_and_a_key_is_found_on_its_line() {
        // "taks" is "task" with two neighbours swapped: one edit, suggested for a 4-letter key.
        assert_eq!(nearest_key("taks", ["task", "spawn"]), Some("task"));
        assert_eq!(nearest_key("lenhgt", ["length"]), Some("length"));
        assert_eq!(nearest_key("xyz", ["task"]), None);
        let text = "# a scenario\n[task]\nmax_steps = 10\ngoal_radus = 0.1\n\n[taks]\n\"robot.mass\" = 1\nrobot.radius = 0.1\n";
        assert_eq!(line_of(text, "task.goal_radus"), Some(4));
        assert_eq!(line_of(text, "taks"), Some(6));
        assert_eq!(line_of(text, "taks.robot.radius"), Some(8));
        assert_eq!(line_of(text, "task.nothing"), None);
    }
}
