//! The robot's own body where it stands as the frame was taken, as
//! capsules: the points within it are the robot, neither objects to plan
//! for nor obstacles to keep clear of (a self-filter). The robot tells
//! where its links are (its joints read with the frame); the planner only
//! leaves their points out.

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::geometry::Workspace;

/// Most capsules a robot body may have (a 6-axis arm, its base column and
/// hand take about a dozen).
pub const MAX_BODY_CAPSULES: usize = 64;

/// Largest capsule radius taken (m): a link thicker than this is not a link.
pub const MAX_BODY_RADIUS_M: f64 = 2.0;

/// A segment `a`-`b` swept by a sphere of `radius_m` (world frame, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyCapsule {
    /// One end of the axis.
    pub a: Vector3<f64>,
    /// The other end (may equal `a`: a sphere).
    pub b: Vector3<f64>,
    /// Radius (m), in (0, [`MAX_BODY_RADIUS_M`]].
    pub radius_m: f64,
}

impl BodyCapsule {
    /// A capsule, checked as [`check_body`] checks each.
    pub fn new(a: Vector3<f64>, b: Vector3<f64>, radius_m: f64) -> Result<Self> {
        let capsule = Self { a, b, radius_m };
        capsule.check(0)?;
        Ok(capsule)
    }

    fn check(&self, index: usize) -> Result<()> {
        for (end, v) in [("a", &self.a), ("b", &self.b)] {
            if !v.iter().all(|c| c.is_finite()) {
                return Err(Error::invalid(
                    format!("robot_body[{index}].{end}"),
                    format!("must be finite, got {v:?}"),
                ));
            }
        }
        if !(self.radius_m.is_finite() && self.radius_m > 0.0 && self.radius_m <= MAX_BODY_RADIUS_M) {
            return Err(Error::invalid(
                format!("robot_body[{index}].radius_m"),
                format!("must be in (0, {MAX_BODY_RADIUS_M}] m, got {}", self.radius_m),
            ));
        }
        Ok(())
    }
}

/// Checks a body: at most [`MAX_BODY_CAPSULES`], each with finite ends and
/// a radius in (0, [`MAX_BODY_RADIUS_M`]]; errors name the capsule.
pub fn check_body(body: &[BodyCapsule]) -> Result<()> {
    if body.len() > MAX_BODY_CAPSULES {
        return Err(Error::invalid(
            "robot_body",
            format!("at most {MAX_BODY_CAPSULES} capsules, got {}", body.len()),
        ));
    }
    body.iter().enumerate().try_for_each(|(i, c)| c.check(i))
}

/// A capsule as the per-point test takes it.
#[derive(Debug, Clone, Copy)]
struct Segment {
    a: [f32; 3],
    /// `b - a`.
    run: [f32; 3],
    /// `1 / |run|^2`, 0 for a sphere.
    inv_len2: f32,
    radius2: f32,
    /// Its bounding box: most points fail here.
    lo: [f32; 3],
    hi: [f32; 3],
}

/// The capsules of a body that meet a box, for the points inside it.
#[derive(Debug, Clone, Default)]
pub(crate) struct BodyFilter {
    segments: Vec<Segment>,
}

impl BodyFilter {
    /// The capsules of `body` whose bounding box meets `region` (an arm
    /// parked beside the workspace costs its points nothing).
    pub(crate) fn new(body: &[BodyCapsule], region: &Workspace) -> Self {
        let segments = body
            .iter()
            .filter_map(|c| {
                let r = c.radius_m;
                let lo = c.a.inf(&c.b).add_scalar(-r);
                let hi = c.a.sup(&c.b).add_scalar(r);
                let meets = (0..3).all(|i| lo[i] <= region.max[i] && hi[i] >= region.min[i]);
                meets.then(|| {
                    let run = c.b - c.a;
                    let len2 = run.norm_squared();
                    let f = |v: Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
                    Segment {
                        a: f(c.a),
                        run: f(run),
                        inv_len2: if len2 > 1e-18 { (1.0 / len2) as f32 } else { 0.0 },
                        radius2: (r * r) as f32,
                        lo: f(lo),
                        hi: f(hi),
                    }
                })
            })
            .collect();
        Self { segments }
    }

    /// True when no capsule is left to test.
    pub(crate) fn is_empty(&self) -> bool {
        self.segments.is_empty()
    }

    /// True when `p` lies within one of the capsules.
    pub(crate) fn contains(&self, p: &[f32; 3]) -> bool {
        self.segments.iter().any(|s| {
            if (0..3).any(|i| p[i] < s.lo[i] || p[i] > s.hi[i]) {
                return false;
            }
            let d = [p[0] - s.a[0], p[1] - s.a[1], p[2] - s.a[2]];
            let along = (d[0] * s.run[0] + d[1] * s.run[1] + d[2] * s.run[2]) * s.inv_len2;
            let t = along.clamp(0.0, 1.0);
            let off = [d[0] - t * s.run[0], d[1] - t * s.run[1], d[2] - t * s.run[2]];
            off[0] * off[0] + off[1] * off[1] + off[2] * off[2] <= s.radius2
        })
    }

    /// Drops the points within the body, and the pixel of each when
    /// `pixels` has one per point (it may be empty); returns how many.
    pub(crate) fn leave_out(&self, points: &mut Vec<[f32; 3]>, pixels: &mut Vec<u32>) -> usize {
        if self.is_empty() {
            return 0;
        }
        let before = points.len();
        if pixels.len() == points.len() {
            let mut kept = 0;
            for i in 0..points.len() {
                if !self.contains(&points[i]) {
                    points[kept] = points[i];
                    pixels[kept] = pixels[i];
                    kept += 1;
                }
            }
            points.truncate(kept);
            pixels.truncate(kept);
        } else {
            points.retain(|p| !self.contains(p));
        }
        before - points.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region() -> Workspace {
        Workspace::new([-1.0; 3], [1.0; 3]).unwrap()
    }

    #[test]
    fn a_capsule_holds_the_points_within_its_radius_of_its_axis() {
        let c = BodyCapsule::new(Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.5), 0.1).unwrap();
        let body = BodyFilter::new(&[c], &region());
        for inside in [
            [0.0, 0.0, 0.25],
            [0.099, 0.0, 0.4],
            [0.0, 0.0, -0.099],
            [0.05, 0.05, 0.55],
        ] {
            assert!(body.contains(&inside), "{inside:?}");
        }
        // Beside the axis by more than the radius, past an end's cap, or in
        // the bounding box's corner.
        for outside in [
            [0.101, 0.0, 0.25],
            [0.0, 0.0, 0.61],
            [0.0, 0.0, -0.11],
            [0.09, 0.09, 0.59],
        ] {
            assert!(!body.contains(&outside), "{outside:?}");
        }
        // A sphere: both ends at one point.
        let s = BodyCapsule::new(Vector3::new(0.5, 0.0, 0.0), Vector3::new(0.5, 0.0, 0.0), 0.05).unwrap();
        let ball = BodyFilter::new(&[s], &region());
        assert!(ball.contains(&[0.53, 0.0, 0.03]));
        assert!(!ball.contains(&[0.54, 0.0, 0.04]));
    }

    #[test]
    fn capsules_away_from_the_region_are_not_tested() {
        let near = BodyCapsule::new(Vector3::new(1.05, 0.0, 0.0), Vector3::new(1.5, 0.0, 0.0), 0.1).unwrap();
        let far = BodyCapsule::new(Vector3::new(1.2, 0.0, 0.0), Vector3::new(1.5, 0.0, 0.0), 0.1).unwrap();
        assert!(!BodyFilter::new(&[near], &region()).is_empty());
        assert!(BodyFilter::new(&[far], &region()).is_empty());
        assert!(BodyFilter::new(&[], &region()).is_empty());
    }

    #[test]
    fn leaving_out_keeps_each_point_with_its_pixel() {
        let c = BodyCapsule::new(Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 1.0), 0.1).unwrap();
        let body = BodyFilter::new(&[c], &region());
        let mut points = vec![
            [0.5, 0.0, 0.5],
            [0.0, 0.0, 0.5],
            [0.5, 0.5, 0.5],
            [0.05, 0.0, 0.1],
        ];
        let mut pixels = vec![10, 11, 12, 13];
        assert_eq!(body.leave_out(&mut points, &mut pixels), 2);
        assert_eq!(points, vec![[0.5, 0.0, 0.5], [0.5, 0.5, 0.5]]);
        assert_eq!(pixels, vec![10, 12]);
        let mut cloud = vec![[0.0, 0.0, 0.2], [0.3, 0.0, 0.2]];
        assert_eq!(body.leave_out(&mut cloud, &mut Vec::new()), 1);
        assert_eq!(cloud, vec![[0.3, 0.0, 0.2]]);
    }

    #[test]
    fn bad_capsules_are_named() {
        let ok = BodyCapsule::new(Vector3::zeros(), Vector3::z(), 0.1).unwrap();
        let nan = BodyCapsule {
            b: Vector3::new(0.0, f64::NAN, 0.0),
            ..ok
        };
        let err = check_body(&[ok, nan]).unwrap_err().to_string();
        assert!(err.contains("robot_body[1].b"), "{err}");
        for radius in [0.0, -0.1, 2.5, f64::INFINITY] {
            let err = BodyCapsule::new(Vector3::zeros(), Vector3::z(), radius)
                .unwrap_err()
                .to_string();
            assert!(err.contains("robot_body[0].radius_m"), "{err}");
        }
        let err = check_body(&vec![ok; MAX_BODY_CAPSULES + 1])
            .unwrap_err()
            .to_string();
        assert!(err.contains("at most 64"), "{err}");
        assert!(check_body(&vec![ok; MAX_BODY_CAPSULES]).is_ok());
    }
}
