//! Sensor input -> points in the world frame, cropped to the workspace.
//!
//! Two inputs: a depth image (uint16 millimetres or float32 metres, row-major,
//! little-endian) with pinhole intrinsics, or a cloud of float32 triples in the
//! camera or world frame. Readings that are 0, NaN or infinite are skipped.

mod intrinsics;

pub use intrinsics::Intrinsics;

use nalgebra::{Isometry3, Point3};

use crate::error::{Error, Result};
use crate::geometry::{Workspace, inside};

/// How depth values are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthEncoding {
    /// uint16 millimetres, little-endian.
    U16Millimetres,
    /// float32 metres, little-endian.
    F32Metres,
}

impl DepthEncoding {
    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::U16Millimetres => 2,
            Self::F32Metres => 4,
        }
    }
}

/// A depth image as it arrives on the wire (borrowed, not copied).
#[derive(Debug, Clone, Copy)]
pub struct DepthFrame<'a> {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Value encoding.
    pub encoding: DepthEncoding,
    /// Row-major little-endian values.
    pub data: &'a [u8],
    /// Pinhole intrinsics of the frame.
    pub intrinsics: Intrinsics,
}

/// The frame a point cloud is expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudFrame {
    /// OpenCV camera frame; `world_from_camera` maps it to the world.
    Camera,
    /// Already in the world frame.
    World,
}

/// A point cloud of little-endian float32 `x, y, z` triples (metres).
#[derive(Debug, Clone, Copy)]
pub struct PointCloud<'a> {
    /// Packed triples, 12 bytes a point.
    pub xyz: &'a [u8],
    /// Frame of the points.
    pub frame: CloudFrame,
}

/// What the sensor delivered.
#[derive(Debug, Clone, Copy)]
pub enum SensorInput<'a> {
    /// An organised depth image.
    Depth(DepthFrame<'a>),
    /// An unorganised cloud.
    Cloud(PointCloud<'a>),
}

/// Points of one frame, in the world frame, inside the workspace.
#[derive(Debug, Clone, Default)]
pub struct WorldCloud {
    /// The cropped points.
    pub points: Vec<[f32; 3]>,
    /// Readings that were valid before the crop.
    pub valid: usize,
}

/// Largest image side accepted (pixels); guards allocations on bad input.
pub const MAX_IMAGE_SIDE_PX: u32 = 8192;

/// Converts a sensor input into world-frame points inside `workspace`.
///
/// Errors name the offending field: size/data-length mismatches, bad
/// intrinsics, a frame without one valid reading, or a workspace that keeps
/// no point.
pub fn world_points(
    input: &SensorInput<'_>,
    world_from_camera: &Isometry3<f64>,
    workspace: &Workspace,
) -> Result<WorldCloud> {
    let cloud = match input {
        SensorInput::Depth(frame) => depth_to_world(frame, world_from_camera, workspace)?,
        SensorInput::Cloud(cloud) => cloud_to_world(cloud, world_from_camera, workspace)?,
    };
    if cloud.valid == 0 {
        let (field, samples) = match input {
            SensorInput::Depth(f) => ("depth.data", f.width as usize * f.height as usize),
            SensorInput::Cloud(c) => ("cloud.xyz", c.xyz.len() / 12),
        };
        return Err(Error::NoValidDepth { field, samples });
    }
    if cloud.points.is_empty() {
        return Err(Error::EmptyWorkspace {
            valid_points: cloud.valid,
        });
    }
    Ok(cloud)
}

fn check_frame(frame: &DepthFrame<'_>) -> Result<(usize, usize)> {
    let (w, h) = (frame.width, frame.height);
    if w == 0 || h == 0 || w > MAX_IMAGE_SIDE_PX || h > MAX_IMAGE_SIDE_PX {
        return Err(Error::invalid(
            "depth.width",
            format!("image must be 1..={MAX_IMAGE_SIDE_PX} px a side, got {w}x{h}"),
        ));
    }
    let expected = w as usize * h as usize * frame.encoding.bytes_per_pixel();
    if frame.data.len() != expected {
        return Err(Error::invalid(
            "depth.data",
            format!(
                "{w}x{h} {:?} needs {expected} bytes, got {}",
                frame.encoding,
                frame.data.len()
            ),
        ));
    }
    frame.intrinsics.validate("depth.intrinsics")?;
    Ok((w as usize, h as usize))
}

/// Depth image -> world points. The camera ray of pixel (u, v) in the world is
/// `R * ((u-cx)/fx, (v-cy)/fy, 1)`, which splits into a per-column and a
/// per-row term, so each pixel costs two vector adds and a scale.
fn depth_to_world(
    frame: &DepthFrame<'_>,
    world_from_camera: &Isometry3<f64>,
    workspace: &Workspace,
) -> Result<WorldCloud> {
    let (w, h) = check_frame(frame)?;
    debug_assert_eq!(frame.data.len(), w * h * frame.encoding.bytes_per_pixel());
    let k = &frame.intrinsics;
    let r = world_from_camera.rotation.to_rotation_matrix();
    let r = r.matrix();
    let t = world_from_camera.translation.vector;
    let column_term: Vec<[f32; 3]> = (0..w)
        .map(|u| {
            let x = (u as f64 - k.cx) / k.fx;
            [
                (r[(0, 0)] * x) as f32,
                (r[(1, 0)] * x) as f32,
                (r[(2, 0)] * x) as f32,
            ]
        })
        .collect();
    let (lo, hi) = workspace.bounds_f32();
    let origin = [t.x as f32, t.y as f32, t.z as f32];
    let mut cloud = WorldCloud {
        points: Vec::with_capacity(w * h / 2),
        valid: 0,
    };
    let bpp = frame.encoding.bytes_per_pixel();
    for (v, row) in frame.data.chunks_exact(w * bpp).enumerate() {
        let y = (v as f64 - k.cy) / k.fy;
        let row_term = [
            (r[(0, 1)] * y + r[(0, 2)]) as f32,
            (r[(1, 1)] * y + r[(1, 2)]) as f32,
            (r[(2, 1)] * y + r[(2, 2)]) as f32,
        ];
        let mut emit = |u: usize, z: f32| {
            // 0, NaN, +-inf and negative readings are "no reading".
            if !(z > 0.0 && z.is_finite()) {
                return;
            }
            cloud.valid += 1;
            let c = &column_term[u];
            let p = [
                origin[0] + z * (c[0] + row_term[0]),
                origin[1] + z * (c[1] + row_term[1]),
                origin[2] + z * (c[2] + row_term[2]),
            ];
            if inside(&p, &lo, &hi) {
                cloud.points.push(p);
            }
        };
        match frame.encoding {
            DepthEncoding::U16Millimetres => {
                for (u, b) in row.chunks_exact(2).enumerate() {
                    emit(u, f32::from(u16::from_le_bytes([b[0], b[1]])) * 1e-3);
                }
            }
            DepthEncoding::F32Metres => {
                for (u, b) in row.chunks_exact(4).enumerate() {
                    emit(u, f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
                }
            }
        }
    }
    Ok(cloud)
}

/// Largest cloud accepted (points); guards allocations on bad input.
pub const MAX_CLOUD_POINTS: usize = 5_000_000;

fn cloud_to_world(
    cloud: &PointCloud<'_>,
    world_from_camera: &Isometry3<f64>,
    workspace: &Workspace,
) -> Result<WorldCloud> {
    if cloud.xyz.len() % 12 != 0 {
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
    let transform = match cloud.frame {
        CloudFrame::Camera => Some(world_from_camera.cast::<f32>()),
        CloudFrame::World => None,
    };
    let (lo, hi) = workspace.bounds_f32();
    let mut out = WorldCloud {
        points: Vec::with_capacity(n),
        valid: 0,
    };
    for b in cloud.xyz.chunks_exact(12) {
        let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let p = [f(0), f(4), f(8)];
        if p.iter().any(|c| !c.is_finite()) {
            continue;
        }
        out.valid += 1;
        let p = match &transform {
            Some(t) => {
                let q = t * Point3::from(p);
                [q.x, q.y, q.z]
            }
            None => p,
        };
        if inside(&p, &lo, &hi) {
            out.points.push(p);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::pose_from_parts;

    fn k() -> Intrinsics {
        Intrinsics {
            fx: 500.0,
            fy: 500.0,
            cx: 1.5,
            cy: 1.0,
        }
    }

    fn everywhere() -> Workspace {
        Workspace::new([-10.0; 3], [10.0; 3]).unwrap()
    }

    #[test]
    fn u16_and_f32_frames_give_the_same_points() {
        let mm: [u16; 12] = [1000, 0, 1200, 800, 900, 1000, 0, 1100, 1000, 1000, 1000, 1000];
        let bytes16: Vec<u8> = mm.iter().flat_map(|v| v.to_le_bytes()).collect();
        let bytes32: Vec<u8> = mm
            .iter()
            .flat_map(|&v| (f32::from(v) * 1e-3).to_le_bytes())
            .collect();
        let pose = pose_from_parts("p", [0.1, 0.2, 0.9], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let run = |encoding, data: &[u8]| {
            let frame = DepthFrame {
                width: 4,
                height: 3,
                encoding,
                data,
                intrinsics: k(),
            };
            world_points(&SensorInput::Depth(frame), &pose, &everywhere()).unwrap()
        };
        let a = run(DepthEncoding::U16Millimetres, &bytes16);
        let b = run(DepthEncoding::F32Metres, &bytes32);
        assert_eq!(a.valid, 10);
        assert_eq!(a.points.len(), 10);
        for (p, q) in a.points.iter().zip(&b.points) {
            for i in 0..3 {
                assert!((p[i] - q[i]).abs() < 1e-6);
            }
        }
        // Pixel (0, 0) at 1 m: camera point ((0-1.5)/500, (0-1)/500, 1); a half
        // turn about x maps (x, y, z) -> (x, -y, -z), then the translation.
        let expected = [0.1 - 1.5 / 500.0, 0.2 + 1.0 / 500.0, 0.9 - 1.0];
        for i in 0..3 {
            assert!(
                (a.points[0][i] - expected[i] as f32).abs() < 1e-6,
                "{:?}",
                a.points[0]
            );
        }
    }

    #[test]
    fn size_mismatch_names_the_data_field() {
        let data = vec![0u8; 10];
        let frame = DepthFrame {
            width: 4,
            height: 3,
            encoding: DepthEncoding::U16Millimetres,
            data: &data,
            intrinsics: k(),
        };
        let err =
            world_points(&SensorInput::Depth(frame), &Isometry3::identity(), &everywhere()).unwrap_err();
        assert!(
            err.to_string().contains("depth.data") && err.to_string().contains("24 bytes"),
            "{err}"
        );
    }

    #[test]
    fn all_invalid_readings_is_no_valid_depth() {
        let data: Vec<u8> = [f32::NAN, 0.0, f32::INFINITY, -1.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let frame = DepthFrame {
            width: 2,
            height: 2,
            encoding: DepthEncoding::F32Metres,
            data: &data,
            intrinsics: k(),
        };
        let err =
            world_points(&SensorInput::Depth(frame), &Isometry3::identity(), &everywhere()).unwrap_err();
        assert_eq!(
            err,
            Error::NoValidDepth {
                field: "depth.data",
                samples: 4
            }
        );
    }

    #[test]
    fn cloud_outside_workspace_is_empty_workspace() {
        let data: Vec<u8> = [5.0f32, 5.0, 5.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let cloud = PointCloud {
            xyz: &data,
            frame: CloudFrame::World,
        };
        let ws = Workspace::new([-1.0; 3], [1.0; 3]).unwrap();
        let err = world_points(&SensorInput::Cloud(cloud), &Isometry3::identity(), &ws).unwrap_err();
        assert_eq!(err, Error::EmptyWorkspace { valid_points: 1 });
        let cloud = PointCloud {
            xyz: &data[..11],
            frame: CloudFrame::World,
        };
        let err = world_points(&SensorInput::Cloud(cloud), &Isometry3::identity(), &ws).unwrap_err();
        assert!(err.to_string().contains("cloud.xyz"), "{err}");
    }
}
