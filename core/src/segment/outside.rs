//! What stands on the table outside the workspace, as boxes: not planned,
//! but reported, so that an arm on its way to a grasp does not hit an
//! object it was never asked to pick (one that rolled out of the bin's
//! square, a cup left beside it).
//!
//! The points are binned into square cells on the world's x-y; touching
//! occupied cells (8-neighbourhood) form one obstacle, whose box runs from
//! the table up to its highest point. The boxes are world-axis-aligned and
//! err on the large side: two objects closer than a cell become one box.

use std::collections::HashMap;

use nalgebra::Vector3;

use super::table::TablePlane;
use super::union_find::UnionFind;

/// How the points outside the workspace become obstacle boxes.
#[derive(Debug, Clone, PartialEq)]
pub struct ObstacleConfig {
    /// Rows and columns of a depth image skipped + 1 (every `stride^2`-th
    /// point of a cloud): an obstacle needs no full resolution.
    pub stride: usize,
    /// Side of the square cells the points are binned into (m); also the
    /// margin each box is grown by on every side of the table's plane.
    pub cell_m: f64,
    /// A group of touching cells with fewer points is dropped (noise).
    pub min_points: usize,
    /// At most this many boxes, the ones of most points first.
    pub max_obstacles: usize,
}

impl Default for ObstacleConfig {
    fn default() -> Self {
        Self {
            stride: 4,
            cell_m: 0.02,
            min_points: 6,
            max_obstacles: 32,
        }
    }
}

/// Something seen on the table outside the workspace: a world-frame,
/// axis-aligned box from the table up to its highest point.
#[derive(Debug, Clone, PartialEq)]
pub struct OutsideObstacle {
    /// The box's low corner (world, m): its z is the table's lowest under it.
    pub min: Vector3<f64>,
    /// The box's high corner (world, m).
    pub max: Vector3<f64>,
    /// Points of the (strided) frame inside it.
    pub point_count: usize,
    /// The detected object it continues, when it reaches within a cell of
    /// that object's bounds and no other's (an object the workspace's
    /// border cuts): the rest of it ([`continued_objects`]).
    pub object_id: Option<u32>,
}

/// The obstacle boxes of `points` (world, above `table`), most points
/// first, at most `config.max_obstacles` (a group of touching cells with
/// fewer than `config.min_points` is dropped). `dropped` counts the groups
/// past the cap.
pub fn outside_obstacles(
    points: &[[f32; 3]],
    table: &TablePlane,
    config: &ObstacleConfig,
) -> (Vec<OutsideObstacle>, usize) {
    let cell = config.cell_m.max(1e-3);
    // Per occupied cell: points, then min x, min y, max x, max y, max z.
    let mut cells: HashMap<(i64, i64), (usize, [f64; 5])> = HashMap::new();
    for p in points {
        let (x, y, z) = (f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            continue;
        }
        let key = ((x / cell).floor() as i64, (y / cell).floor() as i64);
        let entry = cells.entry(key).or_insert((
            0,
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
        ));
        entry.0 += 1;
        let b = &mut entry.1;
        b[0] = b[0].min(x);
        b[1] = b[1].min(y);
        b[2] = b[2].max(x);
        b[3] = b[3].max(y);
        b[4] = b[4].max(z);
    }
    // A fixed order of the cells, so the answer does not depend on hashing.
    let mut keys: Vec<(i64, i64)> = cells.keys().copied().collect();
    keys.sort_unstable();
    let index: HashMap<(i64, i64), usize> = keys.iter().enumerate().map(|(i, &k)| (k, i)).collect();
    let mut sets = UnionFind::new(keys.len());
    for (i, &(cx, cy)) in keys.iter().enumerate() {
        // Half of the 8-neighbourhood: each touching pair once.
        for (dx, dy) in [(1, -1), (1, 0), (1, 1), (0, 1)] {
            // Saturating: far-off points (a pose 1e30 m away) land in the edge cells.
            if let Some(&j) = index.get(&(cx.saturating_add(dx), cy.saturating_add(dy))) {
                let (a, b) = (sets.find(i), sets.find(j));
                if a != b {
                    sets.union_roots(a, b);
                }
            }
        }
    }
    let mut groups: HashMap<usize, (usize, [f64; 5])> = HashMap::new();
    for (i, key) in keys.iter().enumerate() {
        let (count, b) = cells[key];
        let root = sets.find(i);
        let g = groups.entry(root).or_insert((
            0,
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
        ));
        g.0 += count;
        g.1[0] = g.1[0].min(b[0]);
        g.1[1] = g.1[1].min(b[1]);
        g.1[2] = g.1[2].max(b[2]);
        g.1[3] = g.1[3].max(b[3]);
        g.1[4] = g.1[4].max(b[4]);
    }
    let mut boxes: Vec<OutsideObstacle> = groups
        .into_values()
        .filter(|(count, _)| *count >= config.min_points.max(1))
        .map(|(count, b)| {
            // Grown by half a cell: the strided points miss up to a grid step of each edge.
            let margin = cell / 2.0;
            let (x0, y0, x1, y1) = (b[0] - margin, b[1] - margin, b[2] + margin, b[3] + margin);
            let floor = [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]
                .into_iter()
                .map(|(x, y)| table_z(table, x, y))
                .fold(f64::INFINITY, f64::min);
            OutsideObstacle {
                min: Vector3::new(x0, y0, floor.min(b[4])),
                max: Vector3::new(x1, y1, b[4]),
                point_count: count,
                object_id: None,
            }
        })
        .collect();
    boxes.sort_by(|a, b| {
        b.point_count
            .cmp(&a.point_count)
            .then(a.min.x.total_cmp(&b.min.x))
            .then(a.min.y.total_cmp(&b.min.y))
    });
    let dropped = boxes.len().saturating_sub(config.max_obstacles);
    boxes.truncate(config.max_obstacles);
    (boxes, dropped)
}

/// Marks each box that reaches within `cell_m` of exactly one object's
/// x-y bounds (`objects`: `[min x, min y, max x, max y]` by id) as
/// continuing that object: the workspace's border cut it, and the box is
/// the rest of it. A box near several objects' bounds (a heap at the
/// border) continues none: it stays an obstacle for every grasp.
pub fn continued_objects(boxes: &mut [OutsideObstacle], objects: &[[f64; 4]], cell_m: f64) {
    for b in boxes {
        let mut near = objects.iter().enumerate().filter(|(_, o)| {
            o[0] - cell_m <= b.max.x
                && b.min.x <= o[2] + cell_m
                && o[1] - cell_m <= b.max.y
                && b.min.y <= o[3] + cell_m
        });
        b.object_id = match (near.next(), near.next()) {
            (Some((i, _)), None) => Some(i as u32),
            _ => None,
        };
    }
}

/// The table's height at `(x, y)` (its normal has `z > 0`).
fn table_z(table: &TablePlane, x: f64, y: f64) -> f64 {
    let n = &table.normal;
    -(table.offset_m + n.x * x + n.y * y) / n.z
}

#[cfg(test)]
mod tests {
    use super::*;

    fn level_table() -> TablePlane {
        TablePlane {
            normal: Vector3::z(),
            offset_m: 0.0,
            support: 1.0,
        }
    }

    /// A filled box's top and sides, sampled every `step` m.
    fn block(lo: [f32; 3], hi: [f32; 3], step: f32) -> Vec<[f32; 3]> {
        let n = |a: f32, b: f32| ((b - a) / step).round() as usize + 1;
        let mut points = Vec::new();
        for i in 0..n(lo[0], hi[0]) {
            for j in 0..n(lo[1], hi[1]) {
                points.push([lo[0] + i as f32 * step, lo[1] + j as f32 * step, hi[2]]);
            }
        }
        points
    }

    #[test]
    fn two_objects_apart_are_two_boxes_from_the_table_to_their_tops() {
        let mut points = block([0.50, 0.10, 0.0], [0.56, 0.14, 0.12], 0.005);
        points.extend(block([-0.60, -0.20, 0.0], [-0.50, -0.12, 0.05], 0.005));
        let (boxes, dropped) = outside_obstacles(&points, &level_table(), &ObstacleConfig::default());
        assert_eq!((boxes.len(), dropped), (2, 0));
        // The larger first; each covers its points, grown by 1 cm, down to the table.
        let (big, small) = (&boxes[0], &boxes[1]);
        assert!(big.point_count > small.point_count);
        assert!(
            (big.min.x - -0.61).abs() < 1e-4 && (big.max.x - -0.49).abs() < 1e-4,
            "{big:?}"
        );
        assert!(
            (big.max.z - 0.05).abs() < 1e-6 && big.min.z.abs() < 1e-9,
            "{big:?}"
        );
        assert!(
            (small.min.y - 0.09).abs() < 1e-4 && (small.max.y - 0.15).abs() < 1e-4,
            "{small:?}"
        );
        assert!((small.max.z - 0.12).abs() < 1e-6, "{small:?}");
    }

    #[test]
    fn touching_cells_join_and_stray_points_and_the_cap_drop() {
        // Two blocks 1.5 cm apart share a neighbourhood of 2 cm cells: one box.
        let mut points = block([0.0, 0.0, 0.0], [0.04, 0.04, 0.03], 0.005);
        points.extend(block([0.055, 0.0, 0.0], [0.09, 0.04, 0.08], 0.005));
        // Three stray readings far away: under min_points.
        points.extend([[1.0, 1.0, 0.2], [1.005, 1.0, 0.2], [1.0, 1.005, 0.2]]);
        let (boxes, _) = outside_obstacles(&points, &level_table(), &ObstacleConfig::default());
        assert_eq!(boxes.len(), 1, "{boxes:?}");
        assert!((boxes[0].max.z - 0.08).abs() < 1e-6);
        // A cap of one keeps the bigger of two and counts the other.
        points.extend(block([-0.5, -0.5, 0.0], [-0.48, -0.48, 0.02], 0.005));
        let config = ObstacleConfig {
            max_obstacles: 1,
            ..ObstacleConfig::default()
        };
        let (boxes, dropped) = outside_obstacles(&points, &level_table(), &config);
        assert_eq!((boxes.len(), dropped), (1, 1));
        assert!((boxes[0].max.z - 0.08).abs() < 1e-6);
    }

    #[test]
    fn far_off_points_do_not_overflow_the_cells() {
        let points = [[3e38_f32, -3e38, 1.0], [3e38, 3e38, 1.0], [-3e38, 3e38, 1.0]].repeat(3);
        let config = ObstacleConfig {
            min_points: 1,
            ..ObstacleConfig::default()
        };
        let (boxes, _) = outside_obstacles(&points, &level_table(), &config);
        assert_eq!(boxes.len(), 3);
        assert!(boxes.iter().all(|b| b.point_count == 3));
    }

    #[test]
    fn a_tilted_table_puts_each_box_floor_at_its_lowest_corner() {
        // z = 0.1 x: the normal (-0.1, 0, 1) normalised, offset 0.
        let n = Vector3::new(-0.1, 0.0, 1.0).normalize();
        let table = TablePlane {
            normal: n,
            offset_m: 0.0,
            support: 1.0,
        };
        let points = block([0.3, 0.0, 0.0], [0.4, 0.05, 0.2], 0.005);
        let (boxes, _) = outside_obstacles(&points, &table, &ObstacleConfig::default());
        assert_eq!(boxes.len(), 1);
        // The low corner x = 0.29: the plane there is at z = 0.029.
        assert!((boxes[0].min.z - 0.029).abs() < 1e-6, "{:?}", boxes[0]);
    }
}
