//! The Khepera IV's sensors, one file each behind the [`Sensor`] contract, and the [`Suite`] of
//! sensors a robot carries.
//!
//! A sensor owns everything about itself: its scenario keys in `[sensors]` (declared with
//! defaults, units and comments), its model and noise, its reading in the real robot's units
//! (what `sensor_readings()` returns), the normalisation of that reading into its observation
//! block, and how it is drawn. Which sensors a robot carries (`[sensors] carry`) and which of
//! those the observation holds (`[sensors] observe`) is scenario data; the observation blocks
//! come in the order of the registry below, whatever the order of those lists.
//!
//! Adding a sensor: a file here implementing [`Sensor`], and one line in `sensor_registry!`.
//!
//! Frame: robot frame x forward, y left; bearings counter-clockwise from forward, in radians.
//! Threading: a world's sensors are read by the one thread stepping that world, drawing noise
//! from that world's random stream only, robot after robot and, for each robot, sensor after
//! sensor in registry order (so a world's results do not depend on the thread count).

pub mod camera;
mod context;
pub mod ground;
pub mod gyro;
pub mod imu;
pub mod ir;
mod ir_lanes;
pub mod ultrasonic;

use rand_chacha::ChaCha8Rng;
use rapier2d::math::Vector;
use serde::{de::DeserializeOwned, Deserialize, Serialize};
use toml::{Table, Value};

use crate::config::{self, ConfigTable, KeyDoc};
use crate::draw::Mark;
use crate::error::{Error, Result};
use crate::obs::{Block, ObsWriter};

pub use camera::Camera;
#[cfg(test)]
pub(crate) use context::TestSurroundings;
pub use context::{SenseContext, Surroundings};
pub use ground::GroundSensors;
pub use gyro::Gyro;
pub use imu::Imu;
pub use ir::{IrRing, IR_BEARINGS, IR_COUNT};
pub use ultrasonic::{Ultrasonic, US_BEARINGS, US_COUNT, US_DISABLED, US_NOTHING, US_TOO_CLOSE};

/// Where a robot is, for drawing its sensors.
pub struct DrawContext {
    /// Its centre (m).
    pub position: Vector,
    /// Its heading (rad).
    pub heading: f32,
    /// Its body radius (m).
    pub radius: f32,
}

/// Readings in the real robot's units, gathered for `sensor_readings()`: named channels of a
/// fixed number of values per robot.
#[derive(Debug, Default)]
pub struct Readout {
    /// The channels, in the order they were first written.
    pub channels: Vec<Channel>,
}

/// One channel of a [`Readout`].
#[derive(Debug)]
pub struct Channel {
    /// Its key in `sensor_readings()` (`"ir_raw"`).
    pub name: &'static str,
    /// Values per robot (0: one scalar per robot).
    pub per_robot: usize,
    /// The values, robot after robot, as integers (raw counts) or reals.
    pub values: ChannelValues,
}

/// The values of a [`Channel`].
#[derive(Debug)]
pub enum ChannelValues {
    /// Raw counts or codes.
    Int(Vec<i64>),
    /// Physical quantities.
    Real(Vec<f32>),
}

impl Readout {
    fn channel(&mut self, name: &'static str, per_robot: usize, int: bool) -> &mut ChannelValues {
        let index = match self.channels.iter().position(|c| c.name == name) {
            Some(i) => i,
            None => {
                self.channels.push(Channel {
                    name,
                    per_robot,
                    values: if int {
                        ChannelValues::Int(Vec::new())
                    } else {
                        ChannelValues::Real(Vec::new())
                    },
                });
                self.channels.len() - 1
            }
        };
        &mut self.channels[index].values
    }

    /// Appends one robot's integer values of channel `name` (`per_robot` 0 for a scalar).
    pub fn ints(&mut self, name: &'static str, per_robot: usize, values: &[i64]) {
        if let ChannelValues::Int(v) = self.channel(name, per_robot, true) {
            v.extend_from_slice(values);
        }
    }

    /// Appends one robot's real values of channel `name` (`per_robot` 0 for a scalar).
    pub fn reals(&mut self, name: &'static str, per_robot: usize, values: &[f32]) {
        if let ChannelValues::Real(v) = self.channel(name, per_robot, false) {
            v.extend_from_slice(values);
        }
    }
}

/// The contract every sensor implements.
pub trait Sensor: Clone + Serialize + DeserializeOwned {
    /// Its name in `[sensors] carry/observe` and its observation block's name (`"ir"`).
    const NAME: &'static str;
    /// Its keys in the `[sensors]` table, each with default, units and comment.
    type Config: ConfigTable;
    /// One robot's reading, in the real robot's units.
    type Reading: Clone + Default + Serialize + DeserializeOwned + std::fmt::Debug;

    /// The sensor of a scenario (parameters given as ranges start at their low end).
    fn new(cfg: &Self::Config) -> Self;

    /// Checks what its keys' domains cannot (each key alone is checked by its declaration):
    /// keys that relate to one another. The error names `origin` and `sensors.<key>`.
    fn validate(_cfg: &Self::Config, _origin: &str) -> Result<()> {
        Ok(())
    }

    /// Draws this episode's parameters given as `[low, high]` ranges (domain randomisation).
    fn randomise(&mut self, cfg: &Self::Config, rng: &mut ChaCha8Rng);

    /// Reads the sensor of the robot described by `ctx`, with noise from `rng`.
    fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, reading: &mut Self::Reading);

    /// Its observation block (name, length, bounds).
    fn block(&self) -> Block;

    /// The length of its observation block (hot path: no allocation).
    fn obs_len(&self) -> usize;

    /// Writes `reading`, normalised, into its observation block.
    fn observe(&self, reading: &Self::Reading, out: &mut [f32]);

    /// Appends its channels of `sensor_readings()` for one robot.
    fn readout(&self, reading: &Self::Reading, out: &mut Readout);

    /// Appends what the renderer draws for one robot's reading.
    fn draw(&self, at: &DrawContext, reading: &Self::Reading, marks: &mut Vec<Mark>);

    /// How far (m) from the robot's centre another robot's centre can be and still change this
    /// sensor's reading, robots being discs of `radius`: worlds of many robots show the sensor
    /// only the robots within it (`SenseContext::others`). Infinite (the default): all of them.
    fn reach(&self, _radius: f32) -> f32 {
        f32::INFINITY
    }

    /// Its reach (as [`Sensor::reach`]) at the coming reading, whose `reading` is the last one,
    /// `dt` s old, or none if it is `fresh` (a new episode): 0 when the sensor will hold its
    /// last reading rather than look at other robots (the sonars between two sweeps), so that a
    /// swarm then looks only as far as its other sensors need.
    fn reach_now(&self, radius: f32, _reading: &Self::Reading, _dt: f32, _fresh: bool) -> f32 {
        self.reach(radius)
    }
}

/// A sensor a robot carries, and whether its observation holds it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Carried<S> {
    /// The sensor.
    pub sensor: S,
    /// Whether its block is part of the observation.
    pub observed: bool,
}

/// The `[sensors]` keys that are not any one sensor's.
const SUITE_KEYS: &[KeyDoc] = &[
    KeyDoc::new(
        "carry",
        "[\"ir\", \"us\", \"gyro\"]",
        "sensors each robot has (ir, us, gyro, imu, ground, camera); others cost nothing",
        "Vec<String>",
        None,
    ),
    KeyDoc::new(
        "observe",
        "[\"ir\", \"us\"]",
        "carried sensors whose blocks the observation holds, in registry order",
        "Vec<String>",
        None,
    ),
];

/// Declares the sensors a robot may carry. Each line is `field: Type`; the order is the order of
/// reading (random draws) and of the observation blocks.
macro_rules! sensor_registry {
    ($($field:ident : $ty:ty),* $(,)?) => {
        /// Names of the sensors, in registry order.
        pub const NAMES: &[&str] = &[$(<$ty as Sensor>::NAME),*];

        /// The `[sensors]` table: what a robot carries and observes, and every sensor's keys.
        #[derive(Debug, Clone, PartialEq)]
        pub struct SensorsConfig {
            /// Sensors each robot has.
            pub carry: Vec<String>,
            /// Carried sensors whose readings the observation holds.
            pub observe: Vec<String>,
            $(
                #[doc = concat!("Keys of the `", stringify!($field), "` sensor.")]
                pub $field: <$ty as Sensor>::Config,
            )*
        }

        impl SensorsConfig {
            /// Every key of the table, in order.
            pub fn keys() -> Vec<KeyDoc> {
                let mut keys = Vec::new();
                $(keys.extend_from_slice(<<$ty as Sensor>::Config as ConfigTable>::KEYS);)*
                keys.extend_from_slice(SUITE_KEYS);
                keys
            }

            /// The defaults as a TOML table.
            pub fn defaults_table() -> Table {
                config::keys_table(&Self::keys())
            }

            /// Reads the table; every key must be known. Errors name `origin` and `sensors.key`.
            pub fn from_table(table: &Table, origin: &str) -> Result<Self> {
                for key in table.keys() {
                    if !Self::keys().iter().any(|k| k.name == key) {
                        let known: Vec<&str> = Self::keys().iter().map(|k| k.name).collect();
                        let hint = config::did_you_mean(key, known.iter().copied());
                        return Err(Error::config(
                            origin,
                            &format!("sensors.{key}"),
                            format!("unknown key{hint}; known keys here: {known:?}"),
                        ));
                    }
                }
                let part = |keys: &[KeyDoc]| -> Table {
                    table
                        .iter()
                        .filter(|(k, _)| keys.iter().any(|d| d.name == k.as_str()))
                        .map(|(k, v)| (k.clone(), v.clone()))
                        .collect()
                };
                #[derive(Deserialize)]
                #[serde(deny_unknown_fields)]
                struct Lists {
                    carry: Vec<String>,
                    observe: Vec<String>,
                }
                let lists: Lists = config::read_table(&part(SUITE_KEYS), origin, "sensors")?;
                Ok(Self {
                    carry: lists.carry,
                    observe: lists.observe,
                    $(
                        $field: config::read_table(
                            &part(<<$ty as Sensor>::Config as ConfigTable>::KEYS),
                            origin,
                            "sensors",
                        )?,
                    )*
                })
            }

            /// The table, every key in declaration order.
            pub fn to_table(&self) -> Table {
                let mut table = Table::new();
                // Through TOML text, so that f32 values read back as written (0.1, not
                // 0.10000000149011612).
                $(
                    if let Some(t) = toml::to_string(&self.$field)
                        .ok()
                        .and_then(|text| text.parse::<Table>().ok())
                    {
                        table.extend(t);
                    }
                )*
                table.insert("carry".into(), strings(&self.carry));
                table.insert("observe".into(), strings(&self.observe));
                table
            }

            /// Checks every sensor's keys and the carry/observe lists.
            pub fn validate(&self, origin: &str) -> Result<()> {
                $(<$ty as Sensor>::validate(&self.$field, origin)?;)*
                for (key, list) in [("sensors.carry", &self.carry), ("sensors.observe", &self.observe)] {
                    for (i, name) in list.iter().enumerate() {
                        if !NAMES.contains(&name.as_str()) {
                            return Err(Error::config(
                                origin,
                                key,
                                format!("unknown sensor {name:?}; known: {NAMES:?}"),
                            ));
                        }
                        if list[..i].contains(name) {
                            return Err(Error::config(origin, key, format!("{name:?} is listed twice")));
                        }
                    }
                }
                if let Some(name) = self.observe.iter().find(|n| !self.carry.contains(n)) {
                    return Err(Error::config(
                        origin,
                        "sensors.observe",
                        format!("{name:?} is observed but not carried (add it to sensors.carry)"),
                    ));
                }
                Ok(())
            }
        }

        /// The sensors of a world's robots (one model shared by the robots of a world; each
        /// robot keeps its own [`Readings`]).
        #[derive(Debug, Clone, Serialize, Deserialize)]
        pub struct Suite {
            $(
                #[doc = concat!("The `", stringify!($field), "` sensor, if carried.")]
                pub $field: Option<Carried<$ty>>,
            )*
        }

        /// One robot's last reading of each sensor (a sensor not carried keeps its default).
        #[derive(Debug, Clone, Default, Serialize, Deserialize)]
        pub struct Readings {
            $(
                #[doc = concat!("The `", stringify!($field), "` reading.")]
                pub $field: <$ty as Sensor>::Reading,
            )*
        }

        impl Suite {
            /// The suite a validated `[sensors]` table describes.
            pub fn new(cfg: &SensorsConfig) -> Self {
                Self {
                    $(
                        $field: cfg.carry.iter().any(|n| n == <$ty as Sensor>::NAME).then(|| {
                            Carried {
                                sensor: <$ty as Sensor>::new(&cfg.$field),
                                observed: cfg.observe.iter().any(|n| n == <$ty as Sensor>::NAME),
                            }
                        }),
                    )*
                }
            }

            /// Draws this episode's sensor parameters (domain randomisation).
            pub fn randomise(&mut self, cfg: &SensorsConfig, rng: &mut ChaCha8Rng) {
                $(
                    if let Some(c) = &mut self.$field {
                        c.sensor.randomise(&cfg.$field, rng);
                    }
                )*
            }

            /// Reads every carried sensor of one robot.
            #[inline]
            pub fn read(&mut self, ctx: &SenseContext, rng: &mut ChaCha8Rng, readings: &mut Readings) {
                $(
                    if let Some(c) = &mut self.$field {
                        c.sensor.read(ctx, rng, &mut readings.$field);
                    }
                )*
            }

            /// The observed sensors' blocks, in registry order.
            pub fn blocks(&self) -> Vec<Block> {
                let mut blocks = Vec::new();
                $(
                    if let Some(c) = &self.$field {
                        if c.observed {
                            blocks.push(c.sensor.block());
                        }
                    }
                )*
                blocks
            }

            /// Writes one robot's observed sensor blocks.
            #[inline]
            pub fn observe(&self, readings: &Readings, out: &mut ObsWriter) {
                $(
                    if let Some(c) = &self.$field {
                        if c.observed {
                            let block = out.take(c.sensor.obs_len());
                            c.sensor.observe(&readings.$field, block);
                        }
                    }
                )*
            }

            /// Appends one robot's channels of `sensor_readings()`.
            pub fn readout(&self, readings: &Readings, out: &mut Readout) {
                $(
                    if let Some(c) = &self.$field {
                        c.sensor.readout(&readings.$field, out);
                    }
                )*
            }

            /// The largest [`Sensor::reach`] of the carried sensors (0 when none looks at
            /// other robots).
            pub fn reach(&self, radius: f32) -> f32 {
                let mut reach = 0.0f32;
                $(
                    if let Some(c) = &self.$field {
                        reach = reach.max(c.sensor.reach(radius));
                    }
                )*
                reach
            }

            /// The largest [`Sensor::reach_now`] of the carried sensors at one robot's coming
            /// reading (0 when none will look at other robots).
            #[inline]
            pub fn reach_now(&self, radius: f32, readings: &Readings, dt: f32, fresh: bool) -> f32 {
                let mut reach = 0.0f32;
                $(
                    if let Some(c) = &self.$field {
                        reach = reach.max(c.sensor.reach_now(radius, &readings.$field, dt, fresh));
                    }
                )*
                reach
            }

            /// Appends what every carried sensor of one robot draws.
            pub fn draw(&self, at: &DrawContext, readings: &Readings, marks: &mut Vec<Mark>) {
                $(
                    if let Some(c) = &self.$field {
                        c.sensor.draw(at, &readings.$field, marks);
                    }
                )*
            }
        }
    };
}

sensor_registry! {
    ir: IrRing,
    us: Ultrasonic,
    gyro: Gyro,
    imu: Imu,
    ground: GroundSensors,
    camera: Camera,
}

fn strings(list: &[String]) -> Value {
    Value::Array(list.iter().map(|s| Value::String(s.clone())).collect())
}

/// `v` rotated by the angle whose cosine and sine are `c` and `s`.
#[inline]
pub fn rotate(v: Vector, c: f32, s: f32) -> Vector {
    Vector::new(c * v.x - s * v.y, s * v.x + c * v.y)
}

/// The unit vector at `angle` (rad).
pub fn unit(angle: f32) -> Vector {
    let (s, c) = angle.sin_cos();
    Vector::new(c, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_carry_the_gyro_and_observe_the_ring_and_the_sonars() {
        let cfg = SensorsConfig::from_table(&SensorsConfig::defaults_table(), "t").expect("cfg");
        // v1 carries the gyroscope (for odometry); observations keep the ring and sonars.
        assert_eq!(cfg.carry, vec!["ir", "us", "gyro"]);
        cfg.validate("t").expect("valid");
        let suite = Suite::new(&cfg);
        let names: Vec<String> = suite.blocks().into_iter().map(|b| b.name).collect();
        assert_eq!(names, vec!["ir", "us"]);
        let back = SensorsConfig::from_table(&cfg.to_table(), "t").expect("round trip");
        assert_eq!(back, cfg);
    }

    #[test]
    fn observing_an_uncarried_or_unknown_sensor_is_an_error() {
        let mut table = SensorsConfig::defaults_table();
        table.insert("carry".into(), strings(&["ir".into()]));
        let cfg = SensorsConfig::from_table(&table, "f.toml").expect("cfg");
        let e = cfg.validate("f.toml").unwrap_err().to_string();
        assert!(e.starts_with("f.toml: sensors.observe:"), "{e}");
        table.insert("observe".into(), strings(&["lidar".into()]));
        let e = SensorsConfig::from_table(&table, "f.toml")
            .and_then(|c| c.validate("f.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown sensor \"lidar\""), "{e}");
    }
}
