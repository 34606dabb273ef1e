//! The planner's segmentation (table, clusters, crease split) on the first
//! frames of the tuning seeds' pile and clutter episodes (`sim eval --seed
//! 800000`), where the crease split cuts parts and step 6 joins some back:
//! the default against the split without step 6 (`split-only`). One core:
//!
//! ```text
//! taskset -c 0 cargo bench -p mvgrasp-sim --bench segment
//! ```

#![allow(clippy::expect_used)] // a benchmark's set-up may stop on bad fixtures

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{ClusterConfig, GraspNet, MomentsNet, Planner, PlannerConfig};
use mvgrasp_sim::camera::{NoiseModel, render};
use mvgrasp_sim::eval::{crease_setting, episode_scene};
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::scene::Scenario;

/// Frames per scenario.
const FRAMES: u64 = 8;

fn segment(c: &mut Criterion) {
    let contract = MomentsNet::default().contract().clone();
    let planner = |crease: &str| {
        let config = PlannerConfig {
            cluster: ClusterConfig {
                crease: crease_setting(crease).expect("a crease setting"),
                ..ClusterConfig::default()
            },
            ..PlannerConfig::default()
        };
        Planner::new(config, contract.clone()).expect("planner")
    };
    let families: Vec<Family> = Family::ALL.into_iter().filter(|f| *f != Family::Bowl).collect();
    let catalog = Catalog::of(&families);
    for scenario in [Scenario::Pile, Scenario::Clutter] {
        // Depth frames as `sim eval` draws them (its noise seed).
        let frames: Vec<_> = (800_000..800_000 + FRAMES)
            .map(|seed| {
                let (scene, camera) = episode_scene(scenario, seed, &catalog).expect("scene");
                let mut rng = SplitMix64::new(seed ^ 0x0153_EAB0);
                let frame = render(&scene, &camera, Some((&NoiseModel::default(), &mut rng)));
                let bytes = frame.depth_le_bytes();
                (frame, bytes, scene.workspace())
            })
            .collect();
        let mut group = c.benchmark_group(format!("segment_{FRAMES}_{}_frames", scenario.name()));
        for crease in ["split-only", "on"] {
            let planner = planner(crease);
            let detections: usize = frames
                .iter()
                .map(|(frame, bytes, workspace)| {
                    let input = frame.scene_input(bytes, *workspace);
                    planner.segment(&input).expect("segment").clusters.len()
                })
                .sum();
            eprintln!("{} {crease}: {detections} detections", scenario.name());
            group.bench_function(crease, |b| {
                b.iter(|| {
                    for (frame, bytes, workspace) in &frames {
                        let input = frame.scene_input(bytes, *workspace);
                        black_box(planner.segment(black_box(&input)).expect("segment"));
                    }
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, segment);
criterion_main!(benches);
