//! Range sensors of the Khepera IV: the 8-sensor infrared proximity ring and the 5 ultrasonic
//! sensors. Each module holds the real response (raw units of the K-Team library) and noise;
//! the rays themselves are cast by `world::Scene`.
//!
//! Frame: robot frame x forward, y left; bearings counter-clockwise from forward, in radians.

pub mod ir;
pub mod ultrasonic;

pub use ir::{IrModel, IR_BEARINGS, IR_COUNT};
pub use ultrasonic::{UsModel, US_BEARINGS, US_COUNT, US_DISABLED, US_NOTHING, US_TOO_CLOSE};
