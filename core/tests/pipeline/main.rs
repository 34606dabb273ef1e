//! Integration tests of the whole pipeline on ray-cast scenes.

#![allow(clippy::expect_used)] // fixtures stop the test on bad set-up

mod decoding;
mod hand;
mod inputs;
mod obstacles;
mod properties;
mod scene;
mod scenes;
mod views;

use mvgrasp_core::{GraspNet, MomentsNet, Plan, PlanOptions, Planner, PlannerConfig, Workspace};
use scene::{Camera, Rendered, Scene};

/// A workspace covering the table top up to 40 cm above it.
pub fn table_workspace(scene: &Scene) -> Workspace {
    let [hx, hy] = scene.table_half;
    Workspace::new([-hx, -hy, scene.table_z - 0.05], [hx, hy, scene.table_z + 0.4]).expect("valid box")
}

/// Renders `scene` and plans on it with the analytic baseline network.
pub fn plan_rendered(scene: &Scene, camera: &Camera, options: &PlanOptions) -> (Plan, Rendered) {
    plan_rendered_with(PlannerConfig::default(), scene, camera, options)
}

/// [`plan_rendered`] with a planner configured by `config`.
pub fn plan_rendered_with(
    config: PlannerConfig,
    scene: &Scene,
    camera: &Camera,
    options: &PlanOptions,
) -> (Plan, Rendered) {
    plan_rendered_by(config, scene, camera, options, &mut MomentsNet::default())
}

/// [`plan_rendered_with`] with `net` in place of the analytic baseline.
pub fn plan_rendered_by(
    config: PlannerConfig,
    scene: &Scene,
    camera: &Camera,
    options: &PlanOptions,
    net: &mut dyn GraspNet,
) -> (Plan, Rendered) {
    let rendered = scene::render(scene, camera);
    let bytes = rendered.depth_bytes();
    let input = camera.scene_input(&bytes, table_workspace(scene));
    let planner = Planner::new(config, net.contract().clone()).expect("planner");
    let plan = planner.plan(&input, options, net).expect("plan");
    (plan, rendered)
}
