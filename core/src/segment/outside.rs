//! What stands on the table outside the workspace, as boxes: not planned,
//! but reported, so that an arm on its way to a grasp does not hit an
//! object it was never asked to pick (one that rolled out of the bin's
//! square, a cup left beside it).
//!
//! The points are binned into square cells on the world's x-y; touching
//! occupied cells (8-neighbourhood) form one obstacle, whose box runs from
//! the table up to its highest point. The boxes are world-axis-aligned and
//! err on the large side: two objects closer than a cell become one box.
//!
//! Where the workspace's border cuts a detected object, its surface runs
//! on across the border: the cells that continue it (tops level with the
//! object's points beside them, then with each other) are the rest of it,
//! boxed apart from a neighbour that lies against it with a step in height.

use nalgebra::Vector3;
use rustc_hash::{FxHashMap, FxHashSet};

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
    /// Most a detected object's surface steps where it runs on outside the
    /// workspace (m): between the tops of its points in a cell and of the
    /// outside points within a cell of them, then between touching outside
    /// cells. A surface sloping 55 degrees steps this much over a 2 cm cell.
    pub continue_step_m: f64,
}

impl Default for ObstacleConfig {
    fn default() -> Self {
        Self {
            stride: 4,
            cell_m: 0.02,
            min_points: 6,
            max_obstacles: 32,
            continue_step_m: 0.03,
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
    /// The detected object it continues (an object the workspace's border
    /// cuts): the rest of it, whose surface runs on from the object's
    /// points inside and reaches no other object's.
    pub object_id: Option<u32>,
}

/// The objects detected inside the workspace: their points (world) and,
/// per object id, the indices of its points.
#[derive(Debug, Clone, Copy)]
pub struct Detected<'a> {
    /// The points above the table inside the workspace (world, m).
    pub points: &'a [[f32; 3]],
    /// Per object id, the indices of its points in `points`.
    pub objects: &'a [Vec<u32>],
}

/// Points binned together and where they reach on x-y and in height.
#[derive(Debug, Clone, Copy)]
struct Extent {
    count: usize,
    min: [f64; 2],
    max: [f64; 2],
    top: f64,
}

impl Extent {
    const EMPTY: Self = Self {
        count: 0,
        min: [f64::INFINITY; 2],
        max: [f64::NEG_INFINITY; 2],
        top: f64::NEG_INFINITY,
    };

    fn add(&mut self, x: f64, y: f64, z: f64) {
        self.merge(&Self {
            count: 1,
            min: [x, y],
            max: [x, y],
            top: z,
        });
    }

    fn merge(&mut self, other: &Self) {
        self.count += other.count;
        for i in 0..2 {
            self.min[i] = self.min[i].min(other.min[i]);
            self.max[i] = self.max[i].max(other.max[i]);
        }
        self.top = self.top.max(other.top);
    }
}

type Key = (i64, i64);

/// A point's coordinates, when all are finite.
fn finite(p: &[f32; 3]) -> Option<(f64, f64, f64)> {
    let (x, y, z) = (f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
    (x.is_finite() && y.is_finite() && z.is_finite()).then_some((x, y, z))
}

/// The cell of `(x, y)`; saturating, so far-off points (a pose 1e30 m away)
/// land in the edge cells.
fn key(x: f64, y: f64, cell: f64) -> Key {
    ((x / cell).floor() as i64, (y / cell).floor() as i64)
}

/// The 8-neighbourhood of `k` and `k` itself.
fn around(k: Key) -> impl Iterator<Item = Key> {
    (-1..=1).flat_map(move |dx| (-1..=1).map(move |dy| (k.0.saturating_add(dx), k.1.saturating_add(dy))))
}

/// Whose rest an outside cell is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Rest {
    Nobody,
    Of(u32),
    /// Reached from two objects' surfaces: a heap at the border, no one's.
    Shared,
}

/// The obstacle boxes of `points` (world, above `table`), most points
/// first, at most `config.max_obstacles` (a group of touching cells with
/// fewer than `config.min_points` is dropped). `dropped` counts the groups
/// past the cap. The boxes that continue one of `detected`'s objects carry
/// its id.
pub fn outside_obstacles(
    points: &[[f32; 3]],
    detected: Detected<'_>,
    table: &TablePlane,
    config: &ObstacleConfig,
) -> (Vec<OutsideObstacle>, usize) {
    let cell = config.cell_m.max(1e-3);
    let mut by_key: FxHashMap<Key, Extent> = FxHashMap::default();
    for (x, y, z) in points.iter().filter_map(finite) {
        by_key
            .entry(key(x, y, cell))
            .or_insert(Extent::EMPTY)
            .add(x, y, z);
    }
    // A fixed order of the cells, so the answer does not depend on hashing.
    let mut keys: Vec<Key> = by_key.keys().copied().collect();
    keys.sort_unstable();
    let cells: Vec<Extent> = keys.iter().map(|k| by_key[k]).collect();
    let index: FxHashMap<Key, usize> = keys.iter().enumerate().map(|(i, &k)| (k, i)).collect();
    let rests = rests(&keys, &cells, &index, detected, cell, config.continue_step_m);
    let owner = |i: usize| match rests[i] {
        Rest::Of(o) => Some(o),
        Rest::Nobody | Rest::Shared => None,
    };

    let mut sets = UnionFind::new(keys.len());
    for (i, &(cx, cy)) in keys.iter().enumerate() {
        // Half of the 8-neighbourhood: each touching pair once; an object's
        // rest and what lies against it stay apart.
        for (dx, dy) in [(1, -1), (1, 0), (1, 1), (0, 1)] {
            if let Some(&j) = index.get(&(cx.saturating_add(dx), cy.saturating_add(dy))) {
                let (a, b) = (sets.find(i), sets.find(j));
                if a != b && owner(i) == owner(j) {
                    sets.union_roots(a, b);
                }
            }
        }
    }
    let mut groups: FxHashMap<usize, (Extent, Option<u32>)> = FxHashMap::default();
    for (i, extent) in cells.iter().enumerate() {
        let root = sets.find(i);
        groups
            .entry(root)
            .or_insert((Extent::EMPTY, owner(i)))
            .0
            .merge(extent);
    }
    let mut boxes: Vec<OutsideObstacle> = groups
        .into_values()
        .filter(|(g, _)| g.count >= config.min_points.max(1))
        .map(|(g, object_id)| {
            // Grown by half a cell: the strided points miss up to a grid step of each edge.
            let margin = cell / 2.0;
            let (x0, y0) = (g.min[0] - margin, g.min[1] - margin);
            let (x1, y1) = (g.max[0] + margin, g.max[1] + margin);
            let floor = [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]
                .into_iter()
                .map(|(x, y)| table_z(table, x, y))
                .fold(f64::INFINITY, f64::min);
            OutsideObstacle {
                min: Vector3::new(x0, y0, floor.min(g.top)),
                max: Vector3::new(x1, y1, g.top),
                point_count: g.count,
                object_id,
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

/// Per outside cell, whose rest it is: a cell within a cell of an
/// object's points, its top within `step` of theirs there, starts that
/// object's rest, which takes in touching cells whose tops are within
/// `step` of each other.
fn rests(
    keys: &[Key],
    cells: &[Extent],
    index: &FxHashMap<Key, usize>,
    detected: Detected<'_>,
    cell: f64,
    step: f64,
) -> Vec<Rest> {
    let mut rests = vec![Rest::Nobody; keys.len()];
    if keys.is_empty() {
        return rests;
    }
    // The tops of each object's points in the cells beside outside ones.
    let beside: FxHashSet<Key> = keys.iter().flat_map(|&k| around(k)).collect();
    let mut tops: FxHashMap<Key, Vec<(u32, f64)>> = FxHashMap::default();
    for (id, members) in detected.objects.iter().enumerate() {
        let id = id as u32;
        for &i in members {
            let Some((x, y, z)) = detected.points.get(i as usize).and_then(finite) else {
                continue;
            };
            let k = key(x, y, cell);
            if !beside.contains(&k) {
                continue;
            }
            let at = tops.entry(k).or_default();
            match at.iter_mut().find(|(o, _)| *o == id) {
                Some((_, top)) => *top = top.max(z),
                None => at.push((id, z)),
            }
        }
    }
    let mut seeds: Vec<Vec<usize>> = vec![Vec::new(); detected.objects.len()];
    for (i, (&k, c)) in keys.iter().zip(cells).enumerate() {
        for n in around(k) {
            for &(id, top) in tops.get(&n).into_iter().flatten() {
                if (c.top - top).abs() <= step {
                    seeds[id as usize].push(i);
                }
            }
        }
    }
    // The object whose fill last reached each cell.
    let mut reached = vec![u32::MAX; keys.len()];
    let mut stack = Vec::new();
    for (id, seeds) in seeds.into_iter().enumerate() {
        let id = id as u32;
        for s in seeds {
            if reached[s] != id {
                reached[s] = id;
                stack.push(s);
            }
        }
        while let Some(i) = stack.pop() {
            // Each object's fill reaches a cell once: a second owner shares it.
            rests[i] = match rests[i] {
                Rest::Nobody => Rest::Of(id),
                Rest::Of(_) | Rest::Shared => Rest::Shared,
            };
            for n in around(keys[i]) {
                if let Some(&j) = index.get(&n)
                    && reached[j] != id
                    && (cells[j].top - cells[i].top).abs() <= step
                {
                    reached[j] = id;
                    stack.push(j);
                }
            }
        }
    }
    rests
}

/// The table's height at `(x, y)` (its normal has `z > 0`).
fn table_z(table: &TablePlane, x: f64, y: f64) -> f64 {
    let n = &table.normal;
    -(table.offset_m + n.x * x + n.y * y) / n.z
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOTHING: Detected<'static> = Detected {
        points: &[],
        objects: &[],
    };

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
        let (boxes, dropped) =
            outside_obstacles(&points, NOTHING, &level_table(), &ObstacleConfig::default());
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
        let (boxes, _) = outside_obstacles(&points, NOTHING, &level_table(), &ObstacleConfig::default());
        assert_eq!(boxes.len(), 1, "{boxes:?}");
        assert!((boxes[0].max.z - 0.08).abs() < 1e-6);
        // A cap of one keeps the bigger of two and counts the other.
        points.extend(block([-0.5, -0.5, 0.0], [-0.48, -0.48, 0.02], 0.005));
        let config = ObstacleConfig {
            max_obstacles: 1,
            ..ObstacleConfig::default()
        };
        let (boxes, dropped) = outside_obstacles(&points, NOTHING, &level_table(), &config);
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
        let (boxes, _) = outside_obstacles(&points, NOTHING, &level_table(), &config);
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
        let (boxes, _) = outside_obstacles(&points, NOTHING, &table, &ObstacleConfig::default());
        assert_eq!(boxes.len(), 1);
        // The low corner x = 0.29: the plane there is at z = 0.029.
        assert!((boxes[0].min.z - 0.029).abs() < 1e-6, "{:?}", boxes[0]);
    }

    /// The boxes of `outside` beside one object inside the workspace (its
    /// points `inside`, id 0): each box's object and top (mm), lowest first.
    fn beside_one_object(inside: &[[f32; 3]], outside: &[[f32; 3]]) -> Vec<(Option<u32>, i64)> {
        let objects = [(0..inside.len() as u32).collect::<Vec<_>>()];
        let detected = Detected {
            points: inside,
            objects: &objects,
        };
        let (boxes, _) = outside_obstacles(outside, detected, &level_table(), &ObstacleConfig::default());
        let mut found: Vec<_> = boxes
            .iter()
            .map(|b| (b.object_id, (b.max.z * 1000.0).round() as i64))
            .collect();
        found.sort_by_key(|b| b.1);
        found
    }

    #[test]
    fn the_rest_of_a_cut_object_is_its_own_and_a_neighbour_against_it_is_no_ones() {
        // A box 8 cm high cut by the border at x = 0.3: 4 cm inside, 5 cm out.
        let inside = block([0.26, 0.0, 0.0], [0.298, 0.06, 0.08], 0.005);
        let rest = block([0.302, 0.0, 0.0], [0.35, 0.06, 0.08], 0.005);
        let found = beside_one_object(&inside, &rest);
        assert_eq!(found, [(Some(0), 80)]);
        // A can 15 cm high lying against the rest: its own box, no one's,
        // though its cells touch the rest's (one box before 2026-12-01).
        let mut outside = rest.clone();
        outside.extend(block([0.355, 0.0, 0.0], [0.41, 0.06, 0.15], 0.005));
        let found = beside_one_object(&inside, &outside);
        assert_eq!(found, [(Some(0), 80), (None, 150)]);
        // The rest sloping down 2 cm per cell (a lying cylinder's side) is still the rest.
        let mut slope = Vec::new();
        for i in 0..6 {
            let x0 = 0.302 + 0.01 * i as f32;
            slope.extend(block(
                [x0, 0.0, 0.0],
                [x0 + 0.008, 0.06, 0.08 - 0.01 * i as f32],
                0.004,
            ));
        }
        assert_eq!(beside_one_object(&inside, &slope), [(Some(0), 80)]);
    }

    #[test]
    fn a_neighbour_across_the_border_from_an_uncut_object_is_no_ones() {
        // A low box 3 cm high inside, its edge at the border; a 12 cm box just outside.
        let inside = block([0.22, 0.0, 0.0], [0.298, 0.06, 0.03], 0.005);
        let outside = block([0.302, 0.0, 0.0], [0.36, 0.06, 0.12], 0.005);
        assert_eq!(beside_one_object(&inside, &outside), [(None, 120)]);
        // Far from any object: no one's either.
        let far = block([0.6, 0.3, 0.0], [0.66, 0.36, 0.08], 0.005);
        assert_eq!(beside_one_object(&inside, &far), [(None, 80)]);
    }

    #[test]
    fn a_rest_two_objects_run_on_into_is_no_ones() {
        // Two boxes 8 cm high inside, side by side on y, both cut at x = 0.3,
        // their outer halves one surface (a heap at the border).
        let mut inside = block([0.26, 0.0, 0.0], [0.298, 0.05, 0.08], 0.005);
        let first = inside.len() as u32;
        inside.extend(block([0.26, 0.055, 0.0], [0.298, 0.1, 0.08], 0.005));
        let objects = [
            (0..first).collect::<Vec<_>>(),
            (first..inside.len() as u32).collect::<Vec<_>>(),
        ];
        let detected = Detected {
            points: &inside,
            objects: &objects,
        };
        let outside = block([0.302, 0.0, 0.0], [0.35, 0.1, 0.08], 0.005);
        let (boxes, _) = outside_obstacles(&outside, detected, &level_table(), &ObstacleConfig::default());
        assert_eq!(boxes.len(), 1, "{boxes:?}");
        assert_eq!(boxes[0].object_id, None);
    }
}
