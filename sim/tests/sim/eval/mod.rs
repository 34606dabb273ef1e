//! The clear-the-table loop (`sim::eval`), one file per concept: `settings`,
//! `episodes`, `hooks` (what an episode hands out), `stats` (summaries and reports).

use mvgrasp_core::{
    CreaseConfig, GraspNet, MomentsNet, Planner, PlannerConfig, Repairs, ViewAxis, ViewPolicy,
};
use mvgrasp_sim::camera::Camera;
use mvgrasp_sim::camera::Frame;
use mvgrasp_sim::eval::{
    Attempt, CollisionSite, End, Episode, EpisodeConfig, Failure, GraspSource, InProcess, PlannedGrasp,
    Setting, Summary, collision_list, crease_setting, crease_text, episode_bootstrap, episode_record,
    episode_scene, horizontal_lever_m, label_table, markdown_table, object_tilt_deg, objects_outside_view,
    pose_name, provenance_table, run_episode, same_grasp, square_turn_setting,
};
use mvgrasp_sim::grasp::{HandPart, Obstacle, pose_of, weight_torque_nm};
use mvgrasp_sim::objects::Family;
use mvgrasp_sim::scene::Scenario;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

mod episodes;
mod hooks;
mod settings;
mod stats;
