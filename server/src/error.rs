//! The one error type of the server, and its mapping to gRPC status codes.

use std::borrow::Cow;

use tonic::{Code, Status};

/// Everything a request or the server's start can fail with.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The request is malformed; `field` is named as the proto names it.
    #[error("invalid `{field}`: {reason}")]
    InvalidArgument {
        /// e.g. `depth.intrinsics.fx`.
        field: Cow<'static, str>,
        /// Why it was rejected.
        reason: String,
    },
    /// The request is over a configured limit.
    #[error("`{field}` is over the server's limit: {reason}")]
    LimitExceeded {
        /// The field or resource.
        field: Cow<'static, str>,
        /// The numbers.
        reason: String,
    },
    /// The server is at capacity (queue full, too many requests in flight).
    #[error("overloaded: {0}")]
    Overloaded(String),
    /// The caller's deadline passed before the plan was ready.
    #[error("deadline exceeded during {stage}")]
    DeadlineExceeded {
        /// The stage that was reached.
        stage: &'static str,
    },
    /// The pipeline could not handle the scene (no table, no valid depth, ...).
    #[error(transparent)]
    Pipeline(mvgrasp_core::Error),
    /// The model is not loaded or the inference worker has stopped.
    #[error("model unavailable: {0}")]
    Unavailable(String),
    /// Loading the model or configuring the server failed.
    #[error("startup: {0}")]
    Startup(String),
    /// A bug or a runtime failure (task panicked, backend failed).
    #[error("internal: {0}")]
    Internal(String),
}

/// Shorthand used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::InvalidArgument`] naming `field`.
    pub fn invalid(field: impl Into<Cow<'static, str>>, reason: impl Into<String>) -> Self {
        Self::InvalidArgument {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// The gRPC code this error is answered with.
    pub fn code(&self) -> Code {
        match self {
            Self::InvalidArgument { .. } => Code::InvalidArgument,
            Self::LimitExceeded { .. } | Self::Overloaded(_) => Code::ResourceExhausted,
            Self::DeadlineExceeded { .. } => Code::DeadlineExceeded,
            Self::Pipeline(e) if e.is_bad_input() => Code::InvalidArgument,
            Self::Pipeline(_) | Self::Internal(_) => Code::Internal,
            Self::Unavailable(_) => Code::Unavailable,
            Self::Startup(_) => Code::FailedPrecondition,
        }
    }
}

impl From<mvgrasp_core::Error> for Error {
    fn from(e: mvgrasp_core::Error) -> Self {
        match e {
            mvgrasp_core::Error::InvalidInput { field, reason } => Self::InvalidArgument { field, reason },
            other => Self::Pipeline(other),
        }
    }
}

impl From<Error> for Status {
    fn from(e: Error) -> Self {
        Status::new(e.code(), e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes() {
        assert_eq!(
            Status::from(Error::invalid("depth.width", "0")).code(),
            Code::InvalidArgument
        );
        let no_table = mvgrasp_core::Error::NoTablePlane {
            best_inliers: 1,
            sampled: 10,
            required: 5,
            max_tilt_deg: 10.0,
        };
        assert_eq!(Error::from(no_table).code(), Code::InvalidArgument);
        let backend = mvgrasp_core::Error::Backend("shape".into());
        assert_eq!(Error::from(backend).code(), Code::Internal);
        let field = mvgrasp_core::Error::invalid("workspace.min", "nan");
        let status = Status::from(Error::from(field));
        assert!(status.message().contains("workspace.min"), "{}", status.message());
        assert_eq!(
            Status::from(Error::Overloaded("queue".into())).code(),
            Code::ResourceExhausted
        );
    }
}
