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
use mvgrasp_core::{GraspNet, MomentsNet};
use mvgrasp_sim::eval::{episode_first_frame, planner_with_crease};
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::scene::Scenario;

/// Frames per scenario.
const FRAMES: u64 = 8;

fn segment(c: &mut Criterion) {
    let contract = MomentsNet::default().contract().clone();
    let families: Vec<Family> = Family::ALL.into_iter().filter(|f| *f != Family::Bowl).collect();
    let catalog = Catalog::of(&families);
    for scenario in [Scenario::Pile, Scenario::Clutter] {
        // The episodes' first frames, as `sim eval` draws them.
        let frames: Vec<_> = (800_000..800_000 + FRAMES)
            .map(|seed| {
                let (scene, frame) = episode_first_frame(scenario, seed, &catalog).expect("scene");
                let bytes = frame.depth_le_bytes();
                (frame, bytes, scene.workspace())
            })
            .collect();
        let mut group = c.benchmark_group(format!("segment_{FRAMES}_{}_frames", scenario.name()));
        for crease in ["split-only", "on"] {
            let planner = planner_with_crease(crease, &contract).expect("planner");
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
