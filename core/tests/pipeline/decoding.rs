//! Decoding a synthetic map with a known peak lands at the known 3D point,
//! angle and width, for every view direction and both camera sides.

use mvgrasp_core::decode::{DecodeConfig, ViewPlacement, decode_view};
use mvgrasp_core::object::object_frame;
use mvgrasp_core::{GraspMaps, Gripper, ModelContract, OrthoView, TablePlane, ViewAxis};
use nalgebra::{Point3, Vector3};

const YAW: f64 = 0.5;
const CENTER: [f64; 3] = [0.3, -0.1, 0.04];
const HALF: [f64; 3] = [0.04, 0.025, 0.04];

/// Points on all six faces of a box (8 x 5 x 8 cm, yaw 0.5 rad, on a table
/// at z = 0), symmetric so that their centroid is the box centre.
fn box_points() -> Vec<[f32; 3]> {
    let (c, s) = (YAW.cos(), YAW.sin());
    let mut points = Vec::new();
    let steps = 40;
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            for i in 0..steps {
                for j in 0..steps {
                    let (a, b) = (
                        (i as f64 + 0.5) / steps as f64 * 2.0 - 1.0,
                        (j as f64 + 0.5) / steps as f64 * 2.0 - 1.0,
                    );
                    let mut local = [0.0; 3];
                    local[axis] = sign * HALF[axis];
                    local[(axis + 1) % 3] = a * HALF[(axis + 1) % 3];
                    local[(axis + 2) % 3] = b * HALF[(axis + 2) % 3];
                    let world = [
                        CENTER[0] + c * local[0] - s * local[1],
                        CENTER[1] + s * local[0] + c * local[1],
                        CENTER[2] + local[2],
                    ];
                    points.push(world.map(|v| v as f32));
                }
            }
        }
    }
    points
}

/// Maps of one view: a Gaussian quality peak at `(u, v)`, constant angle and width.
fn maps_with_peak(contract: &ModelContract, u: usize, v: usize, phi: f32, width_m: f32) -> GraspMaps {
    let l = contract.input_size_px;
    let mut data = vec![0.0f32; 4 * l * l];
    for i in 0..l * l {
        let (du, dv) = ((i % l) as f32 - u as f32, (i / l) as f32 - v as f32);
        data[i] = 0.9 * (-(du * du + dv * dv) / 8.0).exp();
        data[l * l + i] = (2.0 * phi).cos();
        data[2 * l * l + i] = (2.0 * phi).sin();
        data[3 * l * l + i] = width_m / contract.width_scale_m;
    }
    GraspMaps {
        size_px: l,
        len: 1,
        data,
    }
}

#[test]
fn known_peak_lands_at_known_pose_in_every_view() {
    let contract = ModelContract::baseline();
    let points = box_points();
    let indices: Vec<u32> = (0..points.len() as u32).collect();
    let table = TablePlane {
        normal: Vector3::z(),
        offset_m: 0.0,
        support: 1.0,
    };
    let config = DecodeConfig {
        smoothing_sigma_px: 0.0,
        opening_margin_m: 0.0,
        ..DecodeConfig::default()
    };
    let (c, s) = (YAW.cos(), YAW.sin());
    let box_x = Vector3::new(c, s, 0.0); // the long (8 cm) horizontal side
    let box_y = Vector3::new(-s, c, 0.0);
    let z = Vector3::z();
    // Cameras on each side of the box's y axis (both in front of its +x face).
    for camera_side in [1.0, -1.0] {
        let camera = Point3::from(Vector3::from(CENTER) + 1.0 * box_x + camera_side * 0.6 * box_y + 0.5 * z);
        let (frame, local) = object_frame(&points, &indices, &camera);
        assert!((frame.world_from_object.translation.vector - Vector3::from(CENTER)).norm() < 1e-5);
        let object_x = frame.world_from_object.rotation * Vector3::x();
        assert!(
            (object_x - box_x).norm() < 1e-5,
            "X = the long side, towards the camera: {object_x} vs {box_x}, {}",
            (object_x - box_x).norm()
        );
        let plus_y = camera_side > 0.0;
        // Documented view axes (u, v, viewing direction) in the world, per view.
        let expected = [
            (ViewAxis::Top, box_x, -box_y, -z, HALF[2]),
            (ViewAxis::Front, box_y, -z, -box_x, HALF[0]),
            if plus_y {
                (ViewAxis::Side, -box_x, -z, -box_y, HALF[1])
            } else {
                (ViewAxis::Side, box_x, -z, box_y, HALF[1])
            },
        ];
        for (axis, u_dir, v_dir, look, half_depth) in expected {
            let view = OrthoView::render(
                axis,
                plus_y,
                &local,
                contract.input_size_px,
                contract.pixel_size_m,
            );
            // The face centre the view looks at, and 1 cm to the right of it along image u.
            let target = Vector3::from(CENTER) - half_depth * look + 0.01 * u_dir;
            let in_object = frame
                .world_from_object
                .inverse_transform_vector(&(target - Vector3::from(CENTER)));
            let (pu, pv, _) = view.pixel_of(&in_object);
            let (u, v) = (pu.floor() as usize, pv.floor() as usize);
            for (phi, closing) in [(0.0f32, u_dir), (std::f32::consts::FRAC_PI_2 - 1e-4, v_dir)] {
                let maps = maps_with_peak(&contract, u, v, phi, 0.05);
                let placement = ViewPlacement {
                    view: &view,
                    world_from_object: &frame.world_from_object,
                    object_id: 7,
                };
                let grasps = decode_view(
                    &placement,
                    &maps,
                    0,
                    &contract,
                    &Gripper::default(),
                    &table,
                    0.5,
                    &config,
                )
                .grasps;
                let Some(g) = grasps.first() else {
                    panic!("{axis:?} phi {phi}: no grasp")
                };
                let origin = g.world_from_grasp.translation.vector;
                let expected_origin = target + config.insertion_m * look;
                let err = origin - expected_origin;
                // Within one pixel in the image plane; exact in depth (flat face).
                assert!(err.dot(&look).abs() < 1e-4, "{axis:?}: depth error {err:?}");
                assert!(
                    (err - err.dot(&look) * look).norm() < contract.pixel_size_m as f64,
                    "{axis:?}: {err:?}"
                );
                let rotation = g.world_from_grasp.rotation;
                assert!(
                    (rotation * Vector3::z() - look).norm() < 1e-5,
                    "{axis:?}: approach {} vs {look} phi {phi}",
                    rotation * Vector3::z()
                );
                assert!(
                    (rotation * Vector3::x()).dot(&closing).abs() > 0.99999,
                    "{axis:?} phi {phi}: closing"
                );
                assert!((g.width_m - 0.05).abs() < 1e-6);
                assert_eq!((g.object_id, g.view, g.pixel), (7, axis, [u as u32, v as u32]));
                // An opening margin widens the same grasp (closing horizontally,
                // so the wider pads stay clear of the table), within the stroke.
                if phi == 0.0 {
                    for (margin, width) in [(0.02, 0.07), (0.5, Gripper::default().max_width_m)] {
                        let wider = DecodeConfig {
                            opening_margin_m: margin,
                            ..config.clone()
                        };
                        let grasps = decode_view(
                            &placement,
                            &maps,
                            0,
                            &contract,
                            &Gripper::default(),
                            &table,
                            0.5,
                            &wider,
                        )
                        .grasps;
                        assert_eq!(grasps.len(), 1, "{axis:?} margin {margin}");
                        assert!(
                            (grasps[0].width_m - width).abs() < 1e-9,
                            "{axis:?} margin {margin}"
                        );
                        assert_eq!(grasps[0].world_from_grasp, g.world_from_grasp);
                    }
                }
            }
        }
    }
}

/// A side grasp closing vertically whose lower pad would sit in the table is
/// dropped and counted; the same grasp narrow enough to clear it is kept; a
/// peak wider than the stroke is counted too wide, or decoded at the stroke
/// within `wide_slack_m`.
#[test]
fn grasps_into_the_table_or_too_wide_are_dropped_and_counted() {
    let contract = ModelContract::baseline();
    let points = box_points();
    let indices: Vec<u32> = (0..points.len() as u32).collect();
    let camera = Point3::new(2.0, 0.0, 1.0);
    let (frame, local) = object_frame(&points, &indices, &camera);
    let view = OrthoView::render(
        ViewAxis::Front,
        true,
        &local,
        contract.input_size_px,
        contract.pixel_size_m,
    );
    let table = TablePlane {
        normal: Vector3::z(),
        offset_m: 0.0,
        support: 1.0,
    };
    let config = DecodeConfig {
        smoothing_sigma_px: 0.0,
        opening_margin_m: 0.0,
        wide_slack_m: 0.0,
        ..DecodeConfig::default()
    };
    let placement = ViewPlacement {
        view: &view,
        world_from_object: &frame.world_from_object,
        object_id: 0,
    };
    let centre = contract.input_size_px / 2;
    let vertical = std::f32::consts::FRAC_PI_2;
    // Face centre 4 cm above the table: a 10 cm opening puts the lower pad 1 cm under it.
    let decode = |maps: &_, config: &DecodeConfig| {
        decode_view(
            &placement,
            maps,
            0,
            &contract,
            &Gripper::default(),
            &table,
            0.5,
            config,
        )
    };
    let wide = decode(
        &maps_with_peak(&contract, centre, centre, vertical, 0.10),
        &config,
    );
    assert!(wide.grasps.is_empty());
    assert_eq!(
        (wide.no_pose, wide.too_wide),
        (1, 0),
        "counted: no pose clears the table"
    );
    let narrow = decode(
        &maps_with_peak(&contract, centre, centre, vertical, 0.06),
        &config,
    );
    assert_eq!((narrow.grasps.len(), narrow.no_pose, narrow.too_wide), (1, 0, 0));
    // Wider than the gripper opens: counted too wide, unless within the
    // slack, where it is decoded at the full stroke for the hand check.
    let stroke = Gripper::default().max_width_m;
    let too_wide = maps_with_peak(&contract, centre, centre, 0.0, stroke as f32 + 0.01);
    let refused = decode(&too_wide, &config);
    assert!(refused.grasps.is_empty());
    assert_eq!((refused.too_wide, refused.no_pose), (1, 0));
    let slack = DecodeConfig {
        wide_slack_m: 0.02,
        ..config.clone()
    };
    let kept = decode(&too_wide, &slack);
    assert_eq!((kept.grasps.len(), kept.too_wide), (1, 0));
    assert!((kept.grasps[0].width_m - stroke).abs() < 1e-9);
    let beyond = maps_with_peak(&contract, centre, centre, 0.0, stroke as f32 + 0.03);
    assert_eq!(decode(&beyond, &slack).too_wide, 1);
}
