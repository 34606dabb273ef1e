//! The one error type of the robot bridge.

/// What can go wrong between a grasp and a motion.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A pose or joint vector with NaN/inf or an invalid rotation.
    #[error("invalid `{field}`: {reason}")]
    InvalidInput {
        /// The offending field.
        field: &'static str,
        /// Why it was rejected.
        reason: String,
    },
    /// No joint solution reaches the pose (within the joint limits).
    #[error("pose unreachable: {0}")]
    Unreachable(String),
    /// A connection failed, timed out or dropped.
    #[error("connection: {0}")]
    Io(String),
    /// The peer sent something malformed.
    #[error("protocol: {0}")]
    Protocol(String),
    /// A protective stop (or another safety stop) happened during a motion;
    /// nothing further was sent.
    #[error("protective stop (safety mode {safety_mode}) during the motion: robot left stopped")]
    ProtectiveStop {
        /// The controller's safety mode (1 = normal).
        safety_mode: i32,
    },
    /// The controller refused a request or is not in a state to move.
    #[error("controller: {0}")]
    Controller(String),
}

/// Shorthand used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
