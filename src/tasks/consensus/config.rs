//! consensus_v1's scenario table `[consensus]`: the robots, their graph, their objective and
//! their messages, with the checks that make an impossible scenario a `ConfigError` naming the
//! key. Units: metres, seconds.

use toml::Table;

use super::MAX_DELAY_STEPS;
use crate::config::ConfigTable;
use crate::error::{Error, Result};
use crate::scenario::Scenario;

/// Most robots of a consensus world (one observation slot per other robot).
pub const MAX_ROBOTS: u32 = 32;

/// The communication graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Graph {
    /// i linked to i ± 1 (mod N).
    Ring,
    /// i linked to i ± 1 (a path).
    Line,
    /// Every pair linked.
    Complete,
    /// Pairs within `range` m (true distance, at each step).
    Geometric,
    /// The pairs of `edges`.
    Edges,
}

/// What the robots agree on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// One meeting point (c_i = 0).
    Rendezvous,
    /// A regular polygon of radius `formation_radius` (c_i its vertices).
    Formation,
}

/// When a robot broadcasts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Trigger {
    /// Every `period` s.
    Periodic,
    /// When its estimate has moved `threshold` m from its last broadcast.
    Event,
}

crate::config_table! {
    /// `[consensus]`: the robots, their graph, their messages.
    pub struct ConsensusConfig {
        /// robots (2..32)
        n_robots: u32 = 4,
        /// ring, line, complete, geometric (within range) or edges (the pairs below)
        graph: Graph = "ring",
        /// m, radio range of the geometric graph [E]
        range: f32 = 1.0,
        /// undirected pairs [i, j] of robot indices, for graph = "edges"
        edges: Vec<[u32; 2]> = [],
        /// rendezvous (one point) or formation (a regular polygon)
        objective: Objective = "formation",
        /// m, the formation polygon's radius
        formation_radius: f32 = 0.3,
        /// periodic (every period) or event (the estimate moved by threshold)
        trigger: Trigger = "periodic",
        /// s between a robot's periodic broadcasts (rounded to whole control steps, at least one)
        period: f32 = 0.05,
        /// m the estimate moves before an event-triggered broadcast [E]
        threshold: f32 = 0.01,
        /// probability that a message is lost, per receiver [0, 1)
        drop: f32 = 0.0,
        /// control steps a message takes to arrive (0..100)
        delay_steps: u32 = 0,
        /// m, the robots have converged when the error is below this (plus the rendezvous floor)
        tolerance: f32 = 0.03,
        /// reward per metre of error per step
        error_weight: f32 = 1.0,
    }
}

pub(super) fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    let c = ConsensusConfig::from_table(table, origin, "consensus")?;
    let bad = |key: &str, msg: String| Err(Error::config(origin, &format!("consensus.{key}"), msg));
    let n = c.n_robots;
    if !(2..=MAX_ROBOTS).contains(&n) {
        return bad("n_robots", format!("must be in 2..={MAX_ROBOTS}, got {n}"));
    }
    let fit = crate::tasks::multinav::robots_that_fit(scenario);
    if n as usize > fit {
        return bad(
            "n_robots",
            format!(
                "{n} robots do not fit in a {} m x {} m arena: random placement fits about {fit}",
                scenario.arena.width, scenario.arena.height
            ),
        );
    }
    if !(c.range.is_finite() && c.range > 0.0) {
        return bad(
            "range",
            format!("must be a finite number > 0, got {}", c.range),
        );
    }
    if c.graph == Graph::Edges && c.edges.is_empty() {
        return bad("edges", "graph = \"edges\" needs at least one pair".into());
    }
    if c.graph != Graph::Edges && !c.edges.is_empty() {
        return bad(
            "edges",
            format!(
                "only read with graph = \"edges\" (the graph is {:?})",
                c.graph
            ),
        );
    }
    for [i, j] in &c.edges {
        if *i >= n || *j >= n || i == j {
            return bad(
                "edges",
                format!("[{i}, {j}] is not a pair of two robots among 0..{}", n - 1),
            );
        }
    }
    if !(c.period.is_finite() && c.period > 0.0) {
        return bad(
            "period",
            format!("must be a finite number > 0, got {}", c.period),
        );
    }
    if !(c.threshold.is_finite() && c.threshold >= 0.0) {
        return bad(
            "threshold",
            format!("must be finite and >= 0, got {}", c.threshold),
        );
    }
    if !(0.0..1.0).contains(&c.drop) {
        return bad("drop", format!("must be in [0, 1), got {}", c.drop));
    }
    if c.delay_steps > MAX_DELAY_STEPS {
        return bad(
            "delay_steps",
            format!("must be in 0..={MAX_DELAY_STEPS}, got {}", c.delay_steps),
        );
    }
    if !(c.tolerance.is_finite() && c.tolerance > 0.0) {
        return bad(
            "tolerance",
            format!("must be a finite number > 0, got {}", c.tolerance),
        );
    }
    if !(c.error_weight.is_finite() && c.error_weight >= 0.0) {
        return bad(
            "error_weight",
            format!("must be finite and >= 0, got {}", c.error_weight),
        );
    }
    if c.objective == Objective::Formation {
        let r = c.formation_radius;
        let side = 2.0 * r * (std::f32::consts::PI / n as f32).sin();
        let least = 2.0 * scenario.robot.radius + scenario.obstacles.spawn_clearance;
        if !(r.is_finite() && side >= least) {
            return bad(
                "formation_radius",
                format!(
                    "{n} robots on a circle of radius {r} m would be {side:.3} m apart, less than \
                     a diameter plus obstacles.spawn_clearance ({least:.3} m): use at least {:.3} m",
                    least / (2.0 * (std::f32::consts::PI / n as f32).sin())
                ),
            );
        }
        let room = 0.5 * scenario.arena.width.min(scenario.arena.height) - scenario.robot.radius;
        if r >= room {
            return bad(
                "formation_radius",
                format!("the polygon must fit the arena: below {room:.3} m, got {r}"),
            );
        }
    }
    if !scenario.spawn.start.is_empty() || !scenario.spawn.goal.is_empty() {
        return Err(Error::config(
            origin,
            "spawn.start",
            "consensus places its robots at random: spawn.start and spawn.goal are not read",
        ));
    }
    Ok(())
}
