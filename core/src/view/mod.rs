//! Orthographic virtual views of each object.

mod orthographic;

pub use orthographic::{HOLE_FILL_MIN_NEIGHBOURS, OrthoView, ViewAxis};
