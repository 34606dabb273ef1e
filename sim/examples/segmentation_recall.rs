//! How many of a scene's objects the planner's segmentation finds, per
//! scenario, on the scenes and cameras of `sim eval --seed 800000` (the
//! tuning seeds), with the analytic baseline network (segmentation does not
//! depend on the network).
//!
//!     cargo run --release -p mvgrasp-sim --example segmentation_recall [EPISODES]
//!
//! An object counts as visible with at least 200 pixels more than 1 cm above
//! the table, and as found when a detected object's centroid lies within
//! 2 cm of its visible points' centroid. A detection is "merged" when the
//! centroids of two or more visible objects lie in its box.

use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{GraspNet, MomentsNet, PlanOptions, Planner, PlannerConfig};
use mvgrasp_sim::camera::{NoiseModel, render};
use mvgrasp_sim::eval::episode_scene;
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::scene::Scenario;

fn main() -> anyhow::Result<()> {
    let episodes: u64 = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(16);
    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone())?;
    // The seen families of results/seen-families (every family but the bowl).
    let families: Vec<Family> = Family::ALL.into_iter().filter(|f| *f != Family::Bowl).collect();
    let catalog = Catalog::of(&families);
    println!("scenario | visible | detected | found | merged detections");
    for scenario in [
        Scenario::Isolated,
        Scenario::Packed,
        Scenario::Pile,
        Scenario::Clutter,
    ] {
        let (mut visible, mut found, mut detected, mut merged) = (0, 0, 0, 0);
        for seed in 800_000..800_000 + episodes {
            let (scene, camera) = episode_scene(scenario, seed, &catalog)?;
            let z = f64::from(scene.table_z);
            // The first frame of the episode, with `sim eval`'s noise draw.
            let mut rng = SplitMix64::new(seed ^ 0x0153_EAB0);
            let frame = render(&scene, &camera, Some((&NoiseModel::default(), &mut rng)));
            let bytes = frame.depth_le_bytes();
            let input = frame.scene_input(&bytes, scene.workspace());
            let plan = planner.plan(&input, &PlanOptions::default(), &mut net)?;
            detected += plan.objects.len();
            let mut held = vec![0usize; plan.objects.len()];
            for (_, centroid) in frame.visible_centroids(scene.objects.len(), z, 0.01, 200) {
                visible += 1;
                let frames = plan.objects.iter().map(|o| &o.frame);
                if frames
                    .clone()
                    .any(|f| (f.world_from_object.translation.vector - centroid.coords).norm() < 0.02)
                {
                    found += 1;
                }
                for (n, f) in held.iter_mut().zip(frames) {
                    let local = f.world_from_object.inverse_transform_point(&centroid).coords;
                    if (0..3).all(|i| {
                        local[i] >= f.extent_min_m[i] - 0.005 && local[i] <= f.extent_max_m[i] + 0.005
                    }) {
                        *n += 1;
                    }
                }
            }
            merged += held.iter().filter(|&&n| n > 1).count();
        }
        println!("{scenario:?} | {visible} | {detected} | {found} | {merged}");
    }
    Ok(())
}
