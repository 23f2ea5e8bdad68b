//! The documented maxima of scenario values, shared by the keys' domains ([`super::Domain`]):
//! far beyond anything the robot or its tasks need, and low enough that no value within them
//! overflows float32 physics or makes a reward infinite. Every reward term is a weight (at most
//! [`WEIGHT`]) times a distance or speed the arena bounds (at most its diagonal, about 1.4 km,
//! or a speed of at most [`SPEED`]), so a step's reward stays below about 10^10 and an
//! episode's return below 10^20, well inside float32's 3.4 x 10^38.
//!
//! Units: SI (m, s, m/s, m/s^2, rad/s, kg).

/// Largest length or coordinate (m): an arena's side, a curve's size, a sensor's range.
/// Positions are float32 metres, which keep millimetre precision well beyond this.
pub const LENGTH: f64 = 1000.0;
/// Largest speed (m/s): over 100 times the Khepera IV's 0.813 m/s.
pub const SPEED: f64 = 100.0;
/// Largest acceleration (m/s^2), other than `inf` where a key takes it for "none".
pub const ACCEL: f64 = 10_000.0;
/// Largest turn rate (rad/s).
pub const TURN_RATE: f64 = 1000.0;
/// Largest reward weight, bonus or penalty (reward per metre, per step, per unit).
pub const WEIGHT: f64 = 1.0e6;
/// Largest duration (s): about 11.6 days of simulated time.
pub const TIME: f64 = 1.0e6;
/// Largest friction coefficient.
pub const FRICTION: f64 = 100.0;
/// Largest mass (kg).
pub const MASS: f64 = 1000.0;
/// Largest infrared reflectance relative to white paper.
pub const REFLECTANCE: f64 = 100.0;
