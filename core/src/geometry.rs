//! Poses, the workspace box and the small numeric helpers shared by the stages.

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::error::{Error, Result};

/// How far a quaternion's norm may stray from 1 before it is rejected rather
/// than normalised.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// A rigid transform from its parts, validated: finite numbers, and a
/// quaternion `(x, y, z, w)` of norm within [`QUATERNION_NORM_TOLERANCE`] of 1
/// (normalised), else an error naming `field`.
pub fn pose_from_parts(
    field: &'static str,
    position: [f64; 3],
    quaternion_xyzw: [f64; 4],
) -> Result<Isometry3<f64>> {
    if position.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            format!("{field}.position"),
            format!("must be finite, got {position:?}"),
        ));
    }
    let [x, y, z, w] = quaternion_xyzw;
    if quaternion_xyzw.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            format!("{field}.orientation"),
            format!("must be finite, got {quaternion_xyzw:?}"),
        ));
    }
    let q = Quaternion::new(w, x, y, z);
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(Error::invalid(
            format!("{field}.orientation"),
            format!("quaternion norm is {norm:.6}; it must be 1 within {QUATERNION_NORM_TOLERANCE}"),
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(position[0], position[1], position[2]),
        UnitQuaternion::new_normalize(q),
    ))
}

/// An axis-aligned box in the world frame; points outside it are ignored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Workspace {
    /// Lower corner, world frame (m).
    pub min: Point3<f64>,
    /// Upper corner, world frame (m).
    pub max: Point3<f64>,
}

impl Workspace {
    /// A validated box: finite corners and `min < max` on every axis.
    pub fn new(min: [f64; 3], max: [f64; 3]) -> Result<Self> {
        Self::named("workspace", min, max)
    }

    /// [`Self::new`] for a box that errors call `field` (e.g. a request's
    /// `obstacle_region`).
    pub fn named(field: &'static str, min: [f64; 3], max: [f64; 3]) -> Result<Self> {
        for (corner_name, corner) in [("min", min), ("max", max)] {
            if corner.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    format!("{field}.{corner_name}"),
                    format!("must be finite, got {corner:?}"),
                ));
            }
        }
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            if min[axis] >= max[axis] {
                return Err(Error::invalid(
                    field,
                    format!(
                        "min.{name} ({}) must be below max.{name} ({})",
                        min[axis], max[axis]
                    ),
                ));
            }
        }
        Ok(Self {
            min: min.into(),
            max: max.into(),
        })
    }

    /// The box as f32 bounds, for the per-point crop.
    pub(crate) fn bounds_f32(&self) -> ([f32; 3], [f32; 3]) {
        (
            [self.min.x as f32, self.min.y as f32, self.min.z as f32],
            [self.max.x as f32, self.max.y as f32, self.max.z as f32],
        )
    }
}

/// World "up" (gravity is -z).
pub fn world_up() -> Vector3<f64> {
    Vector3::z()
}

/// The pose of a camera at `eye` looking at `target` (OpenCV axes: z forward,
/// x right, y down), with the image's up as close to world up as it can be.
pub fn camera_looking_at(eye: Vector3<f64>, target: Vector3<f64>) -> Isometry3<f64> {
    let z = (target - eye).normalize();
    let x = z
        .cross(&Vector3::z())
        .try_normalize(1e-9)
        .unwrap_or_else(Vector3::x);
    let y = z.cross(&x);
    let rotation = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[x, y, z]));
    Isometry3::from_parts(
        Translation3::from(eye),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_unit_quaternion_is_normalised() {
        let pose = pose_from_parts("world_from_camera", [0.0; 3], [0.0, 0.0, 0.0, 1.0005]);
        let Ok(pose) = pose else {
            panic!("rejected: {pose:?}")
        };
        assert!((pose.rotation.quaternion().norm() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_quaternions_are_rejected_naming_the_field() {
        for q in [
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.01],
            [f64::NAN, 0.0, 0.0, 1.0],
        ] {
            let err = pose_from_parts("world_from_camera", [0.0; 3], q).unwrap_err();
            assert!(err.to_string().contains("world_from_camera.orientation"), "{err}");
        }
        let err = pose_from_parts(
            "world_from_camera",
            [f64::INFINITY, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        )
        .unwrap_err();
        assert!(err.to_string().contains("world_from_camera.position"), "{err}");
    }

    #[test]
    fn inverted_workspace_is_rejected() {
        let err = Workspace::new([0.0, 0.0, 1.0], [1.0, 1.0, 0.0]).unwrap_err();
        assert!(err.to_string().contains("min.z"), "{err}");
        assert!(Workspace::new([0.0; 3], [1.0; 3]).is_ok());
        assert!(Workspace::new([f64::NAN, 0.0, 0.0], [1.0; 3]).is_err());
    }
}
