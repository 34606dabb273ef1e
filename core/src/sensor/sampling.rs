//! Which readings are converted: the whole frame, a random sample for the
//! table fit, or only the blocks of pixels near objects ([`BlockMask`]).

use nalgebra::Isometry3;

use super::cloud::{check_cloud, cloud_point, cloud_to_world, cloud_transform};
use super::depth::{Rays, check_frame, depth_to_world};
use super::input::{Above, DepthFrame, SensorInput, WorldCloud};
use crate::error::{Error, Result};
use crate::geometry::Workspace;

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

/// Points inside `region` and `above` but outside `workspace`, on a grid of
/// every `stride`-th row and column (every `stride^2`-th point of a cloud):
/// what stands on the rest of the table, for the obstacle boxes. The frame
/// was checked by the passes before; a region that keeps no point is an
/// empty answer, not an error.
pub fn world_points_outside(
    input: &SensorInput<'_>,
    world_from_camera: &Isometry3<f64>,
    region: &Workspace,
    workspace: &Workspace,
    above: &Above,
    stride: usize,
) -> Result<Vec<[f32; 3]>> {
    let keep = Keep::new(region, Some(above));
    let sampling = Sampling::Grid {
        stride: stride.max(1),
        pixels: false,
    };
    let mut cloud = convert(input, world_from_camera, &keep, sampling)?;
    let inner = Keep::new(workspace, None);
    cloud.points.retain(|p| !inner.inside(p));
    Ok(cloud.points)
}

/// Blocks of `stride x stride` pixels of a depth image that are worth a
/// full-resolution look: those whose corner pixel stands above the table,
/// and their 8 neighbours (so object edges between samples are not lost).
/// An object narrower than a block and missed by every sample is missed,
/// which at stride 4 means under ~4 px: far below the smallest cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockMask {
    pub(super) stride: usize,
    pub(super) blocks_wide: usize,
    pub(super) marked: Vec<bool>,
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
pub(super) enum Sampling<'a> {
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
pub(super) struct Keep {
    lo: [f32; 3],
    hi: [f32; 3],
    pub(super) above: Above,
}

impl Keep {
    pub(super) fn new(workspace: &Workspace, above: Option<&Above>) -> Self {
        let (lo, hi) = workspace.bounds_f32();
        // "Above nothing": 0 . p + 1 > 0 always holds.
        let above = above.copied().unwrap_or(Above {
            normal: [0.0; 3],
            offset: 1.0,
        });
        Self { lo, hi, above }
    }

    #[inline(always)]
    pub(super) fn inside(&self, p: &[f32; 3]) -> bool {
        (p[0] >= self.lo[0])
            & (p[0] <= self.hi[0])
            & (p[1] >= self.lo[1])
            & (p[1] <= self.hi[1])
            & (p[2] >= self.lo[2])
            & (p[2] <= self.hi[2])
    }

    /// The half-space normal's component along `d`.
    #[inline(always)]
    pub(super) fn height_dir(&self, d: &[f32; 3]) -> f32 {
        let n = &self.above.normal;
        n[0] * d[0] + n[1] * d[1] + n[2] * d[2]
    }

    #[inline(always)]
    pub(super) fn test(&self, p: &[f32; 3]) -> bool {
        let n = &self.above.normal;
        self.inside(p) & (n[0] * p[0] + n[1] * p[1] + n[2] * p[2] + self.above.offset > 0.0)
    }
}
