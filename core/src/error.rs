//! The one error type of `mvgrasp-core`.

use std::borrow::Cow;

/// Everything that can go wrong between a sensor frame and a ranked grasp list.
///
/// Variants carry the offending field (as the API names it) or the numbers that
/// made a stage give up, so a caller can tell a user what to fix.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A request field is missing, malformed or out of range.
    #[error("invalid `{field}`: {reason}")]
    InvalidInput {
        /// The field as the public API names it, e.g. `depth.intrinsics.fx`.
        field: Cow<'static, str>,
        /// Why it was rejected.
        reason: String,
    },
    /// The frame holds no usable reading (every pixel is 0, NaN or infinite).
    #[error("invalid `{field}`: no valid depth reading in {samples} samples (all 0, NaN or infinite)")]
    NoValidDepth {
        /// `depth.data` or `cloud.xyz`.
        field: &'static str,
        /// How many samples were looked at.
        samples: usize,
    },
    /// Valid points exist, but none lies inside the requested workspace box.
    #[error("invalid `workspace`: none of the {valid_points} valid points lies inside it")]
    EmptyWorkspace {
        /// Valid points before cropping.
        valid_points: usize,
    },
    /// No plane close enough to horizontal with enough support was found.
    #[error(
        "no table plane found: the best plane within {max_tilt_deg:.1} deg of horizontal holds \
         {best_inliers} of {sampled} sampled points, {required} required"
    )]
    NoTablePlane {
        /// Support of the best horizontal hypothesis.
        best_inliers: usize,
        /// Points the hypotheses were scored on.
        sampled: usize,
        /// Support needed to accept a plane.
        required: usize,
        /// The tilt limit that was applied.
        max_tilt_deg: f64,
    },
    /// The model contract (ONNX metadata) is missing a key or holds a bad value.
    #[error("model contract: `{key}`: {reason}")]
    Contract {
        /// Metadata key.
        key: Cow<'static, str>,
        /// What is wrong with it.
        reason: String,
    },
    /// The inference backend failed or returned maps of the wrong shape.
    #[error("inference backend: {0}")]
    Backend(String),
}

/// Shorthand used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::InvalidInput`] for `field`.
    pub fn invalid(field: impl Into<Cow<'static, str>>, reason: impl Into<String>) -> Self {
        Self::InvalidInput {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// True for errors caused by the request itself (as opposed to the backend).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Self::InvalidInput { .. }
            | Self::NoValidDepth { .. }
            | Self::EmptyWorkspace { .. }
            | Self::NoTablePlane { .. } => true,
            Self::Contract { .. } | Self::Backend(_) => false,
        }
    }
}
