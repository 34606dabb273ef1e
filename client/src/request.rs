//! Building requests from in-memory frames (a camera driver, a simulator)
//! rather than from files.

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};

use crate::pb;

/// `pose` as a message (its unit quaternion as x, y, z, w).
pub fn pose_message(pose: &Isometry3<f64>) -> pb::Pose {
    let (t, q) = (pose.translation.vector, pose.rotation.quaternion());
    pb::Pose {
        position: Some(pb::Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        orientation: Some(pb::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

/// A pose message as an isometry; a missing pose or orientation is the
/// identity, and the quaternion is normalised.
pub fn pose_from_message(p: Option<&pb::Pose>) -> Isometry3<f64> {
    let Some(p) = p else { return Isometry3::identity() };
    let t = p.position.unwrap_or_default();
    let q = p.orientation.unwrap_or(pb::Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    });
    Isometry3::from_parts(
        Translation3::new(t.x, t.y, t.z),
        UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
    )
}

fn point_message(p: &Point3<f64>) -> pb::Vector3 {
    pb::Vector3 {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// A request for a uint16-millimetre depth frame (`depth_mm` row-major, 0 =
/// no reading) seen from `world_from_camera`, cropped to the world box
/// `workspace` (`min`, `max`) when given; everything else the server's defaults.
pub fn depth_request(
    width: u32,
    height: u32,
    depth_mm: &[u16],
    intrinsics: pb::CameraIntrinsics,
    world_from_camera: &Isometry3<f64>,
    workspace: Option<(Point3<f64>, Point3<f64>)>,
) -> pb::PlanGraspsRequest {
    pb::PlanGraspsRequest {
        sensor: Some(pb::plan_grasps_request::Sensor::Depth(pb::DepthImage {
            width,
            height,
            encoding: pb::DepthEncoding::Uint16Mm as i32,
            data: depth_mm.iter().flat_map(|d| d.to_le_bytes()).collect(),
            intrinsics: Some(intrinsics),
        })),
        world_from_camera: Some(pose_message(world_from_camera)),
        workspace: workspace.map(|(min, max)| pb::Workspace {
            min: Some(point_message(&min)),
            max: Some(point_message(&max)),
        }),
        ..Default::default()
    }
}
