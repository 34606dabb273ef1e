//! `sim datagen`: shards, manifest counts, candidate density, label salt, neighbours.

use super::*;

#[test]
fn datagen_writes_shards_its_manifest_counts() {
    use mvgrasp_sim::dataset::{DatagenConfig, generate};
    use mvgrasp_sim::targets::TargetConfig;

    let out = std::env::temp_dir().join(format!("mvgrasp-datagen-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let contract = MomentsNet::default().contract().clone();
    let config = DatagenConfig {
        scenes: 3,
        seed: 40,
        scenarios: vec![Scenario::Isolated, Scenario::Packed],
        catalog: Catalog::of(&Family::ALL),
        scenes_per_shard: 2,
        targets: TargetConfig::default(),
        noise: Some(NoiseModel::default()),
        data_version: "test".into(),
        label_salt: 0,
    };
    let report = generate(&out, &contract, &config, false).unwrap();
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    assert_eq!(report.shards, 2);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["views"], report.views);
    let mut lines = 0;
    for shard in ["shard_00000", "shard_00001"] {
        let meta = std::fs::read_to_string(out.join(shard).join("meta.jsonl")).unwrap();
        let n = meta.lines().count();
        lines += n;
        // .npy: a 64-byte-aligned header, then n x 4 x 96 x 96 float32.
        let maps = std::fs::read(out.join(shard).join("maps.npy")).unwrap();
        let header = usize::from(u16::from_le_bytes([maps[8], maps[9]]));
        assert_eq!((10 + header) % 64, 0);
        assert_eq!(maps.len(), 10 + header + n * 4 * 96 * 96 * 4);
        let text = String::from_utf8_lossy(&maps[10..10 + header]).into_owned();
        assert!(text.contains(&format!("'shape': ({n}, 4, 96, 96)")), "{text}");
        // grasps.npy: one row of 6 per labelled positive.
        let lines: Vec<serde_json::Value> = meta.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        let positives: usize = lines
            .iter()
            .map(|l| l["positives"].as_u64().unwrap() as usize)
            .sum();
        for l in &lines {
            // Each view's refusal counts cover the candidates that are not positive.
            let refused: u64 = l["refused"]
                .as_object()
                .unwrap()
                .values()
                .map(|n| n.as_u64().unwrap())
                .sum();
            assert_eq!(
                refused + l["positives"].as_u64().unwrap(),
                l["candidates"].as_u64().unwrap(),
                "{l}"
            );
        }
        let grasps = std::fs::read(out.join(shard).join("grasps.npy")).unwrap();
        let header = usize::from(u16::from_le_bytes([grasps[8], grasps[9]]));
        assert_eq!(grasps.len(), 10 + header + positives * 6 * 4);
        let text = String::from_utf8_lossy(&grasps[10..10 + header]).into_owned();
        assert!(text.contains(&format!("'shape': ({positives}, 6)")), "{text}");
    }
    assert_eq!(lines, report.views);
    let _ = std::fs::remove_dir_all(&out);
}

/// Test-sized `sim datagen` settings: one scene per shard, no noise, salt 0.
fn small_datagen(
    scenes: u64,
    seed: u64,
    scenario: Scenario,
    families: &[Family],
) -> mvgrasp_sim::dataset::DatagenConfig {
    mvgrasp_sim::dataset::DatagenConfig {
        scenes,
        seed,
        scenarios: vec![scenario],
        catalog: Catalog::of(families),
        scenes_per_shard: scenes,
        targets: mvgrasp_sim::targets::TargetConfig::default(),
        noise: None,
        data_version: "test".into(),
        label_salt: 0,
    }
}

/// Runs `config` into a fresh `out` (no scene may fail) and returns its manifest.
fn datagen_into(out: &std::path::Path, config: &mvgrasp_sim::dataset::DatagenConfig) -> serde_json::Value {
    let _ = std::fs::remove_dir_all(out);
    let contract = MomentsNet::default().contract().clone();
    let report = mvgrasp_sim::dataset::generate(out, &contract, config, false).unwrap();
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap()
}

/// The data of an `.npy` file: past its 10-byte preamble and header.
fn npy_data(bytes: &[u8]) -> &[u8] {
    &bytes[10 + usize::from(u16::from_le_bytes([bytes[8], bytes[9]]))..]
}

#[test]
fn datagen_refuses_a_zero_candidate_stride_or_no_angles_and_denser_candidates_find_more() {
    use mvgrasp_sim::Error;
    use mvgrasp_sim::dataset::{DatagenConfig, generate};
    use mvgrasp_sim::targets::TargetConfig;

    let out = std::env::temp_dir().join(format!("mvgrasp-datagen-dense-{}", std::process::id()));
    let contract = MomentsNet::default().contract().clone();
    let config = |stride_px, angles| DatagenConfig {
        targets: TargetConfig {
            stride_px,
            angles,
            ..TargetConfig::default()
        },
        ..small_datagen(1, 41, Scenario::Isolated, &[Family::Box])
    };
    for (stride, angles) in [(0, 8), (3, 0)] {
        let _ = std::fs::remove_dir_all(&out);
        match generate(&out, &contract, &config(stride, angles), false) {
            Err(Error::Invalid { field: "targets", .. }) => {}
            other => panic!("stride {stride}, angles {angles}: {other:?}"),
        }
        assert!(!out.exists(), "nothing written for refused settings");
    }
    let positives = |stride, angles| {
        let manifest = datagen_into(&out, &config(stride, angles));
        assert_eq!(manifest["generator"]["stride_px"], stride);
        assert_eq!(manifest["generator"]["angles"], angles);
        let grasps = std::fs::read(out.join("shard_00000").join("grasps.npy")).unwrap();
        npy_data(&grasps).len() / (6 * 4)
    };
    let (sparse, dense) = (positives(3, 8), positives(1, 16));
    assert!(sparse > 0, "a lone box has positives");
    assert!(
        dense > 4 * sparse,
        "every pixel at twice the angles: {dense} vs {sparse}"
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn a_label_salt_redraws_noise_and_annealing_for_the_same_scenes_and_cameras() {
    use mvgrasp_sim::dataset::DatagenConfig;

    let out = std::env::temp_dir().join(format!("mvgrasp-datagen-salt-{}", std::process::id()));
    // One scene labelled with a salt: (views.npy, grasps.npy rows, meta.jsonl).
    let run = |noise: bool, label_salt: u64| {
        let config = DatagenConfig {
            noise: noise.then(NoiseModel::default),
            label_salt,
            ..small_datagen(1, 43, Scenario::Isolated, &[Family::Box])
        };
        let manifest = datagen_into(&out, &config);
        assert_eq!(manifest["generator"]["label_salt"], label_salt);
        let shard = out.join("shard_00000");
        let views = std::fs::read(shard.join("views.npy")).unwrap();
        let grasps = std::fs::read(shard.join("grasps.npy")).unwrap();
        let rows: Vec<[f32; 6]> = npy_data(&grasps)
            .chunks_exact(24)
            .map(|r| std::array::from_fn(|k| f32::from_le_bytes(r[4 * k..4 * k + 4].try_into().unwrap())))
            .collect();
        (views, rows, meta_lines(&shard))
    };
    let pixels = |rows: &[[f32; 6]]| rows.iter().map(|r| (r[0], r[1], r[2])).collect::<Vec<_>>();
    // Which scene object and view each line is (counts change with the noise).
    let which = |meta: &[serde_json::Value]| {
        meta.iter()
            .map(|v| (v["instance"].to_string(), v["view"].to_string()))
            .collect::<Vec<_>>()
    };

    // Salt 0 is each scene's own draw, run after run.
    let (views, rows, meta) = run(true, 0);
    assert!(!rows.is_empty(), "a lone box has positives");
    assert_eq!(run(true, 0), (views.clone(), rows.clone(), meta.clone()));

    // A perfect sensor: the same views and the same positive pixels, but
    // the annealing wanders elsewhere in angle and opening.
    let (clean, clean_rows, clean_meta) = run(false, 0);
    let (salted, salted_rows, salted_meta) = run(false, 9);
    assert_eq!(salted, clean);
    assert_eq!(salted_meta, clean_meta);
    assert_eq!(pixels(&salted_rows), pixels(&clean_rows));
    assert_ne!(salted_rows, clean_rows, "annealing redrawn");

    // With noise, the same scene and camera seen through other noise: the
    // same objects and views, different depth pixels.
    let (noisy, _, noisy_meta) = run(true, 9);
    assert_ne!(noisy, views, "noise redrawn");
    assert_eq!(which(&noisy_meta), which(&meta));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn labels_without_neighbours_keep_the_views_and_lose_no_positive() {
    use mvgrasp_sim::dataset::DatagenConfig;
    use mvgrasp_sim::targets::TargetConfig;

    let out = std::env::temp_dir().join(format!("mvgrasp-datagen-alone-{}", std::process::id()));
    // Packed scenes, labelled with and without the other objects: (views.npy, positives per view).
    let run = |neighbours: bool| {
        let config = DatagenConfig {
            targets: TargetConfig {
                neighbours,
                ..TargetConfig::default()
            },
            noise: Some(NoiseModel::default()),
            ..small_datagen(2, 44, Scenario::Packed, &[Family::Box, Family::Cylinder])
        };
        let manifest = datagen_into(&out, &config);
        assert_eq!(manifest["generator"]["neighbours"], neighbours);
        let shard = out.join("shard_00000");
        let positives: Vec<u64> = meta_lines(&shard)
            .iter()
            .map(|v| v["positives"].as_u64().unwrap())
            .collect();
        (std::fs::read(shard.join("views.npy")).unwrap(), positives)
    };
    let (views, with) = run(true);
    let (alone_views, alone) = run(false);
    assert_eq!(alone_views, views, "the same frames and views");
    assert_eq!(alone.len(), with.len());
    // A neighbour can only refuse a candidate, never make one hold.
    assert!(
        with.iter().zip(&alone).all(|(w, a)| a >= w),
        "{with:?} vs {alone:?}"
    );
    let (w, a): (u64, u64) = (with.iter().sum(), alone.iter().sum());
    assert!(
        a > w,
        "packed objects refuse some grasps to their neighbours: {a} vs {w}"
    );
    let _ = std::fs::remove_dir_all(&out);
}
