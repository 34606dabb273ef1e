//! Test fixture: boxes and cylinders on a table, rendered by exact ray casting
//! into a pinhole depth camera, with a per-pixel object label.
//!
//! Shared by the integration tests and the stage benchmark
//! (`benches/stages.rs` includes this file).

#![allow(dead_code)]

use mvgrasp_core::{DepthEncoding, DepthFrame, Intrinsics, SceneInput, SensorInput, Workspace};
use nalgebra::{Isometry3, Point3, Vector3};

/// A solid standing on (or lying on) the table.
#[derive(Debug, Clone, Copy)]
pub enum Shape {
    /// A box turned by `yaw` about world z.
    Cuboid {
        center: Vector3<f64>,
        yaw: f64,
        half: Vector3<f64>,
    },
    /// A cylinder about `axis` (unit) through `center`.
    Cylinder {
        center: Vector3<f64>,
        axis: Vector3<f64>,
        radius: f64,
        half_length: f64,
    },
}

impl Shape {
    /// A box standing on a table at height `table_z`.
    pub fn standing_box(table_z: f64, x: f64, y: f64, yaw: f64, size: [f64; 3]) -> Self {
        Shape::Cuboid {
            center: Vector3::new(x, y, table_z + size[2] / 2.0),
            yaw,
            half: Vector3::new(size[0], size[1], size[2]) / 2.0,
        }
    }

    /// An upright cylinder standing on a table at height `table_z`.
    pub fn upright_cylinder(table_z: f64, x: f64, y: f64, radius: f64, height: f64) -> Self {
        Shape::Cylinder {
            center: Vector3::new(x, y, table_z + height / 2.0),
            axis: Vector3::z(),
            radius,
            half_length: height / 2.0,
        }
    }

    /// A cylinder lying on the table along world direction `yaw`.
    pub fn lying_cylinder(table_z: f64, x: f64, y: f64, yaw: f64, radius: f64, length: f64) -> Self {
        Shape::Cylinder {
            center: Vector3::new(x, y, table_z + radius),
            axis: Vector3::new(yaw.cos(), yaw.sin(), 0.0),
            radius,
            half_length: length / 2.0,
        }
    }

    /// Ray parameter of the first hit, if any (`dir` unit).
    fn hit(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<f64> {
        match *self {
            Shape::Cuboid { center, yaw, half } => {
                let (c, s) = (yaw.cos(), yaw.sin());
                let to_local = |v: Vector3<f64>| Vector3::new(c * v.x + s * v.y, -s * v.x + c * v.y, v.z);
                let (o, d) = (to_local(origin - center), to_local(*dir));
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                for a in 0..3 {
                    if d[a].abs() < 1e-12 {
                        if o[a].abs() > half[a] {
                            return None;
                        }
                        continue;
                    }
                    let (ta, tb) = ((-half[a] - o[a]) / d[a], (half[a] - o[a]) / d[a]);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                (t0 <= t1 && t0 > 0.0).then_some(t0)
            }
            Shape::Cylinder {
                center,
                axis,
                radius,
                half_length,
            } => {
                let o = origin - center;
                let (oa, da) = (o.dot(&axis), dir.dot(&axis));
                let (op, dp) = (o - oa * axis, dir - da * axis);
                let mut best = f64::INFINITY;
                let a = dp.norm_squared();
                if a > 1e-12 {
                    let b = 2.0 * op.dot(&dp);
                    let c = op.norm_squared() - radius * radius;
                    let disc = b * b - 4.0 * a * c;
                    if disc >= 0.0 {
                        let t = (-b - disc.sqrt()) / (2.0 * a);
                        if t > 0.0 && (oa + t * da).abs() <= half_length {
                            best = t;
                        }
                    }
                }
                if da.abs() > 1e-12 {
                    for cap in [-half_length, half_length] {
                        let t = (cap - oa) / da;
                        if t > 0.0 && t < best && (op + t * dp).norm_squared() <= radius * radius {
                            best = t;
                        }
                    }
                }
                best.is_finite().then_some(best)
            }
        }
    }
}

/// A table (a horizontal rectangle) with shapes on it.
#[derive(Debug, Clone)]
pub struct Scene {
    pub table_z: f64,
    pub table_half: [f64; 2],
    pub shapes: Vec<Shape>,
}

/// A pinhole camera.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    pub world_from_camera: Isometry3<f64>,
}

impl Camera {
    /// A camera at `eye` looking at `target` (OpenCV axes, image up ~ world up).
    pub fn looking_at(
        eye: Vector3<f64>,
        target: Vector3<f64>,
        width: u32,
        height: u32,
        focal_px: f64,
    ) -> Self {
        Self {
            width,
            height,
            intrinsics: Intrinsics {
                fx: focal_px,
                fy: focal_px,
                cx: (f64::from(width) - 1.0) / 2.0,
                cy: (f64::from(height) - 1.0) / 2.0,
            },
            world_from_camera: mvgrasp_core::camera_looking_at(eye, target),
        }
    }

    /// On a circle around `target`: `distance_m` away, `elevation_deg` above the table, at `azimuth_deg`.
    pub fn orbit(target: Vector3<f64>, distance_m: f64, elevation_deg: f64, azimuth_deg: f64) -> Self {
        let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        let eye = target + distance_m * Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
        Self::looking_at(eye, target, 640, 480, 600.0)
    }
}

/// A rendered frame.
pub struct Rendered {
    /// uint16 millimetres, row-major; 0 = no hit.
    pub depth_mm: Vec<u16>,
    /// 0 = nothing, 1 = table, 2 + i = shape i.
    pub labels: Vec<u16>,
}

impl Rendered {
    /// The depth as little-endian bytes, as the wire carries it.
    pub fn depth_bytes(&self) -> Vec<u8> {
        self.depth_mm.iter().flat_map(|d| d.to_le_bytes()).collect()
    }
}

impl Camera {
    /// A uint16-millimetre frame of this camera (`depth_bytes` as from
    /// [`Rendered::depth_bytes`]) as the pipeline takes it.
    pub fn scene_input<'a>(&self, depth_bytes: &'a [u8], workspace: Workspace) -> SceneInput<'a> {
        SceneInput {
            sensor: SensorInput::Depth(DepthFrame {
                width: self.width,
                height: self.height,
                encoding: DepthEncoding::U16Millimetres,
                data: depth_bytes,
                intrinsics: self.intrinsics,
            }),
            world_from_camera: self.world_from_camera,
            workspace,
        }
    }
}

/// Ray casts every pixel centre; depth is the optical-axis z, rounded to mm.
pub fn render(scene: &Scene, camera: &Camera) -> Rendered {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let k = camera.intrinsics;
    let rotation = camera.world_from_camera.rotation;
    let origin = camera.world_from_camera.translation.vector;
    let mut depth_mm = vec![0u16; w * h];
    let mut labels = vec![0u16; w * h];
    for v in 0..h {
        for u in 0..w {
            let ray_cam = Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
            let dir = rotation * ray_cam.normalize();
            let mut best = (f64::INFINITY, 0u16);
            if dir.z.abs() > 1e-12 {
                let t = (scene.table_z - origin.z) / dir.z;
                let p = origin + t * dir;
                if t > 0.0 && p.x.abs() <= scene.table_half[0] && p.y.abs() <= scene.table_half[1] {
                    best = (t, 1);
                }
            }
            for (i, shape) in scene.shapes.iter().enumerate() {
                if let Some(t) = shape.hit(&origin, &dir)
                    && t < best.0
                {
                    best = (t, 2 + i as u16);
                }
            }
            if best.1 != 0 {
                let z = best.0 * ray_cam.normalize().z;
                depth_mm[v * w + u] = (z * 1000.0).round() as u16;
                labels[v * w + u] = best.1;
            }
        }
    }
    Rendered { depth_mm, labels }
}

/// World points of the pixels labelled `label`, from the rendered depth.
pub fn labelled_points(rendered: &Rendered, camera: &Camera, label: u16) -> Vec<Point3<f64>> {
    let w = camera.width as usize;
    rendered
        .labels
        .iter()
        .enumerate()
        .filter(|(_, l)| **l == label)
        .map(|(i, _)| {
            let z = f64::from(rendered.depth_mm[i]) * 1e-3;
            let p = camera.intrinsics.unproject((i % w) as f64, (i / w) as f64, z);
            camera.world_from_camera * p
        })
        .collect()
}

/// Deterministic objects on a `cols x rows` grid of `pitch_m`, alternating
/// boxes, upright cylinders and lying cylinders, sizes varied by index.
pub fn grid_scene(table_z: f64, count: usize, cols: usize, pitch_m: f64) -> Scene {
    let rows = count.div_ceil(cols);
    let mut shapes = Vec::new();
    for i in 0..count {
        let (c, r) = ((i % cols) as f64, (i / cols) as f64);
        let x = (c - (cols as f64 - 1.0) / 2.0) * pitch_m;
        let y = (r - (rows as f64 - 1.0) / 2.0) * pitch_m;
        let f = (i % 4) as f64;
        shapes.push(match i % 3 {
            0 => Shape::standing_box(table_z, x, y, 0.3 * f, [0.05 + 0.01 * f, 0.035, 0.05 + 0.01 * f]),
            1 => Shape::upright_cylinder(table_z, x, y, 0.025 + 0.003 * f, 0.06 + 0.01 * f),
            _ => Shape::lying_cylinder(table_z, x, y, 0.5 * f, 0.02, 0.07),
        });
    }
    Scene {
        table_z,
        table_half: [0.6, 0.4],
        shapes,
    }
}
