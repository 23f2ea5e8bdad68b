//! The values a scenario key may take, declared next to its default in
//! [`crate::config_table!`] (`width: f32 = 2.0 => Domain::POSITIVE.at_most(1000.0)`), and the
//! one validator that enforces every declaration on the TOML table of a scenario, whether the
//! key is used by that scenario or not.
//!
//! What is checked, from the key's declared type and its [`Domain`]:
//! * every number (a scalar, each end of a `[low, high]` [`Param`](super::Param) range, each
//!   entry of an array or list, each number of a list's tables) is finite (`+inf` only where the
//!   domain says `or_inf`) and within the domain's bounds;
//! * a `[T; N]` array has exactly N entries (serde alone would drop extra ones), a list has the
//!   domain's number of entries, a range has two ends, the low one first;
//! * the fields of a list of tables (`floor.lines`, `obstacles.fixed`) have their own types and
//!   domains ([`Field`]).
//!
//! A value of the wrong kind (a string for a number) is left to serde, whose message names the
//! expected type. The domain is also what the scenario reference shows (`allowed: ...` after
//! each key's comment, [`Domain::describe`]).
//!
//! Units: each key's own (its comment says them).

use toml::Value;

/// A bound of a domain.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Bound {
    /// None.
    Open,
    /// The value itself is allowed.
    Inclusive(f64),
    /// Only values beyond it are.
    Exclusive(f64),
}

/// The values a key may take: finite numbers (or `+inf` with [`Domain::or_inf`]) within
/// bounds, whole numbers, lists of a given length. Built in `const` context with the methods
/// below, e.g. `Domain::POSITIVE.at_most(1000.0)`, `Domain::range(0.0, 1.0)`,
/// `Domain::NON_NEGATIVE.entries(5)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Domain {
    low: Bound,
    high: Bound,
    /// Whether `+inf` is allowed (a fixed value meaning "none", never a range's end).
    infinite: bool,
    /// Whether only whole numbers are.
    whole: bool,
    /// Least and most entries of a list.
    min_entries: usize,
    max_entries: usize,
    /// The fields of the tables of a list of tables.
    fields: &'static [Field],
}

/// A field of the tables of a list of tables (`width` of a `floor.lines` entry): its name, its
/// Rust type as written (`"[f32; 2]"`) and its domain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Field {
    /// The field's name.
    pub name: &'static str,
    /// Its type as declared (`"f32"`, `"[f32; 2]"`, `"Vec<[f32; 2]>"`).
    pub ty: &'static str,
    /// Its domain.
    pub domain: Domain,
}

impl Field {
    /// A field `name` of type `ty` within `domain`.
    pub const fn new(name: &'static str, ty: &'static str, domain: Domain) -> Self {
        Self { name, ty, domain }
    }
}

impl Domain {
    /// Any finite number.
    pub const FINITE: Domain = Domain {
        low: Bound::Open,
        high: Bound::Open,
        infinite: false,
        whole: false,
        min_entries: 0,
        max_entries: usize::MAX,
        fields: &[],
    };
    /// Finite and > 0.
    pub const POSITIVE: Domain = Domain::above(0.0);
    /// Finite and >= 0.
    pub const NON_NEGATIVE: Domain = Domain::at_least(0.0);
    /// In [0, 1]: a fraction, a grey level, a colour channel, a probability.
    pub const UNIT: Domain = Domain::range(0.0, 1.0);

    /// Finite and >= `low`.
    pub const fn at_least(low: f64) -> Self {
        Self {
            low: Bound::Inclusive(low),
            ..Self::FINITE
        }
    }

    /// Finite and > `low`.
    pub const fn above(low: f64) -> Self {
        Self {
            low: Bound::Exclusive(low),
            ..Self::FINITE
        }
    }

    /// In [`low`, `high`].
    pub const fn range(low: f64, high: f64) -> Self {
        Self::at_least(low).at_most(high)
    }

    /// Also <= `high`.
    pub const fn at_most(self, high: f64) -> Self {
        Self {
            high: Bound::Inclusive(high),
            ..self
        }
    }

    /// Also < `high`.
    pub const fn below(self, high: f64) -> Self {
        Self {
            high: Bound::Exclusive(high),
            ..self
        }
    }

    /// Also `+inf` (as a fixed value: "none", "no limit").
    pub const fn or_inf(self) -> Self {
        Self {
            infinite: true,
            ..self
        }
    }

    /// Whole numbers only.
    pub const fn whole(self) -> Self {
        Self {
            whole: true,
            ..self
        }
    }

    /// A list of exactly `n` entries.
    pub const fn entries(self, n: usize) -> Self {
        Self {
            min_entries: n,
            max_entries: n,
            ..self
        }
    }

    /// A list of `low` to `high` entries.
    pub const fn between_entries(self, low: usize, high: usize) -> Self {
        Self {
            min_entries: low,
            max_entries: high,
            ..self
        }
    }

    /// A list of at most `n` entries.
    pub const fn at_most_entries(self, n: usize) -> Self {
        Self {
            max_entries: n,
            ..self
        }
    }

    /// A list of tables with these fields (each checked by its own type and domain).
    pub const fn tables(fields: &'static [Field]) -> Self {
        Self {
            fields,
            ..Self::FINITE
        }
    }

    /// The domain of a key of type `ty` as the scenario reference writes it: `finite, > 0,
    /// <= 1000`; `>= 1, <= 64` for an integer type; `3 entries` for `[T; 3]`; empty for a type
    /// without numbers and no length rule (a string, a flag).
    pub fn describe(&self, ty: &str) -> String {
        let ty = compact(ty);
        let mut parts: Vec<String> = Vec::new();
        // The key's own length ([T; N]) and its entries' ([T; N] inside a list).
        let (own, inner) = match ty.strip_prefix("Vec<").and_then(|t| t.strip_suffix('>')) {
            Some(item) => (None, item),
            None => match fixed_length(&ty) {
                Some((n, item)) => (Some(n), item),
                None => (None, ty.as_str()),
            },
        };
        let (entry, item) = match fixed_length(inner) {
            Some((n, item)) => (Some(n), item),
            None => (None, inner),
        };
        if !self.fields.is_empty() {
            let fields: Vec<String> = self
                .fields
                .iter()
                .map(|f| format!("{} ({})", f.name, f.domain.describe(f.ty)))
                .collect();
            parts.push(format!("each entry: {}", fields.join("; ")));
        } else if item == "Param" || is_number_type(item) {
            let text = self.number_text(item != "Param" && !item.starts_with('f'));
            if !text.is_empty() {
                parts.push(text);
            }
        }
        if let Some(n) = own {
            parts.push(format!("{n} entries"));
        }
        if let Some(n) = entry {
            parts.push(format!("entries of {n} numbers"));
        }
        match (self.min_entries, self.max_entries) {
            (0, usize::MAX) => {}
            (lo, hi) if lo == hi => parts.push(format!("{lo} entries")),
            (0, hi) => parts.push(format!("at most {hi} entries")),
            (lo, usize::MAX) => parts.push(format!("at least {lo} entries")),
            (lo, hi) => parts.push(format!("{lo} to {hi} entries")),
        }
        parts.join(", ")
    }

    /// The numbers allowed: `finite, > 0, <= 1000` (for an integer type: its bounds only).
    fn number_text(&self, integer: bool) -> String {
        let mut parts: Vec<String> = Vec::new();
        if !integer {
            parts.push(
                if self.infinite {
                    "finite or inf"
                } else {
                    "finite"
                }
                .into(),
            );
            if self.whole {
                parts.push("whole".into());
            }
        }
        match self.low {
            Bound::Inclusive(v) => parts.push(format!(">= {}", number(v))),
            Bound::Exclusive(v) => parts.push(format!("> {}", number(v))),
            Bound::Open => {}
        }
        match self.high {
            Bound::Inclusive(v) => parts.push(format!("<= {}", number(v))),
            Bound::Exclusive(v) => parts.push(format!("< {}", number(v))),
            Bound::Open => {}
        }
        parts.join(", ")
    }

    /// Checks `value`, of a key declared with type `ty` (`"f32"`, `"Param"`, `"[f32; 3]"`,
    /// `"Vec<[f32; 2]>"`, a struct's name), against this domain. The error is the message and
    /// the path below the key where it applies (`"[2].a"`, or empty for the key itself).
    pub fn check(&self, ty: &str, value: &Value) -> Result<(), (String, String)> {
        self.check_as(&compact(ty), value)
    }

    fn check_as(&self, ty: &str, value: &Value) -> Result<(), (String, String)> {
        if ty == "Param" {
            return self.check_param(value);
        }
        if let Some((n, item)) = fixed_length(ty) {
            let Value::Array(entries) = value else {
                return Ok(());
            };
            if entries.len() != n {
                return Err((
                    format!("must have exactly {n} entries, got {}", entries.len()),
                    String::new(),
                ));
            }
            return self.check_entries(item, entries);
        }
        if let Some(item) = ty.strip_prefix("Vec<").and_then(|t| t.strip_suffix('>')) {
            let Value::Array(entries) = value else {
                return Ok(());
            };
            let n = entries.len();
            if n < self.min_entries || n > self.max_entries {
                let wanted = match (self.min_entries, self.max_entries) {
                    (lo, hi) if lo == hi => format!("exactly {lo}"),
                    (0, hi) => format!("at most {hi}"),
                    (lo, usize::MAX) => format!("at least {lo}"),
                    (lo, hi) => format!("{lo} to {hi}"),
                };
                return Err((
                    format!("must have {wanted} entries, got {n}"),
                    String::new(),
                ));
            }
            return self.check_entries(item, entries);
        }
        match value {
            Value::Integer(_) | Value::Float(_) if is_number_type(ty) => self
                .check_number(value, !ty.starts_with('f'))
                .map_err(|m| (m, String::new())),
            Value::Table(table) if !self.fields.is_empty() => {
                for field in self.fields {
                    if let Some(v) = table.get(field.name) {
                        field
                            .domain
                            .check(field.ty, v)
                            .map_err(|(m, at)| (m, format!(".{}{at}", field.name)))?;
                    }
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn check_entries(&self, item: &str, entries: &[Value]) -> Result<(), (String, String)> {
        for (i, entry) in entries.iter().enumerate() {
            self.check_as(item, entry)
                .map_err(|(m, at)| (m, format!("[{i}]{at}")))?;
        }
        Ok(())
    }

    /// A number or a `[low, high]` range of two numbers within the domain, low <= high; a
    /// range's ends are finite even where the key takes `inf`.
    fn check_param(&self, value: &Value) -> Result<(), (String, String)> {
        let whole = |m: String| (m, String::new());
        match value {
            Value::Integer(_) | Value::Float(_) => self.check_number(value, false).map_err(whole),
            Value::Array(ends) => {
                if ends.len() != 2 {
                    return Err(whole(format!(
                        "must be a number or a [low, high] range, got {} entries",
                        ends.len()
                    )));
                }
                let finite = Domain {
                    infinite: false,
                    ..*self
                };
                let mut numbers = [0.0; 2];
                for (i, end) in ends.iter().enumerate() {
                    let Some(v) = as_number(end) else {
                        return Ok(());
                    };
                    finite
                        .check_number(end, false)
                        .map_err(|m| whole(format!("a range's {} end {m}", ["low", "high"][i])))?;
                    numbers[i] = v;
                }
                if numbers[0] > numbers[1] {
                    return Err(whole(format!(
                        "must be a [low, high] range with low <= high, got [{}, {}]",
                        number(numbers[0]),
                        number(numbers[1])
                    )));
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// A number within the domain (of an integer type when `integer`: a float is left to
    /// serde); the message says what is allowed.
    fn check_number(&self, value: &Value, integer: bool) -> Result<(), String> {
        let Some(v) = as_number(value) else {
            return Ok(());
        };
        if integer && matches!(value, Value::Float(_)) {
            return Ok(());
        }
        let fail = || {
            Err(format!(
                "must be {}, got {}",
                self.number_text(integer),
                number(v)
            ))
        };
        if v.is_nan() || (v.is_infinite() && !(self.infinite && v > 0.0)) {
            return fail();
        }
        if v.is_infinite() {
            return Ok(());
        }
        // A float is read into float32 (a few keys into f64): it is compared with the bounds at
        // float32 precision, so that a value written back from float32 (pi/2 as 1.5707964 when
        // a resolved scenario is saved and loaded again) stays within a bound of pi/2, and a
        // value float32 rounds to 0 is not "> 0".
        let at_precision = |x: f64| match value {
            Value::Float(_) => x as f32 as f64,
            _ => x,
        };
        let w = at_precision(v);
        let low_ok = match self.low {
            Bound::Open => true,
            Bound::Inclusive(b) => w >= at_precision(b),
            Bound::Exclusive(b) => w > at_precision(b),
        };
        let high_ok = match self.high {
            Bound::Open => true,
            Bound::Inclusive(b) => w <= at_precision(b),
            Bound::Exclusive(b) => w < at_precision(b),
        };
        if !(low_ok && high_ok) || (self.whole && v.fract() != 0.0) {
            return fail();
        }
        Ok(())
    }
}

/// `ty` without whitespace (`stringify!` of a type may space it).
fn compact(ty: &str) -> String {
    ty.chars().filter(|c| !c.is_whitespace()).collect()
}

/// `[T;N]` as (N, T).
fn fixed_length(ty: &str) -> Option<(usize, &str)> {
    let inner = ty.strip_prefix('[')?.strip_suffix(']')?;
    let (item, n) = inner.rsplit_once(';')?;
    Some((n.parse().ok()?, item))
}

fn is_number_type(ty: &str) -> bool {
    matches!(
        ty,
        "f32" | "f64" | "u8" | "u16" | "u32" | "u64" | "usize" | "i32" | "i64"
    )
}

fn as_number(value: &Value) -> Option<f64> {
    match value {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

/// A bound or value as written in messages: `1000`, `0.5`, `1e-6`, `inf`, `NaN`.
fn number(v: f64) -> String {
    if v.is_nan() {
        "NaN".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.into()
    } else if v != 0.0 && (v.abs() >= 1e7 || v.abs() < 1e-4) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(text: &str) -> Value {
        let table: toml::Table = format!("v = {text}").parse().expect("toml");
        table["v"].clone()
    }

    fn check(domain: Domain, ty: &str, text: &str) -> Result<(), (String, String)> {
        domain.check(ty, &value(text))
    }

    #[test]
    fn numbers_are_finite_and_within_bounds() {
        let d = Domain::POSITIVE.at_most(1000.0);
        assert!(check(d, "f32", "2.0").is_ok());
        assert!(check(d, "f32", "1000").is_ok());
        for bad in ["0.0", "-1", "nan", "inf", "-inf", "1000.5", "1e20"] {
            let (message, at) = check(d, "f32", bad).unwrap_err();
            assert!(
                message.starts_with("must be finite, > 0, <= 1000"),
                "{message}"
            );
            assert!(at.is_empty());
        }
        assert!(check(Domain::NON_NEGATIVE.or_inf(), "f32", "inf").is_ok());
        assert!(check(Domain::NON_NEGATIVE.or_inf(), "f32", "-inf").is_err());
        assert!(check(Domain::FINITE.whole(), "f32", "3.5").is_err());
        // float32 round trips of a bound stay within it: pi/2 saved from float32 is 1.5707964.
        let right_angle = Domain::POSITIVE.at_most(std::f64::consts::FRAC_PI_2);
        assert!(check(right_angle, "f32", "1.5707964").is_ok());
        assert!(check(right_angle, "f32", "1.5708").is_err());
        assert!(check(Domain::POSITIVE, "f32", "1e-50").is_err());
        // Another kind is serde's to refuse.
        assert!(check(d, "f32", "\"big\"").is_ok());
    }

    #[test]
    fn ranges_have_two_finite_ordered_ends() {
        let d = Domain::POSITIVE.or_inf();
        assert!(check(d, "Param", "[0.1, 0.2]").is_ok());
        assert!(check(d, "Param", "inf").is_ok());
        assert!(check(d, "Param", "[0.1, inf]").is_err());
        assert!(check(d, "Param", "[0.2, 0.1]").is_err());
        assert!(check(d, "Param", "[0.1, nan]").is_err());
        assert!(check(d, "Param", "[0.1, 0.2, 0.3]").is_err());
    }

    #[test]
    fn arrays_have_exactly_their_length_and_lists_their_entries() {
        let colour = Domain::UNIT;
        assert!(check(colour, "[f32; 3]", "[0.1, 0.2, 0.3]").is_ok());
        let (message, _) = check(colour, "[f32; 3]", "[0.1, 0.2, 0.3, 0.4]").unwrap_err();
        assert_eq!(message, "must have exactly 3 entries, got 4");
        let (_, at) = check(colour, "[f32; 3]", "[0.1, 2.0, 0.3]").unwrap_err();
        assert_eq!(at, "[1]");
        let points = Domain::FINITE;
        let (message, at) = check(points, "Vec<[f32; 2]>", "[[1, 2], [1, 2, 3]]").unwrap_err();
        assert_eq!(
            (message.as_str(), at.as_str()),
            ("must have exactly 2 entries, got 3", "[1]")
        );
        let (_, at) = check(points, "Vec<[f32;2]>", "[[1, 2], [1, nan]]").unwrap_err();
        assert_eq!(at, "[1][1]");
        assert!(check(Domain::FINITE.entries(5), "Vec<bool>", "[true, true]").is_err());
        assert!(check(Domain::FINITE.at_most_entries(2), "Vec<f32>", "[1, 2, 3]").is_err());
    }

    #[test]
    fn tables_of_a_list_check_their_fields() {
        const FIELDS: &[Field] = &[
            Field::new("a", "[f32; 2]", Domain::FINITE),
            Field::new("width", "f32", Domain::POSITIVE),
        ];
        let d = Domain::tables(FIELDS);
        assert!(check(d, "Vec<LineMark>", "[{a = [0, 1], width = 0.1}]").is_ok());
        let (_, at) = check(d, "Vec<LineMark>", "[{a = [0, 1, 2], width = 0.1}]").unwrap_err();
        assert_eq!(at, "[0].a");
        let (_, at) = check(d, "Vec<LineMark>", "[{a = [0, 1], width = nan}]").unwrap_err();
        assert_eq!(at, "[0].width");
        let text = d.describe("Vec<LineMark>");
        assert_eq!(
            text,
            "each entry: a (finite, 2 entries); width (finite, > 0)"
        );
    }

    #[test]
    fn descriptions_read_as_the_reference_shows_them() {
        let d = Domain::POSITIVE.at_most(1000.0);
        assert_eq!(d.describe("f32"), "finite, > 0, <= 1000");
        assert_eq!(
            Domain::UNIT.describe("[f32; 3]"),
            "finite, >= 0, <= 1, 3 entries"
        );
        assert_eq!(
            Domain::POSITIVE.or_inf().describe("Param"),
            "finite or inf, > 0"
        );
        assert_eq!(Domain::range(1.0, 64.0).describe("u32"), ">= 1, <= 64");
        assert_eq!(Domain::FINITE.whole().describe("f32"), "finite, whole");
        assert_eq!(Domain::FINITE.describe("[bool; 5]"), "5 entries");
        assert_eq!(
            Domain::FINITE.at_most_entries(16).describe("Vec<[f32; 2]>"),
            "finite, entries of 2 numbers, at most 16 entries"
        );
        assert_eq!(Domain::FINITE.describe("String"), "");
        assert_eq!(
            Domain::range(0.0, 1e9).describe("f32"),
            "finite, >= 0, <= 1e9"
        );
    }
}
