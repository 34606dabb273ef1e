//! Euclidean clustering of the object points: the connected components of
//! the graph that joins every two points closer than `tolerance_m`. Exact, at
//! point level (no voxel approximation).
//!
//! Points are binned into cubic cells of edge `tolerance_m / sqrt(3)`, so any
//! two points in one cell are within the tolerance and a cell is one node.
//! Two cells can only hold a pair within the tolerance if their offset is at
//! most 2 on every axis (and not 2 on all three); for each such pair of
//! occupied cells, in one direction only, a union-find skips pairs already
//! joined, the cells' point bounding boxes settle most of the rest, and only
//! the remainder compares points (stopping at the first close pair).
//!
//! The cells live in a dense array over the points' bounding box (a hash map
//! when that box would need more than [`MAX_DENSE_CELLS`] cells), so the
//! neighbour lookups are array reads. A k-d tree range search per point
//! (`kiddo`) gives the same components (a test checks it on random clouds)
//! but measured ~60x slower here (BENCHMARKS.md), so it serves as the
//! reference, not the engine.
//!
//! Objects that touch (packed boxes, a pile) merge into one cluster when
//! their visible surfaces meet: nothing in the geometry separates them.
//! Clusters come out in a fixed order (by centroid x, then y, then z, at
//! 0.1 mm), independent of the point order.

use rustc_hash::FxHashMap;

use super::CreaseConfig;
use super::union_find::UnionFind;

/// Settings of the clustering stage.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterConfig {
    /// Points closer than this belong to one object (m).
    pub tolerance_m: f32,
    /// Smaller clusters are noise (points).
    pub min_points: usize,
    /// Larger clusters are not objects (points).
    pub max_points: usize,
    /// At most this many objects are kept (the largest ones).
    pub max_objects: usize,
    /// Split clusters at creases and steps of the depth image (`None`: off,
    /// the default; a point cloud input is never split). Off because real
    /// objects have creases of their own: on the referee's train pool the
    /// split cut them apart and cleared 16 of 192 objects fewer
    /// (docs/experiments/2026-11-28-segmentation-and-hand.md).
    pub crease: Option<CreaseConfig>,
}

impl Default for ClusterConfig {
    fn default() -> Self {
        Self {
            tolerance_m: 0.01,
            min_points: 60,
            max_points: 400_000,
            max_objects: 64,
            crease: None,
        }
    }
}

/// Above this many cells the cell index is a hash map instead of an array.
pub const MAX_DENSE_CELLS: usize = 1 << 22;

/// The clusters as lists of indices into the input points, in the fixed order.
pub fn euclidean_clusters(points: &[[f32; 3]], config: &ClusterConfig) -> Vec<Vec<u32>> {
    if points.is_empty() || config.tolerance_m.is_nan() || config.tolerance_m <= 0.0 {
        return Vec::new();
    }
    let (cells, component_of_cell, count) = connected_components(points, config.tolerance_m);
    // Sizes and centroid keys per component, from the cells' sums.
    let mut sizes = vec![0usize; count];
    let mut sums = vec![[0i64; 3]; count];
    for (c, &k) in component_of_cell.iter().enumerate() {
        sizes[k as usize] += cells.members_of(c).len();
        for (sum, part) in sums[k as usize].iter_mut().zip(cells.key_sum[c]) {
            *sum += part;
        }
    }
    let mut kept: Vec<(usize, [i64; 3])> = (0..count)
        .filter(|&k| sizes[k] >= config.min_points && sizes[k] <= config.max_points)
        .map(|k| {
            // The centroid in 0.1 mm units: integer sums make it independent
            // of the order the points arrived in.
            let n = sizes[k] as i64;
            (k, sums[k].map(|s| (s / n).div_euclid(10)))
        })
        .collect();
    if kept.len() > config.max_objects {
        kept.sort_by(|a, b| sizes[b.0].cmp(&sizes[a.0]).then(a.1.cmp(&b.1)));
        kept.truncate(config.max_objects);
    }
    kept.sort_by(|a, b| a.1.cmp(&b.1).then(sizes[a.0].cmp(&sizes[b.0])));
    // Gather each kept component's points, cell by cell.
    let mut position = vec![usize::MAX; count];
    for (i, &(k, _)) in kept.iter().enumerate() {
        position[k] = i;
    }
    let mut clusters: Vec<Vec<u32>> = kept.iter().map(|&(k, _)| Vec::with_capacity(sizes[k])).collect();
    for (c, &k) in component_of_cell.iter().enumerate() {
        if let Some(cluster) = clusters.get_mut(position[k as usize]) {
            cluster.extend_from_slice(cells.members_of(c));
        }
    }
    clusters
}

/// `clusters` in the fixed order of [`euclidean_clusters`] (by centroid at
/// 0.1 mm, then size), at most `max_objects` of them (the largest): for
/// clusters changed after clustering.
pub fn fixed_order(points: &[[f32; 3]], mut clusters: Vec<Vec<u32>>, max_objects: usize) -> Vec<Vec<u32>> {
    // The same integer centroid as the cells' sums give.
    let key = |c: &[u32]| {
        let mut sum = [0i64; 3];
        for &i in c {
            for (s, v) in sum.iter_mut().zip(points[i as usize]) {
                *s += i64::from((v * 1e5) as i32);
            }
        }
        let n = c.len().max(1) as i64;
        sum.map(|s| (s / n).div_euclid(10))
    };
    if clusters.len() > max_objects {
        clusters.sort_by_cached_key(|c| (std::cmp::Reverse(c.len()), key(c)));
        clusters.truncate(max_objects);
    }
    clusters.sort_by_cached_key(|c| (key(c), c.len()));
    clusters
}

/// The cells, the component id of every cell (ids in order of first
/// appearance) and the number of components.
fn connected_components(points: &[[f32; 3]], tolerance_m: f32) -> (Cells, Vec<u32>, usize) {
    let radius_sq = tolerance_m * tolerance_m;
    // Slightly under tol / sqrt 3, so rounding never puts a pair farther
    // than the tolerance into one cell.
    let edge = tolerance_m / 3f32.sqrt() * 0.999;
    let cells = Cells::new(points, edge);

    // Every pair of occupied cells close enough to hold a pair of points
    // within the tolerance, each pair once, joined as soon as it is found:
    // the union-find skips pairs already joined, the cells' point boxes
    // settle most of the rest, and only the remainder compares points.
    let mut sets = UnionFind::new(cells.len());
    // Joins cell `a` with those of its forward neighbours `found` that hold
    // a close pair (`a`'s root is found once, and kept across joins).
    let mut join = |a: usize, found: &[u32]| {
        let mut root = sets.find(a);
        for &b in found {
            let b = b as usize;
            let other = sets.find(b);
            if other != root && cells.may_touch(a, b, radius_sq) && cells.any_pair_within(a, b, radius_sq) {
                root = sets.union_roots(root, other);
            }
        }
    };
    let mut found = [0u32; FORWARD_OFFSETS.len()];
    match &cells.index {
        CellIndex::Dense { cell, dims, .. } => {
            // The grid is padded by 2 cells on every side, so a neighbour's
            // slot is the cell's slot plus a fixed offset, never out of bounds.
            let stride_y = dims[0] as isize;
            let stride_z = (dims[0] * dims[1]) as isize;
            let deltas = FORWARD_OFFSETS
                .map(|[dx, dy, dz]| dx as isize + dy as isize * stride_y + dz as isize * stride_z);
            for (a, &slot) in cells.slot.iter().enumerate() {
                // Gathered without branching: a quarter of the slots hold a
                // cell, in no pattern a branch predictor learns.
                let mut n = 0;
                for &delta in &deltas {
                    let b = cell[(slot as isize + delta) as usize];
                    found[n] = b;
                    n += usize::from(b != u32::MAX);
                }
                join(a, &found[..n]);
            }
        }
        CellIndex::Sparse(map) => {
            for (a, &[x, y, z]) in cells.coords.iter().enumerate() {
                let mut n = 0;
                for &[dx, dy, dz] in FORWARD_OFFSETS.iter() {
                    let c = [x as i64 + dx, y as i64 + dy, z as i64 + dz];
                    if c.iter().any(|&v| v < 0 || v > i64::from(u32::MAX)) {
                        continue;
                    }
                    if let Some(&b) = map.get(&c.map(|v| v as u32)) {
                        found[n] = b;
                        n += 1;
                    }
                }
                join(a, &found[..n]);
            }
        }
    }
    // Dense component ids, in order of first appearance.
    let mut id_of_root = vec![u32::MAX; cells.len()];
    let mut next = 0;
    let mut component_of_cell = vec![0u32; cells.len()];
    for (c, component) in component_of_cell.iter_mut().enumerate() {
        let root = sets.find(c);
        if id_of_root[root] == u32::MAX {
            id_of_root[root] = next;
            next += 1;
        }
        *component = id_of_root[root];
    }
    (cells, component_of_cell, next as usize)
}

/// Cell offsets that can hold a point within the tolerance of a point in the
/// origin cell (at most 2 on each axis, not 2 on all three), one of each +-
/// pair: the lexicographically positive half.
const FORWARD_OFFSETS: [[i64; 3]; 58] = forward_offsets();

const fn forward_offsets() -> [[i64; 3]; 58] {
    let mut out = [[0i64; 3]; 58];
    let mut n = 0;
    let mut dz = -2;
    while dz <= 2 {
        let mut dy = -2;
        while dy <= 2 {
            let mut dx = -2;
            while dx <= 2 {
                let twos = (dx == 2 || dx == -2) as i32
                    + (dy == 2 || dy == -2) as i32
                    + (dz == 2 || dz == -2) as i32;
                let positive = dz > 0 || (dz == 0 && (dy > 0 || (dy == 0 && dx > 0)));
                if twos < 3 && positive {
                    out[n] = [dx, dy, dz];
                    n += 1;
                }
                dx += 1;
            }
            dy += 1;
        }
        dz += 1;
    }
    out
}

/// Occupied cells: their coordinates, points (compressed rows) and point
/// bounding boxes, and the lookup from coordinates to cell.
struct Cells {
    coords: Vec<[u32; 3]>,
    start: Vec<u32>,
    members: Vec<u32>,
    /// The points in `members` order (contiguous per cell).
    sorted: Vec<[f32; 3]>,
    lo: Vec<[f32; 3]>,
    hi: Vec<[f32; 3]>,
    /// Per cell, the sum of its points' coordinates in 10 um units.
    key_sum: Vec<[i64; 3]>,
    /// Slot of each cell in the dense grid (unused with the sparse index).
    slot: Vec<u32>,
    index: CellIndex,
}

/// Grid margin, in cells, around the points' box: the reach of an offset.
const PAD: u32 = 2;

enum CellIndex {
    /// Cell id per slot (`u32::MAX` = empty) over the box grown by [`PAD`].
    Dense {
        dims: [usize; 3],
        cell: Vec<u32>,
    },
    Sparse(FxHashMap<[u32; 3], u32>),
}

impl Cells {
    fn new(points: &[[f32; 3]], edge: f32) -> Self {
        let inv = 1.0 / edge;
        // The box of the points in metres (a cheap pass); cell coordinates
        // count from its low corner, so they are never negative and the
        // floor is a plain truncating cast (saturating beyond 2^32 cells).
        let mut lo_m = [f32::INFINITY; 3];
        let mut hi_m = [f32::NEG_INFINITY; 3];
        for p in points {
            for a in 0..3 {
                // Plain comparisons (one instruction each); f32::min's NaN
                // rule costs more and the points are finite.
                lo_m[a] = if p[a] < lo_m[a] { p[a] } else { lo_m[a] };
                hi_m[a] = if p[a] > hi_m[a] { p[a] } else { hi_m[a] };
            }
        }
        let coord = |p: &[f32; 3]| [0, 1, 2].map(|a| (((p[a] - lo_m[a]) * inv) as u32).saturating_add(PAD));
        let hi = coord(&hi_m);
        let dims = hi.map(|h| h as usize + PAD as usize + 1);
        let dense = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n <= MAX_DENSE_CELLS);
        let mut index = match dense {
            Some(n) => CellIndex::Dense {
                dims,
                cell: vec![u32::MAX; n],
            },
            None => CellIndex::Sparse(FxHashMap::default()),
        };
        let mut coords = Vec::new();
        let mut slot = Vec::new();
        let mut cell_of_point = Vec::with_capacity(points.len());
        // Consecutive points (neighbouring pixels) mostly share a cell.
        let mut last = ([u32::MAX; 3], 0u32);
        for p in points {
            let c = coord(p);
            if c != last.0 {
                let (id, s) = index.get_or_insert(c, coords.len() as u32);
                if id as usize == coords.len() {
                    coords.push(c);
                    slot.push(s);
                }
                last = (c, id);
            }
            cell_of_point.push(last.1);
        }
        let n = coords.len();
        let mut start = vec![0u32; n + 1];
        for &c in &cell_of_point {
            start[c as usize + 1] += 1;
        }
        for c in 0..n {
            start[c + 1] += start[c];
        }
        // Points sorted by cell (a counting sort), with their original index.
        let mut fill = start.clone();
        let mut members = vec![0u32; points.len()];
        let mut sorted = vec![[0f32; 3]; points.len()];
        for (i, (&c, p)) in cell_of_point.iter().zip(points).enumerate() {
            let at = fill[c as usize] as usize;
            members[at] = i as u32;
            sorted[at] = *p;
            fill[c as usize] += 1;
        }
        let mut bb_lo = vec![[f32::INFINITY; 3]; n];
        let mut bb_hi = vec![[f32::NEG_INFINITY; 3]; n];
        let mut key_sum = vec![[0i64; 3]; n];
        for c in 0..n {
            let (lo, hi, sum) = (&mut bb_lo[c], &mut bb_hi[c], &mut key_sum[c]);
            for p in &sorted[start[c] as usize..start[c + 1] as usize] {
                for a in 0..3 {
                    lo[a] = if p[a] < lo[a] { p[a] } else { lo[a] };
                    hi[a] = if p[a] > hi[a] { p[a] } else { hi[a] };
                    // 10 um units, truncated; the cast saturates beyond +-21 km.
                    sum[a] += i64::from((p[a] * 1e5) as i32);
                }
            }
        }
        Self {
            coords,
            start,
            members,
            sorted,
            lo: bb_lo,
            hi: bb_hi,
            key_sum,
            slot,
            index,
        }
    }

    fn len(&self) -> usize {
        self.coords.len()
    }

    fn members_of(&self, c: usize) -> &[u32] {
        &self.members[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// False when the cells' point boxes are farther apart than the radius.
    fn may_touch(&self, a: usize, b: usize, radius_sq: f32) -> bool {
        let mut gap_sq = 0.0;
        for axis in 0..3 {
            let gap = (self.lo[b][axis] - self.hi[a][axis])
                .max(self.lo[a][axis] - self.hi[b][axis])
                .max(0.0);
            gap_sq += gap * gap;
        }
        gap_sq <= radius_sq
    }

    fn points_of(&self, c: usize) -> &[[f32; 3]] {
        &self.sorted[self.start[c] as usize..self.start[c + 1] as usize]
    }

    fn any_pair_within(&self, a: usize, b: usize, radius_sq: f32) -> bool {
        self.points_of(a).iter().any(|p| {
            self.points_of(b).iter().any(|q| {
                (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2])
                    <= radius_sq
            })
        })
    }
}

impl CellIndex {
    /// The id of cell `c` (inserting `new_id` if it is not there yet) and its slot.
    fn get_or_insert(&mut self, c: [u32; 3], new_id: u32) -> (u32, u32) {
        match self {
            CellIndex::Dense { dims, cell } => {
                let l = c.map(|v| v as usize);
                let slot = (l[2] * dims[1] + l[1]) * dims[0] + l[0];
                if cell[slot] == u32::MAX {
                    cell[slot] = new_id;
                }
                (cell[slot], slot as u32)
            }
            CellIndex::Sparse(map) => (*map.entry(c).or_insert(new_id), 0),
        }
    }
}

#[cfg(test)]
mod tests {
    use kiddo::{KdTree, SquaredEuclidean};

    use super::*;
    use crate::rng::SplitMix64;

    fn blob(center: [f32; 3], n: usize) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let (a, b) = ((i % 10) as f32 * 0.002, (i / 10) as f32 * 0.002);
                [center[0] + a, center[1] + b, center[2]]
            })
            .collect()
    }

    #[test]
    fn offsets_are_the_forward_half_of_the_reachable_cells() {
        assert_eq!(FORWARD_OFFSETS.len(), (125 - 8 - 1) / 2);
        for o in FORWARD_OFFSETS {
            assert!(!FORWARD_OFFSETS.contains(&o.map(|v| -v)));
        }
    }

    #[test]
    fn separates_blobs_and_orders_them_by_x() {
        let mut points = blob([0.3, 0.0, 0.05], 100);
        points.extend(blob([0.0, 0.0, 0.05], 100));
        points.extend(blob([0.0, 0.5, 0.05], 5)); // noise: too small
        let clusters = euclidean_clusters(&points, &ClusterConfig::default());
        assert_eq!(clusters.len(), 2);
        assert!(clusters[0].iter().all(|i| (100..200).contains(i)), "x = 0 first");
        assert!(clusters[1].iter().all(|&i| i < 100));
    }

    #[test]
    fn the_tolerance_is_exact() {
        // Two blobs 1.8 cm long along y, the second starting a gap after the first.
        for (gap, expected) in [(0.0099, 1), (0.0101, 2)] {
            let mut points = blob([0.0, 0.0, 0.05], 100);
            points.extend(blob([0.0, 0.018 + gap, 0.05], 100));
            assert_eq!(
                euclidean_clusters(&points, &ClusterConfig::default()).len(),
                expected,
                "gap {gap}"
            );
        }
    }

    #[test]
    fn order_does_not_depend_on_point_order() {
        let mut points = blob([0.3, 0.0, 0.05], 100);
        points.extend(blob([0.0, 0.2, 0.05], 120));
        let a = euclidean_clusters(&points, &ClusterConfig::default());
        points.reverse();
        let b = euclidean_clusters(&points, &ClusterConfig::default());
        let sizes = |c: &Vec<Vec<u32>>| c.iter().map(Vec::len).collect::<Vec<_>>();
        assert_eq!(sizes(&a), sizes(&b));
        assert_eq!(sizes(&a), vec![120, 100]);
    }

    /// Reference: flood fill over `kiddo` k-d tree range queries, point by point.
    fn kd_tree_components(points: &[[f32; 3]], tolerance: f32) -> Vec<u32> {
        let mut tree: KdTree<f32, 3> = KdTree::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            tree.add(p, i as u64);
        }
        let mut label = vec![u32::MAX; points.len()];
        let mut next = 0;
        for seed in 0..points.len() {
            if label[seed] != u32::MAX {
                continue;
            }
            label[seed] = next;
            let mut stack = vec![seed];
            while let Some(v) = stack.pop() {
                for n in tree.within_unsorted::<SquaredEuclidean>(&points[v], tolerance * tolerance) {
                    if label[n.item as usize] == u32::MAX {
                        label[n.item as usize] = next;
                        stack.push(n.item as usize);
                    }
                }
            }
            next += 1;
        }
        label
    }

    /// The cell method and a k-d tree flood fill find the same components on
    /// random clouds of mixed density, tolerances and both cell indexes.
    #[test]
    fn agrees_with_a_kd_tree_flood_fill() {
        let mut rng = SplitMix64::new(42);
        let mut uniform =
            |lo: f32, hi: f32| lo + (hi - lo) * (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        for trial in 0..24 {
            let n = 200 + trial * 40;
            let spread = if trial % 2 == 0 { 0.04 } else { 0.3 };
            let mut points: Vec<[f32; 3]> = (0..n)
                .map(|_| {
                    [
                        uniform(-spread, spread),
                        uniform(-spread, spread),
                        uniform(0.0, 0.05),
                    ]
                })
                .collect();
            if trial % 6 == 5 {
                points.push([5000.0, -5000.0, 0.0]); // a far point: the sparse index
            }
            let tolerance = 0.008 + 0.002 * (trial % 5) as f32;
            let (cells, component_of_cell, _) = connected_components(&points, tolerance);
            let mut ours = vec![0u32; points.len()];
            for (c, &k) in component_of_cell.iter().enumerate() {
                for &i in cells.members_of(c) {
                    ours[i as usize] = k;
                }
            }
            let reference = kd_tree_components(&points, tolerance);
            // Same partition: a bijection between labels.
            let mut map = FxHashMap::default();
            for (a, b) in ours.iter().zip(&reference) {
                assert_eq!(
                    *map.entry(*a).or_insert(*b),
                    *b,
                    "trial {trial}: partitions differ"
                );
            }
            let distinct: std::collections::HashSet<_> = map.values().collect();
            assert_eq!(distinct.len(), map.len(), "trial {trial}: partitions differ");
        }
    }
}
