//! Grasp maps -> 6-DoF grasps in the world, and their ranking.

mod grasp;
mod peaks;
mod rank;

pub use grasp::{DecodeConfig, Grasp, ViewPlacement, decode_view, grasp_at};
pub use peaks::{NEGLIGIBLE_QUALITY, find_peaks, smooth, smoothed_peaks};
pub use rank::{RankConfig, rank_grasps};
