//! View selection: viewpoint entropy and the policies built on it.

mod entropy;
mod policy;

pub use entropy::{EntropySums, log2_fast, view_entropy};
pub use policy::{ViewPolicy, select_views};
