//! Plain geometry, built from plain values (sizes, shapes, segments, an image file) rather than
//! from scenario tables: the static scene and its exact ray casts, the floor the ground sensors
//! read, a grid over points, and the reachability map of a scene. It uses only `error` (whose
//! messages name the scenario key to change); the sensors, the scenario's checks and the world
//! sit on it.
//!
//! Units: metres, radians; world frame (x right, y up), the arena centred at the origin.

pub mod floor;
pub mod grid;
pub mod rays;
pub mod reach;
pub mod scene;
