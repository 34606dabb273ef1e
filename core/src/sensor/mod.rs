//! Sensor input -> points in the world frame, cropped to the workspace.
//!
//! Two inputs: a depth image (uint16 millimetres or float32 metres, row-major,
//! little-endian) with pinhole intrinsics, or a cloud of float32 triples in the
//! camera or world frame. Readings that are 0, NaN or infinite are skipped.
//! `input`: what arrives; `sampling`: which readings are converted (the
//! public entry points); `depth` and `cloud`: the conversions.

mod cloud;
mod depth;
mod input;
mod intrinsics;
mod sampling;

pub use cloud::MAX_CLOUD_POINTS;
pub use input::{
    Above, CloudFrame, DepthEncoding, DepthFrame, FieldOfView, MAX_IMAGE_SIDE_PX, PointCloud, SensorInput,
    WorldCloud,
};
pub use intrinsics::Intrinsics;
pub use sampling::{BlockMask, random_world_points, world_points, world_points_above, world_points_outside};

#[cfg(test)]
mod tests {
    use nalgebra::Isometry3;

    use super::*;
    use crate::error::Error;
    use crate::geometry::{Workspace, pose_from_parts};

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
        for (got, want) in a.points[0].iter().zip(expected) {
            assert!((got - want as f32).abs() < 1e-6, "{:?}", a.points[0]);
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
