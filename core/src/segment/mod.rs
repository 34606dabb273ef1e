//! Segmentation: table plane removal, then Euclidean clustering into objects.

mod cluster;
mod table;

pub use cluster::{ClusterConfig, MAX_DENSE_CELLS, euclidean_clusters};
pub use table::{TableConfig, TablePlane, fit_table};
