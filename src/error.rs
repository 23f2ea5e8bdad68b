//! The core's error type. Every fallible public function returns [`Result`]; the Python binding
//! maps each variant to one class of `khepera_gym.errors` (see src/python/errors.rs), so no user
//! input can end in a panic.

/// An error the simulator reports to its caller.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A scenario file or override is malformed or impossible. `origin` names the file
    /// (or `<built-in>`, `<override>`), `key` the dotted key (`robot.radius`).
    #[error("{origin}: {key}: {message}")]
    Config {
        origin: String,
        key: String,
        message: String,
    },
    /// An action buffer has the wrong length or holds NaN/inf.
    #[error("{0}")]
    Action(String),
    /// A call in the wrong state (e.g. stepping a finished episode without reset).
    #[error("{0}")]
    State(String),
    /// A controller's parameter is unknown, of the wrong type or impossible; the message names
    /// the controller and the parameter (`vfh: sectors must be in 4..=360, got 2`).
    #[error("{0}")]
    Param(String),
    /// The memory an input asks for cannot be had (the system refused it): Python's
    /// `MemoryError`. Sizes beyond a documented limit are [`Error::Config`] instead.
    #[error("{0}")]
    Memory(String),
    /// A saved state cannot be restored: not a state, corrupt, or saved from another batch
    /// (task, scenario or number of worlds).
    #[error("{0}")]
    SavedState(String),
}

impl Error {
    /// A configuration error about `key` from `origin`.
    pub fn config(origin: &str, key: &str, message: impl Into<String>) -> Self {
        Error::Config {
            origin: origin.to_string(),
            key: key.to_string(),
            message: message.into(),
        }
    }
}

/// Result with the core's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
