//! The simulated depth camera: a pinhole camera posed around the table, ray
//! casting against the scene (each object's bounding box first, then its
//! compound shape's own bounding-volume tree), and a consumer depth camera's
//! noise.

use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{DepthEncoding, DepthFrame, Intrinsics, SceneInput, SensorInput, Workspace};
use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};

use crate::scene::Scene;

/// A pinhole camera (OpenCV axes: x right, y down, z forward).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Intrinsics (px).
    pub intrinsics: Intrinsics,
    /// Pose in the world.
    pub world_from_camera: Isometry3<f64>,
}

impl Camera {
    /// A camera at `eye` looking at `target`, image up towards world up.
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

    /// A 640x480 camera (fx = fy = 600 px, about a Kinect's field of view)
    /// 0.6-1.2 m from `target` at 30-60 degrees elevation (the paper's
    /// recommendation), any azimuth; or straight down from 0.6-1.2 m.
    pub fn random(rng: &mut SplitMix64, target: Vector3<f64>, top_down: bool) -> Self {
        let distance = rng.uniform(0.6, 1.2);
        let elevation = if top_down { 89.9 } else { rng.uniform(30.0, 60.0) }.to_radians();
        let azimuth = rng.uniform(0.0, std::f64::consts::TAU);
        let eye = target
            + distance
                * Vector3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                );
        Self::looking_at(eye, target, 640, 480, 600.0)
    }
}

/// A consumer depth camera's errors (defaults after Nguyen et al., 2012, for
/// a Kinect): axial noise `sigma = a + b (z - 0.4)^2`, readings lost or
/// smeared at depth edges, millimetre quantisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// `a` of the axial noise (m).
    pub axial_base_m: f64,
    /// `b` of the axial noise (1/m).
    pub axial_quadratic_per_m: f64,
    /// A pixel next to a depth jump larger than this is an edge pixel (m).
    pub edge_jump_m: f64,
    /// Chance an edge pixel has no reading.
    pub edge_dropout: f64,
    /// Chance an edge pixel that kept its reading is a flying pixel (a depth between the two sides).
    pub flying_pixel: f64,
    /// Readings farther than this are lost (m).
    pub max_range_m: f64,
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self {
            axial_base_m: 0.0012,
            axial_quadratic_per_m: 0.0019,
            edge_jump_m: 0.02,
            edge_dropout: 0.5,
            flying_pixel: 0.3,
            max_range_m: 3.0,
        }
    }
}

impl NoiseModel {
    /// Standard deviation of the axial noise at depth `z_m`.
    pub fn sigma_m(&self, z_m: f64) -> f64 {
        self.axial_base_m + self.axial_quadratic_per_m * (z_m - 0.4).powi(2)
    }
}

/// A rendered frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// The camera.
    pub camera: Camera,
    /// Optical-axis depth in millimetres, row-major; 0 = no reading.
    pub depth_mm: Vec<u16>,
    /// What each pixel saw: 0 nothing, 1 the table, 2 + i object i.
    pub labels: Vec<u16>,
}

/// The noiseless optical-axis depth (m) and label of every pixel.
pub fn ray_cast(scene: &Scene, camera: &Camera) -> (Vec<f64>, Vec<u16>) {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let k = camera.intrinsics;
    let pose = camera.world_from_camera;
    let eye = pose.translation.vector;
    let origin = Vector::new(eye.x as f32, eye.y as f32, eye.z as f32);
    let mut depth = vec![f64::INFINITY; w * h];
    let mut labels = vec![0u16; w * h];
    for v in 0..h {
        for u in 0..w {
            let d_cam = Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
            let d_world = pose.rotation * d_cam; // t along this is the optical-axis depth
            let dir = Vector::new(d_world.x as f32, d_world.y as f32, d_world.z as f32);
            let ray = Ray::new(origin, dir);
            let mut best = f64::INFINITY;
            let mut label = 0u16;
            // The table top.
            if d_world.z.abs() > 1e-12 {
                let t = (f64::from(scene.table_z) - eye.z) / d_world.z;
                let p = eye + t * d_world;
                if t > 0.0
                    && p.x.abs() <= f64::from(scene.table_half[0])
                    && p.y.abs() <= f64::from(scene.table_half[1])
                {
                    best = t;
                    label = 1;
                }
            }
            for (i, o) in scene.objects.iter().enumerate() {
                let Some(t_box) = o.world_aabb.cast_local_ray(&ray, best as f32, true) else {
                    continue;
                };
                if f64::from(t_box) >= best {
                    continue;
                }
                if let Some(t) = o
                    .model
                    .shape
                    .cast_ray(&o.world_from_object, &ray, best as f32, true)
                {
                    let t = f64::from(t);
                    if t < best {
                        best = t;
                        label = 2 + i as u16;
                    }
                }
            }
            depth[v * w + u] = best;
            labels[v * w + u] = label;
        }
    }
    (depth, labels)
}

/// Renders `scene` through `camera`, with `noise` drawn from `rng` when given.
pub fn render(scene: &Scene, camera: &Camera, noise: Option<(&NoiseModel, &mut SplitMix64)>) -> Frame {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let (clean, labels) = ray_cast(scene, camera);
    let mut depth = clean.clone();
    if let Some((model, rng)) = noise {
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let z = clean[i];
                if !z.is_finite() {
                    continue;
                }
                // The farthest-apart 4-neighbour decides whether this is an edge.
                let mut other = z;
                for (du, dv) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (x, y) = (u as i64 + du, v as i64 + dv);
                    if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                        continue;
                    }
                    let n = clean[y as usize * w + x as usize];
                    if !n.is_finite() || (n - z).abs() > (other - z).abs() {
                        other = n;
                    }
                }
                let mut reading = z;
                if !other.is_finite() || (other - z).abs() > model.edge_jump_m {
                    if rng.next_f64() < model.edge_dropout {
                        depth[i] = f64::INFINITY;
                        continue;
                    }
                    if other.is_finite() && rng.next_f64() < model.flying_pixel {
                        reading = z + rng.next_f64() * (other - z);
                    }
                }
                reading += model.sigma_m(reading) * rng.gaussian();
                depth[i] = if reading > 0.0 && reading <= model.max_range_m {
                    reading
                } else {
                    f64::INFINITY
                };
            }
        }
    }
    let depth_mm = depth
        .iter()
        .map(|&z| {
            if z.is_finite() && z > 0.0 {
                (z * 1000.0).round().clamp(0.0, f64::from(u16::MAX)) as u16
            } else {
                0
            }
        })
        .collect();
    Frame {
        camera: *camera,
        depth_mm,
        labels,
    }
}

impl Frame {
    /// The depth as little-endian bytes, as the wire and the pipeline carry it.
    pub fn depth_le_bytes(&self) -> Vec<u8> {
        self.depth_mm.iter().flat_map(|d| d.to_le_bytes()).collect()
    }

    /// This frame as the pipeline takes it (`depth_le` from [`Self::depth_le_bytes`]).
    pub fn scene_input<'a>(&self, depth_le: &'a [u8], workspace: Workspace) -> SceneInput<'a> {
        let c = &self.camera;
        SceneInput {
            sensor: SensorInput::Depth(DepthFrame {
                width: c.width,
                height: c.height,
                encoding: DepthEncoding::U16Millimetres,
                data: depth_le,
                intrinsics: c.intrinsics,
            }),
            world_from_camera: c.world_from_camera,
            workspace,
        }
    }

    /// The world points of the pixels labelled `label` (from the stored depth).
    pub fn labelled_points(&self, label: u16) -> Vec<Point3<f64>> {
        let (w, k) = (self.camera.width as usize, self.camera.intrinsics);
        self.depth_mm
            .iter()
            .zip(&self.labels)
            .enumerate()
            .filter(|(_, (d, l))| **d > 0 && **l == label)
            .map(|(i, (d, _))| {
                let z = f64::from(*d) / 1000.0;
                let p = k.unproject((i % w) as f64, (i / w) as f64, z);
                self.camera.world_from_camera * p
            })
            .collect()
    }

    /// The centroid of each of the scene's first `objects` objects (labels
    /// 2, 3, ...) seen with at least `min_points` pixels more than `above_m`
    /// over the table top at `table_z`, with the object's index.
    pub fn visible_centroids(
        &self,
        objects: usize,
        table_z: f64,
        above_m: f64,
        min_points: usize,
    ) -> Vec<(usize, Point3<f64>)> {
        (0..objects)
            .filter_map(|i| {
                let points: Vec<_> = self
                    .labelled_points(2 + i as u16)
                    .into_iter()
                    .filter(|p| p.z > table_z + above_m)
                    .collect();
                (points.len() >= min_points).then(|| {
                    let sum = points.iter().map(|p| p.coords).sum::<Vector3<f64>>();
                    (i, Point3::from(sum / points.len() as f64))
                })
            })
            .collect()
    }
}
