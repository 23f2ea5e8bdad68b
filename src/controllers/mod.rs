//! The KH4VREP paper's classical controllers (Farias et al. 2017, §3.3–3.5), written once in
//! Rust: the scripted formation leader uses them inside the simulator, and the baselines of
//! `khepera_gym.baselines` call the same code on observations.
//!
//! Units: metres, seconds, radians; robot frame x forward, y left, angles CCW.

pub mod braitenberg;
pub mod position;

pub use braitenberg::Braitenberg;
pub use position::PositionControl;
