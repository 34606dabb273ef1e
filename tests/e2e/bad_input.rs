//! Invalid requests: each answered with the right code naming its field, and
//! the server still answers a valid request after each.

use futures_util::StreamExt;
use mvgrasp_client::{Error, pb};
use mvgrasp_server::BackendKind;
use nalgebra::Vector3;
use tonic::Code;

use crate::{
    fixture::{request, settings, start},
    scene::{Camera, grid_scene},
};

type Edit = Box<dyn Fn(&mut pb::PlanGraspsRequest)>;

fn depth(r: &mut pb::PlanGraspsRequest) -> &mut pb::DepthImage {
    match r.sensor.as_mut() {
        Some(pb::plan_grasps_request::Sensor::Depth(d)) => d,
        _ => unreachable!("the base request is a depth frame"),
    }
}

fn cloud(xyz: Vec<u8>, frame: i32) -> Option<pb::plan_grasps_request::Sensor> {
    Some(pb::plan_grasps_request::Sensor::Cloud(pb::PointCloud {
        xyz: xyz.into(),
        frame,
    }))
}

fn gripper(max_width_m: f64, finger_width_m: f64, finger_depth_m: f64) -> Option<pb::Gripper> {
    Some(pb::Gripper {
        max_width_m,
        finger_width_m,
        finger_depth_m,
    })
}

fn workspace(min: [f64; 3], max: [f64; 3]) -> Option<pb::Workspace> {
    let v = |[x, y, z]: [f64; 3]| Some(pb::Vector3 { x, y, z });
    Some(pb::Workspace {
        min: v(min),
        max: v(max),
    })
}

fn cone(axis: [f64; 3], half_angle_rad: f64) -> Option<pb::ApproachCone> {
    let [x, y, z] = axis;
    Some(pb::ApproachCone {
        axis: Some(pb::Vector3 { x, y, z }),
        half_angle_rad,
    })
}

/// `n` copies of a capsule from `a` to `b` of `radius_m`, as a robot body.
fn body(n: usize, a: [f64; 3], b: [f64; 3], radius_m: f64) -> Vec<pb::Capsule> {
    let v = |[x, y, z]: [f64; 3]| Some(pb::Vector3 { x, y, z });
    vec![
        pb::Capsule {
            a: v(a),
            b: v(b),
            radius_m,
        };
        n
    ]
}

/// A UR5e-like reach, shoulder at `shoulder`, with its `max_m` and `min_axis_m`.
fn reach(shoulder: [f64; 3], max_m: f64, min_axis_m: f64) -> Option<pb::ArmReach> {
    let [x, y, z] = shoulder;
    Some(pb::ArmReach {
        shoulder: Some(pb::Vector3 { x, y, z }),
        axis: None,
        wrist_back_m: 0.33,
        approach_m: 0.1,
        max_m,
        min_axis_m,
    })
}

fn cases() -> Vec<(&'static str, Code, &'static str, Edit)> {
    let v = |x, y, z| Some(pb::Vector3 { x, y, z });
    vec![
        (
            "no sensor",
            Code::InvalidArgument,
            "sensor",
            Box::new(|r| r.sensor = None),
        ),
        (
            "size mismatch",
            Code::InvalidArgument,
            "depth.data",
            Box::new(|r| {
                depth(r).data.truncate(1000);
            }),
        ),
        (
            "width off",
            Code::InvalidArgument,
            "depth.data",
            Box::new(|r| depth(r).width = 641),
        ),
        (
            "zero width",
            Code::InvalidArgument,
            "depth.width",
            Box::new(|r| depth(r).width = 0),
        ),
        (
            "unknown encoding",
            Code::InvalidArgument,
            "depth.encoding",
            Box::new(|r| depth(r).encoding = 7),
        ),
        (
            "unspecified encoding",
            Code::InvalidArgument,
            "depth.encoding",
            Box::new(|r| depth(r).encoding = 0),
        ),
        (
            "float32 with uint16 bytes",
            Code::InvalidArgument,
            "depth.data",
            Box::new(|r| {
                depth(r).encoding = pb::DepthEncoding::Float32M as i32;
            }),
        ),
        (
            "no intrinsics",
            Code::InvalidArgument,
            "depth.intrinsics",
            Box::new(|r| depth(r).intrinsics = None),
        ),
        (
            "zero intrinsics",
            Code::InvalidArgument,
            "depth.intrinsics.fx",
            Box::new(|r| {
                depth(r).intrinsics = Some(pb::CameraIntrinsics::default());
            }),
        ),
        (
            "NaN focal length",
            Code::InvalidArgument,
            "depth.intrinsics.fy",
            Box::new(|r| {
                depth(r).intrinsics.as_mut().unwrap().fy = f64::NAN;
            }),
        ),
        (
            "all-zero depth",
            Code::InvalidArgument,
            "depth.data",
            Box::new(|r| {
                let d = depth(r);
                d.data = vec![0; d.data.len()].into();
            }),
        ),
        (
            "no pose",
            Code::InvalidArgument,
            "world_from_camera",
            Box::new(|r| r.world_from_camera = None),
        ),
        (
            "NaN pose",
            Code::InvalidArgument,
            "world_from_camera.position",
            Box::new(|r| {
                r.world_from_camera.as_mut().unwrap().position.as_mut().unwrap().x = f64::NAN;
            }),
        ),
        (
            "no orientation",
            Code::InvalidArgument,
            "world_from_camera.orientation",
            Box::new(|r| {
                r.world_from_camera.as_mut().unwrap().orientation = None;
            }),
        ),
        (
            "zero quaternion",
            Code::InvalidArgument,
            "world_from_camera.orientation",
            Box::new(|r| {
                r.world_from_camera.as_mut().unwrap().orientation = Some(pb::Quaternion::default());
            }),
        ),
        (
            "empty cloud",
            Code::InvalidArgument,
            "cloud.xyz",
            Box::new(|r| r.sensor = cloud(Vec::new(), 0)),
        ),
        (
            "ragged cloud",
            Code::InvalidArgument,
            "cloud.xyz",
            Box::new(|r| r.sensor = cloud(vec![0; 13], 0)),
        ),
        (
            "unknown cloud frame",
            Code::InvalidArgument,
            "cloud.frame",
            Box::new(|r| r.sensor = cloud(vec![0; 12], 9)),
        ),
        (
            "NaN cloud",
            Code::InvalidArgument,
            "cloud.xyz",
            Box::new(|r| {
                r.sensor = cloud(f32::NAN.to_le_bytes().repeat(300), 1);
            }),
        ),
        (
            "inverted workspace",
            Code::InvalidArgument,
            "workspace",
            Box::new(move |r| {
                r.workspace = workspace([1.0, 1.0, 1.0], [-1.0, -1.0, -1.0]);
            }),
        ),
        (
            "workspace without max",
            Code::InvalidArgument,
            "workspace.max",
            Box::new(move |r| {
                r.workspace = Some(pb::Workspace {
                    min: v(0.0, 0.0, 0.0),
                    max: None,
                });
            }),
        ),
        (
            "empty workspace",
            Code::InvalidArgument,
            "workspace",
            Box::new(move |r| {
                r.workspace = workspace([5.0, 5.0, 5.0], [6.0, 6.0, 6.0]);
            }),
        ),
        (
            "negative gripper",
            Code::InvalidArgument,
            "gripper.max_width_m",
            Box::new(|r| {
                r.gripper = gripper(-0.1, 0.02, 0.04);
            }),
        ),
        (
            "quality above 1",
            Code::InvalidArgument,
            "min_quality",
            Box::new(|r| r.min_quality = Some(1.5)),
        ),
        (
            "NaN quality",
            Code::InvalidArgument,
            "min_quality",
            Box::new(|r| r.min_quality = Some(f32::NAN)),
        ),
        (
            "unknown policy",
            Code::InvalidArgument,
            "view_policy",
            Box::new(|r| r.view_policy = 42),
        ),
        (
            "approach cone without an axis",
            Code::InvalidArgument,
            "approach_cone.axis",
            Box::new(|r| {
                r.approach_cone = Some(pb::ApproachCone {
                    axis: None,
                    half_angle_rad: 1.0,
                })
            }),
        ),
        (
            "approach cone with a zero axis",
            Code::InvalidArgument,
            "approach_cone.axis",
            Box::new(|r| r.approach_cone = cone([0.0, 0.0, 0.0], 1.0)),
        ),
        (
            "approach cone of no angle",
            Code::InvalidArgument,
            "approach_cone.half_angle_rad",
            Box::new(|r| r.approach_cone = cone([0.0, 0.0, -1.0], f64::NAN)),
        ),
        (
            "arm reach without a shoulder",
            Code::InvalidArgument,
            "arm_reach.shoulder",
            Box::new(|r| {
                r.arm_reach = reach([0.0; 3], 0.9, 0.1).map(|a| pb::ArmReach { shoulder: None, ..a })
            }),
        ),
        (
            "arm reach with a zero axis",
            Code::InvalidArgument,
            "arm_reach.axis",
            Box::new(|r| {
                r.arm_reach = reach([0.0; 3], 0.9, 0.1).map(|a| pb::ArmReach {
                    axis: Some(pb::Vector3::default()),
                    ..a
                })
            }),
        ),
        (
            "arm reach of no length",
            Code::InvalidArgument,
            "arm_reach.max_m",
            Box::new(|r| r.arm_reach = reach([0.0; 3], 0.0, 0.0)),
        ),
        (
            "arm reach that keeps clear of more than it reaches",
            Code::InvalidArgument,
            "arm_reach.min_axis_m",
            Box::new(|r| r.arm_reach = reach([0.0; 3], 0.9, 1.0)),
        ),
        (
            "arm reach with a NaN wrist",
            Code::InvalidArgument,
            "arm_reach.wrist_back_m",
            Box::new(|r| {
                r.arm_reach = reach([0.0; 3], 0.9, 0.1).map(|a| pb::ArmReach {
                    wrist_back_m: f64::NAN,
                    ..a
                })
            }),
        ),
        (
            "inverted obstacle region",
            Code::InvalidArgument,
            "obstacle_region",
            Box::new(|r| r.obstacle_region = workspace([1.0, 1.0, 1.0], [-1.0, -1.0, -1.0])),
        ),
        (
            "obstacle region with a NaN corner",
            Code::InvalidArgument,
            "obstacle_region.max",
            Box::new(|r| r.obstacle_region = workspace([-1.0, -1.0, -1.0], [f64::NAN, 1.0, 1.0])),
        ),
        (
            "robot body with a NaN end",
            Code::InvalidArgument,
            "robot_body[0].b",
            Box::new(|r| r.robot_body = body(1, [0.0; 3], [f64::NAN, 0.0, 0.0], 0.1)),
        ),
        (
            "robot body capsule with no end",
            Code::InvalidArgument,
            "robot_body[1].a",
            Box::new(|r| {
                r.robot_body = body(2, [0.0; 3], [0.0, 0.0, 0.5], 0.1);
                r.robot_body[1].a = None;
            }),
        ),
        (
            "robot body capsule of radius 0",
            Code::InvalidArgument,
            "robot_body[0].radius_m",
            Box::new(|r| r.robot_body = body(1, [0.0; 3], [0.0, 0.0, 0.5], 0.0)),
        ),
        (
            "robot body of 65 capsules",
            Code::InvalidArgument,
            "robot_body",
            Box::new(|r| r.robot_body = body(65, [0.0; 3], [0.0, 0.0, 0.5], 0.1)),
        ),
        (
            "too many pixels",
            Code::ResourceExhausted,
            "depth",
            Box::new(|r| {
                let d = depth(r);
                (d.width, d.height) = (4000, 3000);
            }),
        ),
        (
            "oversized message",
            Code::ResourceExhausted,
            "too large",
            Box::new(|r| {
                depth(r).data = vec![1; 3 << 20].into();
            }),
        ),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_bad_field_is_named_and_the_server_keeps_serving() {
    let mut s = settings(BackendKind::Onnx);
    s.limits.max_message_bytes = 2 << 20;
    s.limits.max_image_pixels = 2_000_000;
    let (server, mut client) = start(s).await;
    let good = request(
        &grid_scene(0.0, 3, 3, 0.13),
        &Camera::orbit(Vector3::zeros(), 0.85, 50.0, -90.0),
    );
    for (name, code, field, edit) in cases() {
        let mut bad = good.clone();
        edit(&mut bad);
        match client.plan(bad).await {
            Err(Error::Rpc(status)) => {
                assert_eq!(status.code(), code, "{name}: {}", status.message());
                assert!(
                    status.message().contains(field),
                    "{name}: the message does not name `{field}`: {}",
                    status.message()
                );
            }
            other => panic!("{name}: expected {code:?}, got {other:?}"),
        }
        let after = client.plan(good.clone()).await;
        assert!(after.is_ok(), "after {name}: {after:?}");
    }
    // In a stream, the first bad frame ends the stream with its status.
    let mut broken = good.clone();
    depth(&mut broken).encoding = 7;
    let frames = vec![good.clone(), broken, good.clone()];
    let mut answers = client.stream(futures_util::stream::iter(frames)).await.unwrap();
    assert!(answers.next().await.unwrap().is_ok());
    let status = answers.next().await.unwrap().unwrap_err();
    assert_eq!(status.code(), Code::InvalidArgument);
    assert!(status.message().contains("frame 1") && status.message().contains("depth.encoding"));
    assert!(answers.next().await.is_none());
    // An oversized frame in a stream is RESOURCE_EXHAUSTED too.
    let mut huge = good.clone();
    depth(&mut huge).data = vec![1; 3 << 20].into();
    let mut answers = client
        .stream(futures_util::stream::iter(vec![huge]))
        .await
        .unwrap();
    let status = answers.next().await.unwrap().unwrap_err();
    assert_eq!(status.code(), Code::ResourceExhausted, "{}", status.message());
    assert!(client.plan(good).await.is_ok());
    server.shutdown().await.unwrap();
}

/// Edge values of every field: each call gets INVALID_ARGUMENT or
/// RESOURCE_EXHAUSTED naming what is off, or a valid answer (finite,
/// ranked, within the gripper); never INTERNAL (a panic), never a hang
/// (each call has a 20 s deadline); and the next valid call is answered.
fn edges() -> Vec<(&'static str, Edit)> {
    fn v(x: f64, y: f64, z: f64) -> Option<pb::Vector3> {
        Some(pb::Vector3 { x, y, z })
    }
    fn f32s(values: &[f32]) -> Vec<u8> {
        values.iter().flat_map(|x| x.to_le_bytes()).collect()
    }
    let intrinsic = |set: fn(&mut pb::CameraIntrinsics)| -> Edit {
        Box::new(move |r| set(depth(r).intrinsics.as_mut().unwrap()))
    };
    let mut out: Vec<(&'static str, Edit)> = vec![
        ("fx infinite", intrinsic(|k| k.fx = f64::INFINITY)),
        ("fx negative", intrinsic(|k| k.fx = -600.0)),
        ("fx huge", intrinsic(|k| k.fx = 1e300)),
        ("fx tiny", intrinsic(|k| k.fx = 1e-300)),
        ("cx NaN", intrinsic(|k| k.cx = f64::NAN)),
        ("cy far outside the image", intrinsic(|k| k.cy = -1e9)),
        (
            "1x1 image",
            Box::new(|r| {
                let d = depth(r);
                (d.width, d.height) = (1, 1);
                d.data = 800u16.to_le_bytes().to_vec().into();
            }),
        ),
        (
            "1x1 image of zero depth",
            Box::new(|r| {
                let d = depth(r);
                (d.width, d.height) = (1, 1);
                d.data = vec![0, 0].into();
            }),
        ),
        (
            "8192x8192 image header",
            Box::new(|r| {
                let d = depth(r);
                (d.width, d.height) = (8192, 8192);
            }),
        ),
        (
            "every pixel at 65.535 m",
            Box::new(|r| {
                let d = depth(r);
                d.data = vec![0xff; d.data.len()].into();
            }),
        ),
        (
            "float32 depth of NaN, inf, negative",
            Box::new(move |r| {
                let d = depth(r);
                let n = (d.width * d.height) as usize;
                let values: Vec<f32> = (0..n)
                    .map(|i| [f32::NAN, f32::INFINITY, -1.0, 0.0][i % 4])
                    .collect();
                d.encoding = pb::DepthEncoding::Float32M as i32;
                d.data = f32s(&values).into();
            }),
        ),
        (
            "position infinite",
            Box::new(|r| {
                r.world_from_camera.as_mut().unwrap().position.as_mut().unwrap().z = f64::INFINITY;
            }),
        ),
        (
            "position huge",
            Box::new(|r| {
                r.world_from_camera.as_mut().unwrap().position.as_mut().unwrap().x = 1e30;
            }),
        ),
        (
            "quaternion NaN",
            Box::new(|r| {
                r.world_from_camera
                    .as_mut()
                    .unwrap()
                    .orientation
                    .as_mut()
                    .unwrap()
                    .w = f64::NAN;
            }),
        ),
        (
            "quaternion not unit (x1000)",
            Box::new(|r| {
                let q = r
                    .world_from_camera
                    .as_mut()
                    .unwrap()
                    .orientation
                    .as_mut()
                    .unwrap();
                (q.x, q.y, q.z, q.w) = (q.x * 1e3, q.y * 1e3, q.z * 1e3, q.w * 1e3);
            }),
        ),
        (
            "quaternion of subnormals",
            Box::new(|r| {
                r.world_from_camera.as_mut().unwrap().orientation = Some(pb::Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 1e-310,
                });
            }),
        ),
        (
            "camera under the table, looking up",
            Box::new(|r| {
                r.world_from_camera = Some(pb::Pose {
                    position: v(0.0, 0.0, -0.8),
                    orientation: Some(pb::Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: 0.0,
                        w: 1.0,
                    }),
                });
            }),
        ),
        (
            "workspace NaN",
            Box::new(move |r| {
                r.workspace = workspace([f64::NAN, -1.0, -1.0], [1.0, 1.0, 1.0]);
            }),
        ),
        (
            "workspace of zero volume",
            Box::new(move |r| {
                r.workspace = workspace([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]);
            }),
        ),
        (
            "workspace infinite",
            Box::new(move |r| {
                r.workspace = workspace(
                    [f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY],
                    [f64::INFINITY, f64::INFINITY, f64::INFINITY],
                );
            }),
        ),
        (
            "cloud of one point",
            Box::new(|r| r.sensor = cloud(f32s(&[0.0, 0.0, 0.8]), 1)),
        ),
        (
            "cloud of one point repeated 1,000 times",
            Box::new(move |r| r.sensor = cloud(f32s(&[0.1, 0.0, 0.8]).repeat(1000), 1)),
        ),
        (
            "cloud with infinities",
            Box::new(move |r| r.sensor = cloud(f32s(&[f32::INFINITY, 0.0, 0.8, 0.0, 0.0, 0.8]), 1)),
        ),
        (
            "cloud of huge coordinates",
            Box::new(move |r| r.sensor = cloud(f32s(&[1e30, -1e30, 1e30]).repeat(100), 1)),
        ),
        (
            "gripper NaN",
            Box::new(|r| {
                r.gripper = gripper(f64::NAN, 0.02, 0.04);
            }),
        ),
        (
            "gripper infinite",
            Box::new(|r| {
                r.gripper = gripper(f64::INFINITY, f64::INFINITY, f64::INFINITY);
            }),
        ),
        (
            "gripper of zero fingers",
            Box::new(|r| {
                r.gripper = gripper(0.14, 0.0, 0.0);
            }),
        ),
        (
            "gripper 100 m wide",
            Box::new(|r| {
                r.gripper = gripper(100.0, 0.02, 0.04);
            }),
        ),
        ("max_grasps u32::MAX", Box::new(|r| r.max_grasps = u32::MAX)),
        (
            "min_quality 1 (nothing passes)",
            Box::new(|r| r.min_quality = Some(1.0)),
        ),
        ("min_quality negative", Box::new(|r| r.min_quality = Some(-0.5))),
        (
            "view policy random, seed u64::MAX",
            Box::new(|r| {
                r.view_policy = pb::ViewPolicy::Random as i32;
                r.random_seed = u64::MAX;
            }),
        ),
        (
            "approach cone wider than a sphere",
            Box::new(|r| r.approach_cone = cone([0.0, 0.0, -1.0], 10.0)),
        ),
        (
            "approach cone of negative angle",
            Box::new(|r| r.approach_cone = cone([0.0, 0.0, -1.0], -0.5)),
        ),
        (
            "approach cone with an infinite axis",
            Box::new(|r| r.approach_cone = cone([f64::INFINITY, 0.0, -1.0], 0.5)),
        ),
        (
            "arm reach 1 km away",
            Box::new(|r| r.arm_reach = reach([1000.0, 0.0, 0.0], 0.9, 0.1)),
        ),
        (
            "arm reach of 1e300 m",
            Box::new(|r| r.arm_reach = reach([0.0; 3], 1e300, 0.0)),
        ),
        (
            "obstacle region of 2 km",
            Box::new(|r| r.obstacle_region = workspace([-1000.0; 3], [1000.0; 3])),
        ),
        (
            "obstacle region far from the table",
            Box::new(|r| r.obstacle_region = workspace([50.0, 50.0, 50.0], [51.0, 51.0, 51.0])),
        ),
        (
            "robot body of 64 capsules of 2 m over the whole scene",
            Box::new(|r| r.robot_body = body(64, [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0], 2.0)),
        ),
        (
            "robot body 1 km away",
            Box::new(|r| r.robot_body = body(3, [1000.0; 3], [1000.0, 0.0, 0.0], 0.1)),
        ),
        (
            "request id of 100 kB",
            Box::new(|r| r.request_id = "x".repeat(100_000)),
        ),
        (
            "debug views asked for",
            Box::new(|r| r.include_debug_views = true),
        ),
    ];
    // Out-of-range enum values the proto cannot stop.
    out.push(("cloud frame -1", Box::new(|r| r.sensor = cloud(vec![0; 12], -1))));
    out
}

fn check_valid(name: &str, answer: &pb::PlanGraspsResponse) {
    for g in &answer.grasps {
        let pose = g.pose.unwrap_or_default();
        let p = pose.position.unwrap_or_default();
        let q = pose.orientation.unwrap_or_default();
        assert!(
            [p.x, p.y, p.z, q.x, q.y, q.z, q.w].iter().all(|v| v.is_finite()),
            "{name}: a grasp with non-finite pose {pose:?}"
        );
        assert!(
            g.quality.is_finite() && g.width_m.is_finite() && g.width_m > 0.0,
            "{name}: {g:?}"
        );
    }
    assert!(answer.objects.len() <= 4096, "{name}");
    for o in &answer.obstacles {
        let (lo, hi) = (o.min.unwrap_or_default(), o.max.unwrap_or_default());
        assert!(
            [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z].iter().all(|v| v.is_finite())
                && lo.x < hi.x
                && lo.y < hi.y
                && lo.z <= hi.z,
            "{name}: {o:?}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn edge_values_get_a_clear_error_or_a_valid_answer() {
    let mut s = settings(BackendKind::Onnx);
    s.limits.max_image_pixels = 2_000_000;
    let (server, client) = start(s).await;
    let mut client = client.with_timeout(std::time::Duration::from_secs(20));
    let good = request(
        &grid_scene(0.0, 3, 3, 0.13),
        &Camera::orbit(Vector3::zeros(), 0.85, 50.0, -90.0),
    );
    let mut outcomes = Vec::new();
    for (name, edit) in edges() {
        let mut edge = good.clone();
        edit(&mut edge);
        let outcome = match client.plan(edge).await {
            Ok(answer) => {
                check_valid(name, &answer);
                format!(
                    "answered: {} objects, {} grasps",
                    answer.objects.len(),
                    answer.grasps.len()
                )
            }
            Err(Error::Rpc(status)) => {
                assert!(
                    matches!(status.code(), Code::InvalidArgument | Code::ResourceExhausted),
                    "{name}: {:?} {}",
                    status.code(),
                    status.message()
                );
                assert!(
                    status.message().len() > 10,
                    "{name}: say what is off: {}",
                    status.message()
                );
                format!("{:?}: {}", status.code(), status.message())
            }
            Err(other) => panic!("{name}: {other}"),
        };
        outcomes.push(format!("{name:<40} {outcome}"));
        let after = client.plan(good.clone()).await;
        assert!(after.is_ok(), "after {name}: {after:?}");
    }
    eprintln!("{}", outcomes.join("\n"));
    server.shutdown().await.unwrap();
}
