//! A point cloud of float32 triples -> world points.

use nalgebra::{Isometry3, Point3};

use super::input::{CloudFrame, PointCloud, WorldCloud};
use super::sampling::Keep;
use crate::error::{Error, Result};

/// Largest cloud accepted (points); guards allocations on bad input.
pub const MAX_CLOUD_POINTS: usize = 5_000_000;

/// The number of points, after checking the byte length and the limit.
pub(super) fn check_cloud(cloud: &PointCloud<'_>) -> Result<usize> {
    if !cloud.xyz.len().is_multiple_of(12) {
        return Err(Error::invalid(
            "cloud.xyz",
            format!(
                "length {} is not a multiple of 12 (three float32 per point)",
                cloud.xyz.len()
            ),
        ));
    }
    let n = cloud.xyz.len() / 12;
    if n > MAX_CLOUD_POINTS {
        return Err(Error::invalid(
            "cloud.xyz",
            format!("{n} points exceed the limit of {MAX_CLOUD_POINTS}"),
        ));
    }
    Ok(n)
}

pub(super) fn cloud_to_world(
    cloud: &PointCloud<'_>,
    world_from_camera: &Isometry3<f64>,
    keep: &Keep,
    step: usize,
) -> Result<WorldCloud> {
    let n = check_cloud(cloud)?;
    let transform = cloud_transform(cloud, world_from_camera);
    let mut out = WorldCloud {
        points: Vec::with_capacity(n / step),
        ..WorldCloud::default()
    };
    for b in cloud.xyz.chunks_exact(12).step_by(step) {
        if let Some(p) = cloud_point(b, &transform) {
            out.valid += 1;
            if keep.test(&p) {
                out.points.push(p);
            }
        }
    }
    Ok(out)
}

/// Maps the cloud's points to the world.
pub(super) fn cloud_transform(cloud: &PointCloud<'_>, world_from_camera: &Isometry3<f64>) -> Isometry3<f32> {
    match cloud.frame {
        CloudFrame::Camera => world_from_camera.cast::<f32>(),
        CloudFrame::World => Isometry3::identity(),
    }
}

/// One little-endian float32 triple (12 bytes) in the world; `None` if not finite.
pub(super) fn cloud_point(bytes: &[u8], transform: &Isometry3<f32>) -> Option<[f32; 3]> {
    let f = |i: usize| f32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let p = [f(0), f(4), f(8)];
    if p.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let q = transform * Point3::from(p);
    Some([q.x, q.y, q.z])
}
