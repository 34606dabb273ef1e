//! Segmentation: table plane removal, Euclidean clustering into objects, and
//! a split of clusters at concave creases and depth steps of the image.

mod body;
mod cluster;
mod crease;
mod outside;
mod table;
mod union_find;

pub(crate) use body::BodyFilter;
pub use body::{BodyCapsule, MAX_BODY_CAPSULES, MAX_BODY_RADIUS_M, check_body};
pub use cluster::{ClusterConfig, MAX_DENSE_CELLS, euclidean_clusters, fixed_order};
pub use crease::{CreaseConfig, ImagePoints, Reattach, split_at_creases};
pub use outside::{Detected, ObstacleConfig, OutsideObstacle, outside_obstacles};
pub use table::{TableConfig, TablePlane, fit_table};
