//! Fixtures shared by the hand check's and the repairs' tests: tables,
//! top-down grasps, point blocks and obstacles framed by a pose.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::collision::{Obstacle, hand_collides};
use super::hand::HandConfig;
use crate::gripper::Gripper;
use crate::segment::TablePlane;

pub(super) fn table_at(z: f64) -> TablePlane {
    TablePlane {
        normal: Vector3::z(),
        offset_m: -z,
        support: 1.0,
    }
}

/// A top-down grasp at height `z`: approach -z (world), closing along world x.
pub(super) fn top_down(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    Isometry3::from_parts(Translation3::new(x, y, z), rotation)
}

/// `points` (world frame) as one obstacle, framed by the identity.
pub(super) fn collides(
    grasp: &Isometry3<f64>,
    width: f64,
    hand: &HandConfig,
    table: &TablePlane,
    points: &[[f32; 3]],
) -> bool {
    let identity = Isometry3::identity();
    let (lo, hi) = bounds(points);
    let obstacle = Obstacle {
        world_from_object: &identity,
        extent_min_m: &lo,
        extent_max_m: &hi,
        points,
    };
    let obstacles = if points.is_empty() { vec![] } else { vec![obstacle] };
    hand_collides(
        grasp,
        width,
        &Gripper::default(),
        hand,
        table,
        &obstacles,
        Some(0),
    )
}

/// Points filling a box (world frame) on a 5 mm grid.
pub(super) fn block(lo: [f64; 3], hi: [f64; 3]) -> Vec<[f32; 3]> {
    let mut out = Vec::new();
    let steps = |a: f64, b: f64| ((b - a) / 0.005).round() as usize;
    for i in 0..=steps(lo[0], hi[0]) {
        for j in 0..=steps(lo[1], hi[1]) {
            for k in 0..=steps(lo[2], hi[2]) {
                out.push([
                    (lo[0] + i as f64 * 0.005) as f32,
                    (lo[1] + j as f64 * 0.005) as f32,
                    (lo[2] + k as f64 * 0.005) as f32,
                ]);
            }
        }
    }
    out
}

/// Local points with their box, framed by `world_from_object`.
pub(super) type Framed = (Vec<[f32; 3]>, Vector3<f64>, Vector3<f64>);

/// `points` (object frame) with their box.
pub(super) fn framed(points: Vec<[f32; 3]>) -> Framed {
    let (lo, hi) = bounds(&points);
    (points, lo, hi)
}

/// The box of `points` (their frame).
pub(super) fn bounds(points: &[[f32; 3]]) -> (Vector3<f64>, Vector3<f64>) {
    let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
    for p in points {
        let v = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        lo = lo.inf(&v);
        hi = hi.sup(&v);
    }
    (lo, hi)
}

pub(super) fn obstacle_of<'a>(
    world_from_object: &'a Isometry3<f64>,
    (local, lo, hi): &'a Framed,
) -> Obstacle<'a> {
    Obstacle {
        world_from_object,
        extent_min_m: lo,
        extent_max_m: hi,
        points: local,
    }
}
