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
use mvgrasp_core::{GraspMaps, GraspNet, ModelContract, Planner, ViewBatch};
use mvgrasp_server::{Overrides, Settings, backend, convert};

/// The network, each call's maps kept (one entry per cascade round).
struct Recording<'a> {
    net: &'a mut dyn GraspNet,
    kept: Vec<GraspMaps>,
}

impl GraspNet for Recording<'_> {
    fn contract(&self) -> &ModelContract {
        self.net.contract()
    }

    fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
        let maps = self.net.infer(batch)?;
        self.kept.push(maps.clone());
        Ok(maps)
    }
}

/// Recorded maps given back round by round, in place of the network.
struct Replay<'a> {
    contract: &'a ModelContract,
    kept: &'a [GraspMaps],
    round: usize,
}

impl GraspNet for Replay<'_> {
    fn contract(&self) -> &ModelContract {
        self.contract
    }

    fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
        let maps = &self.kept[self.round];
        assert_eq!(
            maps.len, batch.len,
            "round {} asks for other views than were recorded",
            self.round
        );
        self.round += 1;
        Ok(maps.clone())
    }
}

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
    let contract = net.contract().clone();
    let planner = Planner::new(settings.planner_config().expect("views"), contract.clone()).expect("planner");
    let scene = mvgrasp_client::scene::SceneFiles::load_depth(
        &repo.join("samples/table6/depth.png"),
        &repo.join("samples/table6/camera.json"),
    )
    .expect("sample frame");
    let request = scene.request();
    // What the service does with the request, the network's part given by `rounds`.
    let plan = |rounds: &mut dyn GraspNet| {
        let scene = convert::scene_of(&request, &settings.limits).expect("scene");
        let options = convert::options_of(&request, &settings.defaults).expect("options");
        planner.plan(&scene, &options, rounds).expect("plan")
    };

    // One plan through the network, each round's maps kept.
    let mut recording = Recording {
        net: net.as_mut(),
        kept: Vec::new(),
    };
    let first = plan(&mut recording);
    let kept = recording.kept;
    let views: Vec<usize> = kept.iter().map(|m| m.len).collect();
    eprintln!(
        "sample frame: {} objects, {} grasps, network rounds of {views:?} views, stages (ms) {:?}",
        first.objects.len(),
        first.grasps.len(),
        first.timings
    );
    let mut group = c.benchmark_group("sample_frame_table6");
    group.bench_function("cpu_stages_replayed_network", |b| {
        b.iter(|| {
            let mut replay = Replay {
                contract: &contract,
                kept: &kept,
                round: 0,
            };
            black_box(plan(&mut replay))
        })
    });
    group.finish();
}

criterion_group!(benches, sample_frame);
criterion_main!(benches);
