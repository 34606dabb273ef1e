//! What a sensor delivers, as it arrives on the wire: a depth image or a
//! point cloud (borrowed, not copied), and what is made of it.

use nalgebra::{Isometry3, Point3};

use super::Intrinsics;

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

/// Where a depth camera looked: its pose, intrinsics and image size. A
/// point outside it was never seen, free or not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldOfView {
    /// Camera pose in the world (OpenCV camera frame).
    pub world_from_camera: Isometry3<f64>,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

impl FieldOfView {
    /// The field of view of `frame` taken from `world_from_camera`.
    pub fn of(frame: &DepthFrame<'_>, world_from_camera: &Isometry3<f64>) -> Self {
        Self {
            world_from_camera: *world_from_camera,
            intrinsics: frame.intrinsics,
            width: frame.width,
            height: frame.height,
        }
    }

    /// Whether the world point `p` lies in front of the camera and projects
    /// onto the image (pixel centres at integers; the image spans
    /// `-0.5 ..= width - 0.5`).
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        let in_camera = self.world_from_camera.inverse_transform_point(p);
        self.intrinsics.project(&in_camera).is_some_and(|(u, v, _)| {
            (-0.5..=f64::from(self.width) - 0.5).contains(&u)
                && (-0.5..=f64::from(self.height) - 0.5).contains(&v)
        })
    }
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
    /// For a grid sample of a depth image: the pixel (`v * width + u`) of
    /// each point (empty otherwise).
    pub pixels: Vec<u32>,
}

/// Largest image side accepted (pixels); guards allocations on bad input.
pub const MAX_IMAGE_SIDE_PX: u32 = 8192;

/// A half-space `normal . p + offset > 0` (world frame), used to keep only the
/// points above the table while converting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Above {
    /// Unit normal.
    pub normal: [f32; 3],
    /// Offset (m); a point is kept when `normal . p + offset > 0`.
    pub offset: f32,
}
