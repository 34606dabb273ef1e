//! The sim crate's integration tests, one file per concept: the camera,
//! the pipeline on simulated frames, grasp labels, targets, `sim datagen`,
//! physics, `sim eval`, snapshots and meshes. Shared scene helpers here.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{GraspNet, MomentsNet, PlanOptions, Planner, PlannerConfig};
use mvgrasp_sim::camera::{Camera, Frame, NoiseModel, render};
use mvgrasp_sim::objects::{Catalog, Family, ObjectModel};
use mvgrasp_sim::scene::{PlacedObject, Scenario, Scene};
use nalgebra::Vector3;
use parry3d::math::{Pose, Vector};
use parry3d::shape::SharedShape;

fn one_object(table_z: f32, model: ObjectModel, x: f32, y: f32) -> Scene {
    let pose = Pose::from_translation(Vector::new(x, y, table_z));
    Scene {
        table_z,
        table_half: [0.6, 0.5],
        objects: vec![PlacedObject {
            world_aabb: model.shape.compute_aabb(&pose),
            model,
            world_from_object: pose,
        }],
        scenario: Scenario::Isolated,
        seed: 0,
    }
}

fn top_down(table_z: f32, height_m: f64) -> Camera {
    let target = Vector3::new(0.0, 0.0, f64::from(table_z));
    Camera::looking_at(
        target + Vector3::new(0.0, -1e-4, height_m),
        target,
        640,
        480,
        600.0,
    )
}

/// A shard's `meta.jsonl`, a value per view.
fn meta_lines(shard: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(shard.join("meta.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

mod camera;
mod datagen;
mod eval;
mod grasp_labels;
mod meshes;
mod physics;
mod pipeline;
mod snapshots;
mod targets;
