//! The `[platoon]` table of the platoon task: its own keys (`robots`, `time_gap`) followed by
//! every key of Track's `[track]` table (the reference, start offsets, reward, end and
//! statistics, declared once in `tasks/track/config.rs` and read here under `platoon.`), and the
//! checks that the robots fit on the reference: apart enough that their reference points never
//! overlap, and no more than one lap holds. Errors name the key (`platoon.time_gap`).
//!
//! A scenario has one task table, so the platoon's is Track's with two keys more rather than a
//! `[track]` table beside a `[platoon]` one. Units: metres, seconds, m/s.

use toml::Table;

use crate::config::{limits, ConfigTable, Domain, KeyDoc};
use crate::error::{Error, Result};
use crate::scenario::Scenario;
use crate::tasks::reference::{Reference, Shape};
use crate::tasks::track::TrackConfig;

/// Most robots in a platoon: 16 × 0.30 m is more than the default circle's 3.77 m lap, so the
/// lap, not this cap, limits the default scenario (the check names `platoon.robots`).
pub const MAX_ROBOTS: u32 = 16;

/// Free gap between two robots' shells when their reference points are closest (m): the
/// reference points must stay at least a robot diameter plus this apart [E: 2 cm, the size of
/// the tracking error Kanayama's controller keeps after its transient].
pub const SPACING_MARGIN: f32 = 0.02;

/// Samples of one lap on which the reference points' distances are checked.
const SPACING_SAMPLES: usize = 720;

crate::config_table! {
    /// The platoon's own keys of `[platoon]` (Track's keys follow them in the same table).
    pub struct PlatoonKeys {
        /// robots in the platoon, one agent each (1..16; at most as many as one lap holds)
        robots: u32 = 3 => Domain::range(1.0, MAX_ROBOTS as f64),
        /// s: robot k tracks the reference delayed by k x time_gap, so neighbours are time_gap x speed apart along the curve: 2 s gives 0.30 m at 0.15 m/s, about one body (0.14 m) of free space between shells, the road's two-second headway rule [E]
        time_gap: f32 = 2.0 => Domain::POSITIVE.at_most(limits::TIME),
    }
}

/// Number of keys in `[platoon]`: its own and Track's.
const N_KEYS: usize = PlatoonKeys::KEYS.len() + TrackConfig::KEYS.len();

/// Every key of `[platoon]` in file order: its own, then Track's.
pub const KEYS: [KeyDoc; N_KEYS] = join(PlatoonKeys::KEYS, TrackConfig::KEYS);

const fn join<const N: usize>(first: &[KeyDoc], second: &[KeyDoc]) -> [KeyDoc; N] {
    let mut out = [KeyDoc::new("", "", "", "", None); N];
    let mut i = 0;
    while i < first.len() {
        out[i] = first[i];
        i += 1;
    }
    let mut j = 0;
    while j < second.len() {
        out[i + j] = second[j];
        j += 1;
    }
    out
}

/// The `[platoon]` table read: the platoon's own keys and Track's.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlatoonConfig {
    /// `robots` and `time_gap`.
    pub own: PlatoonKeys,
    /// The reference and everything else a single robot's tracking has.
    pub track: TrackConfig,
}

impl PlatoonConfig {
    /// Reads `table` (the `[platoon]` table of a scenario); errors name `platoon.<key>`.
    pub fn from_table(table: &Table, origin: &str) -> Result<Self> {
        let (mut own, mut track) = (Table::new(), Table::new());
        for (key, value) in table {
            let part = match PlatoonKeys::KEYS.iter().any(|k| k.name == key) {
                true => &mut own,
                false => &mut track,
            };
            part.insert(key.clone(), value.clone());
        }
        Ok(Self {
            own: PlatoonKeys::from_table(&own, origin, "platoon")?,
            track: TrackConfig::from_table(&track, origin, "platoon")?,
        })
    }

    /// Number of robots.
    pub fn n_robots(&self) -> usize {
        self.own.robots as usize
    }

    /// The lag of robot `k` behind the reference (s).
    pub fn lag(&self, k: usize) -> f64 {
        k as f64 * self.own.time_gap as f64
    }

    /// Track's checks (named `platoon.<key>`), then the platoon's own.
    fn validate(&self, origin: &str, cfg: &Scenario) -> Result<()> {
        self.track.validate(origin, cfg).map_err(as_platoon_error)?;
        let bad = |key: &str, msg: String| Err(Error::config(origin, key, msg));
        let PlatoonKeys { robots, time_gap } = self.own;
        for (key, start) in [
            ("spawn.start", &cfg.spawn.start),
            ("spawn.goal", &cfg.spawn.goal),
        ] {
            if !start.is_empty() {
                return bad(
                    key,
                    "must be []: the platoon starts each robot near its own reference point \
                     (platoon.start_offset) and has no goals"
                        .into(),
                );
            }
        }
        if robots < 2 {
            return Ok(());
        }
        // The spline is drawn at reset; its mean circle stands for it here.
        let reference = self.track.base_reference(0.0, 1.0);
        let length = reference.curve.length();
        let mean_speed = length / reference.period;
        let spacing = time_gap as f64 * mean_speed;
        let least = 2.0 * cfg.robot.radius + SPACING_MARGIN;
        if spacing < least as f64 {
            return bad(
                "platoon.time_gap",
                format!(
                    "time_gap x the reference's mean speed = {spacing:.3} m along the curve, less \
                     than a robot's diameter plus {SPACING_MARGIN} m ({least:.3} m): the robots' \
                     reference points would overlap; raise platoon.time_gap to at least {:.2} s",
                    least as f64 / mean_speed
                ),
            );
        }
        let needed = robots as f64 * time_gap as f64;
        if needed > reference.period {
            return bad(
                "platoon.robots",
                format!(
                    "{robots} robots x time_gap = {needed:.2} s ({:.2} m) is more than one lap \
                     ({:.2} s, {length:.2} m): at most {} robots fit; lower platoon.robots or \
                     platoon.time_gap",
                    needed * mean_speed,
                    reference.period,
                    (reference.period / time_gap as f64).floor()
                ),
            );
        }
        if self.track.reference != Shape::Spline {
            if let Some((k, distance, t)) = self.closest_approach(&reference) {
                if distance < least {
                    return bad(
                        "platoon.time_gap",
                        format!(
                            "on this reference the points of robots k and k + {k} come within \
                             {distance:.3} m of each other (at t = {t:.2} s): less than a \
                             robot's diameter plus {SPACING_MARGIN} m ({least:.3} m), where the \
                             curve slows down or crosses itself; change platoon.time_gap or \
                             platoon.robots"
                        ),
                    );
                }
            }
        }
        Ok(())
    }

    /// The closest any two robots' reference points come over one lap: (index difference,
    /// distance in m, time in s), sampled; None for a single robot.
    pub fn closest_approach(&self, reference: &Reference) -> Option<(usize, f32, f64)> {
        let dt = reference.period / SPACING_SAMPLES as f64;
        let mut closest: Option<(usize, f32, f64)> = None;
        for i in 0..SPACING_SAMPLES {
            let t = i as f64 * dt;
            let lead = reference.at(t).position;
            for k in 1..self.n_robots() {
                let distance = (reference.at(t - self.lag(k)).position - lead).length();
                if closest.is_none_or(|c| distance < c.1) {
                    closest = Some((k, distance, t));
                }
            }
        }
        closest
    }
}

/// An error of Track's checks, about the same key of `[platoon]`.
fn as_platoon_error(error: Error) -> Error {
    match error {
        Error::Config {
            origin,
            key,
            message,
        } => Error::Config {
            origin,
            key: key.replacen("track.", "platoon.", 1),
            message: message.replace("track.", "platoon."),
        },
        other => other,
    }
}

pub(super) fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    PlatoonConfig::from_table(table, origin)?.validate(origin, scenario)
}
