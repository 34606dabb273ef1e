//! Per-stage benchmark of the pipeline on a 640x480 frame with 6 objects
//! (everything except a learned network; the analytic baseline stands in
//! for it where maps are needed). Run on one core:
//!
//! ```text
//! taskset -c 0 cargo bench -p mvgrasp-core --bench stages
//! ```

#![allow(clippy::expect_used)] // a benchmark's set-up may stop on bad fixtures

use std::hint::black_box;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use mvgrasp_core::object::object_frame;
use mvgrasp_core::segment::{ImagePoints, euclidean_clusters, fit_table, split_at_creases};
use mvgrasp_core::select::view_entropy;
use mvgrasp_core::sensor::{BlockMask, random_world_points, world_points_above};
use mvgrasp_core::{
    BodyCapsule, GraspNet, ModelContract, MomentsNet, OrthoView, PlanOptions, Planner, PlannerConfig,
    SensorInput, ViewAxis, Workspace,
};
use nalgebra::{Point3, Vector3};

#[allow(dead_code, clippy::all)]
#[path = "../tests/pipeline/scene.rs"]
mod scene;

fn stages(c: &mut Criterion) {
    let table_scene = scene::grid_scene(0.0, 6, 3, 0.13);
    let camera = scene::Camera::orbit(Vector3::zeros(), 0.8, 50.0, -90.0);
    let bytes = scene::render(&table_scene, &camera).depth_bytes();
    let input = camera.scene_input(
        &bytes,
        Workspace::new([-0.6, -0.4, -0.05], [0.6, 0.4, 0.4]).expect("workspace"),
    );
    // The view size and pixel size of the default model (models/manifest.toml:
    // 72 px of 3.33 mm); the analytic baseline speaks it.
    let shipped = ModelContract {
        input_size_px: 72,
        pixel_size_m: 0.003_333_333,
        ..ModelContract::baseline()
    };
    let mut net = MomentsNet::new(shipped);
    let contract = net.contract().clone();
    let planner = Planner::new(PlannerConfig::default(), contract.clone()).expect("planner");
    let config = planner.config().clone();
    let options = PlanOptions::default();

    // Intermediate results, so each stage is timed on its own input.
    let (sensor, pose, workspace) = (&input.sensor, &input.world_from_camera, &input.workspace);
    let (samples, seed) = (config.table.sample_points, config.table.seed);
    let sparse = random_world_points(sensor, pose, workspace, samples, seed).expect("cloud");
    let table = fit_table(&sparse.points, &config.table).expect("table");
    let half_space = table.above(config.table.object_min_height_m);
    let SensorInput::Depth(frame) = sensor else {
        unreachable!("a depth frame")
    };
    let stride = config.table.mask_stride;
    let near = BlockMask::from_frame(frame, pose, workspace, &half_space, stride).expect("mask");
    let above_cloud = world_points_above(sensor, pose, workspace, &half_space, Some(&near)).expect("objects");
    let full = world_points_above(sensor, pose, workspace, &half_space, None).expect("objects");
    let above = above_cloud.points.clone();
    assert_eq!(
        above.len(),
        full.points.len(),
        "the block mask must not lose object points here"
    );
    eprintln!("block mask keeps {:.1}% of the frame", 100.0 * near.coverage());
    let clusters = euclidean_clusters(&above, &config.cluster);
    assert_eq!(clusters.len(), 6, "the bench scene must hold 6 objects");
    let cam = Point3::from(camera.world_from_camera.translation.vector);
    let framed: Vec<_> = clusters.iter().map(|cl| object_frame(&above, cl, &cam)).collect();
    let views: Vec<OrthoView> = framed
        .iter()
        .flat_map(|(_, local)| {
            ViewAxis::ALL.map(|axis| {
                OrthoView::render(axis, true, local, contract.input_size_px, contract.pixel_size_m)
            })
        })
        .collect();
    let prepared = planner.prepare(&input, &options).expect("prepare");
    let maps = net.infer(prepared.batch()).expect("maps");
    eprintln!(
        "bench frame: {} random points for the table, {} object points, {} objects, {} views inferred",
        sparse.points.len(),
        above.len(),
        clusters.len(),
        prepared.batch().len
    );

    let mut group = c.benchmark_group("640x480_6_objects");
    group.bench_function("1_sensor_random_points_for_table", |b| {
        b.iter(|| random_world_points(black_box(sensor), pose, workspace, samples, seed))
    });
    group.bench_function("2_table_ransac", |b| {
        b.iter(|| fit_table(black_box(&sparse.points), &config.table))
    });
    group.bench_function("3_sensor_objects_above_table", |b| {
        b.iter(|| {
            let near = BlockMask::from_frame(frame, pose, workspace, &half_space, stride).expect("mask");
            world_points_above(black_box(sensor), pose, workspace, &half_space, Some(&near))
        })
    });
    group.bench_function("3_sensor_objects_full_frame_no_mask", |b| {
        b.iter(|| world_points_above(black_box(sensor), pose, workspace, &half_space, None))
    });
    group.bench_function("4_cluster", |b| {
        b.iter(|| euclidean_clusters(black_box(&above), &config.cluster))
    });
    // The crease split is off by default (`cluster.crease = None`): timed with its defaults.
    let crease = config.cluster.crease.clone().unwrap_or_default();
    let axis = pose.rotation * Vector3::z();
    let origin = pose.translation.vector;
    let image = ImagePoints {
        points: &above,
        pixels: &above_cloud.pixels,
        width: frame.width as usize,
        origin: [origin.x as f32, origin.y as f32, origin.z as f32],
        axis: [axis.x as f32, axis.y as f32, axis.z as f32],
        focal_px: frame.intrinsics.fx as f32,
    };
    group.bench_function("4b_crease_split", |b| {
        b.iter_batched(
            || clusters.clone(),
            |clusters| split_at_creases(black_box(&image), clusters, config.cluster.tolerance_m, &crease),
            BatchSize::SmallInput,
        )
    });
    group.bench_function("4_cluster_reference_kiddo_kd_tree_flood_fill", |b| {
        b.iter(|| kd_tree_flood_fill(black_box(&above), config.cluster.tolerance_m))
    });
    group.bench_function("5_object_frames", |b| {
        b.iter(|| {
            clusters
                .iter()
                .map(|cl| object_frame(black_box(&above), cl, &cam))
                .collect::<Vec<_>>()
        })
    });
    group.bench_function("6_render_views_and_entropy", |b| {
        b.iter(|| {
            framed
                .iter()
                .flat_map(|(frame, local)| {
                    ViewAxis::ALL.map(|axis| {
                        OrthoView::render_within(
                            axis,
                            true,
                            black_box(local),
                            frame.extent_f32(),
                            contract.input_size_px,
                            contract.pixel_size_m,
                        )
                    })
                })
                .collect::<Vec<_>>()
        })
    });
    // Stage 6 already sums each view's entropy; this is the standalone
    // function over whole images, for comparison (not on the pipeline path).
    group.bench_function("entropy_of_18_whole_images_standalone", |b| {
        b.iter(|| {
            views
                .iter()
                .map(|v| view_entropy(black_box(&v.image)))
                .sum::<f64>()
        })
    });
    group.bench_function("7_decode_and_rank", |b| {
        b.iter_batched(
            || planner.prepare(&input, &options).expect("prepare"),
            |p| planner.finish(p, &maps).expect("finish"),
            BatchSize::SmallInput,
        )
    });
    // The same without the hand's collision check, to read its cost.
    let unchecked = Planner::new(
        PlannerConfig {
            hand: mvgrasp_core::decode::HandConfig {
                enabled: false,
                ..Default::default()
            },
            ..planner.config().clone()
        },
        planner.contract().clone(),
    )
    .expect("planner");
    group.bench_function("7_decode_and_rank_without_hand_check", |b| {
        b.iter_batched(
            || unchecked.prepare(&input, &options).expect("prepare"),
            |p| unchecked.finish(p, &maps).expect("finish"),
            BatchSize::SmallInput,
        )
    });
    group.bench_function("all_but_network", |b| {
        b.iter(|| {
            let p = planner.prepare(black_box(&input), &options).expect("prepare");
            planner.finish(p, &maps).expect("finish")
        })
    });
    // A workspace that cuts the outer columns (x = +-0.13 m) through, with
    // and without the region around it: the obstacle boxes' pass and the
    // rest of each cut object.
    let narrow = camera.scene_input(
        &bytes,
        Workspace::new([-0.11, -0.4, -0.05], [0.11, 0.4, 0.4]).expect("workspace"),
    );
    let region = PlanOptions {
        obstacle_region: Some(Workspace::new([-0.6, -0.4, -0.05], [0.6, 0.4, 0.5]).expect("region")),
        ..PlanOptions::default()
    };
    // The same told a UR5e's body at home (the robot-bridge's 13 capsules
    // for the referee's cell), its base at the region's border: every
    // capsule meets the region, so every outside point is tested.
    let body = PlanOptions {
        robot_body: [
            ([0.0, -0.45, 0.0], [0.0, -0.45, 0.162], 0.12),
            ([0.12, -0.381, 0.162], [0.083, -0.317, 0.581], 0.09),
            ([-0.031, -0.383, 0.581], [0.162, -0.717, 0.513], 0.08),
            ([0.156, -0.721, 0.513], [0.272, -0.654, 0.513], 0.075),
            ([0.272, -0.654, 0.513], [0.321, -0.74, 0.513], 0.075),
            ([0.321, -0.74, 0.513], [0.321, -0.74, 0.413], 0.075),
            ([0.0, -0.45, 0.162], [0.12, -0.381, 0.162], 0.09),
            ([0.083, -0.317, 0.581], [-0.031, -0.383, 0.581], 0.08),
            ([0.162, -0.717, 0.513], [0.156, -0.721, 0.513], 0.075),
            ([0.321, -0.74, 0.313], [0.321, -0.74, 0.423], 0.09),
            ([0.262, -0.638, 0.325], [0.38, -0.842, 0.325], 0.085),
            ([0.277, -0.663, 0.211], [0.277, -0.663, 0.305], 0.058),
            ([0.366, -0.817, 0.211], [0.366, -0.817, 0.305], 0.058),
        ]
        .map(|(a, b, r)| BodyCapsule::new(Vector3::from(a), Vector3::from(b), r).expect("capsule"))
        .to_vec(),
        ..region.clone()
    };
    for (name, options) in [
        ("prepare_narrow_workspace", &options),
        ("prepare_narrow_workspace_obstacle_region", &region),
        ("prepare_narrow_workspace_obstacle_region_robot_body", &body),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| planner.prepare(black_box(&narrow), options).expect("prepare"))
        });
    }
    // The same end to end with the baseline's 96 px x 2.5 mm views, for comparison.
    let mut net_96 = MomentsNet::default();
    let planner_96 = Planner::new(PlannerConfig::default(), net_96.contract().clone()).expect("planner");
    let prepared_96 = planner_96.prepare(&input, &options).expect("prepare");
    let maps_96 = net_96.infer(prepared_96.batch()).expect("maps");
    group.bench_function("all_but_network_96px_views", |b| {
        b.iter(|| {
            let p = planner_96.prepare(black_box(&input), &options).expect("prepare");
            planner_96.finish(p, &maps_96).expect("finish")
        })
    });
    let map: Vec<f32> = (0..96 * 96).map(|i| (i % 97) as f32 / 97.0).collect();
    group.bench_function("smooth_one_96px_map", |b| {
        b.iter(|| mvgrasp_core::decode::smooth(black_box(&map), 96, 96, 1.0))
    });
    group.bench_function("baseline_net_6_views", |b| {
        b.iter(|| net.infer(black_box(prepared.batch())))
    });
    group.finish();
}

/// The textbook alternative to `euclidean_clusters`' cell method: a flood
/// fill over k-d tree range queries, one per point (same components).
fn kd_tree_flood_fill(points: &[[f32; 3]], tolerance_m: f32) -> usize {
    let mut tree: kiddo::KdTree<f32, 3> = kiddo::KdTree::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        tree.add(p, i as u64);
    }
    let mut label = vec![u32::MAX; points.len()];
    let mut next = 0;
    let mut stack = Vec::new();
    for seed in 0..points.len() {
        if label[seed] != u32::MAX {
            continue;
        }
        label[seed] = next;
        stack.push(seed);
        while let Some(v) = stack.pop() {
            for n in tree.within_unsorted::<kiddo::SquaredEuclidean>(&points[v], tolerance_m * tolerance_m) {
                if label[n.item as usize] == u32::MAX {
                    label[n.item as usize] = next;
                    stack.push(n.item as usize);
                }
            }
        }
        next += 1;
    }
    next as usize
}

criterion_group!(benches, stages);
criterion_main!(benches);
