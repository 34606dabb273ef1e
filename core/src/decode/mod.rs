//! Grasp maps -> 6-DoF grasps in the world, and their ranking.

mod collision;
mod grasp;
mod hand;
mod peaks;
mod rank;
mod repair;
#[cfg(test)]
mod test_support;

pub use collision::{Collision, Obstacle, hand_collides, hand_collision, hand_out_of_view};
pub use grasp::{DecodeConfig, Decoded, Grasp, Repairs, ViewPlacement, decode_view, grasp_at, lever_arm_m};
pub use hand::HandConfig;
pub use peaks::{NEGLIGIBLE_QUALITY, find_peaks, smooth, smoothed_peaks};
pub use rank::{RankConfig, Ranked, Verdict, rank_grasps, rank_grasps_scored, rank_grasps_vetted};
pub use repair::{
    contact_slopes, deepen, deepen_to_middle, depth_to_middle, fit_opening, squaring_turn, turn_away,
};
