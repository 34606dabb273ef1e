//! The table: a RANSAC plane with a gravity prior, then everything on or below
//! it is removed.
//!
//! Hypotheses are planes through three sampled points whose normal lies
//! within `max_tilt_rad` of world up; the one with most support wins and is
//! refined by least squares on its inliers. The table height is never assumed.
//! A plane with more than `max_below_fraction` of the points over 2 cm under
//! it is rejected: the table holds things up, so a box top (or several at one
//! height) seen without the table around it is not taken for it.
//! When no hypothesis reaches `min_support_fraction` of the sample the stage
//! fails with [`Error::NoTablePlane`] rather than guessing a plane: a planner
//! that invents a table would send fingers into it.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::error::{Error, Result};
use crate::rng::SplitMix64;
use crate::sensor::Above;

/// Settings of the table stage.
#[derive(Debug, Clone, PartialEq)]
pub struct TableConfig {
    /// Largest angle between the table normal and world up (rad).
    pub max_tilt_rad: f64,
    /// Point-to-plane distance that counts as support (m).
    pub inlier_distance_m: f64,
    /// RANSAC hypotheses.
    pub iterations: usize,
    /// Points sampled (with replacement) to score hypotheses.
    pub sample_points: usize,
    /// Share of the sample a plane must hold to be accepted.
    pub min_support_fraction: f64,
    /// Points less than this above the plane count as table (m).
    pub object_min_height_m: f64,
    /// A plane with more than this share of the sample further than
    /// `below_margin_m` under it is not the table.
    pub max_below_fraction: f64,
    /// See `max_below_fraction` (m).
    pub below_margin_m: f64,
    /// Seed of the sampling stream.
    pub seed: u64,
    /// After the fit, only the `mask_stride` x `mask_stride` pixel blocks of
    /// a depth image near points above the plane are converted (1 = all).
    pub mask_stride: usize,
}

impl Default for TableConfig {
    fn default() -> Self {
        Self {
            max_tilt_rad: 10f64.to_radians(),
            inlier_distance_m: 0.006,
            iterations: 96,
            sample_points: 2048,
            min_support_fraction: 0.08,
            object_min_height_m: 0.008,
            max_below_fraction: 0.05,
            below_margin_m: 0.02,
            seed: 0x7AB1E,
            mask_stride: 4,
        }
    }
}

/// The supporting plane: `height(p) = normal . p + offset_m`, normal pointing up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TablePlane {
    /// Unit normal, world frame, `z > 0`.
    pub normal: Vector3<f64>,
    /// Plane offset (m).
    pub offset_m: f64,
    /// Share of the scored sample within `inlier_distance_m` of the plane.
    pub support: f64,
}

impl TablePlane {
    /// Signed height of a world point above the plane (m).
    pub fn height_of(&self, p: &Vector3<f64>) -> f64 {
        self.normal.dot(p) + self.offset_m
    }

    /// The half-space more than `min_height_m` above the plane.
    pub fn above(&self, min_height_m: f64) -> Above {
        let n = self.normal.cast::<f32>();
        Above {
            normal: [n.x, n.y, n.z],
            offset: (self.offset_m - min_height_m) as f32,
        }
    }
}

/// Hypotheses drawn at least, whatever the support.
const MIN_ITERATIONS: usize = 16;

/// Finds the table plane in `points` (world frame).
pub fn fit_table(points: &[[f32; 3]], config: &TableConfig) -> Result<TablePlane> {
    let mut rng = SplitMix64::new(config.seed ^ points.len() as u64);
    let to_f64 = |p: &[f32; 3]| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
    // Few enough points (a random sample already): score them all.
    let sample: Vec<Vector3<f64>> = if points.len() <= config.sample_points {
        points.iter().map(to_f64).collect()
    } else {
        (0..config.sample_points)
            .map(|_| to_f64(&points[rng.below(points.len())]))
            .collect()
    };
    let required = ((sample.len() as f64 * config.min_support_fraction).ceil() as usize).max(3);
    let min_up = config.max_tilt_rad.cos();
    let mut best: Option<(usize, Vector3<f64>, f64)> = None;
    // Adaptive stop: once the best support w makes missing a better plane
    // unlikely (1 - w^3)^k < 1e-4, more hypotheses are wasted.
    let mut needed = config.iterations;
    let mut done = 0;
    while done < needed.min(config.iterations) {
        done += 1;
        if sample.len() < 3 {
            break;
        }
        let a = sample[rng.below(sample.len())];
        let b = sample[rng.below(sample.len())];
        let c = sample[rng.below(sample.len())];
        let Some(normal) = (b - a).cross(&(c - a)).try_normalize(1e-12) else {
            continue;
        };
        let normal = if normal.z < 0.0 { -normal } else { normal };
        if normal.z < min_up {
            continue;
        }
        let offset = -normal.dot(&a);
        let (support, below) = score(&sample, &normal, offset, config);
        // A table holds the objects up: a plane with much of the scene under
        // it is a box top (or the wall of a bin), not the table.
        if below as f64 > config.max_below_fraction * sample.len() as f64 {
            continue;
        }
        // Most support wins; on a tie the lower plane (the table under a box top).
        let better = match best {
            None => true,
            Some((s, n, o)) => support > s || (support == s && offset / normal.z > o / n.z),
        };
        if better {
            best = Some((support, normal, offset));
            let w = support as f64 / sample.len() as f64;
            let miss = (1.0 - w * w * w).max(1e-12);
            needed = ((1e-4f64).ln() / miss.ln()).ceil().max(MIN_ITERATIONS as f64) as usize;
        }
    }
    let fail = |best_inliers| Error::NoTablePlane {
        best_inliers,
        sampled: sample.len(),
        required,
        max_tilt_deg: config.max_tilt_rad.to_degrees(),
    };
    let Some((support, normal, offset)) = best else {
        return Err(fail(0));
    };
    if support < required {
        return Err(fail(support));
    }
    let (normal, offset) =
        refine(&sample, &normal, offset, config.inlier_distance_m, min_up).unwrap_or((normal, offset));
    let (support, _) = score(&sample, &normal, offset, config);
    Ok(TablePlane {
        normal,
        offset_m: offset,
        support: support as f64 / sample.len() as f64,
    })
}

/// Points within the inlier distance of the plane, and points more than
/// `below_margin_m` under it.
fn score(
    sample: &[Vector3<f64>],
    normal: &Vector3<f64>,
    offset: f64,
    config: &TableConfig,
) -> (usize, usize) {
    let (mut within, mut below) = (0, 0);
    for p in sample {
        let h = normal.dot(p) + offset;
        within += usize::from(h.abs() <= config.inlier_distance_m);
        below += usize::from(h < -config.below_margin_m);
    }
    (within, below)
}

/// Least-squares plane through the inliers of a hypothesis; `None` when the
/// refit is degenerate or tilts past the limit.
fn refine(
    sample: &[Vector3<f64>],
    normal: &Vector3<f64>,
    offset: f64,
    distance: f64,
    min_up: f64,
) -> Option<(Vector3<f64>, f64)> {
    let inliers: Vec<&Vector3<f64>> = sample
        .iter()
        .filter(|p| (normal.dot(p) + offset).abs() <= distance)
        .collect();
    if inliers.len() < 3 {
        return None;
    }
    let centroid = inliers.iter().fold(Vector3::zeros(), |acc, p| acc + **p) / inliers.len() as f64;
    let covariance = inliers.iter().fold(Matrix3::zeros(), |acc, p| {
        let d = **p - centroid;
        acc + d * d.transpose()
    });
    let eigen = SymmetricEigen::new(covariance);
    let smallest = eigen.eigenvalues.imin();
    let mut refined = eigen.eigenvectors.column(smallest).into_owned();
    if refined.z < 0.0 {
        refined = -refined;
    }
    (refined.z >= min_up).then(|| (refined, -refined.dot(&centroid)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 40 x 40 cm grid at height `z`, tilted by `slope` along x, plus a box
    /// top of 10 x 10 cm at 5 cm above it.
    fn table_with_box(z: f32, slope: f32) -> Vec<[f32; 3]> {
        let mut points = Vec::new();
        for i in 0..80 {
            for j in 0..80 {
                let (x, y) = (i as f32 * 0.005 - 0.2, j as f32 * 0.005 - 0.2);
                if x.abs() < 0.05 && y.abs() < 0.05 {
                    points.push([x, y, z + slope * x + 0.05]);
                } else {
                    points.push([x, y, z + slope * x]);
                }
            }
        }
        points
    }

    #[test]
    fn finds_table_at_any_height_and_small_tilt() {
        for (z, slope) in [(0.0, 0.0), (0.73, 0.0), (-0.4, 0.1)] {
            let points = table_with_box(z, slope);
            let plane = fit_table(&points, &TableConfig::default()).unwrap();
            let expected = Vector3::new(-slope as f64, 0.0, 1.0).normalize();
            assert!(plane.normal.dot(&expected) > 0.9999, "{plane:?}");
            assert!(
                plane
                    .height_of(&Vector3::new(0.1, 0.1, f64::from(z + slope * 0.1)))
                    .abs()
                    < 1e-4
            );
            let half_space = plane.above(0.008);
            let n = half_space.normal;
            let above = points
                .iter()
                .filter(|p| n[0] * p[0] + n[1] * p[1] + n[2] * p[2] + half_space.offset > 0.0)
                .count();
            assert_eq!(above, 20 * 20, "the box top and nothing else");
        }
    }

    #[test]
    fn a_wall_is_not_a_table() {
        let points: Vec<[f32; 3]> = (0..2000)
            .map(|i| [0.0, (i % 50) as f32 * 0.01, (i / 50) as f32 * 0.01])
            .collect();
        let err = fit_table(&points, &TableConfig::default()).unwrap_err();
        assert!(matches!(err, Error::NoTablePlane { .. }), "{err}");
        assert!(err.to_string().contains("no table plane"), "{err}");
    }
}
