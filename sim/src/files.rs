//! Frames as files: the 16-bit depth PNG + camera JSON that `mvgrasp plan`,
//! the Python client and `robot-bridge pick` read, a 16-bit label PNG, and
//! PNGs for people: a preview, grasps drawn over it, detections beside the
//! labels.

use std::path::Path;

use mvgrasp_core::Segmentation;
use nalgebra::{Isometry3, Point3};

use crate::camera::Frame;
use crate::error::{Error, Result};
use crate::scene::Scene;

fn file_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::File {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}

fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| file_error(path, e))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(colour);
    encoder.set_depth(depth);
    let mut writer = encoder.write_header().map_err(|e| file_error(path, e))?;
    writer.write_image_data(data).map_err(|e| file_error(path, e))
}

/// 16-bit grey PNG of `values` (PNG stores 16-bit samples big-endian).
fn write_u16_png(path: &Path, width: u32, height: u32, values: &[u16]) -> Result<()> {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
    write_png(
        path,
        width,
        height,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &bytes,
    )
}

/// Writes `depth.png`, `labels.png`, `camera.json` and `preview.png` into `dir`.
pub fn write_frame(dir: &Path, scene: &Scene, frame: &Frame) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| file_error(dir, e))?;
    let c = &frame.camera;
    write_u16_png(&dir.join("depth.png"), c.width, c.height, &frame.depth_mm)?;
    write_u16_png(&dir.join("labels.png"), c.width, c.height, &frame.labels)?;
    let (t, q) = (
        c.world_from_camera.translation.vector,
        c.world_from_camera.rotation,
    );
    let k = c.intrinsics;
    let ws = scene.workspace();
    let camera = serde_json::json!({
        "width": c.width, "height": c.height,
        "intrinsics": { "fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy },
        "world_from_camera": { "position": [t.x, t.y, t.z], "orientation": [q.i, q.j, q.k, q.w] },
        "workspace": { "min": [ws.min.x, ws.min.y, ws.min.z], "max": [ws.max.x, ws.max.y, ws.max.z] },
        "scene": {
            "scenario": scene.scenario.name(), "seed": scene.seed, "table_z": scene.table_z,
            "objects": scene.objects.iter().enumerate().map(|(i, o)| serde_json::json!({
                "label": 2 + i, "family": o.model.family.name(), "mass_kg": o.model.mass_kg,
                "position": o.world_from_object.translation.to_array(),
                "orientation": o.world_from_object.rotation.to_array(),
            })).collect::<Vec<_>>(),
        },
    });
    let path = dir.join("camera.json");
    let text = serde_json::to_string_pretty(&camera).map_err(|e| file_error(&path, e))?;
    std::fs::write(&path, text).map_err(|e| file_error(&path, e))?;
    write_png(
        &dir.join("preview.png"),
        c.width,
        c.height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &preview(frame),
    )
}

/// A grasp to draw: pose, opening (m), and whether it worked.
pub type DrawnGrasp = (Isometry3<f64>, f64, bool);

/// Writes the preview of `frame` with each grasp drawn finger to finger
/// (green: it worked; red: it failed) and a dot at its centre.
pub fn write_grasp_snapshot(path: &Path, frame: &Frame, grasps: &[DrawnGrasp]) -> Result<()> {
    let c = &frame.camera;
    let (w, h) = (c.width as i64, c.height as i64);
    let mut rgb = preview(frame);
    let project = |p: Point3<f64>| -> Option<[f64; 2]> {
        let q = c.world_from_camera.inverse_transform_point(&p);
        (q.z > 1e-3).then(|| {
            [
                c.intrinsics.fx * q.x / q.z + c.intrinsics.cx,
                c.intrinsics.fy * q.y / q.z + c.intrinsics.cy,
            ]
        })
    };
    let mut dot = |x: f64, y: f64, colour: [u8; 3], r: i64| {
        for dy in -r..=r {
            for dx in -r..=r {
                let (px, py) = (x.round() as i64 + dx, y.round() as i64 + dy);
                if (0..w).contains(&px) && (0..h).contains(&py) {
                    let at = 3 * (py * w + px) as usize;
                    rgb[at..at + 3].copy_from_slice(&colour);
                }
            }
        }
    };
    for (pose, width, ok) in grasps {
        let colour = if *ok { [40, 230, 60] } else { [240, 40, 40] };
        let ends = [-width / 2.0, width / 2.0].map(|x| project(pose * Point3::new(x, 0.0, 0.0)));
        if let [Some(a), Some(b)] = ends {
            let n = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                dot(a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, colour, 1);
            }
            for end in [a, b] {
                dot(end[0], end[1], colour, 3);
            }
        }
        if let Some(centre) = project(pose * Point3::origin()) {
            dot(centre[0], centre[1], [255, 255, 255], 1);
        }
    }
    write_png(
        path,
        c.width,
        c.height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb,
    )
}

/// A distinct, light colour for index `i`.
fn colour(i: usize) -> [u8; 3] {
    let h = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    [
        (h >> 56) as u8 | 0x50,
        (h >> 48) as u8 | 0x50,
        (h >> 40) as u8 | 0x50,
    ]
}

/// Writes panels side by side, each as wide as the frame: the renderer's
/// labels, then each of `segmentations`' detections (one colour each),
/// over the depth in grey (nearer than 1.4 m; lost readings black).
pub fn write_detections(path: &Path, frame: &Frame, segmentations: &[&Segmentation]) -> Result<()> {
    let (w, h) = (frame.camera.width as usize, frame.camera.height as usize);
    let panels = 1 + segmentations.len();
    let mut image = vec![0u8; 3 * w * h * panels];
    let at = |pixel: usize, panel: usize| 3 * ((pixel / w) * panels * w + panel * w + pixel % w);
    for (i, (&d, &label)) in frame.depth_mm.iter().zip(&frame.labels).enumerate() {
        let grey = (255.0 * (1.4 - f64::from(d) / 1000.0).clamp(0.0, 1.0)) as u8 * u8::from(d > 0);
        for panel in 0..panels {
            let c = if panel == 0 && label >= 2 {
                colour(usize::from(label))
            } else {
                [grey; 3]
            };
            image[at(i, panel)..][..3].copy_from_slice(&c);
        }
    }
    for (panel, seg) in segmentations.iter().enumerate() {
        for (d, cluster) in seg.clusters.iter().enumerate() {
            for &p in cluster {
                let i = seg.pixels[p as usize] as usize;
                image[at(i, panel + 1)..][..3].copy_from_slice(&colour(100 + d));
            }
        }
    }
    write_png(
        path,
        (panels * w) as u32,
        h as u32,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &image,
    )
}

/// Depth in grey (near = bright), objects tinted by label, lost readings black.
fn preview(frame: &Frame) -> Vec<u8> {
    let valid = frame.depth_mm.iter().copied().filter(|&d| d > 0);
    let (near, far) = valid.fold((u16::MAX, 0), |(lo, hi), d| (lo.min(d), hi.max(d)));
    let span = f64::from(far.saturating_sub(near).max(1));
    const TINTS: [[f64; 3]; 6] = [
        [1.0, 0.45, 0.45],
        [0.45, 1.0, 0.45],
        [0.45, 0.6, 1.0],
        [1.0, 0.9, 0.4],
        [0.9, 0.5, 1.0],
        [0.4, 1.0, 1.0],
    ];
    frame
        .depth_mm
        .iter()
        .zip(&frame.labels)
        .flat_map(|(&d, &label)| {
            if d == 0 {
                return [0, 0, 0];
            }
            let g = 235.0 - f64::from(d - near) / span * 190.0;
            let tint = if label >= 2 {
                TINTS[(label as usize - 2) % TINTS.len()]
            } else {
                [1.0; 3]
            };
            [(g * tint[0]) as u8, (g * tint[1]) as u8, (g * tint[2]) as u8]
        })
        .collect()
}
