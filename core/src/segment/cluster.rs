//! Euclidean clustering of the object points.
//!
//! Points are first pooled into voxels of `voxel_m` (their centroids keep the
//! shape at a few millimetres), the voxel centroids go into a k-d tree
//! (`kiddo`), and voxels closer than `tolerance_m` are connected by a flood
//! fill. Each point then takes the cluster of its voxel. Clustering the
//! ~10x fewer voxels instead of every pixel is what keeps this stage well under
//! a millisecond on a 640x480 frame; the price is that the tolerance is
//! applied between voxel centroids, so it is exact only to about one voxel.
//!
//! Objects that touch (packed boxes, a pile) merge into one cluster: nothing
//! in the geometry separates them. Clusters come out in a fixed order (by
//! centroid x, then y, then z, at 0.1 mm), independent of the point order.

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use rustc_hash::FxHashMap;

/// Settings of the clustering stage.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterConfig {
    /// Largest gap bridged inside one object (m).
    pub tolerance_m: f32,
    /// Voxel edge used to pool points before clustering (m).
    pub voxel_m: f32,
    /// Smaller clusters are noise (points).
    pub min_points: usize,
    /// Larger clusters are not objects (points).
    pub max_points: usize,
    /// At most this many objects are kept (the largest ones).
    pub max_objects: usize,
}

impl Default for ClusterConfig {
    fn default() -> Self {
        Self {
            tolerance_m: 0.01,
            voxel_m: 0.004,
            min_points: 60,
            max_points: 400_000,
            max_objects: 64,
        }
    }
}

/// The clusters as lists of indices into the input points, in the fixed order.
pub fn euclidean_clusters(points: &[[f32; 3]], config: &ClusterConfig) -> Vec<Vec<u32>> {
    if points.is_empty() {
        return Vec::new();
    }
    let (voxel_of_point, voxel_centroids, voxel_counts) = pool_into_voxels(points, config.voxel_m);
    let voxel_cluster = flood_fill(&voxel_centroids, config.tolerance_m);
    let cluster_count = voxel_cluster.iter().copied().max().map_or(0, |m| m as usize + 1);

    let mut sizes = vec![0usize; cluster_count];
    for (voxel, &count) in voxel_counts.iter().enumerate() {
        sizes[voxel_cluster[voxel] as usize] += count as usize;
    }
    let mut clusters: Vec<Vec<u32>> = sizes.iter().map(|&n| Vec::with_capacity(n)).collect();
    for (i, &voxel) in voxel_of_point.iter().enumerate() {
        clusters[voxel_cluster[voxel as usize] as usize].push(i as u32);
    }
    let mut kept: Vec<(Vec<u32>, [i64; 3])> = clusters
        .into_iter()
        .filter(|c| c.len() >= config.min_points && c.len() <= config.max_points)
        .map(|c| {
            let key = centroid_key(points, &c);
            (c, key)
        })
        .collect();
    if kept.len() > config.max_objects {
        kept.sort_by(|a, b| b.0.len().cmp(&a.0.len()).then(a.1.cmp(&b.1)));
        kept.truncate(config.max_objects);
    }
    kept.sort_by(|a, b| a.1.cmp(&b.1).then(a.0.len().cmp(&b.0.len())));
    kept.into_iter().map(|(c, _)| c).collect()
}

/// Voxel id of each point, and the centroid and point count of each voxel.
fn pool_into_voxels(points: &[[f32; 3]], voxel_m: f32) -> (Vec<u32>, Vec<[f32; 3]>, Vec<u32>) {
    let inv = 1.0 / voxel_m;
    let mut index: FxHashMap<u64, u32> = FxHashMap::default();
    index.reserve(points.len() / 4);
    let mut voxel_of_point = Vec::with_capacity(points.len());
    let mut sums: Vec<[f32; 3]> = Vec::new();
    let mut counts: Vec<u32> = Vec::new();
    for p in points {
        let key = voxel_key(p, inv);
        let id = *index.entry(key).or_insert_with(|| {
            sums.push([0.0; 3]);
            counts.push(0);
            (sums.len() - 1) as u32
        });
        let s = &mut sums[id as usize];
        s[0] += p[0];
        s[1] += p[1];
        s[2] += p[2];
        counts[id as usize] += 1;
        voxel_of_point.push(id);
    }
    let centroids = sums
        .iter()
        .zip(&counts)
        .map(|(s, &n)| {
            let n = n as f32;
            [s[0] / n, s[1] / n, s[2] / n]
        })
        .collect();
    (voxel_of_point, centroids, counts)
}

/// Packs the voxel's integer coordinates into 21 bits each (+-4 km at 4 mm).
#[inline]
fn voxel_key(p: &[f32; 3], inv_voxel: f32) -> u64 {
    const MASK: i64 = (1 << 21) - 1;
    let c = |v: f32| ((v * inv_voxel).floor() as i64 + (1 << 20)) & MASK;
    (c(p[0]) as u64) << 42 | (c(p[1]) as u64) << 21 | c(p[2]) as u64
}

/// Connected components of the voxel centroids under `tolerance_m`.
fn flood_fill(centroids: &[[f32; 3]], tolerance_m: f32) -> Vec<u32> {
    const UNSET: u32 = u32::MAX;
    let tree: ImmutableKdTree<f32, u32, 3, 32> = ImmutableKdTree::new_from_slice(centroids);
    let radius_sq = tolerance_m * tolerance_m;
    let mut label = vec![UNSET; centroids.len()];
    let mut next = 0u32;
    let mut stack = Vec::new();
    for seed in 0..centroids.len() {
        if label[seed] != UNSET {
            continue;
        }
        label[seed] = next;
        stack.push(seed as u32);
        while let Some(v) = stack.pop() {
            for neighbour in tree.within_unsorted::<SquaredEuclidean>(&centroids[v as usize], radius_sq) {
                let n = neighbour.item as usize;
                if label[n] == UNSET {
                    label[n] = next;
                    stack.push(neighbour.item);
                }
            }
        }
        next += 1;
    }
    label
}

/// The cluster centroid in 0.1 mm units: the sort key that makes object ids
/// independent of the order the points arrived in.
fn centroid_key(points: &[[f32; 3]], cluster: &[u32]) -> [i64; 3] {
    let mut sum = [0i64; 3];
    for &i in cluster {
        let p = points[i as usize];
        for a in 0..3 {
            // Summing integers (10 um units) makes the key order-independent.
            sum[a] += (f64::from(p[a]) * 1e5).round() as i64;
        }
    }
    let n = cluster.len().max(1) as i64;
    sum.map(|s| (s / n).div_euclid(10))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob(center: [f32; 3], n: usize) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let (a, b) = ((i % 10) as f32 * 0.002, (i / 10) as f32 * 0.002);
                [center[0] + a, center[1] + b, center[2]]
            })
            .collect()
    }

    #[test]
    fn separates_blobs_and_orders_them_by_x() {
        let mut points = blob([0.3, 0.0, 0.05], 100);
        points.extend(blob([0.0, 0.0, 0.05], 100));
        points.extend(blob([0.0, 0.5, 0.05], 5)); // noise: too small
        let clusters = euclidean_clusters(&points, &ClusterConfig::default());
        assert_eq!(clusters.len(), 2);
        assert!(clusters[0].iter().all(|&i| i >= 100 && i < 200), "x = 0 first");
        assert!(clusters[1].iter().all(|&i| i < 100));
    }

    #[test]
    fn gap_below_tolerance_merges() {
        let mut points = blob([0.0, 0.0, 0.05], 100);
        points.extend(blob([0.0, 0.0258, 0.05], 100)); // 0.8 cm gap after the first blob's 1.8 cm
        assert_eq!(euclidean_clusters(&points, &ClusterConfig::default()).len(), 1);
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
}
