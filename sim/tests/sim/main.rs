//! The simulated camera against analytic shapes, its noise, and the planner's
//! pipeline on simulated frames.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{GraspNet, MomentsNet, PlanOptions, Planner, PlannerConfig};
use mvgrasp_sim::camera::{Camera, Frame, NoiseModel, render};
use mvgrasp_sim::objects::{Catalog, Family, ObjectModel};
use mvgrasp_sim::scene::{PlacedObject, Scenario, Scene};
use nalgebra::Vector3;
use parry3d::math::{Pose, Vector};
use parry3d::shape::SharedShape;

fn one_object(table_z: f32, model: ObjectModel, x: f32, y: f32) -> Scene {
    let pose = Pose::from_translation(Vector::new(x, y, table_z));
    Scene {
        table_z,
        table_half: [0.6, 0.5],
        objects: vec![PlacedObject {
            world_aabb: model.shape.compute_aabb(&pose),
            model,
            world_from_object: pose,
        }],
        scenario: Scenario::Isolated,
        seed: 0,
    }
}

fn top_down(table_z: f32, height_m: f64) -> Camera {
    let target = Vector3::new(0.0, 0.0, f64::from(table_z));
    Camera::looking_at(
        target + Vector3::new(0.0, -1e-4, height_m),
        target,
        640,
        480,
        600.0,
    )
}

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

/// A scene of `families` from `seed` and a noisy frame of it from a
/// random camera (both drawn from `seed + 100`).
fn noisy_frame(scenario: Scenario, seed: u64, families: &[Family]) -> (Scene, Frame) {
    let scene = Scene::generate(scenario, seed, families).unwrap();
    let mut rng = SplitMix64::new(seed + 100);
    let camera = Camera::random(&mut rng, Vector3::new(0.0, 0.0, f64::from(scene.table_z)), false);
    let frame = render(&scene, &camera, Some((&NoiseModel::default(), &mut rng)));
    (scene, frame)
}

/// The planner's pipeline finds the objects of simulated, noisy frames.
#[test]
fn the_pipeline_finds_simulated_objects() {
    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
    let (mut visible, mut found) = (0, 0);
    for (scenario, seeds) in [(Scenario::Isolated, 0..8u64), (Scenario::Clutter, 0..3)] {
        for seed in seeds {
            let (scene, frame) = noisy_frame(scenario, seed, &Family::ALL);
            let z = f64::from(scene.table_z);
            let bytes = frame.depth_le_bytes();
            let input = frame.scene_input(&bytes, scene.workspace());
            let plan = planner.plan(&input, &PlanOptions::default(), &mut net).unwrap();
            // Objects with at least 200 pixels in view, more than 1 cm above the table.
            for (_, centroid) in frame.visible_centroids(scene.objects.len(), z, 0.01, 200) {
                visible += 1;
                let near = plan
                    .objects
                    .iter()
                    .any(|o| (o.frame.world_from_object.translation.vector - centroid.coords).norm() < 0.02);
                found += usize::from(near);
                if scenario == Scenario::Isolated {
                    assert!(near, "isolated seed {seed}: the object was not found");
                    assert_eq!(plan.objects.len(), 1, "isolated seed {seed}");
                }
            }
        }
    }
    let share = found as f64 / visible as f64;
    println!(
        "found {found} of {visible} visible objects ({:.0}%)",
        share * 100.0
    );
    assert!(share >= 0.85, "found {found} of {visible} visible objects");
}

/// Isolated mugs and bottles, where the crease split cuts a handle or a
/// neck off at its concave root: step 6 of the split joins such parts
/// back. On these 24 scenes the split alone leaves 11 as one detection and
/// the default 15 (clustering alone: 20; the 5 still cut are handles seen
/// in front of their mug, across a depth step of 15-25 mm, which step 6
/// leaves apart as it would a small object in front of another).
#[test]
fn a_mug_s_handle_or_a_bottle_s_neck_cut_off_by_the_crease_split_joins_it_again() {
    let contract = MomentsNet::default().contract().clone();
    let planner = |crease| mvgrasp_sim::eval::planner_with_crease(crease, &contract).unwrap();
    let (split_only, default) = (planner("split-only"), planner("on"));
    let (mut whole_split_only, mut whole_default, mut scenes) = (0, 0, 0);
    for family in [Family::Mug, Family::Bottle] {
        for seed in 0..12u64 {
            let (scene, frame) = noisy_frame(Scenario::Isolated, seed, &[family]);
            let bytes = frame.depth_le_bytes();
            let input = frame.scene_input(&bytes, scene.workspace());
            let (a, b) = (
                split_only.segment(&input).unwrap(),
                default.segment(&input).unwrap(),
            );
            assert!(
                b.clusters.len() <= a.clusters.len(),
                "{family:?} seed {seed}: step 6 only joins"
            );
            assert_eq!(a.points.len(), b.points.len());
            scenes += 1;
            whole_split_only += usize::from(a.clusters.len() == 1);
            whole_default += usize::from(b.clusters.len() == 1);
        }
    }
    println!("one detection: split only {whole_split_only}, default {whole_default} of {scenes}");
    assert!(
        whole_default >= whole_split_only + 3,
        "{whole_default} vs {whole_split_only}"
    );
}

mod grasp_labels {
    use mvgrasp_sim::grasp::{GraspLabel, GripperModel, HandPart, Obstacle, label_grasp};
    use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3 as V3};

    use super::*;

    /// A top-down grasp at height `z` closing along world `closing` (unit, horizontal).
    pub fn top_down_grasp(x: f64, y: f64, z: f64, closing: V3<f64>) -> Isometry3<f64> {
        let approach = V3::new(0.0, 0.0, -1.0);
        let y_axis = approach.cross(&closing);
        let r = Rotation3::from_basis_unchecked(&[closing, y_axis, approach]);
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_rotation_matrix(&r),
        )
    }

    /// A 6 x 4 x 10 cm box (x by y by z) standing at the origin of a table at z = 0.
    pub fn box_scene(size: [f32; 3]) -> Scene {
        let model = ObjectModel::from_parts(
            Family::Box,
            vec![(
                Pose::from_translation(Vector::new(0.0, 0.0, size[2] / 2.0)),
                SharedShape::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0),
            )],
        );
        one_object(0.0, model, 0.0, 0.0)
    }

    #[test]
    fn across_the_narrow_side_holds() {
        let scene = box_scene([0.06, 0.04, 0.10]);
        let g = GripperModel::robotiq_2f_140();
        // Fingertips 4 cm below the top (z = 0.06): the whole pad on the box,
        // closing along y (4 cm).
        let label = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, 0.06, V3::y()), 0.04, &g);
        let GraspLabel::Positive {
            score,
            contact_width_m,
        } = label
        else {
            panic!("{label:?}");
        };
        assert!((contact_width_m - 0.04).abs() < 1e-3, "{contact_width_m}");
        assert!((score - 1.0).abs() < 1e-6, "{score}");
        // Only 2 cm in: 3 of the pad's 5 rows touch, so it scores less
        // (coverage weighs 0.4: 0.4 * 0.6 + 0.4 + 0.2).
        let shallow = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, 0.08, V3::y()), 0.04, &g);
        assert!(
            matches!(shallow, GraspLabel::Positive { score, .. } if (score - 0.84).abs() < 1e-6),
            "{shallow:?}"
        );
        // Across the 6 cm side holds too.
        assert!(label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, 0.08, V3::x()), 0.06, &g).is_positive());
    }

    #[test]
    fn the_weight_off_the_closing_line_twists_it() {
        // A 40 x 8 x 8 cm bar lying along x (1 kg): gripped across its
        // 8 cm side, the torque grows with the distance from its middle.
        let scene = box_scene([0.40, 0.08, 0.08]);
        let g = GripperModel::robotiq_2f_140();
        let weight = scene.objects[0].model.mass_kg * 9.81;
        let at = |x: f64| label_grasp(&scene, 0, &top_down_grasp(x, 0.0, 0.04, V3::y()), 0.08, &g);
        let score = |label: GraspLabel| match label {
            GraspLabel::Positive { score, .. } => score,
            other => panic!("{other:?}"),
        };
        let (middle, near) = (score(at(0.0)), score(at(0.03)));
        assert!((middle - 1.0).abs() < 1e-6 && near < middle, "{middle} {near}");
        // The limit (0.6 N m) is reached limit / weight from the middle.
        let limit = f64::from(g.max_torque_nm / weight);
        assert!(limit > 0.03 && limit < 0.15, "{limit}");
        assert!(score(at(limit - 0.005)) > 0.8);
        let twisted = at(limit + 0.005);
        assert!(
            matches!(twisted, GraspLabel::Twists { torque_nm } if torque_nm > g.max_torque_nm),
            "{twisted:?}"
        );
    }

    #[test]
    fn faces_turned_past_the_cone_are_not_antipodal() {
        // The 4 cm side turned 15 degrees off the closing direction is
        // within the 20 degree cone; 25 degrees is not (it was under the
        // 26.6 degree cone of sim-4, and held in 0.47 of physics trials).
        let scene = box_scene([0.06, 0.04, 0.10]);
        let g = GripperModel::robotiq_2f_140();
        let turned = |deg: f64| {
            let a = deg.to_radians();
            label_grasp(
                &scene,
                0,
                &top_down_grasp(0.0, 0.0, 0.06, V3::new(-a.sin(), a.cos(), 0.0)),
                0.06,
                &g,
            )
        };
        assert!(turned(15.0).is_positive(), "{:?}", turned(15.0));
        let label = turned(25.0);
        assert!(
            matches!(label, GraspLabel::NotAntipodal { worst_angle_deg } if (worst_angle_deg - 25.0).abs() < 1.0),
            "{label:?}"
        );
    }

    #[test]
    fn edges_wide_sides_air_and_the_table_do_not() {
        let scene = box_scene([0.06, 0.04, 0.10]);
        let g = GripperModel::robotiq_2f_140();
        // Closing along the diagonal: the pads meet the vertical edges at 45+ degrees.
        let diagonal = V3::new(1.0, 1.0, 0.0).normalize();
        let label = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, 0.08, diagonal), 0.07, &g);
        assert!(
            matches!(label, GraspLabel::NotAntipodal { worst_angle_deg } if worst_angle_deg > 30.0),
            "{label:?}"
        );
        // Wider than the stroke.
        let wide = box_scene([0.20, 0.16, 0.10]);
        let label = label_grasp(&wide, 0, &top_down_grasp(0.0, 0.0, 0.08, V3::y()), 0.16, &g);
        assert_eq!(label, GraspLabel::TooWide);
        assert_eq!(label.reason(), "too wide");
        // Beside the object: the pads close on air.
        let label = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.2, 0.08, V3::y()), 0.04, &g);
        assert_eq!(label, GraspLabel::Missed);
        assert_eq!(label.reason(), "missed");
        // So low the fingertips are in the table.
        let label = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, -0.005, V3::y()), 0.04, &g);
        assert!(
            matches!(
                &label,
                GraspLabel::Collision {
                    obstacle: Obstacle::Table,
                    ..
                }
            ),
            "{label:?}"
        );
        assert!(label.reason().starts_with("table: "), "{}", label.reason());
        // 1 cm above the table the pads clear it, but the palm meets the box top.
        let label = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, 0.01, V3::y()), 0.04, &g);
        assert!(
            matches!(
                &label,
                GraspLabel::Collision {
                    obstacle: Obstacle::Target,
                    part: HandPart::Palm
                }
            ),
            "{label:?}"
        );
        assert_eq!(label.reason(), "object: palm");
    }

    /// A 12-sided prism of radius 4 cm and height 10 cm standing at the
    /// origin (a mug's body is such a polygon), vertices at 0, 30, ... degrees.
    fn prism_scene() -> Scene {
        let ring = |z: f32| {
            (0..12).map(move |k| {
                let a = (k as f32 * 30.0).to_radians();
                Vector::new(0.04 * a.cos(), 0.04 * a.sin(), z)
            })
        };
        let points: Vec<Vector> = ring(0.0).chain(ring(0.10)).collect();
        let model = ObjectModel::from_parts(
            Family::Mug,
            vec![(Pose::IDENTITY, SharedShape::convex_hull(&points).expect("a hull"))],
        );
        one_object(0.0, model, 0.0, 0.0)
    }

    #[test]
    fn a_compliant_pad_on_a_polygons_vertex_pushes_along_its_own_normal() {
        // Closing at 0-29 degrees from a vertex: the pads first touch the
        // vertices at 0 and 180 degrees, between faces whose normals lie
        // 15 degrees either side of them. Where the first ray lands on the
        // face more than 20 degrees off, today's label calls the grasp not
        // antipodal; a pad that gives 3 mm feels both faces and pushes
        // along the mean of their normals.
        let scene = prism_scene();
        let stiff = GripperModel::robotiq_2f_140();
        let compliant = GripperModel {
            pad_compliance_m: 0.003,
            ..stiff
        };
        let mut turned_away = 0;
        for deg in 0..30 {
            let a = f64::from(deg).to_radians();
            let grasp = top_down_grasp(0.0, 0.0, 0.07, V3::new(a.cos(), a.sin(), 0.0));
            let (before, after) = (
                label_grasp(&scene, 0, &grasp, 0.085, &stiff),
                label_grasp(&scene, 0, &grasp, 0.085, &compliant),
            );
            if let GraspLabel::NotAntipodal { worst_angle_deg } = before {
                assert!(
                    worst_angle_deg > 20.0 && worst_angle_deg < 31.0,
                    "{deg}: {worst_angle_deg}"
                );
                assert!(after.is_positive(), "{deg} degrees: {after:?}");
                turned_away += 1;
            } else {
                assert!(before.is_positive(), "{deg} degrees: {before:?}");
            }
        }
        assert!(turned_away >= 3, "{turned_away}");
        // A box's 90 degree edge is no polygon's: closing along the diagonal
        // stays not antipodal with the compliant pad.
        let boxed = box_scene([0.06, 0.04, 0.10]);
        let diagonal = V3::new(1.0, 1.0, 0.0).normalize();
        let label = label_grasp(
            &boxed,
            0,
            &top_down_grasp(0.0, 0.0, 0.08, diagonal),
            0.07,
            &compliant,
        );
        assert!(matches!(label, GraspLabel::NotAntipodal { .. }), "{label:?}");
    }

    #[test]
    fn a_neighbour_in_the_way_is_a_collision() {
        let mut scene = box_scene([0.06, 0.04, 0.10]);
        // A second box 3 cm beside the first along y, inside the pads' opening path.
        let other = scene.objects[0].clone();
        let pose = Pose::from_translation(Vector::new(0.0, 0.055, 0.0));
        scene.objects.push(PlacedObject {
            world_aabb: other.model.shape.compute_aabb(&pose),
            world_from_object: pose,
            ..other
        });
        let g = GripperModel::robotiq_2f_140();
        let label = label_grasp(&scene, 0, &top_down_grasp(0.0, 0.0, 0.08, V3::y()), 0.04, &g);
        assert!(
            matches!(
                &label,
                GraspLabel::Collision {
                    obstacle: Obstacle::Neighbour(1),
                    ..
                }
            ),
            "{label:?}"
        );
        assert!(label.reason().starts_with("neighbour: "), "{}", label.reason());
    }
}

mod targets {
    use mvgrasp_core::{Channel, ViewAxis};
    use mvgrasp_sim::grasp::GripperModel;
    use mvgrasp_sim::targets::{Opening, TargetConfig, label_frame};

    use super::*;

    fn labelled(size: [f32; 3]) -> Vec<mvgrasp_sim::targets::LabelledView> {
        labelled_with(size, &TargetConfig::default())
    }

    fn labelled_with(size: [f32; 3], config: &TargetConfig) -> Vec<mvgrasp_sim::targets::LabelledView> {
        let model = ObjectModel::from_parts(
            Family::Box,
            vec![(
                Pose::from_translation(Vector::new(0.0, 0.0, size[2] / 2.0)),
                SharedShape::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0),
            )],
        );
        let scene = one_object(0.2, model, 0.0, 0.0);
        let target = Vector3::new(0.0, 0.0, 0.2);
        let camera = Camera::looking_at(target + Vector3::new(0.5, -0.4, 0.5), target, 640, 480, 600.0);
        let mut rng = SplitMix64::new(1);
        let frame = render(&scene, &camera, Some((&NoiseModel::default(), &mut rng)));
        let net = MomentsNet::default();
        let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
        label_frame(
            &scene,
            &frame,
            &planner,
            &GripperModel::robotiq_2f_140(),
            config,
            &mut rng,
        )
        .unwrap()
    }

    #[test]
    fn the_pads_opening_reaches_past_the_silhouette_over_the_pads_strip() {
        // A disc of radius 10 px centred at (20.5, 20.5) in a 41 px view.
        let l = 41;
        let image: Vec<f32> = (0..l * l)
            .map(|i| {
                let (x, y) = ((i % l) as f64 - 20.0, (i / l) as f64 - 20.0);
                if x * x + y * y <= 100.0 { 0.5 } else { 0.0 }
            })
            .collect();
        let across = (1.0, 0.0);
        let chord = |x, y| Opening::Chord.width_px(&image, l, x, y, across, 8.0);
        let pads = |x, y| Opening::Pads.width_px(&image, l, x, y, across, 8.0);
        // Through the centre (pixels 10..=30 of row 20; the half-pixel
        // steps reach 10 px right and 10.5 px left): the middle row is the
        // widest in the strip, so the pads need its wider side twice.
        assert_eq!(chord(20.5, 20.5), 21.5);
        assert_eq!(pads(20.5, 20.5), 22.0);
        // 6 px right of the centre the chord is the same, but the pads,
        // symmetric about the pixel, must clear the 16.5 px to its left.
        assert_eq!(chord(26.5, 20.5), 21.5);
        assert_eq!(pads(26.5, 20.5), 34.0);
        // 8 px below the centre the chord through the pixel (row 28, pixels
        // 14..=26) is short; the strip, 4 px either side, holds row 24
        // (pixels 11..=29).
        assert_eq!(chord(20.5, 28.5), 13.5);
        assert_eq!(pads(20.5, 28.5), 20.0);
        assert_eq!("pads".parse::<Opening>().unwrap(), Opening::Pads);
        assert!(
            "wide"
                .parse::<Opening>()
                .unwrap_err()
                .to_string()
                .contains("chord or pads")
        );
    }

    #[test]
    fn candidates_opened_over_the_pads_start_outside_a_box_and_lose_no_positive() {
        let size = [0.06, 0.04, 0.10];
        let chord = labelled(size);
        let pads = labelled_with(
            size,
            &TargetConfig {
                opening: Opening::Pads,
                ..TargetConfig::default()
            },
        );
        let pad_hits =
            |v: &mvgrasp_sim::targets::LabelledView| v.refused.get("object: pad").copied().unwrap_or(0);
        for (c, p) in chord.iter().zip(&pads) {
            assert_eq!(
                (c.axis, c.candidates),
                (p.axis, p.candidates),
                "the same views and candidates"
            );
            println!(
                "{:?}: positives {} -> {}, pad on the object {} -> {}",
                c.axis,
                c.positives,
                p.positives,
                pad_hits(c),
                pad_hits(p)
            );
        }
        // Off the chord's middle the pads now start outside the box: the
        // refusals for a pad in the object all but vanish (top 125 -> 0,
        // front 219 -> 9, side 258 -> 0 when written), and no view loses a
        // positive.
        for (c, p) in chord.iter().zip(&pads) {
            assert!(
                pad_hits(p) * 10 <= pad_hits(c),
                "{:?}: {} vs {}",
                c.axis,
                pad_hits(p),
                pad_hits(c)
            );
            assert!(
                p.positives >= c.positives,
                "{:?}: {} vs {}",
                c.axis,
                p.positives,
                c.positives
            );
        }
    }

    #[test]
    fn a_graspable_box_gets_consistent_targets_and_a_wide_one_none_from_above() {
        let contract = MomentsNet::default().contract().clone();
        let l = contract.input_size_px;
        let (q, c, s, w) = (
            contract.channel_index(Channel::Quality),
            contract.channel_index(Channel::Cos2Phi),
            contract.channel_index(Channel::Sin2Phi),
            contract.channel_index(Channel::Width),
        );
        let views = labelled([0.06, 0.04, 0.10]);
        assert_eq!(views.len(), 3, "top, front and side views of the one object");
        for v in &views {
            println!(
                "{:?}: {} of {} candidates positive",
                v.axis, v.positives, v.candidates
            );
        }
        let top = views.iter().find(|v| v.axis == ViewAxis::Top).unwrap();
        assert!(
            top.positives > 20,
            "{} of {} candidates",
            top.positives,
            top.candidates
        );
        for view in &views {
            assert_eq!(view.object, 0);
            assert_eq!(view.grasps.len(), view.positives);
            // Every candidate is a positive or refused for a named reason.
            let refused: usize = view.refused.values().sum();
            assert_eq!(view.positives + refused, view.candidates, "{:?}", view.refused);
            for g in &view.grasps {
                // Each positive is painted at its own pixel, at least as high.
                let i = g.v * l + g.u;
                assert!(view.maps[q * l * l + i] >= g.quality && g.quality > 0.0);
                assert!(g.phi.abs() <= std::f32::consts::FRAC_PI_2 + 1e-6, "{}", g.phi);
                assert!(g.width_m > 0.0 && g.width_m <= 0.14, "{}", g.width_m);
            }
            for i in 0..l * l {
                let quality = view.maps[q * l * l + i];
                let (cos2, sin2, width) = (
                    view.maps[c * l * l + i],
                    view.maps[s * l * l + i],
                    view.maps[w * l * l + i],
                );
                assert!((0.0..=1.0).contains(&quality));
                if quality > 0.0 {
                    assert!((cos2 * cos2 + sin2 * sin2 - 1.0).abs() < 1e-4);
                    let width_m = width * contract.width_scale_m;
                    assert!(width_m > 0.0 && width_m <= 0.14, "{width_m}");
                    assert!(
                        view.image[i] > 0.0 || quality < 1.0,
                        "painted only on or next to the object"
                    );
                } else {
                    assert_eq!((cos2, sin2, width), (0.0, 0.0, 0.0));
                }
            }
        }
        // 20 x 16 cm seen from above: both ways across exceed the 14 cm stroke.
        let wide = labelled([0.20, 0.16, 0.10]);
        let top = wide.iter().find(|v| v.axis == ViewAxis::Top).unwrap();
        assert_eq!(top.positives, 0, "of {} candidates", top.candidates);
        // And the labeller says so: most candidates are wider than the stroke.
        let most = top.refused.iter().max_by_key(|(_, n)| **n).map(|(why, _)| *why);
        assert_eq!(most, Some("over stroke"), "{:?}", top.refused);
    }
}

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

/// A shard's `meta.jsonl`, a value per view.
fn meta_lines(shard: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(shard.join("meta.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
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
fn datagen_refuses_a_pad_compliance_outside_0_to_20_mm_and_records_it() {
    use mvgrasp_sim::Error;
    use mvgrasp_sim::dataset::{DATA_VERSION, DatagenConfig, data_version_of, generate};
    use mvgrasp_sim::targets::TargetConfig;

    let out = std::env::temp_dir().join(format!("mvgrasp-datagen-pad-{}", std::process::id()));
    let contract = MomentsNet::default().contract().clone();
    let config = |pad_compliance_m| DatagenConfig {
        targets: TargetConfig {
            pad_compliance_m,
            ..TargetConfig::default()
        },
        ..small_datagen(1, 41, Scenario::Isolated, &[Family::Mug])
    };
    for bad in [-0.001, 0.025, f32::NAN] {
        let _ = std::fs::remove_dir_all(&out);
        match generate(&out, &contract, &config(bad), false) {
            Err(Error::Invalid {
                field: "pad compliance",
                ..
            }) => {}
            other => panic!("{bad}: {other:?}"),
        }
        assert!(!out.exists(), "nothing written for a refused compliance");
    }
    assert_eq!(data_version_of(&TargetConfig::default()), DATA_VERSION);
    let pad = TargetConfig {
        pad_compliance_m: 0.003,
        ..TargetConfig::default()
    };
    assert_eq!(data_version_of(&pad), format!("{DATA_VERSION}+pad-3mm"));
    let tenth = TargetConfig {
        pad_compliance_m: 0.0001,
        ..TargetConfig::default()
    };
    assert_eq!(data_version_of(&tenth), format!("{DATA_VERSION}+pad-0.1mm"));
    let manifest = datagen_into(&out, &config(0.003));
    let recorded = manifest["gripper"]["pad_compliance_m"].as_f64().unwrap();
    assert!((recorded - 0.003).abs() < 1e-6, "{recorded}");
    // Without compliance the manifest's gripper is sim-6's, key for key.
    let manifest = datagen_into(&out, &config(0.0));
    assert!(
        manifest["gripper"].get("pad_compliance_m").is_none(),
        "{}",
        manifest["gripper"]
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

mod physics {
    use mvgrasp_sim::grasp::{GraspLabel, GripperModel, label_grasp};
    use mvgrasp_sim::physics::{Basket, TrialConfig, TrialOutcome, rest_to_rest, run_trial, trial};
    use nalgebra::Vector3 as V3;

    use super::grasp_labels::{box_scene, top_down_grasp};
    use super::*;

    #[test]
    fn the_carry_speeds_up_and_slows_down_within_its_acceleration() {
        let (speed, accel, dt) = (0.5f32, 1.0f32, 1.0 / 240.0);
        for length in [0.0f32, 0.003, 0.1, 0.8] {
            let path: Vec<f32> = std::iter::once(0.0)
                .chain(rest_to_rest(length, speed, accel, dt))
                .collect();
            assert!(
                (path.last().unwrap() - length).abs() < 1e-6,
                "{length}: ends at {:?}",
                path.last()
            );
            let v: Vec<f32> = std::iter::once(0.0)
                .chain(path.windows(2).map(|w| (w[1] - w[0]) / dt))
                .chain(std::iter::once(0.0))
                .collect();
            assert!(v.iter().all(|&v| v <= speed + 1e-4), "{length}: over speed");
            // Speed changes by at most accel * dt per step, both ways (the
            // last step rounds onto the end: 1e-5 m of slack).
            let worst = v.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0f32, f32::max);
            assert!(
                worst <= accel * dt * 1.01 + 1e-5 / dt,
                "{length}: {worst} m/s in one step"
            );
        }
        // 0.8 m: 0.5 s up to speed (0.125 m), 0.55 m cruising, 0.5 s down: 2.1 s.
        let steps = rest_to_rest(0.8, speed, accel, dt).count() as f32;
        assert!((steps * dt - 2.1).abs() < 0.02, "{} s", steps * dt);
    }

    #[test]
    fn a_narrow_side_grasp_lifts_and_a_grasp_over_a_ball_does_not() {
        let g = GripperModel::robotiq_2f_140();
        let config = TrialConfig::default();
        // Positive analytically and in physics: across the 4 cm side, 4 cm deep.
        let scene = box_scene([0.06, 0.04, 0.10]);
        let grasp = top_down_grasp(0.0, 0.0, 0.06, V3::y());
        assert!(label_grasp(&scene, 0, &grasp, 0.04, &g).is_positive());
        let outcome = trial(&scene, 0, &grasp, 0.04, &g, &config);
        assert!(
            matches!(outcome, TrialOutcome::Held { lifted_m } if lifted_m > 0.14),
            "{outcome:?}"
        );
        // Negative both ways: pads meeting a 4 cm ball 6 mm below its top,
        // where its surface faces up at about 55 degrees.
        let ball = ObjectModel::from_parts(
            Family::Ellipsoid,
            vec![(
                Pose::from_translation(Vector::new(0.0, 0.0, 0.04)),
                SharedShape::ball(0.04),
            )],
        );
        let scene = one_object(0.0, ball, 0.0, 0.0);
        let grasp = top_down_grasp(0.0, 0.0, 0.074, V3::y());
        assert!(matches!(
            label_grasp(&scene, 0, &grasp, 0.04, &g),
            GraspLabel::NotAntipodal { .. }
        ));
        let outcome = trial(&scene, 0, &grasp, 0.04, &g, &config);
        assert!(!outcome.is_held(), "{outcome:?}");
        // Nothing between the pads: no grip.
        let scene = box_scene([0.06, 0.04, 0.10]);
        let outcome = trial(
            &scene,
            0,
            &top_down_grasp(0.0, 0.2, 0.06, V3::y()),
            0.04,
            &g,
            &config,
        );
        assert_eq!(outcome, TrialOutcome::NoGrip);
    }

    #[test]
    fn a_held_box_is_carried_over_its_neighbour_into_the_basket() {
        let g = GripperModel::robotiq_2f_140();
        let basket = Basket::default();
        let config = TrialConfig {
            carry: Some(basket),
            ..TrialConfig::default()
        };
        // The box, and a 25 cm tall box between it and the basket (at y = -0.75).
        let mut scene = box_scene([0.06, 0.04, 0.10]);
        let mut tall = box_scene([0.05, 0.05, 0.25]).objects.remove(0);
        tall.world_from_object.translation.y -= 0.3;
        tall.world_aabb = tall.model.aabb_at(&tall.world_from_object);
        scene.objects.push(tall);
        let grasp = top_down_grasp(0.0, 0.0, 0.06, V3::y());
        let result = run_trial(&scene, 0, &grasp, 0.04, &g, &config);
        assert!(result.outcome.is_held(), "{:?}", result.outcome);
        let [bx, by] = basket.centre_xy;
        let box_at = result.poses[0].translation;
        assert!(
            (box_at.x - bx).abs() < basket.inner_half_m && (box_at.y - by).abs() < basket.inner_half_m,
            "the box rests at {box_at:?}, the basket is at ({bx}, {by})"
        );
        assert!(box_at.z < scene.table_z + 0.1, "the box was let go: {box_at:?}");
        // Carried over the tall one, not through it: it did not move.
        let tall_moved =
            (result.poses[1].translation - scene.objects[1].world_from_object.translation).length();
        assert!(tall_moved < 0.002, "the neighbour moved {tall_moved} m");
        // A grasp that never grips leaves the scene where it was.
        let missed = run_trial(
            &scene,
            0,
            &top_down_grasp(0.0, 0.2, 0.06, V3::y()),
            0.04,
            &g,
            &config,
        );
        assert_eq!(missed.outcome, TrialOutcome::NoGrip);
        let box_moved =
            (missed.poses[0].translation - scene.objects[0].world_from_object.translation).length();
        assert!(box_moved < 0.002, "the box moved {box_moved} m");
    }
}

mod eval {
    use mvgrasp_core::{
        CreaseConfig, GraspNet, MomentsNet, Planner, PlannerConfig, Reattach, Repairs, ViewAxis, ViewPolicy,
    };
    use mvgrasp_sim::camera::Camera;
    use mvgrasp_sim::camera::Frame;
    use mvgrasp_sim::eval::{
        Attempt, CollisionSite, End, Episode, EpisodeConfig, Failure, GraspSource, InProcess, PlannedGrasp,
        Setting, Summary, collision_list, crease_setting, crease_text, episode_bootstrap, episode_record,
        episode_scene, horizontal_lever_m, label_table, markdown_table, object_tilt_deg,
        objects_outside_view, pose_name, provenance_table, run_episode, same_grasp, square_turn_setting,
    };
    use mvgrasp_sim::grasp::{HandPart, Obstacle, pose_of, weight_torque_nm};
    use mvgrasp_sim::objects::Family;
    use mvgrasp_sim::scene::Scenario;
    use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

    /// An episode's camera holds every object whole when one of its draws
    /// does; the count says which objects it would cut.
    #[test]
    fn episode_cameras_hold_every_object() {
        let catalog = mvgrasp_sim::objects::Catalog::of(&Family::ALL);
        let (mut held, mut redrawn) = (0, 0);
        for seed in 900_000..900_006 {
            let (scene, camera) = episode_scene(Scenario::Clutter, seed, &catalog).unwrap();
            // The first draw, as the episode's camera was before 2026-11-24.
            let mut rng =
                mvgrasp_core::rng::SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xE7A1);
            let first = Camera::random(&mut rng, Vector3::new(0.0, 0.0, f64::from(scene.table_z)), false);
            let outside = objects_outside_view(&scene, &camera);
            assert!(outside <= objects_outside_view(&scene, &first));
            held += usize::from(outside == 0);
            redrawn += usize::from(camera.world_from_camera != first.world_from_camera);
            // Every object the camera holds projects inside the image: its
            // rendered pixels never touch the border.
            let frame = mvgrasp_sim::camera::render(&scene, &camera, None);
            let (w, h) = (camera.width as usize, camera.height as usize);
            let touching = (0..scene.objects.len())
                .filter(|&i| {
                    frame.labels.iter().enumerate().any(|(p, &l)| {
                        usize::from(l) == i + 2
                            && (p % w == 0 || p % w == w - 1 || p / w == 0 || p / w == h - 1)
                    })
                })
                .count();
            assert!(
                touching <= outside,
                "seed {seed}: {touching} objects at the border, {outside} outside"
            );
        }
        // 15-20 objects over 0.8 x 0.64 m: the first draw often cuts some.
        assert!(redrawn > 0 && held >= 5, "redrawn {redrawn}, held {held} of 6");
        // Moved 3 m away, an object is outside any camera's view.
        let (mut scene, camera) = episode_scene(Scenario::Isolated, 900_000, &catalog).unwrap();
        assert_eq!(objects_outside_view(&scene, &camera), 0);
        let o = &mut scene.objects[0];
        o.world_from_object.translation.x += 3.0;
        o.world_aabb = o.model.aabb_at(&o.world_from_object);
        assert_eq!(objects_outside_view(&scene, &camera), 1);
    }

    /// `eval.json`'s per-episode record: the books and every attempt.
    #[test]
    fn an_episode_record_keeps_the_books_and_each_attempt() {
        // Straight down (grasp z = world -z), then level (grasp z = world x).
        let down = Isometry3::from_parts(
            nalgebra::Translation3::new(0.1, 0.2, 0.05),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        );
        let level = Isometry3::from_parts(
            nalgebra::Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
        );
        let e = Episode {
            scenario: Scenario::Pile,
            seed: 900_003,
            objects: 5,
            removed: 1,
            fell_off: 1,
            attempts: vec![
                Attempt {
                    plan_ms: 12.345,
                    world_from_grasp: down,
                    width_m: 0.0614,
                    quality: 0.71234,
                    failure: None,
                    collision: None,
                    label: Some(("positive", Family::Box)),
                    view: ViewAxis::Top,
                    pixel: [36, 40],
                    repairs: Repairs {
                        squared: true,
                        deepened: true,
                        ..Repairs::default()
                    },
                    centroid_lever_m: 0.01234,
                    torque_nm: Some(0.04567),
                    tilt_deg: Some(91.26),
                },
                Attempt {
                    plan_ms: 9.0,
                    world_from_grasp: level,
                    width_m: 0.08,
                    quality: 0.5,
                    failure: Some(Failure::CollisionOnApproach),
                    collision: Some(CollisionSite {
                        obstacle: Obstacle::Neighbour(0),
                        part: HandPart::Palm,
                        on_the_way_in: true,
                    }),
                    label: None,
                    view: ViewAxis::Front,
                    pixel: [10, 71],
                    repairs: Repairs::default(),
                    centroid_lever_m: 0.0,
                    torque_nm: None,
                    tilt_deg: None,
                },
                Attempt {
                    plan_ms: 8.0,
                    world_from_grasp: down,
                    width_m: 0.1,
                    quality: 0.4,
                    failure: Some(Failure::SlipDuringLift),
                    collision: None,
                    label: Some(("not antipodal", Family::Mug)),
                    view: ViewAxis::Side,
                    pixel: [0, 0],
                    repairs: Repairs::default(),
                    centroid_lever_m: 0.05,
                    torque_nm: Some(0.3),
                    tilt_deg: None,
                },
            ],
            end: End::NoGraspAboveTau,
            last_plan_ms: Some(7.0),
        };
        let r = episode_record(&e, "all:0.1");
        assert_eq!(r["scenario"], "pile");
        assert_eq!(r["setting"], "all:0.1");
        assert_eq!(r["seed"], 900_003);
        assert_eq!(
            (
                r["objects"].as_u64(),
                r["removed"].as_u64(),
                r["fell_off"].as_u64()
            ),
            (Some(5), Some(1), Some(1))
        );
        assert_eq!(r["end"], "no grasp above tau");
        let a = r["attempts"].as_array().unwrap();
        assert_eq!(a.len(), 3);
        assert_eq!(
            a[0],
            serde_json::json!([
                "ok",
                0.712,
                61.4,
                90.0,
                12.35,
                "positive",
                "box",
                "top",
                [36, 40],
                12.3,
                0.046,
                ["squared", "deepened"],
                91.3
            ])
        );
        // No physics trial: no label, family or torque.
        assert!(
            a[1][5].is_null() && a[1][6].is_null() && a[1][10].is_null(),
            "{}",
            a[1]
        );
        assert_eq!(
            (&a[1][7], &a[1][8]),
            (&"front".into(), &serde_json::json!([10, 71]))
        );
        assert_eq!(a[1][11], serde_json::json!([]));
        assert!(a[1][12].is_null(), "{}", a[1]);
        assert_eq!(
            a[1][0],
            format!(
                "collision on approach: {}",
                e.attempts[1].collision.unwrap().name()
            )
        );
        assert_eq!(a[1][3], 0.0);
        assert_eq!(a[2][0], Failure::SlipDuringLift.name());
        assert_eq!((&a[2][5], &a[2][6]), (&"not antipodal".into(), &"mug".into()));
        assert_eq!(
            (&a[2][7], &a[2][9], &a[2][10]),
            (&"side".into(), &50.0.into(), &0.3.into())
        );
    }

    #[test]
    fn settings_parse_and_bad_ones_say_why() {
        let s = Setting::parse("top-down:0.9").unwrap();
        assert_eq!((s.policy, s.tau), (ViewPolicy::TopDown, 0.9));
        assert_eq!(Setting::parse(&s.name()).unwrap(), s);
        for (bad, why) in [
            ("entropy", "POLICY:TAU"),
            ("entropy:x", "tau"),
            ("entropy:1.5", "outside"),
            ("sideways:0.8", "not a view policy"),
        ] {
            let err = Setting::parse(bad).unwrap_err().to_string();
            assert!(err.contains(why), "{bad}: {err}");
        }
    }

    #[test]
    fn square_turn_settings_within_a_quarter_turn_only() {
        for ok in [0.0, 15.0, 35.0, 90.0] {
            assert_eq!(square_turn_setting(ok).unwrap(), ok);
        }
        for bad in [-1.0, 90.5, f64::NAN, f64::INFINITY] {
            let e = square_turn_setting(bad).unwrap_err().to_string();
            assert!(e.contains("square-turn-deg") && e.contains("0-90"), "{bad}: {e}");
        }
    }

    #[test]
    fn crease_settings_parse_and_bad_ones_say_why() {
        assert_eq!(crease_setting("on").unwrap(), Some(CreaseConfig::default()));
        assert_eq!(crease_setting("off").unwrap(), None);
        let c = crease_setting("3:8:4.5:0.25:120").unwrap().unwrap();
        assert_eq!(
            (c.smooth_radius_px, c.baseline_px, c.min_part_points),
            (3, 8, 120)
        );
        assert!((c.min_valley_m - 0.0045).abs() < 1e-7 && (c.min_valley_ratio - 0.25).abs() < 1e-7);
        assert_eq!(
            c.reattach,
            Some(Reattach::default()),
            "five fields keep step 6's defaults"
        );
        let split_only = crease_setting("split-only").unwrap().unwrap();
        assert_eq!(
            split_only,
            CreaseConfig {
                reattach: None,
                ..CreaseConfig::default()
            }
        );
        let r = crease_setting("2:6:5:0.4:200:15:0.25:0.2:12")
            .unwrap()
            .unwrap()
            .reattach
            .unwrap();
        assert!((r.max_area_m2 - 0.0015).abs() < 1e-7 && (r.max_step_m - 0.012).abs() < 1e-7);
        assert!((r.max_share - 0.25).abs() < 1e-7 && (r.min_outline_share - 0.2).abs() < 1e-7);
        let off = crease_setting("2:6:5:0.4:200:0:0.3:0.15:20").unwrap().unwrap();
        assert_eq!(off.reattach, None, "an area of 0 turns step 6 off");
        for text in [
            "on",
            "off",
            "split-only",
            "3:8:4.5:0.25:120",
            "2:6:5:0.4:200:15:0.25:0.2:12",
        ] {
            let config = crease_setting(text).unwrap();
            let back = crease_setting(&crease_text(config.as_ref())).unwrap();
            assert_eq!(back, config, "{text} -> {}", crease_text(config.as_ref()));
        }
        for (bad, why) in [
            ("maybe", "SMOOTH_PX:BASELINE_PX"),
            ("2:6:5:0.4", "SMOOTH_PX:BASELINE_PX"),
            ("2:6:5:0.4:200:20", "AREA_CM2:SHARE:OUTLINE:STEP_MM"),
            ("2:6:5:0.4:200:20:0.3:0.15:x", "step"),
            ("2:0:5:0.4:200", "at least 1 px"),
            ("2:6:-5:0.4:200", "valley depth"),
            ("2:6:5:nan:200", "ratio"),
            ("2.5:6:5:0.4:200", "smoothing radius"),
        ] {
            let err = crease_setting(bad).unwrap_err().to_string();
            assert!(err.contains(why), "{bad}: {err}");
        }
    }

    #[test]
    fn episodes_keep_their_books_and_end_by_the_rules() {
        let mut net = MomentsNet::default();
        let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
        let config = EpisodeConfig::default();
        let setting = Setting::parse("entropy:0.3").unwrap();
        let mut attempts = 0;
        for (scenario, seed) in [
            (Scenario::Isolated, 900_000),
            (Scenario::Isolated, 900_001),
            (Scenario::Packed, 900_000),
            (Scenario::Pile, 900_000),
        ] {
            let mut run = || {
                let mut source = InProcess {
                    planner: &planner,
                    net: &mut net,
                };
                run_episode(scenario, seed, &setting, &mut source, &config).unwrap()
            };
            let e = run();
            // Same seed, same episode: scenes, cameras and noise are fixed by the seed.
            let again = run();
            let outcomes = |e: &Episode| {
                let tried: Vec<_> = e.attempts.iter().map(|a| (a.quality, a.failure)).collect();
                (e.removed, e.fell_off, e.end, tried)
            };
            assert_eq!(outcomes(&e), outcomes(&again));
            assert_eq!(e.removed, e.successes());
            assert!(e.removed + e.fell_off <= e.objects);
            assert!(e.attempts.len() <= 2 * e.objects + 3);
            let tail = e
                .attempts
                .iter()
                .rev()
                .take_while(|a| a.failure.is_some())
                .count();
            match e.end {
                End::Cleared => assert_eq!(e.removed + e.fell_off, e.objects),
                End::ConsecutiveFailures => assert_eq!(tail, 3),
                End::NoGraspAboveTau => assert!(e.last_plan_ms.is_some()),
                End::AttemptLimit => assert_eq!(e.attempts.len(), 2 * e.objects + 3),
            }
            assert!(e.attempts.iter().all(|a| a.quality >= 0.3 && a.plan_ms > 0.0));
            attempts += e.attempts.len();
        }
        assert!(attempts > 0, "the baseline tried no grasp at all");
    }

    /// `run_episode_with` planning in process with `planner` and `net`.
    fn hooked_episode(
        planner: &Planner,
        net: &mut dyn GraspNet,
        (scenario, seed, setting): (Scenario, u64, &Setting),
        config: &EpisodeConfig,
        hook: &mut dyn FnMut(usize, &mvgrasp_sim::scene::Scene, &Frame),
    ) -> Episode {
        let mut source = InProcess { planner, net };
        mvgrasp_sim::eval::run_episode_with(scenario, seed, setting, &mut source, config, hook).unwrap()
    }

    /// `sim eval --attempt-views`: keeping the views changes nothing about
    /// the episode, every attempt gets the view its grasp came from (the
    /// network reads the attempt's smoothed quality at its pixel there), and the
    /// files hold one row per attempt.
    #[test]
    fn each_attempt_keeps_the_view_its_grasp_came_from() {
        use mvgrasp_core::{Channel, ViewBatch};
        use mvgrasp_sim::eval::{ViewKeeping, write_attempt_views};

        let mut net = MomentsNet::default();
        let contract = net.contract().clone();
        let l = contract.input_size_px;
        let planner = Planner::new(PlannerConfig::default(), contract.clone()).unwrap();
        let config = EpisodeConfig::default();
        let setting = Setting::parse("all:0.1").unwrap();
        let (scenario, seed) = (Scenario::Pile, 900_000);
        let plain = hooked_episode(
            &planner,
            &mut net,
            (scenario, seed, &setting),
            &config,
            &mut |_, _, _| {},
        );
        let mut keeping = ViewKeeping::new(InProcess {
            planner: &planner,
            net: &mut net,
        });
        let kept = run_episode(scenario, seed, &setting, &mut keeping, &config).unwrap();
        let outcomes = |e: &Episode| {
            let tried: Vec<_> = e
                .attempts
                .iter()
                .map(|a| (a.quality, a.failure, a.pixel, a.world_from_grasp))
                .collect();
            (e.removed, e.fell_off, e.end, tried)
        };
        assert_eq!(outcomes(&kept), outcomes(&plain));
        assert!(kept.attempts.len() >= 3, "{} attempts", kept.attempts.len());
        let rows = keeping.rows(&kept, &[], 0, &config).unwrap();
        assert_eq!(rows.len(), kept.attempts.len(), "every attempt has its view");
        assert!(
            rows.iter()
                .enumerate()
                .all(|(k, r)| r.step == k && !r.alternative)
        );
        let views: Vec<Vec<f32>> = rows.iter().map(|r| r.view.to_vec()).collect();
        let mut again = MomentsNet::default();
        let q = contract.channel_index(Channel::Quality);
        for (a, view) in kept.attempts.iter().zip(&views) {
            assert_eq!(view.len(), l * l);
            let maps = again
                .infer(&ViewBatch {
                    size_px: l,
                    len: 1,
                    data: view.clone(),
                })
                .unwrap();
            // The planner peaks on the smoothed quality map.
            let quality = mvgrasp_core::decode::smooth(
                &maps.data[q * l * l..(q + 1) * l * l],
                l,
                l,
                planner.config().decode.smoothing_sigma_px,
            );
            let [u, v] = a.pixel.map(|p| p as usize);
            let at = quality[v * l + u];
            assert!(
                (at - a.quality).abs() < 1e-5,
                "quality {} at the pixel, {} planned",
                at,
                a.quality
            );
        }
        assert!(
            keeping.rows(&kept, &[], 1, &config).is_err(),
            "alternatives need the frames' scenes"
        );
        let out = std::env::temp_dir().join(format!("mvgrasp-attempt-views-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        let mut short = rows[1].clone();
        short.view = &short.view[1..];
        let err = write_attempt_views(&out, (scenario, seed), &[short], l).unwrap_err();
        assert!(err.to_string().contains(&format!("not {l} x {l}")), "{err}");
        let rows = write_attempt_views(&out, (scenario, seed), &rows[1..], l).unwrap();
        assert_eq!(rows, kept.attempts.len() - 1);
        let stem = out.join(format!("attempts_pile_{seed}"));
        let records: Vec<serde_json::Value> =
            serde_json::from_str(&std::fs::read_to_string(stem.with_extension("json")).unwrap()).unwrap();
        assert_eq!(records.len(), rows);
        for (r, (step, a)) in records.iter().zip(kept.attempts.iter().enumerate().skip(1)) {
            assert_eq!(r["step"], step);
            assert_eq!(r["alternative"], false);
            assert_eq!(r["pixel"], serde_json::json!(a.pixel));
            assert_eq!(r["outcome"], a.outcome_name());
            assert_eq!(r["view"], a.view.name());
        }
        let npy = std::fs::read(stem.with_extension("npy")).unwrap();
        let header = String::from_utf8_lossy(&npy[10..npy.len().min(128)]).into_owned();
        assert!(header.contains(&format!("({rows}, {l}, {l})")), "{header}");
        assert_eq!(
            npy.len() % 64,
            (4 * rows * l * l) % 64,
            "header padded to 64 bytes"
        );
        let first = &npy[npy.len() - 4 * rows * l * l..][..4 * l * l];
        let back: Vec<f32> = first
            .chunks(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert_eq!(back, views[1]);
        std::fs::remove_dir_all(&out).unwrap();
    }

    /// The planner's grasps, with the one of rank `rank` moved first on the
    /// first frame only.
    struct RankedFirst<'a> {
        inner: InProcess<'a>,
        rank: usize,
        calls: usize,
    }

    impl GraspSource for RankedFirst<'_> {
        fn grasps(
            &mut self,
            frame: &Frame,
            workspace: mvgrasp_core::Workspace,
            options: &mvgrasp_core::PlanOptions,
        ) -> mvgrasp_sim::Result<Vec<PlannedGrasp>> {
            let mut grasps = self.inner.grasps(frame, workspace, options)?;
            if self.calls == 0 {
                let moved = grasps.remove(self.rank);
                grasps.insert(0, moved);
            }
            self.calls += 1;
            Ok(grasps)
        }
    }

    /// `sim eval --attempt-alternatives`: the grasps ranked below each tried
    /// one are tried from the frame's scene without changing the episode,
    /// and each comes to what the episode records when the planner ranks it
    /// first.
    #[test]
    fn alternatives_end_as_the_episode_would_with_them_first() {
        use mvgrasp_sim::eval::ViewKeeping;

        let mut net = MomentsNet::default();
        let contract = net.contract().clone();
        let l = contract.input_size_px;
        // This pile comes apart into several objects (several grasps ranked
        // below each tried one) with the crease split on.
        let planner = mvgrasp_sim::eval::planner_with_crease("on", &contract).unwrap();
        let config = EpisodeConfig::default();
        let setting = Setting::parse("all:0.1").unwrap();
        let (scenario, seed) = (Scenario::Pile, 900_000);
        let plain = run_episode(
            scenario,
            seed,
            &setting,
            &mut InProcess {
                planner: &planner,
                net: &mut net,
            },
            &config,
        )
        .unwrap();
        let mut keeping = ViewKeeping::new(InProcess {
            planner: &planner,
            net: &mut net,
        });
        let mut scenes = Vec::new();
        let kept = mvgrasp_sim::eval::run_episode_with(
            scenario,
            seed,
            &setting,
            &mut keeping,
            &config,
            &mut |_, scene, _| scenes.push(scene.clone()),
        )
        .unwrap();
        let outcome = |a: &Attempt| {
            (
                a.failure,
                a.collision,
                a.label,
                a.quality,
                a.pixel,
                a.world_from_grasp,
            )
        };
        assert_eq!(
            kept.attempts.iter().map(outcome).collect::<Vec<_>>(),
            plain.attempts.iter().map(outcome).collect::<Vec<_>>()
        );
        let rows = keeping.rows(&kept, &scenes, 2, &config).unwrap();
        let own: Vec<_> = rows.iter().filter(|r| !r.alternative).collect();
        assert_eq!(own.len(), kept.attempts.len());
        let alternatives: Vec<_> = rows.iter().filter(|r| r.alternative).collect();
        assert!(alternatives.len() >= 4, "{} alternatives", alternatives.len());
        for r in &alternatives {
            let tried = own.iter().find(|o| o.step == r.step).unwrap();
            assert!(!same_grasp(
                &tried.attempt.world_from_grasp,
                &r.attempt.world_from_grasp
            ));
            assert!(r.rank > tried.rank, "ranked below the tried grasp");
            assert_eq!(r.view.len(), l * l);
        }
        assert!(
            (0..kept.attempts.len()).all(|step| rows
                .iter()
                .filter(|r| r.step == step && r.alternative)
                .count()
                <= 2),
            "at most 2 per frame"
        );
        assert!(rows.windows(2).all(|w| w[0].step <= w[1].step), "in frame order");
        // The first frame's alternatives, ranked first: the episode's first
        // attempt ends exactly as the alternative did.
        let first: Vec<_> = alternatives.iter().filter(|r| r.step == 0).collect();
        assert!(!first.is_empty());
        let mut net = MomentsNet::default();
        for r in first {
            let rank = r.rank;
            let forced = run_episode(
                scenario,
                seed,
                &setting,
                &mut RankedFirst {
                    inner: InProcess {
                        planner: &planner,
                        net: &mut net,
                    },
                    rank,
                    calls: 0,
                },
                &config,
            )
            .unwrap();
            assert_eq!(outcome(&forced.attempts[0]), outcome(&r.attempt), "rank {rank}");
        }
    }

    /// `sim eval --label-frames`: every frame the planner gets is shown to
    /// the hook in step order without changing the episode, and a
    /// `FrameLabeller` writes them as a dataset whose views name their
    /// frame.
    #[test]
    fn episode_frames_are_labelled_as_datagen_labels_scenes() {
        use mvgrasp_sim::dataset::{DatagenConfig, FrameLabeller};

        let mut net = MomentsNet::default();
        let contract = net.contract().clone();
        let planner = Planner::new(PlannerConfig::default(), contract.clone()).unwrap();
        let config = EpisodeConfig::default();
        let setting = Setting::parse("all:0.1").unwrap();
        let (scenario, seed) = (Scenario::Pile, 900_000);
        let out = std::env::temp_dir().join(format!("mvgrasp-frames-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        let datagen = DatagenConfig {
            scenes: 1,
            seed,
            scenarios: vec![scenario],
            catalog: config.catalog.clone(),
            scenes_per_shard: 1,
            targets: mvgrasp_sim::targets::TargetConfig::default(),
            noise: config.noise,
            data_version: "test".into(),
            label_salt: 0,
        };
        assert!(
            FrameLabeller::new(&out, contract.clone(), datagen.clone(), 0, serde_json::json!({})).is_err()
        );
        let labeller = FrameLabeller::new(
            &out,
            contract,
            datagen,
            2,
            serde_json::json!({"setting": setting.name()}),
        )
        .unwrap();
        let (mut steps, mut views, mut objects) = (Vec::new(), Vec::new(), Vec::new());
        let labelled = hooked_episode(
            &planner,
            &mut net,
            (scenario, seed, &setting),
            &config,
            &mut |step, scene, frame| {
                steps.push(step);
                objects.push(scene.objects.len());
                if labeller.wants(step) {
                    views.extend(labeller.label(&planner, (scenario, seed, step), scene, frame));
                }
            },
        );
        let plain = {
            let mut source = InProcess {
                planner: &planner,
                net: &mut net,
            };
            run_episode(scenario, seed, &setting, &mut source, &config).unwrap()
        };
        let outcomes = |e: &Episode| {
            let tried: Vec<_> = e
                .attempts
                .iter()
                .map(|a| (a.quality, a.failure, a.pixel))
                .collect();
            (e.removed, e.fell_off, e.end, tried)
        };
        assert_eq!(outcomes(&labelled), outcomes(&plain));
        assert!(
            labelled.attempts.len() >= 3,
            "{} attempts",
            labelled.attempts.len()
        );
        // One frame before each attempt, and one more if the episode ended on
        // a frame without a grasp to try.
        let frames = labelled.attempts.len() + usize::from(labelled.end == End::NoGraspAboveTau);
        assert_eq!(steps, (0..frames).collect::<Vec<_>>());
        // Objects only leave: the frames after a removal show fewer.
        assert!(objects.windows(2).all(|w| w[1] <= w[0]), "{objects:?}");
        assert!(objects.last() < objects.first(), "{objects:?}");
        // Every second frame labelled: steps 0, 2, ...
        let mut labelled_steps: Vec<usize> = views.iter().filter_map(|v| v.step).collect();
        labelled_steps.dedup();
        assert_eq!(labelled_steps, (0..frames).step_by(2).collect::<Vec<_>>());
        assert!(views.iter().any(|v| v.view.positives > 0));
        labeller.write_episode(scenario, seed, &views).unwrap();
        let report = labeller.finish().unwrap();
        assert_eq!((report.views, report.shards), (views.len(), 1));
        assert!(report.failed.is_empty(), "{:?}", report.failed);
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
        assert_eq!(manifest["views"], views.len());
        assert_eq!(manifest["frames_from"]["every"], 2);
        assert_eq!(manifest["frames_from"]["setting"], "all:0.1");
        assert_eq!(manifest["shards"][0], "shard_pile_900000");
        let meta = super::meta_lines(&out.join("shard_pile_900000"));
        assert_eq!(meta.len(), views.len());
        for (line, v) in meta.iter().zip(&views) {
            let step = v.step.unwrap();
            assert_eq!(line["step"], step);
            assert_eq!(line["instance"], format!("pile-{seed}.{step}:{}", v.view.object));
        }
        let _ = std::fs::remove_dir_all(&out);
    }

    /// `sim eval --judge`: a grasp tried from a frame's state by
    /// `grasp_outcome` ends as the episode's own attempt on that frame did,
    /// and leaves the scene as it was; the tallies count and table it.
    #[test]
    fn a_judged_grasp_ends_as_the_episode_s_attempt_did() {
        use mvgrasp_sim::eval::{JudgeTally, grasp_outcome, judge_table, plan_options};

        let mut net = MomentsNet::default();
        let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
        let config = EpisodeConfig::default();
        let setting = Setting::parse("all:0.1").unwrap();
        let (mut compared, mut failures) = (0, 0);
        for (scenario, seed) in [(Scenario::Packed, 900_001), (Scenario::Packed, 900_002)] {
            let options = plan_options(&setting, seed, &config.gripper);
            let mut judged = Vec::new();
            let mut twin = MomentsNet::default();
            let episode = hooked_episode(
                &planner,
                &mut net,
                (scenario, seed, &setting),
                &config,
                &mut |_, scene, frame| {
                    let before: Vec<_> = scene.objects.iter().map(|o| o.world_from_object).collect();
                    let mut judge = InProcess {
                        planner: &planner,
                        net: &mut twin,
                    };
                    let best = judge.grasps(frame, scene.workspace(), &options).unwrap();
                    judged.push(
                        best.first()
                            .map(|g| (g.world_from_grasp, grasp_outcome(scene, g, &config))),
                    );
                    let after: Vec<_> = scene.objects.iter().map(|o| o.world_from_object).collect();
                    assert_eq!(before, after, "judging moved the scene");
                },
            );
            // Where the episode tried the judge's grasp (no earlier failure
            // made it take another), both end the same way.
            for (attempt, judged) in episode.attempts.iter().zip(&judged) {
                let Some((pose, outcome)) = judged else { continue };
                if same_grasp(pose, &attempt.world_from_grasp) {
                    assert_eq!(*outcome, attempt.failure, "{} {seed}", scenario.name());
                    compared += 1;
                    failures += usize::from(outcome.is_some());
                }
            }
        }
        assert!(
            compared >= 4 && failures >= 2,
            "{compared} compared, {failures} failed"
        );

        let mut tally = JudgeTally::default();
        tally.add(Some(Some(None)));
        tally.add(Some(Some(Some(Failure::SlipDuringLift))));
        tally.add(Some(None));
        tally.add(None);
        assert_eq!(
            (
                tally.frames,
                tally.tried(),
                tally.held,
                tally.no_grasp,
                tally.errors
            ),
            (4, 2, 1, 1, 1)
        );
        let mut all = JudgeTally::default();
        all.merge(&tally);
        all.merge(&tally);
        assert_eq!((all.frames, all.held, all.failures[1]), (8, 2, 2));
        let table = judge_table(&[("pile".into(), "m.onnx".into(), tally)]);
        assert!(table.contains("| pile | m.onnx | 4 (1 planning errors) | 1 | 2 | 1 | 0.25 (1/4) | 0.50 (1/2) | slip during lift 1 |"), "{table}");
        assert!(judge_table(&[]).is_empty());
        let names: Vec<&str> = [
            None,
            Some(None),
            Some(Some(None)),
            Some(Some(Some(Failure::ObjectMissed))),
        ]
        .into_iter()
        .map(JudgeTally::outcome_name)
        .collect();
        assert_eq!(names, ["planning error", "no grasp", "held", "object missed"]);
    }

    /// Plans the same ranked list for every frame.
    struct Scripted(Vec<PlannedGrasp>);

    impl GraspSource for Scripted {
        fn grasps(
            &mut self,
            _: &Frame,
            _: mvgrasp_core::Workspace,
            options: &mvgrasp_core::PlanOptions,
        ) -> mvgrasp_sim::Result<Vec<PlannedGrasp>> {
            Ok(self.0.iter().take(options.max_grasps).cloned().collect())
        }
    }

    #[test]
    fn a_refused_grasp_is_not_tried_again_in_an_unchanged_scene() {
        // Two grasps over empty table, 5 cm apart: neither matches an
        // object, so the scene never moves.
        let at = |x: f64| PlannedGrasp {
            world_from_grasp: Isometry3::translation(x, -0.45, 0.1),
            width_m: 0.05,
            quality: 0.9,
            object_centroid: Point3::new(x, -0.45, 0.1),
            view: ViewAxis::Front,
            pixel: [3, 4],
            repairs: Repairs::default(),
        };
        let mut source = Scripted(vec![at(0.5), at(0.55)]);
        let setting = Setting::parse("all:0.1").unwrap();
        let e = run_episode(
            Scenario::Isolated,
            900_000,
            &setting,
            &mut source,
            &EpisodeConfig::default(),
        )
        .unwrap();
        let tried: Vec<f64> = e
            .attempts
            .iter()
            .map(|a| a.world_from_grasp.translation.x)
            .collect();
        assert_eq!(tried, vec![0.5, 0.55]);
        assert!(
            e.attempts
                .iter()
                .all(|a| a.failure == Some(Failure::ObjectMissed))
        );
        // Where each came from is kept; no object matched, so no trial,
        // torque or tilt.
        assert!(
            e.attempts.iter().all(|a| a.view == ViewAxis::Front
                && a.pixel == [3, 4]
                && a.torque_nm.is_none()
                && a.tilt_deg.is_none()),
            "{:?}",
            e.attempts
        );
        assert_eq!(e.end, End::NoGraspAboveTau);
    }

    #[test]
    fn a_grasp_that_failed_in_physics_is_not_tried_again_until_an_object_is_taken() {
        // Two top-down grasps 30 cm over the isolated object, 5 cm apart,
        // matched to it by their centroid: each passes the approach check,
        // closes on air in the physics trial and leaves the scene as it was.
        let config = EpisodeConfig::default();
        let (scene, _) = episode_scene(Scenario::Isolated, 900_000, &config.catalog).unwrap();
        let aabb = scene.objects[0].world_aabb;
        let centre = (aabb.mins + aabb.maxs) * 0.5;
        let centroid = Point3::new(f64::from(centre.x), f64::from(centre.y), f64::from(centre.z));
        let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let over = |dx: f64| PlannedGrasp {
            world_from_grasp: Isometry3::from_parts(
                (centroid.coords + Vector3::new(dx, 0.0, 0.3)).into(),
                down,
            ),
            width_m: 0.05,
            quality: 0.9,
            object_centroid: centroid,
            view: ViewAxis::Top,
            pixel: [36, 36],
            repairs: Repairs::default(),
        };
        let mut source = Scripted(vec![over(0.0), over(0.05)]);
        let setting = Setting::parse("all:0.1").unwrap();
        let e = run_episode(Scenario::Isolated, 900_000, &setting, &mut source, &config).unwrap();
        let tried: Vec<f64> = e
            .attempts
            .iter()
            .map(|a| a.world_from_grasp.translation.x - centroid.x)
            .collect();
        assert_eq!(tried.len(), 2, "{tried:?}");
        assert!(
            tried[0].abs() < 1e-9 && (tried[1] - 0.05).abs() < 1e-9,
            "{tried:?}"
        );
        // Both ran the trial (a label, no approach collision) and failed.
        assert!(
            e.attempts
                .iter()
                .all(|a| a.failure.is_some() && a.collision.is_none() && a.label.is_some()),
            "{:?}",
            e.attempts
        );
        assert_eq!(e.end, End::NoGraspAboveTau);
        assert_eq!(e.removed, 0);
        // Each trial records the weight's torque at the grasp as planned, in
        // the scene as it stood: the first in the episode's scene, the second
        // in the scene the first trial left (settled; it barely moved).
        let torque = |dx: f64| weight_torque_nm(&scene.objects[0], &pose_of(&over(dx).world_from_grasp));
        assert_eq!(e.attempts[0].torque_nm, Some(torque(0.0)));
        let second = e.attempts[1].torque_nm.expect("a trial ran");
        assert_eq!(e.attempts[0].tilt_deg, Some(object_tilt_deg(&scene.objects[0])));
        assert!((second - torque(0.05)).abs() < 0.01, "{second} {}", torque(0.05));
        // The closing line (world x) runs through the centroid the planner
        // saw, so the lever it saw is zero.
        assert!(
            e.attempts.iter().all(|a| a.centroid_lever_m < 1e-9),
            "{:?}",
            e.attempts
        );
    }

    #[test]
    fn tilt_is_the_angle_of_the_objects_own_up_from_the_worlds() {
        let config = EpisodeConfig::default();
        let (scene, _) = episode_scene(Scenario::Isolated, 900_000, &config.catalog).unwrap();
        let mut object = scene.objects[0].clone();
        for (turn, tilt, pose) in [
            (0.0, 0.0, "upright"),
            (0.4, 22.918_31, "upright"),
            (std::f32::consts::FRAC_PI_2, 90.0, "toppled"),
            (2.7, 154.6986, "upside down"),
            (std::f32::consts::PI, 180.0, "upside down"),
        ] {
            // Any turn about the world's up keeps the tilt.
            object.world_from_object.rotation = parry3d::math::Rotation::from_rotation_z(1.0)
                * parry3d::math::Rotation::from_rotation_x(turn);
            let got = object_tilt_deg(&object);
            assert!((got - tilt).abs() < 1e-3, "{turn}: {got}");
            assert_eq!(pose_name(got), pose, "{turn}: {got}");
        }
    }

    #[test]
    fn the_lever_is_the_horizontal_distance_to_the_closing_line() {
        // Closing along world x through the origin: only the offset across
        // it, horizontally, counts (not along it, not up or down).
        let along_x = Isometry3::identity();
        assert!((horizontal_lever_m(&along_x, &Point3::new(0.3, 0.04, -0.2)) - 0.04).abs() < 1e-12);
        assert!((horizontal_lever_m(&along_x, &Point3::new(0.3, -0.04, 0.5)) - 0.04).abs() < 1e-12);
        // Turned 90 degrees about z and moved: closing along world y.
        let along_y = Isometry3::from_parts(
            nalgebra::Translation3::new(1.0, 2.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        );
        assert!((horizontal_lever_m(&along_y, &Point3::new(1.03, 2.5, 0.1)) - 0.03).abs() < 1e-12);
        // A vertical closing line: the weight has no torque about it.
        let vertical = Isometry3::from_parts(
            nalgebra::Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -std::f64::consts::FRAC_PI_2),
        );
        assert!(horizontal_lever_m(&vertical, &Point3::new(0.05, 0.05, 0.0)) < 1e-12);
    }

    #[test]
    fn provenance_counts_attempts_by_view_and_repair_and_trials_by_torque_and_lever() {
        let attempt = |view, failure, torque_nm: Option<f32>, lever_mm: f64| Attempt {
            plan_ms: 5.0,
            world_from_grasp: Isometry3::identity(),
            width_m: 0.05,
            quality: 0.5,
            failure,
            collision: None,
            label: torque_nm.map(|_| ("positive", Family::Box)),
            view,
            pixel: [0, 0],
            repairs: Repairs::default(),
            centroid_lever_m: lever_mm / 1e3,
            torque_nm,
            tilt_deg: torque_nm.map(|_| 5.0),
        };
        let slip = Some(Failure::SlipDuringLift);
        let episode = |attempts| Episode {
            scenario: Scenario::Packed,
            seed: 1,
            objects: 3,
            removed: 0,
            fell_off: 0,
            attempts,
            end: End::Cleared,
            last_plan_ms: None,
        };
        let episodes = [
            episode(vec![
                attempt(ViewAxis::Top, None, Some(0.01), 5.0),
                attempt(ViewAxis::Top, slip, Some(0.3), 25.0),
                attempt(ViewAxis::Top, Some(Failure::CollisionOnApproach), None, 3.0),
            ]),
            episode(vec![
                Attempt {
                    repairs: Repairs {
                        squared: true,
                        deepened: true,
                        ..Repairs::default()
                    },
                    tilt_deg: Some(90.0),
                    ..attempt(ViewAxis::Front, slip, Some(0.5), 45.0)
                },
                Attempt {
                    repairs: Repairs {
                        deepened: true,
                        ..Repairs::default()
                    },
                    ..attempt(ViewAxis::Top, None, Some(0.07), 12.0)
                },
                attempt(ViewAxis::Front, Some(Failure::ObjectMissed), None, 0.0),
            ]),
        ];
        let table = provenance_table(&episodes.iter().collect::<Vec<_>>());
        for row in [
            "| top | 4 | 0.50 (2/4) | 1 | 1 | 0 |",
            "| front | 2 | 0.00 (0/2) | 0 | 1 | 1 |",
            "| side | 0 | - | 0 | 0 | 0 |",
            // A grasp counts under each of its repairs.
            "| none (as decoded) | 4 | 0.25 (1/4) | 1 | 1 | 1 |",
            "| refit | 0 | - | 0 | 0 | 0 |",
            "| squared | 1 | 0.00 (0/1) | 0 | 1 | 0 |",
            "| deepened | 2 | 0.50 (1/2) | 0 | 1 | 0 |",
            "| 0-0.05 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
            "| 0.05-0.1 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
            "| 0.1-0.2 | 0 | - | - |",
            "| 0.2-0.4 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
            "| >= 0.4 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
            // Lever bins count the four physics trials only.
            "| 0-10 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
            "| 10-20 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
            "| 20-40 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
            "| >= 40 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
            // Slips by family and pose: three upright trials, one toppled.
            "| family | upright | toppled | upside down |",
            "| box | 0.33 (1/3) | 1.00 (1/1) | - |",
        ] {
            assert!(table.contains(row), "{row}\n{table}");
        }
        // Without physics trials only the views; without attempts nothing.
        let untried = [episode(vec![attempt(
            ViewAxis::Side,
            Some(Failure::ObjectMissed),
            None,
            0.0,
        )])];
        let views_only = provenance_table(&untried.iter().collect::<Vec<_>>());
        assert!(
            views_only.contains("| side | 1 | 0.00 (0/1) | 0 | 0 | 1 |"),
            "{views_only}"
        );
        assert!(!views_only.contains("torque"), "{views_only}");
        assert_eq!(provenance_table(&[&episode(Vec::new())]), "");
    }

    #[test]
    fn the_same_grasp_within_a_centimetre_and_15_degrees_either_way_round() {
        let a = Isometry3::translation(0.1, 0.2, 0.3);
        let turned = |deg: f64, axis: Vector3<f64>| {
            Isometry3::from_parts(
                a.translation,
                UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians()),
            )
        };
        assert!(same_grasp(&a, &a));
        assert!(same_grasp(&a, &Isometry3::translation(0.109, 0.2, 0.3)));
        assert!(!same_grasp(&a, &Isometry3::translation(0.111, 0.2, 0.3)));
        assert!(same_grasp(&a, &turned(14.0, Vector3::x())));
        assert!(!same_grasp(&a, &turned(16.0, Vector3::x())));
        // Jaws turned half round about the approach: the same grasp.
        assert!(same_grasp(&a, &turned(180.0, Vector3::z())));
        assert!(same_grasp(&a, &turned(170.0, Vector3::z())));
        assert!(!same_grasp(&a, &turned(90.0, Vector3::z())));
    }

    #[test]
    fn the_episode_bootstrap_brackets_the_rate_and_narrows_with_more_episodes() {
        assert!(episode_bootstrap(&[]).iter().all(|v| v.is_nan()));
        assert!(episode_bootstrap(&[(0, 0), (0, 0)]).iter().all(|v| v.is_nan()));
        // Every episode at 4 of 5: no spread at all.
        assert_eq!(episode_bootstrap(&[(4, 5); 16]), [0.8, 0.8]);
        // Episodes removing 2, 3, 4 or 5 of 5 in turn: the interval holds
        // the overall rate (0.7), and four times the episodes halve it
        // roughly (the bootstrap's 1 / sqrt(n)).
        let pairs = |n: usize| (0..n).map(|i| (2 + i % 4, 5)).collect::<Vec<_>>();
        let [lo16, hi16] = episode_bootstrap(&pairs(16));
        let [lo64, hi64] = episode_bootstrap(&pairs(64));
        assert!(lo16 < 0.7 && 0.7 < hi16, "{lo16} {hi16}");
        assert!(lo64 < 0.7 && 0.7 < hi64, "{lo64} {hi64}");
        let ratio = (hi16 - lo16) / (hi64 - lo64);
        assert!((1.6..2.5).contains(&ratio), "{ratio}");
        // Seeded: the same pairs, the same interval.
        assert_eq!(episode_bootstrap(&pairs(16)), [lo16, hi16]);
    }

    #[test]
    fn summaries_count_rates_and_causes() {
        let attempt = |failure| Attempt {
            plan_ms: 10.0,
            world_from_grasp: Isometry3::identity(),
            width_m: 0.05,
            quality: 0.9,
            failure,
            collision: None,
            label: None,
            view: ViewAxis::Top,
            pixel: [36, 36],
            repairs: Repairs::default(),
            centroid_lever_m: 0.0,
            torque_nm: None,
            tilt_deg: None,
        };
        let tried = |failure, label, family| Attempt {
            label: Some((label, family)),
            ..attempt(failure)
        };
        let collided = |obstacle, part, on_the_way_in| Attempt {
            collision: Some(CollisionSite {
                obstacle,
                part,
                on_the_way_in,
            }),
            ..attempt(Some(Failure::CollisionOnApproach))
        };
        let episodes = vec![
            Episode {
                scenario: Scenario::Packed,
                seed: 1,
                objects: 4,
                removed: 3,
                fell_off: 0,
                attempts: vec![
                    tried(None, "positive", Family::Cylinder),
                    tried(Some(Failure::SlipDuringLift), "not antipodal", Family::Box),
                    tried(None, "positive", Family::Box),
                    tried(None, "not antipodal", Family::Cylinder),
                ],
                end: End::NoGraspAboveTau,
                last_plan_ms: Some(30.0),
            },
            Episode {
                scenario: Scenario::Packed,
                seed: 2,
                objects: 5,
                removed: 0,
                fell_off: 1,
                attempts: vec![
                    Attempt {
                        plan_ms: 30.0,
                        ..collided(Obstacle::Neighbour(0), HandPart::Palm, true)
                    },
                    collided(Obstacle::Table, HandPart::LeftPad, false),
                    collided(Obstacle::Neighbour(0), HandPart::Palm, true),
                ],
                end: End::ConsecutiveFailures,
                last_plan_ms: None,
            },
        ];
        let s = Summary::of(
            Scenario::Packed,
            &Setting::parse("entropy:0.8").unwrap(),
            &episodes,
        );
        assert_eq!((s.attempts, s.successes, s.removed, s.objects), (7, 3, 3, 9));
        assert_eq!(s.fell_off, 1);
        assert!((s.success_rate() - 3.0 / 7.0).abs() < 1e-12);
        assert!((s.removal_rate() - 3.0 / 9.0).abs() < 1e-12);
        assert_eq!(s.failures, [3, 1, 0, 0]);
        let sites: Vec<(String, usize)> = s.collisions.iter().map(|(k, n)| (k.name(), *n)).collect();
        assert_eq!(
            sites,
            [
                ("the table (left pad), at the grasp".to_owned(), 1),
                ("a neighbour (palm), on the way in".to_owned(), 2)
            ]
        );
        let list = collision_list(std::slice::from_ref(&s));
        assert!(
            list.contains("- packed, entropy:0.8: a neighbour (palm), on the way in 2; the table (left pad), at the grasp 1"),
            "{list}"
        );
        assert_eq!((s.ended_without_grasp, s.cleared), (1, 0));
        // Nine planning times (seven of 10 ms, two of 30 ms): p50 10, p90 30.
        assert_eq!(s.plan_ms, [10.0, 30.0]);
        // Resampling the two episodes: both the first (removal 6/8), both
        // the second (0/10) or one of each (3/9), each both ways round.
        assert_eq!(s.removal_ci95, [0.0, 0.75]);
        assert_eq!(s.success_ci95, [0.0, 0.75]);
        let table = markdown_table(&[s]);
        assert!(
            table.contains("| packed | entropy:0.8 | 2 | 0.43 (3/7) | 0.33 (3/9) |"),
            "{table}"
        );
        assert!(table.contains("| 0.00-0.75; 0.00-0.75 |\n"), "{table}");
        // The labels against physics: only the four physics trials count,
        // families in catalogue order.
        let labels = label_table(&episodes.iter().collect::<Vec<_>>());
        for row in [
            "| label | every family | box | cylinder |",
            "| not antipodal | 0.50 (1/2) | 0.00 (0/1) | 1.00 (1/1) |",
            "| positive | 1.00 (2/2) | 1.00 (1/1) | 1.00 (1/1) |",
        ] {
            assert!(labels.contains(row), "{row}\n{labels}");
        }
        assert_eq!(label_table(&[&episodes[1]]), "");
    }
}

#[test]
fn snapshots_draw_a_grasp_where_the_camera_sees_it() {
    use mvgrasp_sim::files::write_grasp_snapshot;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    let table_z = 0.3;
    let scene = Scene {
        table_z,
        table_half: [0.6, 0.5],
        objects: Vec::new(),
        scenario: Scenario::Isolated,
        seed: 0,
    };
    let frame = render(&scene, &top_down(table_z, 1.0), None);
    let path = std::env::temp_dir().join(format!("mvgrasp-snapshot-{}.png", std::process::id()));
    // A 10 cm grasp on the table centre, closing along world x: seen from
    // 1 m above at 600 px focal length, its fingers are 60 px apart.
    let grasp = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, f64::from(table_z)),
        UnitQuaternion::identity(),
    );
    write_grasp_snapshot(&path, &frame, &[(grasp, 0.10, true)]).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgb).unwrap();
    let at = |x: usize, y: usize| &rgb[3 * (y * 640 + x)..3 * (y * 640 + x) + 3];
    let green = [40u8, 230, 60];
    let (cx, cy) = (320usize, 240usize);
    let greens: Vec<usize> = (0..640)
        .filter(|&x| at(x, cy) == green || at(x, cy - 1) == green)
        .collect();
    assert!(!greens.is_empty(), "no grasp drawn on the centre row");
    let span = greens.last().unwrap() - greens.first().unwrap();
    assert!(
        (60..=70).contains(&span),
        "fingers {span} px apart, expected about 60 (+ the end dots)"
    );
    assert!(greens.first().unwrap().abs_diff(cx - 30) <= 4);
    assert_eq!(
        at(100, 100),
        at(540, 380),
        "the table stays grey away from the grasp"
    );
    let _ = std::fs::remove_file(&path);
}

#[test]
fn detections_are_drawn_beside_the_labels() {
    use mvgrasp_core::{Segmentation, TablePlane};
    use mvgrasp_sim::camera::Frame;
    use mvgrasp_sim::files::write_detections;

    let (w, h) = (640usize, 480usize);
    // A flat frame 1 m away; object 0 (label 2) fills a 20 px square at
    // (100, 100), one reading is lost; one detection covers the square's
    // left half.
    let mut frame = Frame {
        camera: top_down(0.0, 1.0),
        depth_mm: vec![1000; w * h],
        labels: vec![1; w * h],
    };
    let square: Vec<usize> = (100..120)
        .flat_map(|y| (100..120).map(move |x| y * w + x))
        .collect();
    for &i in &square {
        frame.labels[i] = 2;
    }
    frame.depth_mm[300 * w + 300] = 0;
    let left: Vec<u32> = square
        .iter()
        .filter(|&&i| i % w < 110)
        .map(|&i| i as u32)
        .collect();
    let seg = Segmentation {
        table: TablePlane {
            normal: Vector3::z(),
            offset_m: 0.0,
            support: 1.0,
        },
        points: vec![[0.0; 3]; left.len()],
        clusters: vec![(0..left.len() as u32).collect()],
        pixels: left,
    };
    let path = std::env::temp_dir().join(format!("mvgrasp-detections-{}.png", std::process::id()));
    write_detections(&path, &frame, &[&seg]).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    assert_eq!(
        (reader.info().width, reader.info().height),
        (2 * w as u32, h as u32)
    );
    let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgb).unwrap();
    let at = |panel: usize, x: usize, y: usize| {
        let i = 3 * (y * 2 * w + panel * w + x);
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    };
    let grey = at(0, 50, 50);
    assert_eq!(grey[0], grey[1]);
    assert_eq!(grey, at(1, 50, 50), "the table is grey in both panels");
    assert_eq!(at(0, 300, 300), [0, 0, 0], "a lost reading is black");
    // Labels: the whole square in one colour.
    assert_ne!(at(0, 105, 105), grey);
    assert_eq!(at(0, 105, 105), at(0, 115, 115));
    // Detections: the left half in its own colour, the right half grey.
    assert_ne!(at(1, 105, 105), grey);
    assert_ne!(at(1, 105, 105), at(0, 105, 105));
    assert_eq!(at(1, 115, 115), grey);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn overlap_counts_merged_detections_and_split_objects() {
    use mvgrasp_core::{Segmentation, TablePlane};
    use mvgrasp_sim::camera::Frame;
    use mvgrasp_sim::overlap::Overlap;

    // Ten pixels of object 0 (label 2), ten of object 1 (label 3), one of
    // the table; every pixel a kept point.
    let labels: Vec<u16> = [vec![2; 10], vec![3; 10], vec![1]].concat();
    let frame = Frame {
        camera: top_down(0.0, 1.0),
        depth_mm: vec![1000; labels.len()],
        labels,
    };
    let seg = |clusters: Vec<Vec<u32>>| Segmentation {
        table: TablePlane {
            normal: Vector3::z(),
            offset_m: 0.0,
            support: 1.0,
        },
        points: vec![[0.0; 3]; 21],
        pixels: (0..21).collect(),
        clusters,
    };
    // Detection 0: object 0's first 5 pixels and all of object 1 (merged);
    // detection 1: object 0's other 5 and the table pixel. Object 0 is split.
    let o = Overlap::new(
        &frame,
        &seg(vec![
            (0..5).chain(10..20).collect(),
            (5..10).chain(20..21).collect(),
        ]),
    );
    assert_eq!(o.of_label[&2], 10);
    assert_eq!(o.of_detection, vec![15, 5], "the table pixel does not count");
    assert_eq!(o.merged(), 1);
    assert!(o.is_split(2));
    assert!(!o.is_split(3));
    // Object 0 in one detection with a pixel of object 1 (under 20%), object 1's
    // other nine unclustered: nothing merged or split, and object 1 still has
    // its ten kept pixels.
    let o = Overlap::new(&frame, &seg(vec![(0..11).collect()]));
    assert_eq!(o.merged(), 0);
    assert!(!o.is_split(2) && !o.is_split(3));
    assert_eq!(o.of_label[&3], 10);
    let mut shares = o.shares(3);
    shares.sort();
    assert_eq!(shares, vec![(0, 1)]);
}

mod meshes {
    use std::path::PathBuf;

    use mvgrasp_sim::mesh::load_meshes;

    use super::*;

    /// The sample meshes (`samples/meshes/make_meshes.py`).
    fn sample_meshes() -> Vec<PathBuf> {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../samples/meshes");
        ["u_channel.obj", "plus_prism.obj", "hex_nut.stl", "wedge.stl"]
            .iter()
            .map(|f| dir.join(f))
            .collect()
    }

    #[test]
    fn the_sample_meshes_load_with_their_volumes_and_make_every_scenario() {
        let meshes = load_meshes(&sample_meshes(), 1.0).unwrap();
        // Solid volumes from the drawings (m^3); the convex parts may bulge a little.
        let expected = [
            ("u_channel", 3.52e-4),
            ("plus_prism", 4.0e-4),
            ("hex_nut", 1.40e-4),
            ("wedge", 1.44e-4),
        ];
        for (m, (name, volume)) in meshes.iter().zip(expected) {
            assert_eq!(m.name, name);
            assert_eq!(m.family, Family::Mesh);
            let v: f32 = m.parts.iter().map(|(_, s)| s.mass_properties(1.0).mass()).sum();
            assert!(
                (v - volume).abs() < 0.2 * volume,
                "{name}: {v:.3e} m^3 in {} parts, drawn {volume:.3e}",
                m.parts.len()
            );
            assert!(
                (m.aabb.mins.z).abs() < 1e-4,
                "{name}: the origin is at the bottom"
            );
        }
        // The hole of the nut needs several convex parts around it.
        assert!(
            meshes[2].parts.len() >= 4,
            "hex_nut: {} parts",
            meshes[2].parts.len()
        );
        let catalog = Catalog {
            families: Vec::new(),
            meshes,
        };
        for scenario in Scenario::ALL {
            let scene = Scene::generate_from(scenario, 3, &catalog).unwrap();
            assert!(scene.objects.iter().all(|o| o.model.family == Family::Mesh));
            let camera = Camera::random(
                &mut SplitMix64::new(3),
                Vector3::new(0.0, 0.0, f64::from(scene.table_z)),
                true,
            );
            let frame = render(&scene, &camera, None);
            let seen = (0..scene.objects.len())
                .filter(|&i| frame.labels.contains(&(2 + i as u16)))
                .count();
            assert!(
                2 * seen >= scene.objects.len(),
                "{}: {seen} of {} mesh objects in view",
                scenario.name(),
                scene.objects.len()
            );
        }
    }

    #[test]
    fn a_catalog_without_meshes_draws_the_scenes_it_always_drew() {
        let before = Scene::generate(Scenario::Packed, 21, &Family::ALL).unwrap();
        let after = Scene::generate_from(Scenario::Packed, 21, &Catalog::of(&Family::ALL)).unwrap();
        let poses = |s: &Scene| -> Vec<[f32; 3]> {
            s.objects
                .iter()
                .map(|o| o.world_from_object.translation.to_array())
                .collect()
        };
        assert_eq!(poses(&before), poses(&after));
        let err = Scene::generate_from(Scenario::Packed, 21, &Catalog::default()).unwrap_err();
        assert!(err.to_string().contains("families"), "{err}");
    }
}
