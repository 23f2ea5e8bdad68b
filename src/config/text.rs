//! Scenario TOML as text and tables: parsing with errors that name the key
//! ([`parse`], [`error_key`]), overlaying a file or keyword overrides on the defaults with a
//! did-you-mean for unknown keys ([`overlay`], [`expand_overrides`], [`did_you_mean`]), and
//! writing a section back with its comments ([`render_section`]).

use toml::{Table, Value};

use super::{KeyDoc, OVERRIDE_ORIGIN};
use crate::error::{Error, Result};

/// Parses TOML text; errors name `origin` and the key (or line).
pub fn parse(text: &str, origin: &str) -> Result<Table> {
    text.parse::<Table>().map_err(|e| {
        let key = error_key(&e, text);
        Error::config(origin, &key, e.message().trim().to_string())
    })
}

/// The dotted key a toml error is about: found from the error's span in `text` (the key on that
/// line, under the last `[section]` header above it), else `line N`.
pub fn error_key(e: &toml::de::Error, text: &str) -> String {
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

/// The candidate spelled most like `key` (at most a third of its letters edited, at least one
/// edit allowed), for a "did you mean" in an unknown key's message; None when none is close.
pub fn nearest_key<'a>(
    key: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    let limit = (key.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .map(|c| (edit_distance(key, c), c))
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// Edit distance between `a` and `b`, in characters: insertions, deletions, substitutions and
/// swaps of two neighbours (`taks` is one edit from `task`), each counting one (the optimal
/// string alignment distance).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    // Rows i - 2, i - 1 and i of the table of distances between prefixes.
    let mut older: Vec<usize> = vec![0; b.len() + 1];
    let mut previous: Vec<usize> = (0..=b.len()).collect();
    for i in 1..=a.len() {
        let mut row = vec![i; b.len() + 1];
        for j in 1..=b.len() {
            let substitution = previous[j - 1] + usize::from(a[i - 1] != b[j - 1]);
            row[j] = (previous[j] + 1).min(row[j - 1] + 1).min(substitution);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                row[j] = row[j].min(older[j - 2] + 1);
            }
        }
        older = std::mem::replace(&mut previous, row);
    }
    previous[b.len()]
}

/// The line (counted from 1) of a scenario file's `text` that sets the dotted `key`
/// (`task.goal_radius` under `[task]`, or written `task.goal_radius = ...` or as a `[task]`
/// header itself), for messages about a key; None when it is not found so.
pub fn line_of(text: &str, key: &str) -> Option<usize> {
    let mut section = String::new();
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.starts_with('[') && line.ends_with(']') {
            section = line
                .trim_matches(|c| c == '[' || c == ']')
                .trim()
                .to_string();
            if section == key {
                return Some(number + 1);
            }
            continue;
        }
        let Some((name, _)) = line.split_once('=') else {
            continue;
        };
        let name: String = name
            .split('.')
            .map(|part| part.trim().trim_matches('"'))
            .collect::<Vec<_>>()
            .join(".");
        let dotted = if section.is_empty() {
            name
        } else {
            format!("{section}.{name}")
        };
        if dotted == key || key.starts_with(&format!("{dotted}.")) {
            return Some(number + 1);
        }
    }
    None
}

/// What an unknown key's message suggests: "; did you mean `name`?" for the nearest of
/// `candidates`, or nothing.
pub fn did_you_mean<'a>(key: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    nearest_key(key, candidates).map_or_else(String::new, |c| format!("; did you mean `{c}`?"))
}

/// Overlays `over` on `base`. Every key of `over` must exist in `base` (so a typo is an error
/// naming the key, not a silently ignored setting).
pub fn overlay(base: &mut Table, over: &Table, prefix: &str, origin: &str) -> Result<()> {
    for (key, value) in over {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match base.get_mut(key) {
            None => {
                let known: Vec<&String> = base.keys().collect();
                let hint = did_you_mean(key, base.keys().map(String::as_str));
                return Err(Error::config(
                    origin,
                    &path,
                    format!("unknown key{hint}; known keys here: {known:?}"),
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

/// Turns keyword overrides into a table shaped like `base`: `task.goal_radius = x` and leaf
/// names that occur in exactly one section (`goal_radius = x`) become `[task] goal_radius`.
pub fn expand_overrides(base: &Table, overrides: &Table) -> Result<Table> {
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
                    // Every key a keyword may name: the sections' leaves and the top level's.
                    let leaves = base.iter().flat_map(|(name, value)| match value {
                        Value::Table(t) => t.keys().map(String::as_str).collect::<Vec<_>>(),
                        _ => vec![name.as_str()],
                    });
                    let hint = did_you_mean(key, leaves);
                    return Err(Error::config(
                        OVERRIDE_ORIGIN,
                        key,
                        format!("unknown key: no scenario section has it{hint}"),
                    ));
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

/// Writes one section of a scenario file: `[name]`, then every key of `keys` with its value in
/// `table` (and, with `comments`, its comment, aligned). Keys of `table` that `keys` does not
/// list follow, bare.
pub fn render_section(
    out: &mut String,
    name: &str,
    keys: &[KeyDoc],
    table: &Table,
    comments: bool,
) {
    out.push_str(&format!("[{name}]\n"));
    let mut lines: Vec<(String, String)> = Vec::new();
    for key in keys {
        if let Some(value) = table.get(key.name) {
            let comment = match (comments, key.allowed()) {
                (false, _) => String::new(),
                (true, allowed) if allowed.is_empty() => key.comment.trim().to_string(),
                (true, allowed) => format!("{}; allowed: {allowed}", key.comment.trim()),
            };
            lines.push((format!("{} = {}", key.name, value), comment));
        }
    }
    for (name, value) in table {
        if !keys.iter().any(|k| k.name == name) {
            lines.push((format!("{name} = {value}"), String::new()));
        }
    }
    let width = lines
        .iter()
        .map(|(l, _)| l.chars().count())
        .filter(|n| *n <= 40)
        .max()
        .unwrap_or(0);
    for (line, comment) in lines {
        if comment.is_empty() {
            out.push_str(&line);
        } else {
            let pad = width.saturating_sub(line.chars().count()) + 2;
            out.push_str(&format!("{line}{}# {comment}", " ".repeat(pad)));
        }
        out.push('\n');
    }
    out.push('\n');
}
