//! Pinhole intrinsics (OpenCV convention: x right, y down, z forward).

use nalgebra::Point3;

use crate::error::{Error, Result};

/// Pinhole camera intrinsics in pixels; no distortion (rectified frames).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
}

impl Intrinsics {
    /// Checks every value is finite, and focal lengths are positive.
    pub fn validate(&self, field: &'static str) -> Result<()> {
        for (name, value) in [("fx", self.fx), ("fy", self.fy)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(Error::invalid(
                    format!("{field}.{name}"),
                    format!("focal length must be finite and positive, got {value}"),
                ));
            }
        }
        for (name, value) in [("cx", self.cx), ("cy", self.cy)] {
            if !value.is_finite() {
                return Err(Error::invalid(
                    format!("{field}.{name}"),
                    format!("principal point must be finite, got {value}"),
                ));
            }
        }
        Ok(())
    }

    /// The camera-frame point seen at pixel `(u, v)` (pixel centres at integer
    /// coordinates, as OpenCV) with depth `z_m` along the optical axis.
    pub fn unproject(&self, u: f64, v: f64, z_m: f64) -> Point3<f64> {
        Point3::new((u - self.cx) / self.fx * z_m, (v - self.cy) / self.fy * z_m, z_m)
    }

    /// Pixel coordinates and depth of a camera-frame point; `None` behind the camera.
    pub fn project(&self, p_in_camera: &Point3<f64>) -> Option<(f64, f64, f64)> {
        (p_in_camera.z > 0.0).then(|| {
            (
                self.fx * p_in_camera.x / p_in_camera.z + self.cx,
                self.fy * p_in_camera.y / p_in_camera.z + self.cy,
                p_in_camera.z,
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_focal_length_names_the_field() {
        let k = Intrinsics {
            fx: 0.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
        };
        let err = k.validate("depth.intrinsics").unwrap_err();
        assert!(err.to_string().contains("depth.intrinsics.fx"), "{err}");
        let k = Intrinsics {
            fx: 500.0,
            fy: 500.0,
            cx: f64::NAN,
            cy: 240.0,
        };
        let err = k.validate("depth.intrinsics").unwrap_err();
        assert!(err.to_string().contains("depth.intrinsics.cx"), "{err}");
    }
}
