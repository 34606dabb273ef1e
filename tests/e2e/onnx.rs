//! The ONNX Runtime backend against the closed form of `tiny.onnx`.

use mvgrasp_core::{Channel, GraspNet, ViewBatch};
use mvgrasp_server::{BackendKind, backend::OnnxNet};

use crate::fixture::settings;

/// quality = sigmoid(10 * mean5x5(x) - 3) with zero padding; 1, 0, 0.4 elsewhere.
fn expected_quality(image: &[f32], l: usize, u: usize, v: usize) -> f32 {
    let mut sum = 0.0f64;
    for dv in -2i64..=2 {
        for du in -2i64..=2 {
            let (x, y) = (u as i64 + du, v as i64 + dv);
            if (0..l as i64).contains(&x) && (0..l as i64).contains(&y) {
                sum += f64::from(image[y as usize * l + x as usize]);
            }
        }
    }
    (1.0 / (1.0 + (-(10.0 * sum / 25.0 - 3.0)).exp())) as f32
}

#[test]
fn tiny_model_matches_its_closed_form_through_ort() {
    let mut net = OnnxNet::load(&settings(BackendKind::Onnx).model, 8).expect("tiny.onnx loads");
    let contract = net.contract().clone();
    assert_eq!(contract.model_version, "fixture-tiny-1");
    assert_eq!(contract.input_size_px, 96);
    assert_eq!(net.provider(), "onnxruntime-cpu");
    let l = contract.input_size_px;
    let mut batch = ViewBatch::new(l);
    for k in 0..3u32 {
        // A deterministic pattern per view: a block plus a ramp.
        let image: Vec<f32> = (0..l * l)
            .map(|i| {
                let (u, v) = (i % l, i / l);
                let block = (20 + k as usize..60).contains(&u) && (30..70).contains(&v);
                if block { 0.3 + 0.005 * (u as f32) } else { 0.0 }
            })
            .collect();
        batch.push(&image);
    }
    let maps = net.infer(&batch).expect("inference");
    maps.check_matches(&batch).unwrap();
    let q = contract.channel_index(Channel::Quality);
    let w = contract.channel_index(Channel::Width);
    let c = contract.channel_index(Channel::Cos2Phi);
    let mut worst = 0.0f32;
    for view in 0..3 {
        let image = batch.view(view);
        for (u, v) in [(0, 0), (20, 30), (40, 50), (59, 69), (61, 71), (95, 95)] {
            let got = maps.channel(view, q)[v * l + u];
            worst = worst.max((got - expected_quality(image, l, u, v)).abs());
            assert!((maps.channel(view, w)[v * l + u] - 0.4).abs() < 1e-6);
            assert!((maps.channel(view, c)[v * l + u] - 1.0).abs() < 1e-6);
        }
    }
    assert!(worst < 1e-5, "quality differs from the closed form by {worst}");
}

#[test]
fn a_model_without_the_contract_is_refused_by_name() {
    let mut s = settings(BackendKind::Onnx).model;
    s.path = "does/not/exist.onnx".into();
    let err = OnnxNet::load(&s, 8).unwrap_err().to_string();
    assert!(err.contains("does/not/exist.onnx"), "{err}");
}

/// A little-endian float32 C-order `.npy` file: (shape, values).
fn read_npy_f32(path: &std::path::Path) -> (Vec<usize>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..6], b"\x93NUMPY", "{} is not .npy", path.display());
    let (header_len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        _ => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
    };
    let header = std::str::from_utf8(&bytes[start..start + header_len]).unwrap();
    assert!(header.contains("'descr': '<f4'"), "{header}");
    assert!(header.contains("'fortran_order': False"), "{header}");
    let dims = header
        .split('(')
        .nth(1)
        .and_then(|s| s.split(')').next())
        .unwrap();
    let shape: Vec<usize> = dims
        .split(',')
        .filter(|d| !d.trim().is_empty())
        .map(|d| d.trim().parse().unwrap())
        .collect();
    let values: Vec<f32> = bytes[start + header_len..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(
        values.len(),
        shape.iter().product::<usize>(),
        "{}",
        path.display()
    );
    (shape, values)
}

/// Padding a batch (what the CUDA backend does to keep one input shape)
/// changes none of the real views' maps and returns only theirs.
#[test]
fn padded_batches_give_the_same_maps() {
    let repo = crate::fixture::repo();
    let mut model = settings(BackendKind::Onnx).model;
    model.path = repo.join("models/mvgrasp-8.onnx");
    let mut net = OnnxNet::load(&model, 8).expect("models/mvgrasp-8.onnx loads");
    let l = net.contract().input_size_px;
    let (_, input) = read_npy_f32(&repo.join("models/golden-mvgrasp-8/input.npy"));
    let mut batch = ViewBatch::new(l);
    for view in input.chunks_exact(l * l) {
        batch.push(view);
    }
    let plain = net.infer(&batch).expect("inference");
    net.pad_batches_to(7);
    let padded = net.infer(&batch).expect("padded inference");
    padded.check_matches(&batch).unwrap();
    assert_eq!(padded.len, batch.len);
    let worst = plain
        .data
        .iter()
        .zip(&padded.data)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "padding changed the maps by {worst}");
}

/// `models/manifest.toml`: what each shipped network is.
#[derive(serde::Deserialize)]
struct Manifest {
    default: String,
    models: std::collections::BTreeMap<String, ManifestEntry>,
}

#[derive(serde::Deserialize)]
struct ManifestEntry {
    version: String,
    file: String,
    sha256: String,
    golden: String,
    data_version: String,
}

fn manifest() -> Manifest {
    let repo = crate::fixture::repo();
    let text = std::fs::read_to_string(repo.join("models/manifest.toml")).expect("models/manifest.toml");
    toml::from_str(&text).expect("models/manifest.toml parses")
}

/// Every network in `models/manifest.toml` is the file it names (sha256),
/// says in its metadata the version and data version listed, and gives,
/// through `ort`, what PyTorch gave when it was exported (its golden folder,
/// written by `mvgrasp_train.export --golden`; for an int8 file, what
/// onnxruntime gave when `mvgrasp_train.quantize --golden` wrote it): any
/// drift between training and serving fails here. Every ONNX file in
/// `models/` is listed, and the default is what the server loads when its
/// settings name no model.
#[test]
fn every_shipped_model_matches_the_manifest_and_its_golden_vectors() {
    let repo = crate::fixture::repo();
    let manifest = manifest();
    let default = &manifest.models[&manifest.default];
    assert_eq!(
        mvgrasp_server::Settings::default().model.path,
        std::path::Path::new("models").join(&default.file),
        "the server's default model is the manifest's"
    );
    let mut shipped: Vec<String> = std::fs::read_dir(repo.join("models"))
        .expect("models/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|name| name.ends_with(".onnx"))
        .collect();
    shipped.sort();
    let mut listed: Vec<String> = manifest.models.values().map(|m| m.file.clone()).collect();
    listed.sort();
    assert_eq!(shipped, listed, "models/*.onnx and the manifest");
    for (name, entry) in &manifest.models {
        let path = repo.join("models").join(&entry.file);
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let digest = ring::digest::digest(&ring::digest::SHA256, &bytes);
        let hex: String = digest.as_ref().iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(hex, entry.sha256, "{name}: {} is not the file listed", entry.file);
        let contract = check_golden(
            &format!("models/{}", entry.file),
            &format!("models/{}", entry.golden),
        );
        assert_eq!(contract.model_version, entry.version, "{name}");
        assert_eq!(contract.data_version, entry.data_version, "{name}");
    }
}

/// Checks `file` against its golden vectors and returns its contract.
fn check_golden(file: &str, golden: &str) -> mvgrasp_core::ModelContract {
    let repo = crate::fixture::repo();
    let mut model = settings(BackendKind::Onnx).model;
    model.path = repo.join(file);
    let mut net = OnnxNet::load(&model, 8).unwrap_or_else(|e| panic!("{file} loads: {e}"));
    let contract = net.contract().clone();
    let l = contract.input_size_px;
    let (in_shape, input) = read_npy_f32(&repo.join(golden).join("input.npy"));
    let (out_shape, expected) = read_npy_f32(&repo.join(golden).join("output.npy"));
    assert_eq!(in_shape, [in_shape[0], 1, l, l]);
    assert_eq!(out_shape, [in_shape[0], 4, l, l]);
    let mut batch = ViewBatch::new(l);
    for view in input.chunks_exact(l * l) {
        batch.push(view);
    }
    let maps = net.infer(&batch).expect("inference");
    maps.check_matches(&batch).unwrap();
    // The golden file is in the contract's channel order (export writes that order).
    let order = [
        Channel::Quality,
        Channel::Cos2Phi,
        Channel::Sin2Phi,
        Channel::Width,
    ];
    let (mut worst, mut sum) = (0.0f32, 0.0f64);
    for view in 0..in_shape[0] {
        for (k, channel) in order.into_iter().enumerate() {
            let got = maps.channel(view, contract.channel_index(channel));
            let want = &expected[(view * 4 + k) * l * l..(view * 4 + k + 1) * l * l];
            for (g, w) in got.iter().zip(want) {
                worst = worst.max((g - w).abs());
                sum += f64::from((g - w).abs());
            }
        }
    }
    let mean = sum / expected.len() as f64;
    if contract.model_version.ends_with("-int8") {
        // ONNX Runtime's int8 convolutions differ by CPU instruction set: the
        // golden output is the writer's machine's. On an AVX2 machine
        // without VNNI the int8 default's worst pixel was 0.32 off, its
        // mean 0.0074 (2026-12-02).
        assert!(
            mean < 0.02,
            "{file}: ort differs from the golden output by {mean} on average (worst {worst})"
        );
    } else {
        assert!(
            worst < 1e-4,
            "{file}: ort differs from PyTorch's golden output by {worst}"
        );
    }
    // Not a degenerate model: its quality map varies over a view with an object.
    let q = maps.channel(0, contract.channel_index(Channel::Quality));
    let (lo, hi) = q
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi - lo > 0.1, "{file}: quality spans only {lo}..{hi}");
    contract
}

/// The shipped default on the committed sample frame (6 objects), default
/// request: with the view cascade every object gets a grasp; with the
/// paper's single pass (`view_cascade: false`) three of them get none.
#[tokio::test]
async fn the_default_request_gives_every_sample_object_a_grasp() {
    let repo = crate::fixture::repo();
    let mut settings = settings(BackendKind::Onnx);
    let manifest = manifest();
    settings.model.path = repo.join("models").join(&manifest.models[&manifest.default].file);
    let (server, mut client) = crate::fixture::start(settings).await;
    let scene = mvgrasp_client::scene::SceneFiles::load_depth(
        &repo.join("samples/table6/depth.png"),
        &repo.join("samples/table6/camera.json"),
    )
    .expect("sample frame");
    let objects_with_grasps = |response: &mvgrasp_client::pb::PlanGraspsResponse| {
        let mut ids: Vec<u32> = response.grasps.iter().map(|g| g.object_id).collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    };
    let cascaded = client.plan(scene.request()).await.expect("plan");
    assert_eq!(cascaded.objects.len(), 6);
    assert_eq!(objects_with_grasps(&cascaded), [0, 1, 2, 3, 4, 5]);
    let single_pass = client
        .plan(mvgrasp_client::pb::PlanGraspsRequest {
            view_cascade: Some(false),
            ..scene.request()
        })
        .await
        .expect("plan");
    assert!(objects_with_grasps(&single_pass).len() < 6);
    // Approaches from below only: no grasp at all, and each object says why.
    let from_below = client
        .plan(mvgrasp_client::pb::PlanGraspsRequest {
            approach_cone: Some(mvgrasp_client::pb::ApproachCone {
                axis: Some(mvgrasp_client::pb::Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: 1.0,
                }),
                half_angle_rad: 0.2,
            }),
            ..scene.request()
        })
        .await
        .expect("plan");
    assert!(from_below.grasps.is_empty());
    assert!(from_below.outside_approach_cone > 0);
    for o in &from_below.objects {
        let refused = o.refused.expect("per-object refusals");
        assert!(refused.outside_approach_cone > 0, "object {}: {refused:?}", o.id);
        assert!(
            o.views.iter().all(|v| v.inferred),
            "object {}: every view tried",
            o.id
        );
    }
    server.shutdown().await.unwrap();
}
