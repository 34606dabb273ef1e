//! The response contract on rendered scenes, for both backends.

use futures_util::StreamExt;
use mvgrasp_client::pb;
use mvgrasp_server::BackendKind;
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::{
    fixture::{request, sample, scrape, settings, start},
    scene::{Camera, Scene, Shape, grid_scene},
};

fn isometry(p: &pb::Pose) -> (Isometry3<f64>, f64) {
    let t = p.position.unwrap();
    let q = p.orientation.unwrap();
    let raw = Quaternion::new(q.w, q.x, q.y, q.z);
    (
        Isometry3::from_parts(
            Translation3::new(t.x, t.y, t.z),
            UnitQuaternion::from_quaternion(raw),
        ),
        raw.norm(),
    )
}

/// Best first; those turned away from a neighbour after the rest, then
/// those reaching past the image border.
fn check_ranked(response: &pb::PlanGraspsResponse) {
    let past = response.ranked_last_out_of_view as usize;
    let turned = response.ranked_after_turned_away as usize;
    assert!(past + turned <= response.grasps.len());
    let (rest, past) = response.grasps.split_at(response.grasps.len() - past);
    let (as_planned, turned) = rest.split_at(rest.len() - turned);
    for part in [as_planned, turned, past] {
        for pair in part.windows(2) {
            assert!(pair[0].quality >= pair[1].quality, "grasps not sorted by quality");
        }
    }
}

/// Checks one answer against its scene.
fn check(response: &pb::PlanGraspsResponse, scene: &Scene, max_width_m: f64) {
    assert_eq!(
        response.objects.len(),
        scene.shapes.len(),
        "every object detected once"
    );
    assert!(!response.grasps.is_empty(), "no grasp");
    check_ranked(response);
    for g in &response.grasps {
        let (world_from_grasp, norm) = isometry(g.pose.as_ref().unwrap());
        assert!((norm - 1.0).abs() < 1e-9, "quaternion norm {norm}");
        assert!(g.width_m > 0.0 && g.width_m <= max_width_m, "width {}", g.width_m);
        assert!((0.0..=1.0).contains(&g.quality));
        // The grasp centre lies on or near its object: within 2 cm of the
        // box its points span, in the object's frame (the fingertips go up
        // to 3.5 cm past the seen surface: 3 cm, then 5 mm deeper where the
        // hand allows, `HandConfig::deepen_m`; past a thin object's far side).
        let object = response
            .objects
            .iter()
            .find(|o| o.id == g.object_id)
            .expect("grasp names a detected object");
        let (world_from_object, _) = isometry(object.world_from_object.as_ref().unwrap());
        let local =
            world_from_object.inverse_transform_point(&Point3::from(world_from_grasp.translation.vector));
        let (lo, hi) = (object.extent_min_m.unwrap(), object.extent_max_m.unwrap());
        let outside = Vector3::new(
            (lo.x - local.x).max(local.x - hi.x).max(0.0),
            (lo.y - local.y).max(local.y - hi.y).max(0.0),
            (lo.z - local.z).max(local.z - hi.z).max(0.0),
        )
        .norm();
        assert!(
            outside < 0.02,
            "grasp {:.3} m outside object {}",
            outside,
            object.id
        );
        // Above the table.
        assert!(
            world_from_grasp.translation.z > scene.table_z,
            "grasp under the table"
        );
    }
    let t = response.timings.unwrap();
    assert!(t.total_ms > 0.0 && t.total_ms >= t.cluster_ms);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rendered_scenes_with_the_onnx_and_baseline_backends() {
    let scenes = [
        (
            Scene {
                table_z: 0.72,
                table_half: [0.6, 0.4],
                shapes: vec![Shape::standing_box(0.72, 0.05, -0.03, 0.4, [0.06, 0.04, 0.10])],
            },
            Camera::orbit(Vector3::new(0.0, 0.0, 0.72), 0.8, 45.0, -60.0),
        ),
        (
            grid_scene(0.0, 6, 3, 0.13),
            Camera::orbit(Vector3::zeros(), 0.85, 50.0, -90.0),
        ),
        (
            grid_scene(-0.2, 5, 5, 0.12),
            Camera::orbit(Vector3::new(0.0, 0.0, -0.2), 0.9, 89.9, 0.0),
        ),
    ];
    for backend in [BackendKind::Onnx, BackendKind::Baseline] {
        let (server, mut client) = start(settings(backend)).await;
        let info = client.model_info().await.unwrap();
        for (scene, camera) in &scenes {
            let response = client.plan(request(scene, camera)).await.unwrap();
            check(&response, scene, 0.14);
            assert_eq!(response.model_version, info.model_version);
        }
        // A smaller gripper: every width fits it.
        let (scene, camera) = &scenes[1];
        let mut narrow = request(scene, camera);
        narrow.gripper = Some(pb::Gripper {
            max_width_m: 0.085,
            finger_width_m: 0.022,
            finger_depth_m: 0.037,
        });
        narrow.max_grasps = 50;
        let response = client.plan(narrow).await.unwrap();
        assert!(response.grasps.iter().all(|g| g.width_m <= 0.085));
        server.shutdown().await.unwrap();
    }
}

/// What stands outside the workspace comes back as boxes when a region is
/// asked for, none of the robot's body told; a bad region or capsule is named.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn objects_outside_the_workspace_come_back_as_obstacle_boxes() {
    let (server, mut client) = start(settings(BackendKind::Onnx)).await;
    // Three columns of three, 13 cm apart; the workspace leaves out the
    // column at x = -0.13, the obstacle region takes in the whole table.
    let scene = grid_scene(0.0, 9, 3, 0.13);
    let mut r = request(&scene, &Camera::orbit(Vector3::zeros(), 0.85, 55.0, -90.0));
    let v = |x, y, z| Some(pb::Vector3 { x, y, z });
    r.workspace = Some(pb::Workspace {
        min: v(-0.065, -0.4, -0.05),
        max: v(0.6, 0.4, 0.4),
    });
    let plain = client.plan(r.clone()).await.unwrap();
    assert!(plain.obstacles.is_empty());
    assert_eq!(plain.objects.len(), 6);
    r.obstacle_region = Some(pb::Workspace {
        min: v(-0.6, -0.4, -0.05),
        max: v(0.6, 0.4, 0.5),
    });
    let answer = client.plan(r.clone()).await.unwrap();
    assert_eq!(answer.objects, plain.objects);
    assert_eq!(
        (answer.obstacles.len(), answer.obstacles_dropped),
        (3, 0),
        "{:?}",
        answer.obstacles
    );
    for (i, shape) in scene.shapes.iter().enumerate().filter(|(i, _)| i % 3 == 0) {
        let Shape::Cuboid { center, half, .. } = shape else {
            panic!("shape {i} of the grid's first column is a box")
        };
        let found = answer.obstacles.iter().any(|o| {
            let (lo, hi) = (o.min.unwrap(), o.max.unwrap());
            (lo.x..=hi.x).contains(&center.x)
                && (lo.y..=hi.y).contains(&center.y)
                && (hi.z - 2.0 * half.z).abs() < 0.005
                && lo.z.abs() < 0.002
                && hi.x < -0.065 + 0.01
                && o.object_id.is_none()
        });
        assert!(found, "shape {i} at {center:?}: {:?}", answer.obstacles);
    }
    // The first column told as the robot's body (a capsule up through each
    // box): no box is left, and the objects planned are the same.
    r.robot_body = scene
        .shapes
        .iter()
        .step_by(3)
        .map(|shape| {
            let Shape::Cuboid { center, half, .. } = shape else {
                panic!("the grid's first column holds boxes")
            };
            pb::Capsule {
                a: v(center.x, center.y, 0.0),
                b: v(center.x, center.y, 2.0 * half.z),
                radius_m: half.xy().norm() + 0.02,
            }
        })
        .collect();
    let body = client.plan(r.clone()).await.unwrap();
    assert!(body.obstacles.is_empty(), "{:?}", body.obstacles);
    assert_eq!(body.objects, plain.objects);
    r.robot_body[1].b = None;
    let err = client.plan(r.clone()).await.unwrap_err().to_string();
    assert!(err.contains("robot_body[1].b"), "{err}");
    r.robot_body.clear();
    // A region with a corner missing is named.
    r.obstacle_region = Some(pb::Workspace {
        min: None,
        max: v(0.6, 0.4, 0.5),
    });
    let err = client.plan(r).await.unwrap_err().to_string();
    assert!(err.contains("obstacle_region.min"), "{err}");
    server.shutdown().await.unwrap();
}

/// A box half outside the image: the service ranks the grasps whose pads
/// reach past the border last and says how many they are.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grasps_past_the_image_border_come_last_and_are_counted() {
    let (server, mut client) = start(settings(BackendKind::Baseline)).await;
    // Straight down from 0.7 m, 160 x 120 px at 150 px: the table is seen
    // out to x = 0.373 m, the box's top (0.62 m away) out to 0.331 m; a
    // second box 20 cm nearer the centre stays in view.
    let camera = Camera::looking_at(Vector3::new(0.0, 0.0, 0.7), Vector3::zeros(), 160, 120, 150.0);
    let scene_at = |x: f64| Scene {
        table_z: 0.0,
        table_half: [0.6, 0.4],
        shapes: vec![
            Shape::standing_box(0.0, x, 0.0, 0.0, [0.06, 0.09, 0.08]),
            Shape::standing_box(0.0, x - 0.2, 0.0, 0.0, [0.06, 0.09, 0.08]),
        ],
    };
    let plan = |x: f64| {
        let mut r = request(&scene_at(x), &camera);
        r.min_quality = Some(0.0);
        r.max_grasps = 100;
        r.view_policy = pb::ViewPolicy::All as i32;
        r
    };
    let cut = client.plan(plan(0.33)).await.unwrap();
    check_ranked(&cut);
    assert!(
        cut.ranked_last_out_of_view > 0,
        "no grasp reaches past the border"
    );
    assert!((cut.ranked_last_out_of_view as usize) < cut.grasps.len());
    let whole = client.plan(plan(0.0)).await.unwrap();
    assert!(!whole.grasps.is_empty());
    assert_eq!(whole.ranked_last_out_of_view, 0);
    let metrics = scrape(server.metrics_addr.unwrap()).await;
    assert_eq!(
        sample(&metrics, "mvgrasp_grasps_out_of_view_total "),
        f64::from(cut.ranked_last_out_of_view)
    );
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn policies_thresholds_and_debug_views() {
    let (server, mut client) = start(settings(BackendKind::Onnx)).await;
    let scene = grid_scene(0.0, 6, 3, 0.13);
    let camera = Camera::orbit(Vector3::zeros(), 0.85, 50.0, -90.0);
    let base = request(&scene, &camera);
    let inferred = |r: &pb::PlanGraspsResponse| -> usize {
        r.objects
            .iter()
            .map(|o| o.views.iter().filter(|v| v.inferred).count())
            .sum()
    };
    let entropy = client
        .plan(pb::PlanGraspsRequest {
            view_cascade: Some(false),
            ..base.clone()
        })
        .await
        .unwrap();
    assert_eq!(inferred(&entropy), 6, "one view per object");
    // With the view cascade (the default) an object without a grasp goes on
    // to its next view: each object ends with a grasp or every view tried
    // (room for every object's grasps: max_grasps cuts the ranked list).
    let cascaded = client
        .plan(pb::PlanGraspsRequest {
            max_grasps: 50,
            ..base.clone()
        })
        .await
        .unwrap();
    assert!(inferred(&cascaded) >= 6);
    for o in &cascaded.objects {
        let views = o.views.iter().filter(|v| v.inferred).count();
        assert!(
            views == 3 || cascaded.grasps.iter().any(|g| g.object_id == o.id),
            "object {}: {views} views and no grasp",
            o.id
        );
    }
    let all = client
        .plan(pb::PlanGraspsRequest {
            view_policy: pb::ViewPolicy::All as i32,
            ..base.clone()
        })
        .await
        .unwrap();
    assert_eq!(inferred(&all), 18, "three views per object");
    let top = client
        .plan(pb::PlanGraspsRequest {
            view_policy: pb::ViewPolicy::TopDown as i32,
            ..base.clone()
        })
        .await
        .unwrap();
    assert!(top.grasps.iter().all(|g| g.view == pb::ViewAxis::Top as i32));
    // The entropy policy infers each object's highest-entropy view.
    for o in &entropy.objects {
        let chosen = o.views.iter().find(|v| v.inferred).unwrap();
        assert!(
            o.views.iter().all(|v| v.entropy <= chosen.entropy),
            "object {}: the inferred view is not the highest-entropy one",
            o.id
        );
    }
    // tau and max_grasps.
    let strict = client
        .plan(pb::PlanGraspsRequest {
            min_quality: Some(0.999),
            ..base.clone()
        })
        .await
        .unwrap();
    assert!(strict.grasps.iter().all(|g| g.quality >= 0.999));
    let two = client
        .plan(pb::PlanGraspsRequest {
            max_grasps: 2,
            ..base.clone()
        })
        .await
        .unwrap();
    assert_eq!(two.grasps.len(), 2);
    // Debug views: every rendered view, maps for the inferred ones.
    let debug = client
        .plan(pb::PlanGraspsRequest {
            include_debug_views: true,
            ..base.clone()
        })
        .await
        .unwrap();
    assert_eq!(debug.debug_views.len(), 18);
    let with_maps = debug.debug_views.iter().filter(|v| !v.maps.is_empty()).count();
    assert_eq!(
        with_maps,
        inferred(&debug),
        "maps for every view inferred, cascade rounds included"
    );
    for v in &debug.debug_views {
        let n = (v.size_px * v.size_px) as usize;
        assert_eq!(v.image.len(), 4 * n);
        assert!(v.maps.is_empty() || v.maps.len() == 16 * n);
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stream_answers_in_order_and_clouds_equal_depth() {
    let (server, mut client) = start(settings(BackendKind::Onnx)).await;
    let cameras = [-90.0, -60.0, -120.0, -90.0, -75.0];
    let scene = grid_scene(0.0, 4, 2, 0.13);
    let requests: Vec<pb::PlanGraspsRequest> = cameras
        .iter()
        .enumerate()
        .map(|(i, &azimuth)| pb::PlanGraspsRequest {
            request_id: format!("frame-{i}"),
            ..request(&scene, &Camera::orbit(Vector3::zeros(), 0.85, 50.0, azimuth))
        })
        .collect();
    let mut answers = client
        .stream(futures_util::stream::iter(requests.clone()))
        .await
        .unwrap();
    let mut ids = Vec::new();
    while let Some(answer) = answers.next().await {
        let answer = answer.unwrap();
        assert_eq!(answer.objects.len(), 4);
        ids.push(answer.request_id);
    }
    let expected: Vec<String> = (0..cameras.len()).map(|i| format!("frame-{i}")).collect();
    assert_eq!(ids, expected);

    // The same frame as a world-frame cloud plans the same objects.
    let depth = client.plan(requests[0].clone()).await.unwrap();
    let Some(pb::plan_grasps_request::Sensor::Depth(image)) = &requests[0].sensor else {
        unreachable!()
    };
    let k = image.intrinsics.unwrap();
    let (world_from_camera, _) = isometry(requests[0].world_from_camera.as_ref().unwrap());
    let mut xyz = Vec::new();
    for (i, d) in image.data.chunks_exact(2).enumerate() {
        let mm = u16::from_le_bytes([d[0], d[1]]);
        if mm == 0 {
            continue;
        }
        let (u, v) = (
            (i % image.width as usize) as f64,
            (i / image.width as usize) as f64,
        );
        let z = f64::from(mm) / 1000.0;
        let p = world_from_camera * Point3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
        xyz.extend(
            [p.x as f32, p.y as f32, p.z as f32]
                .iter()
                .flat_map(|c| c.to_le_bytes()),
        );
    }
    let cloud = client
        .plan(pb::PlanGraspsRequest {
            sensor: Some(pb::plan_grasps_request::Sensor::Cloud(pb::PointCloud {
                xyz: xyz.into(),
                frame: pb::CloudFrame::World as i32,
            })),
            ..requests[0].clone()
        })
        .await
        .unwrap();
    assert_eq!(cloud.objects.len(), depth.objects.len());
    for (a, b) in cloud.objects.iter().zip(&depth.objects) {
        let (pa, pb_) = (
            a.world_from_object.unwrap().position.unwrap(),
            b.world_from_object.unwrap().position.unwrap(),
        );
        let d = ((pa.x - pb_.x).powi(2) + (pa.y - pb_.y).powi(2) + (pa.z - pb_.z).powi(2)).sqrt();
        assert!(d < 0.005, "object {} moved {d} m between cloud and depth", a.id);
    }
    server.shutdown().await.unwrap();
}
