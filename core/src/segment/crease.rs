//! Splitting clusters at concave creases and depth steps, in the depth image.
//!
//! Euclidean clustering joins objects whose visible surfaces meet: in a pile
//! one object leans on another and a crease forms where they touch, and a
//! row of flying pixels can bridge a depth step between them. Seen from the
//! camera both are valleys of the depth image: a pixel deeper than the mean
//! of the two pixels `baseline_px` away on either side (along a row, a
//! column or a diagonal), by more than noise allows. A convex edge (a box's
//! corner, a cylinder's side) is a ridge and passes, and so does a smooth
//! surface, a tilted plane included (perspective adds a term far below the
//! threshold at these distances).
//!
//! Per cluster seen in a depth image:
//! 1. the cluster's depth is box-filtered (a consumer camera's noise is
//!    1-2 mm a pixel; the valley test needs a fraction of that);
//! 2. valley pixels are marked;
//! 3. the unmarked pixels form regions: 4-connected, neighbours within the
//!    clustering tolerance in 3D;
//! 4. the regions grow back over the marked pixels, breadth first;
//! 5. a region under `min_part_points` joins the neighbour it shares the
//!    most border with (the largest region when it touches none), so noise
//!    and small concave details (a handle's root) do not make objects;
//! 6. a part that hangs on a larger one (`Reattach`: a mug's handle, a
//!    bottle's neck) joins it: small in area and against its neighbour,
//!    touching it along much of its outline, and continuous with it in
//!    depth where they touch. Two objects of a pile meet along a short
//!    border, or at a step, or are both large.
//!
//! A cluster left with one region is returned unchanged. A point cloud has
//! no image and is not split. Two parts of one object that another object
//! hides in the middle stay apart (Euclidean clustering alone would join
//! them, and their occluder with them).

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use super::union_find::UnionFind;

/// Settings of the crease split. The defaults were chosen on the tuning
/// seeds (`sim eval --seed 800000`, `segmentation_recall`; sim/README.md):
/// lower thresholds split piles as well but cut more single objects (a
/// bottle's neck, a mug's handle) into parts.
#[derive(Debug, Clone, PartialEq)]
pub struct CreaseConfig {
    /// Half-width of the box filter applied to the depth first (px).
    pub smooth_radius_px: usize,
    /// The valley test compares a pixel with the two this far away (px).
    pub baseline_px: usize,
    /// A valley is deeper than the mean of its two sides by more than this (m) ...
    pub min_valley_m: f32,
    /// ... and by more than this fraction of the distance to each side
    /// (the pixel's footprint times the baseline), so the test means the
    /// same angle near and far.
    pub min_valley_ratio: f32,
    /// Smaller parts join a neighbour (points); clusters under twice this
    /// are not split.
    pub min_part_points: usize,
    /// Parts that hang on a larger one join it (`None`: they stay apart).
    pub reattach: Option<Reattach>,
}

/// When a part of a split cluster joins the neighbour it shares the most
/// border with (step 6). The defaults were chosen on the tuning seeds'
/// first frames (pairs of touching parts labelled same object or not by
/// the renderer; sim/README.md, "Parts that hang on another").
#[derive(Debug, Clone, PartialEq)]
pub struct Reattach {
    /// The part's surface seen from the camera is under this (m^2; a pixel
    /// at depth z covers (z / focal)^2) ...
    pub max_area_m2: f32,
    /// ... it has under this fraction of the neighbour's points ...
    pub max_share: f32,
    /// ... more than this fraction of its outline pixels touch it ...
    pub min_outline_share: f32,
    /// ... and across that border the depth changes by less than this on
    /// average (m).
    pub max_step_m: f32,
}

impl Reattach {
    /// Whether a part of `points` points hangs on a neighbour of
    /// `neighbour_points`: its surface seen from the camera (`area_m2`), the
    /// pixel pairs across their border (`border`), its outline pixels and
    /// the depth change summed over the border pairs (`step_sum_m`).
    pub fn hangs_on(
        &self,
        points: usize,
        neighbour_points: usize,
        area_m2: f32,
        border: usize,
        outline: usize,
        step_sum_m: f32,
    ) -> bool {
        area_m2 < self.max_area_m2
            && (points as f32) < self.max_share * neighbour_points as f32
            && border as f32 > self.min_outline_share * outline as f32
            && step_sum_m < self.max_step_m * border as f32
    }
}

impl Default for Reattach {
    fn default() -> Self {
        Self {
            max_area_m2: 0.0020,
            max_share: 0.3,
            min_outline_share: 0.15,
            max_step_m: 0.020,
        }
    }
}

impl Default for CreaseConfig {
    fn default() -> Self {
        Self {
            smooth_radius_px: 2,
            baseline_px: 6,
            min_valley_m: 0.005,
            min_valley_ratio: 0.4,
            min_part_points: 200,
            reattach: Some(Reattach::default()),
        }
    }
}

/// Points that came from a pinhole depth image, with where they came from.
#[derive(Debug, Clone, Copy)]
pub struct ImagePoints<'a> {
    /// World points.
    pub points: &'a [[f32; 3]],
    /// The pixel (`v * width + u`) of each point.
    pub pixels: &'a [u32],
    /// Image width (px).
    pub width: usize,
    /// Camera origin in the world.
    pub origin: [f32; 3],
    /// Unit optical axis in the world (depth = axis . (p - origin)).
    pub axis: [f32; 3],
    /// Focal length (px): a pixel at depth z spans z / focal_px metres.
    pub focal_px: f32,
}

/// `clusters` (indices into `image.points`) with each split where its
/// surface shows a crease or a step, and whether any was split.
pub fn split_at_creases(
    image: &ImagePoints<'_>,
    clusters: Vec<Vec<u32>>,
    tolerance_m: f32,
    config: &CreaseConfig,
) -> (Vec<Vec<u32>>, bool) {
    if image.pixels.len() != image.points.len() || image.width == 0 {
        return (clusters, false);
    }
    let mut out = Vec::with_capacity(clusters.len());
    let mut split = false;
    let mut scratch = Scratch::default();
    for cluster in clusters {
        if cluster.len() < 2 * config.min_part_points.max(1) {
            out.push(cluster);
            continue;
        }
        let parts = split_one(image, &cluster, tolerance_m, config, &mut scratch);
        if parts.len() > 1 {
            split = true;
            out.extend(parts);
        } else {
            out.push(cluster);
        }
    }
    (out, split)
}

const NONE: u32 = u32::MAX;

/// Buffers reused across clusters.
#[derive(Default)]
struct Scratch {
    grid: Vec<u32>,
    depth: Vec<f32>,
    smooth: Vec<f32>,
    sum: Vec<f64>,
    count: Vec<u32>,
    marked: Vec<bool>,
    label: Vec<u32>,
    xy: Vec<(u32, u32)>,
}

/// The cluster's parts, as indices into the points (one part: no split).
fn split_one(
    image: &ImagePoints<'_>,
    cluster: &[u32],
    tolerance_m: f32,
    config: &CreaseConfig,
    s: &mut Scratch,
) -> Vec<Vec<u32>> {
    let w = image.width;
    let n = cluster.len();
    // The cluster's pixel box and local grid (cluster position per pixel).
    let (mut u0, mut v0, mut u1, mut v1) = (usize::MAX, usize::MAX, 0, 0);
    for &i in cluster {
        let p = image.pixels[i as usize] as usize;
        let (u, v) = (p % w, p / w);
        u0 = u0.min(u);
        u1 = u1.max(u);
        v0 = v0.min(v);
        v1 = v1.max(v);
    }
    let (bw, bh) = (u1 - u0 + 1, v1 - v0 + 1);
    s.grid.clear();
    s.grid.resize(bw * bh, NONE);
    s.xy.clear();
    s.depth.clear();
    let [ox, oy, oz] = image.origin;
    let [ax, ay, az] = image.axis;
    for (k, &i) in cluster.iter().enumerate() {
        let p = image.pixels[i as usize] as usize;
        let (x, y) = (p % w - u0, p / w - v0);
        s.grid[y * bw + x] = k as u32;
        s.xy.push((x as u32, y as u32));
        let q = image.points[i as usize];
        s.depth
            .push(ax * (q[0] - ox) + ay * (q[1] - oy) + az * (q[2] - oz));
    }

    // 1. Box filter through integral images of depth and count (f64 sums:
    // f32 would lose millimetres over a few thousand pixels).
    let sw = bw + 1;
    s.sum.clear();
    s.sum.resize(sw * (bh + 1), 0.0);
    s.count.clear();
    s.count.resize(sw * (bh + 1), 0);
    for y in 0..bh {
        let (mut row_sum, mut row_count) = (0.0f64, 0u32);
        for x in 0..bw {
            let k = s.grid[y * bw + x];
            if k != NONE {
                row_sum += f64::from(s.depth[k as usize]);
                row_count += 1;
            }
            s.sum[(y + 1) * sw + x + 1] = s.sum[y * sw + x + 1] + row_sum;
            s.count[(y + 1) * sw + x + 1] = s.count[y * sw + x + 1] + row_count;
        }
    }
    let r = config.smooth_radius_px;
    s.smooth.clear();
    for &(x, y) in &s.xy {
        let (x, y) = (x as usize, y as usize);
        let (xa, xb) = (x.saturating_sub(r), (x + r + 1).min(bw));
        let (ya, yb) = (y.saturating_sub(r), (y + r + 1).min(bh));
        let sum = s.sum[yb * sw + xb] - s.sum[ya * sw + xb] - s.sum[yb * sw + xa] + s.sum[ya * sw + xa];
        let count =
            s.count[yb * sw + xb] + s.count[ya * sw + xa] - s.count[ya * sw + xb] - s.count[yb * sw + xa];
        // The pixel itself is in its window, so count >= 1.
        s.smooth.push((sum / f64::from(count)) as f32);
    }

    // 2. Valleys along a row, a column and the two diagonals.
    let b = config.baseline_px as i64;
    let at = |x: i64, y: i64| -> u32 {
        if x < 0 || y < 0 || x >= bw as i64 || y >= bh as i64 {
            NONE
        } else {
            s.grid[y as usize * bw + x as usize]
        }
    };
    s.marked.clear();
    for (k, &(x, y)) in s.xy.iter().enumerate() {
        let (x, y) = (i64::from(x), i64::from(y));
        let centre = s.smooth[k];
        let footprint = centre / image.focal_px * b as f32;
        let mut valley = false;
        for (dx, dy, length) in [
            (1, 0, 1.0),
            (0, 1, 1.0),
            (1, 1, 2f32.sqrt()),
            (1, -1, 2f32.sqrt()),
        ] {
            let (a, c) = (at(x - b * dx, y - b * dy), at(x + b * dx, y + b * dy));
            if a == NONE || c == NONE {
                continue;
            }
            let excess = centre - 0.5 * (s.smooth[a as usize] + s.smooth[c as usize]);
            if excess
                > config
                    .min_valley_m
                    .max(config.min_valley_ratio * footprint * length)
            {
                valley = true;
                break;
            }
        }
        s.marked.push(valley);
    }
    // No valley, no cut (a convex object: most clusters).
    if !s.marked.contains(&true) {
        return vec![cluster.to_vec()];
    }

    // 3. Regions of unmarked pixels; 4. grown back over the marked ones.
    let points = image.points;
    let tol_sq = tolerance_m * tolerance_m;
    let close = |a: usize, b: usize| {
        let (p, q) = (points[cluster[a] as usize], points[cluster[b] as usize]);
        (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2) <= tol_sq
    };
    const NEIGHBOURS: [(i64, i64); 4] = [(1, 0), (-1, 0), (0, 1), (0, -1)];
    s.label.clear();
    s.label.resize(n, NONE);
    let mut regions = 0u32;
    let mut stack = Vec::new();
    for seed in 0..n {
        if s.marked[seed] || s.label[seed] != NONE {
            continue;
        }
        s.label[seed] = regions;
        stack.push(seed);
        while let Some(k) = stack.pop() {
            let (x, y) = (i64::from(s.xy[k].0), i64::from(s.xy[k].1));
            for (dx, dy) in NEIGHBOURS {
                let m = at(x + dx, y + dy);
                if m != NONE && !s.marked[m as usize] && s.label[m as usize] == NONE && close(k, m as usize) {
                    s.label[m as usize] = regions;
                    stack.push(m as usize);
                }
            }
        }
        regions += 1;
    }
    if regions <= 1 {
        return vec![cluster.to_vec()];
    }
    let mut queue: VecDeque<usize> = (0..n).filter(|&k| s.label[k] != NONE).collect();
    while let Some(k) = queue.pop_front() {
        let (x, y) = (i64::from(s.xy[k].0), i64::from(s.xy[k].1));
        for (dx, dy) in NEIGHBOURS {
            let m = at(x + dx, y + dy);
            if m != NONE && s.label[m as usize] == NONE && close(k, m as usize) {
                s.label[m as usize] = s.label[k];
                queue.push_back(m as usize);
            }
        }
    }

    // 5. Small regions join the neighbour they share the most border with.
    let regions = regions as usize;
    let mut size = vec![0usize; regions];
    for &l in &s.label {
        if l != NONE {
            size[l as usize] += 1;
        }
    }
    let mut border: Vec<Vec<(u32, u32)>> = vec![Vec::new(); regions];
    for (k, &(x, y)) in s.xy.iter().enumerate() {
        let l = s.label[k];
        if l == NONE {
            continue;
        }
        for (dx, dy) in [(1, 0), (0, 1)] {
            let m = at(i64::from(x) + dx, i64::from(y) + dy);
            if m == NONE {
                continue;
            }
            let o = s.label[m as usize];
            if o != NONE && o != l && close(k, m as usize) {
                border[l as usize].push((o, 1));
                border[o as usize].push((l, 1));
            }
        }
    }
    let mut sets = UnionFind::with_sizes(size.iter().map(|&n| n as u32).collect());
    let mut heap: BinaryHeap<Reverse<(u32, u32)>> = (0..regions as u32)
        .map(|r| Reverse((sets.size(r as usize), r)))
        .collect();
    let mut roots = regions;
    while let Some(Reverse((sz, r))) = heap.pop() {
        if sz as usize >= config.min_part_points || roots == 1 {
            break;
        }
        if sets.find(r as usize) != r as usize || sets.size(r as usize) != sz {
            continue; // stale entry
        }
        // Shared border per neighbouring root.
        let mut shared: Vec<(u32, u32)> = std::mem::take(&mut border[r as usize])
            .into_iter()
            .map(|(o, c)| (sets.find(o as usize) as u32, c))
            .filter(|&(o, _)| o != r)
            .collect();
        shared.sort_unstable();
        let mut best: Option<(u32, u32)> = None; // (count, root)
        let mut i = 0;
        while i < shared.len() {
            let o = shared[i].0;
            let mut c = 0;
            while i < shared.len() && shared[i].0 == o {
                c += shared[i].1;
                i += 1;
            }
            if best.is_none_or(|(bc, bo)| (c, Reverse(o)) > (bc, Reverse(bo))) {
                best = Some((c, o));
            }
        }
        // Touching no region, the largest other region takes it (there is
        // one: `roots` > 1).
        let Some(target) = best.map(|(_, o)| o).or_else(|| {
            (0..regions as u32)
                .filter(|&o| o != r && sets.is_root(o as usize))
                .max_by_key(|&o| (sets.size(o as usize), Reverse(o)))
        }) else {
            break;
        };
        // `r` is the lightest root, so the target stays the root.
        let root = sets.union_roots(target as usize, r as usize) as u32;
        let mut moved: Vec<(u32, u32)> = shared.into_iter().filter(|&(o, _)| o != root).collect();
        border[root as usize].append(&mut moved);
        roots -= 1;
        heap.push(Reverse((sets.size(root as usize), root)));
    }
    if roots <= 1 {
        return vec![cluster.to_vec()];
    }

    // Parts by root; points no region reached join the largest part.
    let Some(largest) = (0..regions as u32)
        .filter(|&o| sets.is_root(o as usize))
        .max_by_key(|&o| (sets.size(o as usize), Reverse(o)))
    else {
        return vec![cluster.to_vec()];
    };
    let mut root_of: Vec<u32> = s
        .label
        .iter()
        .map(|&l| match l {
            NONE => largest,
            l => sets.find(l as usize) as u32,
        })
        .collect();

    // 6. Parts that hang on a larger one join it.
    if let Some(attach) = &config.reattach
        && reattach(&mut root_of, regions, image.focal_px, attach, s, bw, bh)
    {
        return vec![cluster.to_vec()];
    }

    let mut part_of_root = vec![NONE; regions];
    let mut parts: Vec<Vec<u32>> = Vec::new();
    for (&root, &point) in root_of.iter().zip(cluster) {
        if part_of_root[root as usize] == NONE {
            part_of_root[root as usize] = parts.len() as u32;
            parts.push(Vec::new());
        }
        parts[part_of_root[root as usize] as usize].push(point);
    }
    parts
}

/// Step 6 on `root_of` (each point's part, a root in `0..regions`): each
/// part, smallest first, joins the neighbour it shares the most border
/// with when `attach` says it hangs on it. Returns whether one part is left.
fn reattach(
    root_of: &mut [u32],
    regions: usize,
    focal_px: f32,
    attach: &Reattach,
    s: &Scratch,
    bw: usize,
    bh: usize,
) -> bool {
    let at = |x: usize, y: usize| s.grid[y * bw + x];
    let mut size = vec![0u32; regions];
    let mut area = vec![0f32; regions];
    let mut outline = vec![0u32; regions];
    // (part, other part) -> (neighbouring pixel pairs, summed depth change)
    let mut touch: Vec<((u32, u32), (u32, f32))> = Vec::new();
    for (k, &(x, y)) in s.xy.iter().enumerate() {
        let (x, y) = (x as usize, y as usize);
        let r = root_of[k];
        size[r as usize] += 1;
        area[r as usize] += (s.depth[k] / focal_px).powi(2);
        let mut edge = x == 0 || y == 0 || x + 1 == bw || y + 1 == bh;
        for (nx, ny) in [
            (x.wrapping_sub(1), y),
            (x + 1, y),
            (x, y.wrapping_sub(1)),
            (x, y + 1),
        ] {
            if nx >= bw || ny >= bh {
                continue;
            }
            let m = at(nx, ny);
            if m == NONE || root_of[m as usize] != r {
                edge = true;
            }
            // Each pair once: towards +x and +y.
            if m != NONE && (nx > x || ny > y) && root_of[m as usize] != r {
                let o = root_of[m as usize];
                let step = (s.depth[k] - s.depth[m as usize]).abs();
                touch.push(((r, o), (1, step)));
                touch.push(((o, r), (1, step)));
            }
        }
        outline[r as usize] += u32::from(edge);
    }
    touch.sort_unstable_by_key(|&(pair, _)| pair);
    let mut pairs: Vec<((u32, u32), (u32, f32))> = Vec::new();
    for (pair, (n, step)) in touch {
        match pairs.last_mut() {
            Some((last, (ln, ls))) if *last == pair => {
                *ln += n;
                *ls += step;
            }
            _ => pairs.push((pair, (n, step))),
        }
    }

    let mut sets = UnionFind::with_sizes(size.clone());
    let mut order: Vec<u32> = (0..regions as u32).filter(|&r| size[r as usize] > 0).collect();
    let mut left = order.len();
    order.sort_unstable_by_key(|&r| (size[r as usize], r));
    for r in order {
        let r = r as usize;
        // A part that took another in has changed; it stays.
        if !sets.is_root(r) || sets.size(r) != size[r] {
            continue;
        }
        let start = pairs.partition_point(|&((a, _), _)| (a as usize) < r);
        let Some(&((_, o), (n, step))) = pairs[start..]
            .iter()
            .take_while(|&&((a, _), _)| a as usize == r)
            .max_by_key(|&&((_, o), (n, _))| (n, Reverse(o)))
        else {
            continue;
        };
        let target = sets.find(o as usize);
        let hangs = attach.hangs_on(
            size[r] as usize,
            sets.size(target) as usize,
            area[r],
            n as usize,
            outline[r] as usize,
            step,
        );
        if hangs && target != r {
            sets.union_roots(target, r);
            left -= 1;
        }
    }
    for root in root_of.iter_mut() {
        *root = sets.find(*root as usize) as u32;
    }
    left <= 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;
    use crate::segment::{ClusterConfig, euclidean_clusters};

    const W: usize = 160;
    const H: usize = 100;
    const F: f32 = 600.0;

    /// A depth image seen by a camera at the origin looking along +z:
    /// `depth(x, y)` (metres, lateral coordinates at 0.8 m) per pixel, with
    /// Gaussian noise of `sigma` and millimetre rounding as a consumer camera
    /// gives; `None` is no reading.
    fn image(depth: impl Fn(f32, f32) -> Option<f32>, sigma: f64, seed: u64) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut rng = SplitMix64::new(seed);
        let (mut points, mut pixels) = (Vec::new(), Vec::new());
        for v in 0..H {
            for u in 0..W {
                let (x, y) = (
                    (u as f32 - W as f32 / 2.0) / F * 0.8,
                    (v as f32 - H as f32 / 2.0) / F * 0.8,
                );
                let Some(z) = depth(x, y) else { continue };
                let z = ((z + (sigma * rng.gaussian()) as f32) * 1000.0).round() / 1000.0;
                let (px, py) = (
                    (u as f32 - W as f32 / 2.0) / F * z,
                    (v as f32 - H as f32 / 2.0) / F * z,
                );
                points.push([px, py, z]);
                pixels.push((v * W + u) as u32);
            }
        }
        (points, pixels)
    }

    /// The parts of the one Euclidean cluster of the image, largest first.
    fn parts(points: &[[f32; 3]], pixels: &[u32]) -> Vec<usize> {
        parts_with(points, pixels, &CreaseConfig::default())
    }

    /// `parts` with another crease split.
    fn parts_with(points: &[[f32; 3]], pixels: &[u32], crease: &CreaseConfig) -> Vec<usize> {
        let config = ClusterConfig::default();
        let clusters = euclidean_clusters(points, &config);
        assert_eq!(clusters.len(), 1, "the scene must be one Euclidean cluster");
        let image = ImagePoints {
            points,
            pixels,
            width: W,
            origin: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            focal_px: F,
        };
        let (out, split) = split_at_creases(&image, clusters, config.tolerance_m, crease);
        assert_eq!(split, out.len() > 1);
        let mut all: Vec<u32> = out.iter().flatten().copied().collect();
        all.sort_unstable();
        assert_eq!(
            all,
            (0..points.len() as u32).collect::<Vec<_>>(),
            "every point in exactly one part"
        );
        let mut sizes: Vec<usize> = out.iter().map(Vec::len).collect();
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        sizes
    }

    /// Two planes at 45 degrees meeting in a valley (two boxes leaning
    /// together) split along the valley; the same planes meeting in a ridge
    /// (one box's corner) do not.
    #[test]
    fn a_valley_splits_and_a_ridge_does_not() {
        for seed in 0..4 {
            let (points, pixels) = image(|x, _| Some(0.8 + 0.03 - x.abs()), 0.0015, seed);
            let sizes = parts(&points, &pixels);
            assert_eq!(sizes.len(), 2, "valley, seed {seed}: {sizes:?}");
            assert!(
                sizes[1] * 10 > sizes[0] * 8,
                "valley halves should be alike: {sizes:?}"
            );
            let (points, pixels) = image(|x, _| Some(0.8 + x.abs()), 0.0015, seed);
            assert_eq!(parts(&points, &pixels).len(), 1, "ridge, seed {seed}");
        }
    }

    /// A plane at 45 degrees with a small tab across a valley at its edge
    /// (a handle on its mug), `tab_half_y` metres half-high and 2.5 cm wide.
    fn plane_with_tab(tab_half_y: f32) -> impl Fn(f32, f32) -> Option<f32> {
        move |x, y| match x {
            x if x <= 0.05 => Some(0.83 - (0.05 - x)),
            x if x < 0.075 && y.abs() < tab_half_y => Some(0.83 - (x - 0.05)),
            _ => None,
        }
    }

    /// The tab is cut off at its valley by steps 1-5 and joins the plane
    /// again in step 6: small, a third of its outline on the plane,
    /// continuous in depth. A tab larger than `max_area_m2` stays apart,
    /// and so does the small tab with step 6 off.
    #[test]
    fn a_small_tab_hanging_on_a_plane_joins_it_and_a_large_one_does_not() {
        let split_only = CreaseConfig {
            reattach: None,
            ..CreaseConfig::default()
        };
        for seed in 0..3 {
            let (points, pixels) = image(plane_with_tab(0.025), 0.0015, seed);
            assert_eq!(
                parts(&points, &pixels),
                vec![points.len()],
                "small tab, seed {seed}"
            );
            let sizes = parts_with(&points, &pixels, &split_only);
            assert_eq!(sizes.len(), 2, "small tab without step 6, seed {seed}: {sizes:?}");
            // About 19 x 37 px of 1.8 mm^2: 12.5 cm^2.
            assert!((600..=900).contains(&sizes[1]), "seed {seed}: {sizes:?}");

            // The image's full height, 13.3 cm at 0.8 m: 33 cm^2. Only its
            // area keeps it apart.
            let (points, pixels) = image(plane_with_tab(0.1), 0.0015, seed);
            let sizes = parts(&points, &pixels);
            assert_eq!(sizes.len(), 2, "large tab, seed {seed}: {sizes:?}");
            let larger_tabs = CreaseConfig {
                reattach: Some(Reattach {
                    max_area_m2: 0.004,
                    ..Reattach::default()
                }),
                ..CreaseConfig::default()
            };
            assert_eq!(parts_with(&points, &pixels, &larger_tabs).len(), 1, "seed {seed}");
        }
    }

    type Depth = dyn Fn(f32, f32) -> Option<f32>;

    /// Smooth surfaces, tilted or curved outwards, stay whole under noise.
    #[test]
    fn smooth_surfaces_stay_whole() {
        let surfaces: [(&str, Box<Depth>); 3] = [
            ("tilted plane", Box::new(|x, y| Some(0.8 + 0.6 * x - 0.3 * y))),
            (
                "lying cylinder",
                Box::new(|x, _| (x.abs() < 0.045).then(|| 0.8 - (0.05f32.powi(2) - x * x).sqrt())),
            ),
            (
                "bowl-like dish",
                Box::new(|x, y| Some(0.8 + 0.5 * (x * x + y * y))),
            ),
        ];
        for (name, depth) in &surfaces {
            for seed in 0..3 {
                let (points, pixels) = image(depth, 0.002, seed);
                assert_eq!(parts(&points, &pixels), vec![points.len()], "{name}, seed {seed}");
            }
        }
    }

    /// A step of 2.5 cm between two flat objects, bridged by a column of
    /// flying pixels halfway in depth: one Euclidean cluster, two parts (the
    /// flying pixels join one side).
    #[test]
    fn a_bridged_step_splits() {
        let depth = |x: f32, _: f32| {
            Some(if x < -0.0005 {
                0.80
            } else if x < 0.0008 {
                0.8125
            } else {
                0.825
            })
        };
        let (points, pixels) = image(depth, 0.001, 7);
        let sizes = parts(&points, &pixels);
        assert_eq!(sizes.len(), 2, "{sizes:?}");
    }

    /// A shallow dent smaller than a part (a few hundred pixels) stays with
    /// its object.
    #[test]
    fn a_small_dent_stays() {
        let depth = |x: f32, y: f32| {
            let r = (x * x + y * y).sqrt();
            Some(0.8 + (0.004 - r).max(0.0) * 2.0)
        };
        let (points, pixels) = image(depth, 0.0015, 3);
        assert_eq!(parts(&points, &pixels).len(), 1);
    }

    /// Holes (no readings) and a cluster too small to split are left alone.
    #[test]
    fn small_or_holed_clusters_are_left_alone() {
        let (points, pixels) = image(|x, y| (x.abs() < 0.004 && y.abs() < 0.004).then_some(0.8), 0.0, 0);
        assert!(points.len() < 2 * CreaseConfig::default().min_part_points);
        let image = ImagePoints {
            points: &points,
            pixels: &pixels,
            width: W,
            origin: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            focal_px: F,
        };
        let cluster: Vec<u32> = (0..points.len() as u32).collect();
        let (out, split) = split_at_creases(&image, vec![cluster.clone()], 0.01, &CreaseConfig::default());
        assert_eq!((out, split), (vec![cluster], false));
        let holed = image_with_holes();
        assert_eq!(parts(&holed.0, &holed.1), vec![holed.0.len()]);
    }

    fn image_with_holes() -> (Vec<[f32; 3]>, Vec<u32>) {
        image(
            |x, y| ((x * 500.0).sin() * (y * 700.0).sin() < 0.9).then_some(0.8 + 0.2 * x),
            0.0015,
            11,
        )
    }
}
