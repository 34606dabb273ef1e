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
    let mut net = OnnxNet::load(&settings(BackendKind::Onnx).model).expect("tiny.onnx loads");
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
    let err = OnnxNet::load(&s).unwrap_err().to_string();
    assert!(err.contains("does/not/exist.onnx"), "{err}");
}
