//! The one error type of `mvgrasp-sim`.

/// What scene generation and rendering can fail with.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A shape could not be built.
    #[error("shape: {0}")]
    Shape(String),
    /// A scene could not be laid out (e.g. no room left on the table).
    #[error("scene: {0}")]
    Scene(String),
    /// A file could not be read or written.
    #[error("{path}: {reason}")]
    File {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Bad settings.
    #[error("invalid `{field}`: {reason}")]
    Invalid {
        /// The setting.
        field: &'static str,
        /// Why.
        reason: String,
    },
}

/// Shorthand used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
