//! khepera_gym's simulation core: seeded Khepera IV worlds stepped in parallel.
//!
//! Pure Rust with no Python in it (`cargo test` runs it alone); the pyo3 binding lives in
//! `python/` behind the `python` feature. Layout: `robot` (body, drive, units), `sensors` (IR
//! and ultrasonic models), `world` (scene geometry, rapier physics, stepping, sensing),
//! `scenario` (TOML configuration), `tasks` (reset/observe/reward/terminate per task),
//! `batch` (N worlds, rayon, autoreset). Units are SI; angles are radians, CCW, in (-π, π].

pub mod batch;
pub mod controllers;
pub mod error;
pub mod render;
pub mod robot;
pub mod scenario;
pub mod sensors;
pub mod tasks;
pub mod world;

#[cfg(feature = "python")]
mod python;

pub use batch::Batch;
pub use error::{Error, Result};
pub use robot::ActionType;
pub use scenario::{Scenario, Source};
pub use tasks::{Env, TaskKind};
