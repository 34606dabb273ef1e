//! Sensor input -> points in the world frame, cropped to the workspace.
//!
//! Two inputs: a depth image (uint16 millimetres or float32 metres, row-major,
//! little-endian) with pinhole intrinsics, or a cloud of float32 triples in the
//! camera or world frame. Readings that are 0, NaN or infinite are skipped.

mod intrinsics;

pub use intrinsics::Intrinsics;

use nalgebra::{Isometry3, Point3};

use crate::error::{Error, Result};
use crate::geometry::Workspace;

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
    let cloud = convert(
        input,
        world_from_camera,
        &Keep::new(workspace, None),
        Sampling::Grid {
            stride: 1,
            pixels: false,
        },
    )?;
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

/// Up to `n` readings drawn at random (uniformly over the pixels or points,
/// with replacement, from a stream seeded with `seed`), as world points
/// inside `workspace`: enough to fit the table without converting the frame.
/// At most `4 n` draws are made; an empty or short result is not an error
/// here (the caller falls back to [`world_points`], which names the cause).
pub fn random_world_points(
    input: &SensorInput<'_>,
    world_from_camera: &Isometry3<f64>,
    workspace: &Workspace,
    n: usize,
    seed: u64,
) -> Result<WorldCloud> {
    let keep = Keep::new(workspace, None);
    let mut rng = crate::rng::SplitMix64::new(seed);
    let mut out = WorldCloud {
        points: Vec::with_capacity(n),
        ..WorldCloud::default()
    };
    match input {
        SensorInput::Depth(frame) => {
            let (w, h) = check_frame(frame)?;
            let rays = Rays::new(frame, world_from_camera, &keep);
            let mut draws = 0;
            while out.points.len() < n && draws < 4 * n {
                let wanted = n - out.points.len();
                let mut pixels: Vec<usize> = (0..wanted).map(|_| rng.below(w * h)).collect();
                draws += wanted;
                // Sorted, the reads sweep the frame once instead of jumping
                // around it (measured: the random order missed the cache).
                pixels.sort_unstable();
                for pixel in pixels {
                    rays.row(
                        frame,
                        &keep,
                        pixel / w,
                        std::iter::once(pixel % w),
                        false,
                        &mut out,
                    );
                }
            }
        }
        SensorInput::Cloud(cloud) => {
            let count = check_cloud(cloud)?;
            let transform = cloud_transform(cloud, world_from_camera);
            for _ in 0..4 * n {
                if out.points.len() >= n || count == 0 {
                    break;
                }
                if let Some(p) = cloud_point(&cloud.xyz[12 * rng.below(count)..][..12], &transform) {
                    out.valid += 1;
                    if keep.inside(&p) {
                        out.points.push(p);
                    }
                }
            }
        }
    }
    Ok(out)
}

/// Every point inside `workspace` and `above` at full resolution: the object
/// points, without ever storing the table, with each point's pixel for a
/// depth image (the crease split needs the image's neighbourhoods). With
/// `near`, only the pixels of the blocks it marks are converted (a depth
/// image; a cloud ignores it).
pub fn world_points_above(
    input: &SensorInput<'_>,
    world_from_camera: &Isometry3<f64>,
    workspace: &Workspace,
    above: &Above,
    near: Option<&BlockMask>,
) -> Result<WorldCloud> {
    let keep = Keep::new(workspace, Some(above));
    let sampling = match near {
        Some(mask) => Sampling::Blocks(mask),
        None => Sampling::Grid {
            stride: 1,
            pixels: true,
        },
    };
    convert(input, world_from_camera, &keep, sampling)
}

/// Blocks of `stride x stride` pixels of a depth image that are worth a
/// full-resolution look: those whose corner pixel stands above the table,
/// and their 8 neighbours (so object edges between samples are not lost).
/// An object narrower than a block and missed by every sample is missed,
/// which at stride 4 means under ~4 px: far below the smallest cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockMask {
    stride: usize,
    blocks_wide: usize,
    marked: Vec<bool>,
}

impl BlockMask {
    /// The mask of `frame`: its pixels on a grid of `stride` that lie in
    /// `workspace` and `above` mark their blocks, dilated by one block. The
    /// grid pass rejects table pixels with one multiply-add each.
    pub fn from_frame(
        frame: &DepthFrame<'_>,
        world_from_camera: &Isometry3<f64>,
        workspace: &Workspace,
        above: &Above,
        stride: usize,
    ) -> Result<Self> {
        let stride = stride.max(1);
        let keep = Keep::new(workspace, Some(above));
        let sample = depth_to_world(
            frame,
            world_from_camera,
            &keep,
            Sampling::Grid { stride, pixels: true },
        )?;
        let (w, h) = (frame.width as usize, frame.height as usize);
        let (bw, bh) = (w.div_ceil(stride), h.div_ceil(stride));
        let mut hit = vec![false; bw * bh];
        for &pixel in &sample.pixels {
            let (u, v) = (pixel as usize % w, pixel as usize / w);
            hit[(v / stride) * bw + u / stride] = true;
        }
        let mut marked = vec![false; bw * bh];
        for by in 0..bh {
            for bx in 0..bw {
                if hit[by * bw + bx] {
                    for y in by.saturating_sub(1)..=(by + 1).min(bh - 1) {
                        for x in bx.saturating_sub(1)..=(bx + 1).min(bw - 1) {
                            marked[y * bw + x] = true;
                        }
                    }
                }
            }
        }
        Ok(Self {
            stride,
            blocks_wide: bw,
            marked,
        })
    }

    /// Share of the image the mask keeps.
    pub fn coverage(&self) -> f64 {
        self.marked.iter().filter(|&&m| m).count() as f64 / self.marked.len().max(1) as f64
    }
}

/// Which pixels of a depth image (or points of a cloud) are converted.
#[derive(Debug, Clone, Copy)]
enum Sampling<'a> {
    /// Every `stride`-th row and column (every stride^2-th point of a
    /// cloud); with `pixels`, each kept point's pixel is recorded too.
    Grid {
        /// Rows and columns skipped + 1.
        stride: usize,
        /// Record `WorldCloud::pixels`.
        pixels: bool,
    },
    /// Every pixel of the marked blocks, with its pixel recorded (every
    /// point of a cloud).
    Blocks(&'a BlockMask),
}

fn convert(
    input: &SensorInput<'_>,
    world_from_camera: &Isometry3<f64>,
    keep: &Keep,
    sampling: Sampling<'_>,
) -> Result<WorldCloud> {
    match input {
        SensorInput::Depth(frame) => depth_to_world(frame, world_from_camera, keep, sampling),
        SensorInput::Cloud(cloud) => {
            let step = match sampling {
                Sampling::Grid { stride, .. } => stride * stride,
                Sampling::Blocks(_) => 1,
            };
            cloud_to_world(cloud, world_from_camera, keep, step)
        }
    }
}

/// The per-point tests: the workspace box and the half-space.
struct Keep {
    lo: [f32; 3],
    hi: [f32; 3],
    above: Above,
}

impl Keep {
    fn new(workspace: &Workspace, above: Option<&Above>) -> Self {
        let (lo, hi) = workspace.bounds_f32();
        // "Above nothing": 0 . p + 1 > 0 always holds.
        let above = above.copied().unwrap_or(Above {
            normal: [0.0; 3],
            offset: 1.0,
        });
        Self { lo, hi, above }
    }

    #[inline(always)]
    fn inside(&self, p: &[f32; 3]) -> bool {
        (p[0] >= self.lo[0])
            & (p[0] <= self.hi[0])
            & (p[1] >= self.lo[1])
            & (p[1] <= self.hi[1])
            & (p[2] >= self.lo[2])
            & (p[2] <= self.hi[2])
    }

    /// The half-space normal's component along `d`.
    #[inline(always)]
    fn height_dir(&self, d: &[f32; 3]) -> f32 {
        let n = &self.above.normal;
        n[0] * d[0] + n[1] * d[1] + n[2] * d[2]
    }

    #[inline(always)]
    fn test(&self, p: &[f32; 3]) -> bool {
        let n = &self.above.normal;
        self.inside(p) & (n[0] * p[0] + n[1] * p[1] + n[2] * p[2] + self.above.offset > 0.0)
    }
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
/// per-row term, so each pixel costs two vector adds and a scale; its height
/// over the half-space splits the same way and is tested first, so a table
/// pixel costs one multiply-add.
fn depth_to_world(
    frame: &DepthFrame<'_>,
    world_from_camera: &Isometry3<f64>,
    keep: &Keep,
    sampling: Sampling<'_>,
) -> Result<WorldCloud> {
    let (w, h) = check_frame(frame)?;
    let rays = Rays::new(frame, world_from_camera, keep);
    let mut out = WorldCloud::default();
    match sampling {
        Sampling::Grid { stride, pixels } => {
            for v in (0..h).step_by(stride) {
                rays.row(frame, keep, v, (0..w).step_by(stride), pixels, &mut out);
            }
        }
        Sampling::Blocks(mask) => {
            let s = mask.stride;
            let marked = mask.marked.iter().filter(|&&m| m).count();
            out.points.reserve(marked * s * s);
            out.pixels.reserve(marked * s * s);
            let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
            for (block_row, blocks) in mask.marked.chunks_exact(mask.blocks_wide).enumerate() {
                // Runs of marked blocks -> column ranges, shared by the
                // block row's `s` pixel rows.
                runs.clear();
                let mut b = 0;
                while b < blocks.len() {
                    if !blocks[b] {
                        b += 1;
                        continue;
                    }
                    let start = b;
                    while b < blocks.len() && blocks[b] {
                        b += 1;
                    }
                    runs.push(start * s..(b * s).min(w));
                }
                for v in block_row * s..((block_row + 1) * s).min(h) {
                    for columns in &runs {
                        rays.row(frame, keep, v, columns.clone(), true, &mut out);
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The per-column and per-row parts of every pixel's world ray and height.
struct Rays {
    width: usize,
    origin: [f32; 3],
    column_term: Vec<[f32; 3]>,
    column_height: Vec<f32>,
    row_term: Vec<[f32; 3]>,
    row_height: Vec<f32>,
    h0: f32,
}

impl Rays {
    fn new(frame: &DepthFrame<'_>, world_from_camera: &Isometry3<f64>, keep: &Keep) -> Self {
        let k = frame.intrinsics;
        let rotation = *world_from_camera.rotation.to_rotation_matrix().matrix();
        let r = &rotation;
        let t = world_from_camera.translation.vector;
        let column_term: Vec<[f32; 3]> = (0..frame.width as usize)
            .map(|u| {
                let x = (u as f64 - k.cx) / k.fx;
                [
                    (r[(0, 0)] * x) as f32,
                    (r[(1, 0)] * x) as f32,
                    (r[(2, 0)] * x) as f32,
                ]
            })
            .collect();
        let row_term: Vec<[f32; 3]> = (0..frame.height as usize)
            .map(|v| {
                let y = (v as f64 - k.cy) / k.fy;
                [
                    (r[(0, 1)] * y + r[(0, 2)]) as f32,
                    (r[(1, 1)] * y + r[(1, 2)]) as f32,
                    (r[(2, 1)] * y + r[(2, 2)]) as f32,
                ]
            })
            .collect();
        let origin = [t.x as f32, t.y as f32, t.z as f32];
        let column_height = column_term.iter().map(|c| keep.height_dir(c)).collect();
        let row_height = row_term.iter().map(|c| keep.height_dir(c)).collect();
        let h0 = keep.height_dir(&origin) + keep.above.offset;
        Self {
            width: frame.width as usize,
            origin,
            column_term,
            column_height,
            row_term,
            row_height,
            h0,
        }
    }

    /// Converts the pixels `columns` of row `v`.
    #[inline]
    fn row(
        &self,
        frame: &DepthFrame<'_>,
        keep: &Keep,
        v: usize,
        columns: impl Iterator<Item = usize>,
        record_pixels: bool,
        out: &mut WorldCloud,
    ) {
        let bpp = frame.encoding.bytes_per_pixel();
        let row = &frame.data[v * self.width * bpp..(v + 1) * self.width * bpp];
        let (row_term, row_height) = (self.row_term[v], self.row_height[v]);
        for u in columns {
            let z = match frame.encoding {
                DepthEncoding::U16Millimetres => {
                    f32::from(u16::from_le_bytes([row[2 * u], row[2 * u + 1]])) * 1e-3
                }
                DepthEncoding::F32Metres => {
                    f32::from_le_bytes([row[4 * u], row[4 * u + 1], row[4 * u + 2], row[4 * u + 3]])
                }
            };
            // 0, NaN, +-inf and negative readings are "no reading".
            if !((z > 0.0) & (z < f32::INFINITY)) {
                continue;
            }
            out.valid += 1;
            if self.h0 + z * (self.column_height[u] + row_height) <= 0.0 {
                continue;
            }
            let c = &self.column_term[u];
            let p = [
                self.origin[0] + z * (c[0] + row_term[0]),
                self.origin[1] + z * (c[1] + row_term[1]),
                self.origin[2] + z * (c[2] + row_term[2]),
            ];
            if keep.inside(&p) {
                out.points.push(p);
                if record_pixels {
                    out.pixels.push((v * self.width + u) as u32);
                }
            }
        }
    }
}

/// Largest cloud accepted (points); guards allocations on bad input.
pub const MAX_CLOUD_POINTS: usize = 5_000_000;

/// The number of points, after checking the byte length and the limit.
fn check_cloud(cloud: &PointCloud<'_>) -> Result<usize> {
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

fn cloud_to_world(
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
fn cloud_transform(cloud: &PointCloud<'_>, world_from_camera: &Isometry3<f64>) -> Isometry3<f32> {
    match cloud.frame {
        CloudFrame::Camera => world_from_camera.cast::<f32>(),
        CloudFrame::World => Isometry3::identity(),
    }
}

/// One little-endian float32 triple (12 bytes) in the world; `None` if not finite.
fn cloud_point(bytes: &[u8], transform: &Isometry3<f32>) -> Option<[f32; 3]> {
    let f = |i: usize| f32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let p = [f(0), f(4), f(8)];
    if p.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let q = transform * Point3::from(p);
    Some([q.x, q.y, q.z])
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
