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
        xyz,
        frame,
    }))
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
                depth(r).data.iter_mut().for_each(|b| *b = 0);
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
                r.workspace = Some(pb::Workspace {
                    min: v(1.0, 1.0, 1.0),
                    max: v(-1.0, -1.0, -1.0),
                });
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
                r.workspace = Some(pb::Workspace {
                    min: v(5.0, 5.0, 5.0),
                    max: v(6.0, 6.0, 6.0),
                });
            }),
        ),
        (
            "negative gripper",
            Code::InvalidArgument,
            "gripper.max_width_m",
            Box::new(|r| {
                r.gripper = Some(pb::Gripper {
                    max_width_m: -0.1,
                    finger_width_m: 0.02,
                    finger_depth_m: 0.04,
                });
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
            Box::new(|r| {
                r.approach_cone = Some(pb::ApproachCone {
                    axis: Some(pb::Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: 0.0,
                    }),
                    half_angle_rad: 1.0,
                })
            }),
        ),
        (
            "approach cone of no angle",
            Code::InvalidArgument,
            "approach_cone.half_angle_rad",
            Box::new(|r| {
                r.approach_cone = Some(pb::ApproachCone {
                    axis: Some(pb::Vector3 {
                        x: 0.0,
                        y: 0.0,
                        z: -1.0,
                    }),
                    half_angle_rad: f64::NAN,
                })
            }),
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
                depth(r).data = vec![1; 3 << 20];
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
    depth(&mut huge).data = vec![1; 3 << 20];
    let mut answers = client
        .stream(futures_util::stream::iter(vec![huge]))
        .await
        .unwrap();
    let status = answers.next().await.unwrap().unwrap_err();
    assert_eq!(status.code(), Code::ResourceExhausted, "{}", status.message());
    assert!(client.plan(good).await.is_ok());
    server.shutdown().await.unwrap();
}
