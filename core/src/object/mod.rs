//! Detected objects and their gravity-aligned frames.

mod frame;

pub use frame::{ObjectFrame, object_frame};
