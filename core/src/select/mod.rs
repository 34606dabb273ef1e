//! View selection: viewpoint entropy and the policies built on it.

mod entropy;
mod policy;

pub use entropy::{EntropySums, view_entropy};
pub use policy::{ViewPolicy, select_views};
