//! khepera_gym's simulation core: seeded Khepera IV worlds stepped in parallel.
//!
//! Pure Rust with no Python in it (`cargo test` runs it alone); the pyo3 binding lives in
//! `python/` behind the `python` feature. Units are SI; angles are radians, CCW, in (-π, π].
//!
//! Layers, lowest first. A module uses only modules of the lines above its own: never one of
//! its own line, never one below (`tests/layers.rs` reads this list and holds every `crate::`
//! path of `src/` to it, test modules aside; docs/extending.md walks through the layers):
//! * `error` (the core's error type);
//! * `simd` (which of the CPU's vector units run the hot kernels, chosen at run time);
//! * `config` (how scenario tables are declared, overlaid and checked), `obs` (observation
//!   layouts by name), `draw` (what tasks and sensors ask the renderer to draw), `memory` (what
//!   a batch takes, and the check that a request fits), `geometry` (the scene and its exact ray
//!   casts, the floor, a grid over points, reachability: built from plain values);
//! * `motors` (the motor controller's modes, `[motors]`);
//! * `robot` (body, drive, units, `[robot]`);
//! * `odometry` (dead reckoning, `[odometry]`);
//! * `sensors` (one file a sensor, behind the `Sensor` contract);
//! * `scenario` (the scenario: shared sections, loading, validation, versions);
//! * `world` (the robots, their sensors and physics; spawning), `controllers` (one file a
//!   baseline, behind the `Controller` contract);
//! * `tasks` (one file a task, behind the `Task` contract, and `Env`);
//! * `batch` (N worlds, rayon, autoreset), `render` (frames);
//! * `python` (the pyo3 binding, built with the feature of that name).

pub mod batch;
pub mod config;
pub mod controllers;
pub mod draw;
pub mod error;
pub mod geometry;
pub mod memory;
pub mod motors;
pub mod obs;
pub mod odometry;
pub mod render;
pub mod robot;
pub mod scenario;
pub mod sensors;
pub mod simd;
pub mod tasks;
pub mod world;

#[cfg(feature = "python")]
mod python;

pub use batch::Batch;
pub use error::{Error, Result};
pub use robot::ActionType;
pub use scenario::{Scenario, Source};
pub use tasks::{Env, TaskKind};
