//! The gravity-aligned object frame (DESIGN.md, method step 2).
//!
//! Origin at the centroid of the object's points; Z = world up (minus
//! gravity); X = the first principal axis of the points projected on the
//! table (PCA of x, y); Y = Z x X. X is signed to point towards the camera
//! (horizontally), so the "front" view always looks at the side the camera
//! saw; with the camera straight above the object (< 1 cm off horizontally)
//! X is signed to point along world +x instead (then +y).
//!
//! The moments are summed as integers (1 um units, truncated), so the frame is
//! bit-identical whatever order the points come in: a shuffled cloud gives
//! the same frame, even for objects whose cross-section is round.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// An object's frame and the box its points fill in that frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectFrame {
    /// Maps object-frame points to the world.
    pub world_from_object: Isometry3<f64>,
    /// Lower corner of the points' bounding box, object frame (m).
    pub extent_min_m: Vector3<f64>,
    /// Upper corner of the points' bounding box, object frame (m).
    pub extent_max_m: Vector3<f64>,
    /// Points the frame was built from.
    pub point_count: usize,
}

impl ObjectFrame {
    /// The extent as `(min, max)` in f32, the precision it was computed in
    /// (exact: the f64 fields hold f32 values), for
    /// [`crate::OrthoView::render_within`].
    pub fn extent_f32(&self) -> ([f32; 3], [f32; 3]) {
        let f = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        (f(&self.extent_min_m), f(&self.extent_max_m))
    }
}

const MICRONS: f64 = 1e6;

/// Builds the frame of the points `indices` of `points` (world frame) and
/// returns it with those points expressed in it.
pub fn object_frame(
    points: &[[f32; 3]],
    indices: &[u32],
    camera_in_world: &Point3<f64>,
) -> (ObjectFrame, Vec<[f32; 3]>) {
    let n = indices.len().max(1) as i128;
    let (mut sx, mut sy, mut sz) = (0i64, 0i64, 0i64);
    let (mut sxx, mut syy, mut sxy) = (0i128, 0i128, 0i128);
    for &i in indices {
        let p = points[i as usize];
        // Micrometres, truncated: f32 holds whole micrometres up to 16 m,
        // and the cast saturates beyond +-2 km (far outside any workspace).
        let q = |v: f32| i64::from((v * MICRONS as f32) as i32);
        let (x, y, z) = (q(p[0]), q(p[1]), q(p[2]));
        // Linear sums fit i64 for any cluster size; squares need i128 sums.
        sx += x;
        sy += y;
        sz += z;
        sxx += i128::from(x * x);
        syy += i128::from(y * y);
        sxy += i128::from(x * y);
    }
    let (sx, sy, sz) = (i128::from(sx), i128::from(sy), i128::from(sz));
    let centroid = Vector3::new(sx as f64, sy as f64, sz as f64) / (n as f64 * MICRONS);
    // n^2 * covariance, exact.
    let cxx = (n * sxx - sx * sx) as f64;
    let cyy = (n * syy - sy * sy) as f64;
    let cxy = (n * sxy - sx * sy) as f64;
    let theta = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
    let mut x_axis = Vector3::new(theta.cos(), theta.sin(), 0.0);

    let to_camera = Vector3::new(
        camera_in_world.x - centroid.x,
        camera_in_world.y - centroid.y,
        0.0,
    );
    let sign_reference = if to_camera.norm() > 0.01 {
        to_camera
    } else {
        Vector3::new(1.0, 1e-6, 0.0)
    };
    if x_axis.dot(&sign_reference) < 0.0 {
        x_axis = -x_axis;
    }
    let z_axis = Vector3::z();
    let y_axis = z_axis.cross(&x_axis);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_axis, y_axis, z_axis]));
    let world_from_object = Isometry3::from_parts(
        Translation3::from(centroid),
        UnitQuaternion::from_rotation_matrix(&rotation),
    );

    // Object-frame coordinates: R^T (p - c), in f32 for the view renderer.
    let r = rotation.matrix().transpose().cast::<f32>();
    let c = centroid.cast::<f32>();
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    let local: Vec<[f32; 3]> = indices
        .iter()
        .map(|&i| {
            let p = Vector3::from(points[i as usize]) - c;
            let q = r * p;
            let q = [q.x, q.y, q.z];
            for a in 0..3 {
                // Plain comparisons: the points are finite.
                lo[a] = if q[a] < lo[a] { q[a] } else { lo[a] };
                hi[a] = if q[a] > hi[a] { q[a] } else { hi[a] };
            }
            q
        })
        .collect();
    let (lo, hi) = if indices.is_empty() {
        (Vector3::zeros(), Vector3::zeros())
    } else {
        (Vector3::from(lo), Vector3::from(hi))
    };
    let frame = ObjectFrame {
        world_from_object,
        extent_min_m: lo.cast(),
        extent_max_m: hi.cast(),
        point_count: indices.len(),
    };
    (frame, local)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elongated_object_gets_its_long_axis_as_x_towards_the_camera() {
        // A 20 x 4 cm slab, long along world (1, 1)/sqrt 2.
        let (c, s) = (std::f32::consts::FRAC_1_SQRT_2, std::f32::consts::FRAC_1_SQRT_2);
        let mut points = Vec::new();
        for i in 0..100 {
            for j in 0..20 {
                let (a, b) = ((i as f32 - 49.5) * 0.002, (j as f32 - 9.5) * 0.002);
                points.push([0.5 + a * c - b * s, 0.2 + a * s + b * c, 0.03]);
            }
        }
        let indices: Vec<u32> = (0..points.len() as u32).collect();
        let camera_behind = Point3::new(-1.0, -1.0, 1.0);
        let (frame, local) = object_frame(&points, &indices, &camera_behind);
        let x = frame.world_from_object.rotation * Vector3::x();
        assert!(
            (x - Vector3::new(-1.0, -1.0, 0.0).normalize()).norm() < 1e-6,
            "{x}"
        );
        assert!((frame.world_from_object.translation.vector - Vector3::new(0.5, 0.2, 0.03)).norm() < 1e-3);
        assert!((frame.extent_max_m.x - frame.extent_min_m.x - 0.198).abs() < 1e-3);
        assert!((frame.extent_max_m.y - frame.extent_min_m.y - 0.038).abs() < 1e-3);
        assert_eq!(local.len(), points.len());
    }
}
