//! The KH4VREP paper's classical controllers (Farias et al. 2017, §3.3–3.5), written once in
//! Rust, one file each behind the [`Controller`] contract: the baselines of
//! `khepera_gym.baselines` run them on observations, batched, and the scripted formation leader
//! runs their laws inside the simulator.
//!
//! A controller is built from its named parameters (a table declared with `config_table!`:
//! names as in its paper, defaults, units, one comment each — the only list of them; Python
//! builds one from keywords) and bound to the layout of the observations it will read: it finds
//! the blocks it needs (`goal_distance`, `ir`, ...) by name, once. It then maps one observation
//! row to normalised wheel speeds (left, right) in [-1, 1] per robot it drives, for
//! environments with `action_type = "wheels"`.
//!
//! Adding a controller: a file here implementing [`Controller`], one line in
//! `controller_registry!`, and a short Python class in `khepera_gym/baselines.py`.
//!
//! Units: metres, seconds, radians; robot frame x forward, y left, angles CCW.

pub mod blob_servo;
pub mod blob_vfh;
pub mod braitenberg;
pub mod consensus;
pub mod drone_pursuit;
pub mod kanayama;
pub mod leader_follower;
pub mod line_proportional;
pub mod line_threshold;
pub mod position;
pub mod pure_pursuit;
pub mod samson;
pub mod vfh;
pub mod waypoints;

pub use braitenberg::Braitenberg;
pub use leader_follower::LeaderFollower;
pub use position::PositionControl;
pub use vfh::Vfh;

use toml::{Table, Value};

use crate::config::{self, ConfigTable, KeyDoc};
use crate::error::{Error, Result};
use crate::obs::ObsLayout;

/// The robot's drive as a policy needs it to turn (v, ω) into normalised wheel actions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelMap {
    /// Wheel separation (m).
    pub axle_length: f32,
    /// Wheel speed that action 1 stands for (m/s).
    pub max_wheel_speed: f32,
}

impl Default for WheelMap {
    fn default() -> Self {
        Self {
            axle_length: crate::robot::AXLE_LENGTH,
            max_wheel_speed: crate::robot::MAX_WHEEL_SPEED,
        }
    }
}

impl WheelMap {
    /// A drive of wheel separation `axle_length` (m) and full-scale wheel speed
    /// `max_wheel_speed` (m/s); both must be finite and > 0.
    pub fn new(controller: &str, axle_length: f32, max_wheel_speed: f32) -> Result<Self> {
        positive(controller, "axle_length", axle_length)?;
        positive(controller, "max_wheel_speed", max_wheel_speed)?;
        Ok(Self {
            axle_length,
            max_wheel_speed,
        })
    }

    /// Normalised actions of wheel speeds (m/s), clipped to [-1, 1].
    pub fn action(&self, wheels: [f32; 2]) -> [f32; 2] {
        wheels.map(|w| (w / self.max_wheel_speed).clamp(-1.0, 1.0))
    }

    /// Normalised actions of a twist: speed `v` (m/s) and turn rate `w` (rad/s).
    pub fn twist_action(&self, v: f32, w: f32) -> [f32; 2] {
        self.action(position::twist_to_wheels(v, w, self.axle_length))
    }
}

/// The contract every controller implements.
pub trait Controller: Sized + Clone + std::fmt::Debug + PartialEq {
    /// Its name (`"braitenberg"`): the key of `Policy::new` and of `khepera_gym.baselines`.
    const NAME: &'static str;
    /// The task whose default observation it reads when no layout is given.
    const READS: &'static str;
    /// Its parameters: names as in its paper, defaults, units, one comment each.
    type Params: ConfigTable;

    /// The controller with `params`, reading observations laid out as `layout` (it finds its
    /// blocks by name). Errors name the parameter or the missing block.
    fn new(params: &Self::Params, layout: &ObsLayout) -> Result<Self>;

    /// Length of the observation rows it reads.
    fn obs_dim(&self) -> usize;

    /// Length of the action for an observation row of `obs_dim` values (2 per robot driven).
    fn act_dim(&self, obs_dim: usize) -> Result<usize> {
        if obs_dim == self.obs_dim() {
            Ok(2)
        } else {
            Err(Error::Action(format!(
                "{} reads observations of {} values, got {obs_dim}",
                Self::NAME,
                self.obs_dim()
            )))
        }
    }

    /// Writes the action for one observation row into `out` (length from `act_dim`).
    fn act(&self, obs: &[f32], out: &mut [f32]);
}

/// Declares the controllers. Each line is `Variant: Type`.
macro_rules! controller_registry {
    ($($variant:ident : $ty:ty),* $(,)?) => {
        /// A baseline policy on observations: one of the registered controllers.
        #[derive(Debug, Clone, PartialEq)]
        pub enum Policy {
            $(
                #[doc = concat!("The `", stringify!($variant), "` controller.")]
                $variant($ty),
            )*
        }

        /// Names of the controllers, in registry order.
        pub const NAMES: &[&str] = &[$(<$ty as Controller>::NAME),*];

        impl Policy {
            /// The controller `name` with the parameters of `params` (missing ones take their
            /// defaults; unknown ones are errors), reading observations laid out as `layout`.
            pub fn new(name: &str, params: &Table, layout: &ObsLayout) -> Result<Self> {
                $(
                    if name == <$ty as Controller>::NAME {
                        let params = read_params::<<$ty as Controller>::Params>(name, params)?;
                        return Ok(Policy::$variant(<$ty as Controller>::new(&params, layout)?));
                    }
                )*
                Err(Error::config(
                    "<policy>",
                    "controller",
                    format!("unknown controller {name:?}; known: {NAMES:?}"),
                ))
            }

            /// The parameters of controller `name` (with defaults and comments).
            pub fn params(name: &str) -> Option<&'static [KeyDoc]> {
                $(
                    if name == <$ty as Controller>::NAME {
                        return Some(<<$ty as Controller>::Params as ConfigTable>::KEYS);
                    }
                )*
                None
            }

            /// The task whose default observation controller `name` reads.
            pub fn reads(name: &str) -> Option<&'static str> {
                $(
                    if name == <$ty as Controller>::NAME {
                        return Some(<$ty as Controller>::READS);
                    }
                )*
                None
            }

            /// The controller's name.
            pub fn name(&self) -> &'static str {
                match self {
                    $(Policy::$variant(_) => <$ty as Controller>::NAME,)*
                }
            }

            /// Length of the observation rows (or, for several agents, of one block) it reads.
            pub fn obs_dim(&self) -> usize {
                match self {
                    $(Policy::$variant(c) => c.obs_dim(),)*
                }
            }

            /// Length of the action for an observation row of length `obs_dim`.
            pub fn act_dim(&self, obs_dim: usize) -> Result<usize> {
                match self {
                    $(Policy::$variant(c) => c.act_dim(obs_dim),)*
                }
            }

            /// Writes the action for one observation row into `out` (length from
            /// [`Policy::act_dim`]).
            pub fn act(&self, obs: &[f32], out: &mut [f32]) {
                match self {
                    $(Policy::$variant(c) => c.act(obs, out),)*
                }
            }
        }
    };
}

controller_registry! {
    PositionControl: position::PositionPolicy,
    Braitenberg: braitenberg::BraitenbergPolicy,
    Vfh: vfh::VfhPolicy,
    LeaderFollower: leader_follower::LeaderFollowerPolicy,
    Kanayama: kanayama::KanayamaPolicy,
    PositionChase: position::PositionChasePolicy,
    PurePursuit: pure_pursuit::PurePursuitPolicy,
    Samson: samson::SamsonPolicy,
    WaypointSwitching: waypoints::WaypointPolicy,
    DronePursuit: drone_pursuit::DronePursuitPolicy,
    LineThreshold: line_threshold::LineThresholdPolicy,
    LineProportional: line_proportional::LineProportionalPolicy,
    BlobServo: blob_servo::BlobServoPolicy,
    BlobVfh: blob_vfh::BlobVfhPolicy,
    Consensus: consensus::ConsensusPolicy,
}

/// Most preview points a path follower reads (`pathfollow.preview_points`' limit).
pub const MAX_PATH_PREVIEW: usize = crate::tasks::pathfollow::MAX_PREVIEW_POINTS as usize;

impl Policy {
    /// Actions for the rows of `obs`, `obs_dim` values each (row-major).
    pub fn act_batch(&self, obs: &[f32], obs_dim: usize) -> Result<Vec<f32>> {
        let act_dim = self.act_dim(obs_dim)?;
        if let Some(i) = obs.iter().position(|v| !v.is_finite()) {
            return Err(Error::Action(format!(
                "observation row {} element {} is {}",
                i / obs_dim.max(1),
                i % obs_dim.max(1),
                obs[i]
            )));
        }
        let rows = obs.len() / obs_dim.max(1);
        let mut out = vec![0.0f32; rows * act_dim];
        for (row, action) in obs.chunks_exact(obs_dim).zip(out.chunks_exact_mut(act_dim)) {
            self.act(row, action);
        }
        Ok(out)
    }

    /// A leader–follower policy whose leader block (when the observation has one) is driven by
    /// `leader`.
    pub fn with_leader(self, leader: Policy) -> Result<Self> {
        match self {
            Policy::LeaderFollower(lf) => Ok(Policy::LeaderFollower(lf.with_leader(leader)?)),
            other => Err(Error::Param(format!(
                "{}: only leader_follower takes a leader policy",
                other.name()
            ))),
        }
    }
}

/// Reads a controller's parameters: every key must be one of its parameters; an integer may
/// stand for a real number, a real number with no fraction for an integer.
fn read_params<T: ConfigTable>(controller: &str, given: &Table) -> Result<T> {
    let mut table = T::defaults_table();
    for (key, value) in given {
        let Some(default) = table.get(key) else {
            let known: Vec<&str> = T::KEYS.iter().map(|k| k.name).collect();
            return Err(Error::Param(format!(
                "{controller}: unknown parameter '{key}'; its parameters are {known:?}"
            )));
        };
        let value = match (default, value) {
            (Value::Float(_), Value::Integer(i)) => Value::Float(*i as f64),
            (Value::Integer(_), Value::Float(f)) => {
                if f.fract() == 0.0 && f.abs() < 9.0e15 {
                    Value::Integer(*f as i64)
                } else {
                    return Err(Error::Param(format!(
                        "{controller}: {key} must be an integer, got {f}"
                    )));
                }
            }
            (_, v) => v.clone(),
        };
        table.insert(key.clone(), value);
    }
    config::read_table(&table, controller, "").map_err(|e| match e {
        Error::Config { key, message, .. } => {
            Error::Param(format!("{controller}: {key}: {message}"))
        }
        other => other,
    })
}

/// Checks that parameter `name` of `controller` is finite and > 0.
pub fn positive(controller: &str, name: &str, value: f32) -> Result<f32> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(Error::Param(format!(
            "{controller}: {name} must be a finite number > 0, got {value}"
        )))
    }
}

/// Checks that parameter `name` of `controller` is finite and >= 0.
pub fn non_negative(controller: &str, name: &str, value: f32) -> Result<f32> {
    if value >= 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(Error::Param(format!(
            "{controller}: {name} must be a finite number >= 0, got {value}"
        )))
    }
}

/// Goal distance and bearing of an observation row whose goal blocks start at `at`
/// (`goal_distance`, `goal_bearing_sin`, `goal_bearing_cos`).
#[inline]
fn goal_of(obs: &[f32], at: GoalBlocks) -> (f32, f32) {
    (obs[at.distance], obs[at.sin].atan2(obs[at.cos]))
}

/// Where a Nav-like observation keeps its goal.
#[derive(Debug, Clone, Copy, PartialEq)]
struct GoalBlocks {
    distance: usize,
    sin: usize,
    cos: usize,
}

impl GoalBlocks {
    fn find(layout: &ObsLayout, who: &str) -> Result<Self> {
        Ok(Self {
            distance: layout.require("goal_distance", 1, who)?,
            sin: layout.require("goal_bearing_sin", 1, who)?,
            cos: layout.require("goal_bearing_cos", 1, who)?,
        })
    }
}

/// Where a path-following observation keeps the blocks a path follower reads.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PathBlocks {
    cross_track: usize,
    heading: usize,
    curvature: usize,
    preview: usize,
    preview_points: usize,
    speed: usize,
}

impl PathBlocks {
    fn find(layout: &ObsLayout, who: &str) -> Result<Self> {
        let preview_points = layout.find("preview").map_or(0, |r| r.len() / 2);
        if preview_points > MAX_PATH_PREVIEW {
            return Err(Error::Param(format!(
                "{who}: reads at most {MAX_PATH_PREVIEW} preview points, the layout has \
                 {preview_points}"
            )));
        }
        Ok(Self {
            cross_track: layout.require("cross_track_error", 1, who)?,
            heading: layout.require("path_heading_error", 2, who)?,
            curvature: layout.require("curvature", 1 + preview_points, who)?,
            preview: if preview_points > 0 {
                layout.require("preview", 2 * preview_points, who)?
            } else {
                0
            },
            preview_points,
            speed: layout.require("desired_speed", 1, who)?,
        })
    }

    /// The closest path point in the robot frame.
    fn closest(&self, obs: &[f32]) -> [f32; 2] {
        let d = obs[self.cross_track];
        let (sin_e, cos_e) = (obs[self.heading], obs[self.heading + 1]);
        [d * sin_e, -d * cos_e]
    }
}
