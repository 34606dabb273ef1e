//! Grasps drawn over the depth image, and each object's views beside it.
//!
//! Left: the depth image (near = bright), each grasp as a finger-to-finger
//! segment with its rank (best in green, the rest from yellow to red). Right:
//! one row per object with its rendered views (2x); views that went through
//! the network are framed in blue and carry their grasps.

use std::path::Path;

use nalgebra::{Point3, Vector3};

use crate::{Error, Result, pb, request::pose_from_message as pose, scene::SceneFiles};

/// An RGB image with just enough drawing for grasps.
#[derive(Debug, Clone)]
pub struct Image {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Image {
    fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            rgb: vec![20; width * height * 3],
        }
    }

    fn set(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if (0..self.width as i64).contains(&x) && (0..self.height as i64).contains(&y) {
            let at = 3 * (y as usize * self.width + x as usize);
            self.rgb[at..at + 3].copy_from_slice(&colour);
        }
    }

    /// A 2-px segment from `from` to `to`.
    fn segment(&mut self, from: [f64; 2], to: [f64; 2], colour: [u8; 3]) {
        let n = (to[0] - from[0])
            .abs()
            .max((to[1] - from[1]).abs())
            .ceil()
            .max(1.0) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let x = (from[0] + (to[0] - from[0]) * t).round() as i64;
            let y = (from[1] + (to[1] - from[1]) * t).round() as i64;
            self.set(x, y, colour);
            self.set(x + 1, y, colour);
            self.set(x, y + 1, colour);
        }
    }

    fn frame(&mut self, x: usize, y: usize, side: usize, colour: [u8; 3]) {
        let (a, b) = (x as f64 - 1.0, (x + side) as f64);
        let (c, d) = (y as f64 - 1.0, (y + side) as f64);
        for (p, q) in [
            ([a, c], [b, c]),
            ([b, c], [b, d]),
            ([b, d], [a, d]),
            ([a, d], [a, c]),
        ] {
            self.segment(p, q, colour);
        }
    }

    /// Writes an 8-bit RGB PNG.
    pub fn save(&self, path: &Path) -> Result<()> {
        let io = |e: &dyn std::fmt::Display| Error::Input {
            file: path.display().to_string(),
            reason: e.to_string(),
        };
        let file = std::fs::File::create(path).map_err(|e| io(&e))?;
        let mut encoder = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.width as u32,
            self.height as u32,
        );
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| io(&e))?;
        writer.write_image_data(&self.rgb).map_err(|e| io(&e))
    }
}

/// Colour of the grasp of rank `rank` (0 = best) among `n`.
fn rank_colour(rank: usize, n: usize) -> [u8; 3] {
    if rank == 0 {
        return [40, 230, 60];
    }
    let t = rank as f64 / n.max(2) as f64;
    [255, (220.0 * (1.0 - t)) as u8, 30]
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// Draws `response` over `scene` (a depth frame). Views appear when the
/// response carries them (`include_debug_views`).
pub fn draw(scene: &SceneFiles, response: &pb::PlanGraspsResponse) -> Result<Image> {
    let (pb::plan_grasps_request::Sensor::Depth(depth), Some(k)) = (&scene.sensor, scene.intrinsics) else {
        return Err(Error::Input {
            file: "--viz".into(),
            reason: "drawing needs a depth image with intrinsics".into(),
        });
    };
    let (w, h) = (depth.width as usize, depth.height as usize);
    let mm: Vec<u16> = depth
        .data
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let scale = 2;
    let view_px = response.debug_views.first().map_or(0, |v| v.size_px as usize);
    let panel = view_px * scale + 6;
    let views_per_row = 3;
    let right = if view_px > 0 { 8 + views_per_row * panel } else { 0 };
    let rows = response.objects.len().max(1);
    let mut image = Image::new(w + right, h.max(if view_px > 0 { rows * panel } else { 0 }));

    let valid = mm.iter().copied().filter(|&d| d > 0);
    let (near, far) = valid.fold((u16::MAX, 0), |(lo, hi), d| (lo.min(d), hi.max(d)));
    let span = f64::from(far.saturating_sub(near).max(1));
    for (i, &d) in mm.iter().enumerate().take(w * h) {
        let g = if d == 0 {
            0
        } else {
            (235.0 - f64::from(d - near) / span * 190.0) as u8
        };
        image.set((i % w) as i64, (i / w) as i64, [g, g, g]);
    }

    let camera_from_world = pose(Some(&scene.world_from_camera)).inverse();
    let project = |p: Vector3<f64>| {
        let c = camera_from_world * Point3::from(p);
        (c.z > 1e-6).then(|| [k.fx * c.x / c.z + k.cx, k.fy * c.y / c.z + k.cy])
    };
    let n = response.grasps.len();
    for (rank, g) in response.grasps.iter().enumerate().rev() {
        let world_from_grasp = pose(g.pose.as_ref());
        let centre = world_from_grasp.translation.vector;
        let closing = world_from_grasp.rotation * Vector3::x();
        let approach = world_from_grasp.rotation * Vector3::z();
        let half = 0.5 * g.width_m * closing;
        let colour = rank_colour(rank, n);
        let tips = [centre - half, centre + half];
        // Fingers: from the tips back along the approach by 4 cm.
        for tip in tips {
            if let (Some(a), Some(b)) = (project(tip), project(tip - 0.04 * approach)) {
                image.segment(a, b, colour);
            }
        }
        if let (Some(a), Some(b)) = (project(tips[0]), project(tips[1])) {
            image.segment(a, b, colour);
        }
    }

    if view_px == 0 {
        return Ok(image);
    }
    for (row, object) in response.objects.iter().enumerate() {
        let views = response.debug_views.iter().filter(|v| v.object_id == object.id);
        for (col, view) in views.enumerate().take(views_per_row) {
            let (x0, y0) = (w + 8 + col * panel + 3, row * panel + 3);
            let l = view.size_px as usize;
            for (i, value) in f32s(&view.image).into_iter().enumerate().take(l * l) {
                let g = (value.clamp(0.0, 1.0) * 255.0) as u8;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    image.set(
                        (x0 + (i % l) * scale + dx) as i64,
                        (y0 + (i / l) * scale + dy) as i64,
                        [g, g, g],
                    );
                }
            }
            if !view.maps.is_empty() {
                image.frame(x0, y0, l * scale, [60, 160, 255]);
            }
            for (rank, g) in response.grasps.iter().enumerate() {
                if g.object_id != object.id || g.view != view.axis {
                    continue;
                }
                let half_px = 0.5 * g.width_m / view.pixel_size_m.max(1e-6);
                let (c, s) = (f64::from(g.angle_rad).cos(), f64::from(g.angle_rad).sin());
                let (u, v) = (f64::from(g.pixel_u) + 0.5, f64::from(g.pixel_v) + 0.5);
                let at = |t: f64| {
                    [
                        x0 as f64 + (u + t * c) * scale as f64,
                        y0 as f64 + (v + t * s) * scale as f64,
                    ]
                };
                image.segment(at(-half_px), at(half_px), rank_colour(rank, n));
            }
        }
    }
    Ok(image)
}
