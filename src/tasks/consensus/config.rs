//! consensus_v1's scenario table `[consensus]`: the robots, their graph, their objective and
//! their messages, with the checks that make an impossible scenario a `ConfigError` naming the
//! key. Units: metres, seconds.

use toml::Table;

use super::MAX_DELAY_STEPS;
use crate::config::{limits, ConfigTable, Domain};
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
        n_robots: u32 = 4 => Domain::range(2.0, MAX_ROBOTS as f64),
        /// ring, line, complete, geometric (within range) or edges (the pairs below)
        graph: Graph = "ring",
        /// m, radio range of the geometric graph [E]
        range: f32 = 1.0 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// undirected pairs [i, j] of robot indices, for graph = "edges"
        edges: Vec<[u32; 2]> = [] => Domain::range(0.0, (MAX_ROBOTS - 1) as f64),
        /// rendezvous (one point) or formation (a regular polygon)
        objective: Objective = "formation",
        /// m, the formation polygon's radius
        formation_radius: f32 = 0.3 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// periodic (every period) or event (the estimate moved by threshold)
        trigger: Trigger = "periodic",
        /// s between a robot's periodic broadcasts (rounded to whole control steps, at least one)
        period: f32 = 0.05 => Domain::POSITIVE.at_most(limits::TIME),
        /// m the estimate moves before an event-triggered broadcast [E]
        threshold: f32 = 0.01 => Domain::NON_NEGATIVE.at_most(limits::LENGTH),
        /// probability that a message is lost, per receiver [0, 1)
        drop: f32 = 0.0 => Domain::NON_NEGATIVE.below(1.0),
        /// control steps a message takes to arrive (0..100)
        delay_steps: u32 = 0 => Domain::range(0.0, MAX_DELAY_STEPS as f64),
        /// m, the robots have converged when the error is below this (plus the rendezvous floor)
        tolerance: f32 = 0.03 => Domain::POSITIVE.at_most(limits::LENGTH),
        /// reward per metre of error per step
        error_weight: f32 = 1.0 => Domain::NON_NEGATIVE.at_most(limits::WEIGHT),
    }
}

pub(super) fn check_section(table: &Table, scenario: &Scenario, origin: &str) -> Result<()> {
    let c = ConsensusConfig::from_table(table, origin, "consensus")?;
    let bad = |key: &str, msg: String| Err(Error::config(origin, &format!("consensus.{key}"), msg));
    let n = c.n_robots;
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
