//! khepera_gym's simulation core: seeded Khepera IV worlds stepped in parallel.
//!
//! Pure Rust with no Python in it (`cargo test` runs it alone); the pyo3 binding lives in
//! `python/` behind the `python` feature. Units are SI; angles are radians, CCW, in (-π, π].
//!
//! Layers, each using only those above it (docs/extending.md walks through them):
//! * `error`, `config` (how scenario tables are declared and overlaid), `obs` (observation
//!   layouts by name), `draw` (what tasks and sensors ask the renderer to draw);
//! * `robot` (body, drive, units, `[robot]`), `drive` (the motor controller's mode, `[drive]`), `odometry` (dead reckoning), `world::scene`
//!   (geometry and ray casts);
//! * `sensors` (one file a sensor, behind the `Sensor` contract);
//! * `scenario` (the scenario: shared sections, loading, validation);
//! * `world` (the robots, their sensors and rapier physics; spawning);
//! * `controllers` (one file a baseline, behind the `Controller` contract);
//! * `tasks` (one file a task, behind the `Task` contract, and `Env`);
//! * `batch` (N worlds, rayon, autoreset) and `render` (frames).

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
pub mod tasks;
pub mod world;

#[cfg(feature = "python")]
mod python;

pub use batch::Batch;
pub use error::{Error, Result};
pub use robot::ActionType;
pub use scenario::{Scenario, Source};
pub use tasks::{Env, TaskKind};
