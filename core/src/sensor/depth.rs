//! A depth image -> world points: each pixel's camera ray split into a
//! per-column and a per-row term.

use nalgebra::Isometry3;

use super::input::{DepthEncoding, DepthFrame, MAX_IMAGE_SIDE_PX, WorldCloud};
use super::sampling::{Keep, Sampling};
use crate::error::{Error, Result};

/// The frame's size, after checking it, its data length and its intrinsics.
pub(super) fn check_frame(frame: &DepthFrame<'_>) -> Result<(usize, usize)> {
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
pub(super) fn depth_to_world(
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
pub(super) struct Rays {
    width: usize,
    origin: [f32; 3],
    column_term: Vec<[f32; 3]>,
    column_height: Vec<f32>,
    row_term: Vec<[f32; 3]>,
    row_height: Vec<f32>,
    h0: f32,
}

impl Rays {
    pub(super) fn new(frame: &DepthFrame<'_>, world_from_camera: &Isometry3<f64>, keep: &Keep) -> Self {
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
    pub(super) fn row(
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
