//! Grasp maps -> 6-DoF grasps in the world, and their ranking.

mod collision;
mod grasp;
mod peaks;
mod rank;

pub use collision::{
    Collision, HandConfig, Obstacle, contact_slopes, deepen, fit_opening, hand_collides, hand_collision,
    hand_out_of_view, squaring_turn, turn_away,
};
pub use grasp::{DecodeConfig, Grasp, Repairs, ViewPlacement, decode_view, grasp_at, lever_arm_m};
pub use peaks::{NEGLIGIBLE_QUALITY, find_peaks, smooth, smoothed_peaks};
pub use rank::{RankConfig, Ranked, Verdict, rank_grasps, rank_grasps_scored, rank_grasps_vetted};
