//! The simulated camera against analytic shapes: its rays, its noise, its seeds and its poses.

use super::*;

#[test]
fn ray_casts_hit_a_box_and_a_ball_where_geometry_says() {
    let table_z = 0.3;
    // A 6 x 4 x 10 cm box: its top 10 cm above the table, seen from 1 m above the table.
    let boxed = ObjectModel::from_parts(
        Family::Box,
        vec![(
            Pose::from_translation(Vector::new(0.0, 0.0, 0.05)),
            SharedShape::cuboid(0.03, 0.02, 0.05),
        )],
    );
    let frame = render(
        &one_object(table_z, boxed, 0.0, 0.0),
        &top_down(table_z, 1.0),
        None,
    );
    let (w, h) = (640, 480);
    let centre = (h / 2) * w + w / 2;
    assert_eq!(frame.labels[centre], 2);
    assert_eq!(frame.depth_mm[centre], 900);
    // Its footprint: 6 cm at 0.9 m and 600 px focal length is 40 px across.
    let row: Vec<u16> = frame.labels[(h / 2) * w..(h / 2 + 1) * w].to_vec();
    let across = row.iter().filter(|&&l| l == 2).count();
    assert!((39..=41).contains(&across), "{across} px");
    // Beside it, the table at 1 m (off-axis pixels: optical-axis depth stays 1 m).
    assert_eq!(frame.depth_mm[(h / 2) * w + 10], 1000);
    assert_eq!(frame.labels[(h / 2) * w + 10], 1);

    // A ball of radius 4 cm resting on the table: nearest point 8 cm up.
    let ball = ObjectModel::from_parts(
        Family::Ellipsoid,
        vec![(
            Pose::from_translation(Vector::new(0.0, 0.0, 0.04)),
            SharedShape::ball(0.04),
        )],
    );
    let frame = render(
        &one_object(table_z, ball, 0.0, 0.0),
        &top_down(table_z, 0.8),
        None,
    );
    assert_eq!(frame.depth_mm[centre], 720);
}

#[test]
fn noise_matches_its_model_on_a_flat_table() {
    let table_z = 0.0;
    let empty = Scene {
        table_z,
        table_half: [2.0, 2.0],
        objects: Vec::new(),
        scenario: Scenario::Isolated,
        seed: 0,
    };
    let camera = top_down(table_z, 1.0);
    let clean = render(&empty, &camera, None);
    let model = NoiseModel::default();
    let noisy = render(&empty, &camera, Some((&model, &mut SplitMix64::new(4))));
    let errors: Vec<f64> = clean
        .depth_mm
        .iter()
        .zip(&noisy.depth_mm)
        .filter(|(c, n)| **c > 0 && **n > 0)
        .map(|(c, n)| (f64::from(*n) - f64::from(*c)) / 1000.0)
        .collect();
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let sd = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    // sigma(1 m) = 1.88 mm, plus the 1 mm quantisation of both frames (~0.41 mm rms).
    let expected = (model.sigma_m(1.0).powi(2) + 2.0 * 0.001f64.powi(2) / 12.0).sqrt();
    assert!(mean.abs() < 5e-5, "mean error {mean}");
    assert!((sd / expected - 1.0).abs() < 0.05, "sd {sd} vs {expected}");
    // A flat table has no depth edges: nothing is dropped.
    assert_eq!(errors.len(), clean.depth_mm.iter().filter(|&&d| d > 0).count());
}

#[test]
fn the_same_seed_renders_the_same_frame() {
    let scene = Scene::generate(Scenario::Packed, 11, &Family::ALL).unwrap();
    let camera = Camera::random(
        &mut SplitMix64::new(11),
        Vector3::new(0.0, 0.0, f64::from(scene.table_z)),
        false,
    );
    let model = NoiseModel::default();
    let a = render(&scene, &camera, Some((&model, &mut SplitMix64::new(2))));
    let b = render(&scene, &camera, Some((&model, &mut SplitMix64::new(2))));
    let c = render(&scene, &camera, Some((&model, &mut SplitMix64::new(3))));
    assert_eq!(a.depth_mm, b.depth_mm);
    assert_ne!(a.depth_mm, c.depth_mm);
    assert_eq!(a.labels, c.labels, "labels come from the noiseless geometry");
}

#[test]
fn cameras_stay_in_the_recommended_range() {
    let mut rng = SplitMix64::new(9);
    let target = Vector3::new(0.1, -0.2, 0.7);
    for _ in 0..200 {
        let c = Camera::random(&mut rng, target, false);
        let offset = c.world_from_camera.translation.vector - target;
        let d = offset.norm();
        let elevation = (offset.z / d).asin().to_degrees();
        assert!((0.6..=1.2).contains(&d), "{d}");
        assert!((30.0..=60.0).contains(&elevation), "{elevation}");
        // It looks at the target: the optical axis passes through it.
        let axis = c.world_from_camera.rotation * Vector3::z();
        assert!((axis.dot(&(-offset / d)) - 1.0).abs() < 1e-9);
    }
}
