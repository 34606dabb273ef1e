//! The CPU stages of one plan of the committed sample frame
//! (`samples/table6`: 640x480, 6 objects) as the service runs them, with
//! `deploy/server.toml` and the model it names: the request converted, the
//! planner's `prepare` and every `finish_or_cascade` round. The network is
//! left out: its maps are recorded once per cascade round and replayed.
//! Needs ONNX Runtime (`ORT_DYLIB_PATH`, `scripts/fetch-onnxruntime.sh`);
//! without it the bench says so and measures nothing. Run on one core:
//!
//! ```text
//! ORT_DYLIB_PATH=$(scripts/fetch-onnxruntime.sh) taskset -c 0 cargo bench -p mvgrasp-server --bench sample_frame
//! ```

#![allow(clippy::expect_used)] // a benchmark's set-up may stop on bad fixtures

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use mvgrasp_core::{Finished, GraspMaps, Plan, Planner};
use mvgrasp_server::{Overrides, Settings, backend, convert};

fn sample_frame(c: &mut Criterion) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let overrides = Overrides {
        config: Some(repo.join("deploy/server.toml")),
        ..Overrides::default()
    };
    let mut settings = Settings::load(&overrides).expect("deploy/server.toml");
    settings.model.path = repo.join(&settings.model.path);
    let mut net = match backend::load(&settings.model, settings.batching.max_batch_views) {
        Ok(loaded) => loaded.net,
        Err(e) => {
            eprintln!("sample_frame: no network ({e}); set ORT_DYLIB_PATH (scripts/fetch-onnxruntime.sh)");
            return;
        }
    };
    let planner = Planner::new(settings.planner_config(), net.contract().clone()).expect("planner");
    let scene = mvgrasp_client::scene::SceneFiles::load_depth(
        &repo.join("samples/table6/depth.png"),
        &repo.join("samples/table6/camera.json"),
    )
    .expect("sample frame");
    let request = scene.request();

    // One plan through the network, each round's maps kept.
    let plan_with = |maps_of_round: &mut dyn FnMut(usize, &mvgrasp_core::ViewBatch) -> GraspMaps| -> Plan {
        let scene = convert::scene_of(&request, &settings.limits).expect("scene");
        let options = convert::options_of(&request, &settings.defaults).expect("options");
        let mut prepared = planner.prepare(&scene, &options).expect("prepare");
        for round in 0.. {
            let maps = maps_of_round(round, prepared.batch());
            match planner.finish_or_cascade(prepared, &maps).expect("finish") {
                Finished::Plan(plan) => return *plan,
                Finished::More(next) => prepared = *next,
            }
        }
        unreachable!("the cascade ends")
    };
    let mut recorded: Vec<GraspMaps> = Vec::new();
    let plan = plan_with(&mut |_, batch| {
        let maps = net.infer(batch).expect("network");
        recorded.push(maps.clone());
        maps
    });
    let views: Vec<usize> = recorded.iter().map(|m| m.len).collect();
    eprintln!(
        "sample frame: {} objects, {} grasps, network rounds of {views:?} views, stages (ms) {:?}",
        plan.objects.len(),
        plan.grasps.len(),
        plan.timings
    );
    let replay = |round: usize, batch: &mvgrasp_core::ViewBatch| {
        let maps = &recorded[round];
        assert_eq!(
            maps.len, batch.len,
            "round {round} asks for other views than were recorded"
        );
        maps.clone()
    };
    let mut group = c.benchmark_group("sample_frame_table6");
    group.bench_function("cpu_stages_replayed_network", |b| {
        b.iter(|| plan_with(&mut |round, batch| replay(round, black_box(batch))))
    });
    group.finish();
}

criterion_group!(benches, sample_frame);
criterion_main!(benches);
