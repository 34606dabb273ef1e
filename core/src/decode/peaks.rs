//! Quality peaks: optional Gaussian smoothing, local maxima, non-maximum suppression.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Qualities below this are treated as 0.
pub const NEGLIGIBLE_QUALITY: f32 = 1e-6;

/// Separable Gaussian blur of a `w x h` map (edges clamp); `sigma_px <= 0` copies.
///
/// Both passes loop over whole rows per kernel tap, which the compiler turns
/// into vector code. Values under [`NEGLIGIBLE_QUALITY`] and NaN become 0
/// first: a network's far tails are denormal floats, which are two orders of
/// magnitude slower to multiply (measured: 6x slower decoding).
pub fn smooth(map: &[f32], w: usize, h: usize, sigma_px: f32) -> Vec<f32> {
    let map: Vec<f32> = map
        .iter()
        .map(|&q| if q > NEGLIGIBLE_QUALITY { q } else { 0.0 })
        .collect();
    if sigma_px <= 0.0 || w == 0 || h == 0 {
        return map;
    }
    let r = (3.0 * sigma_px).ceil() as usize;
    let kernel: Vec<f32> = (0..=2 * r)
        .map(|i| {
            let d = i as f32 - r as f32;
            (-(d * d) / (2.0 * sigma_px * sigma_px)).exp()
        })
        .collect();
    let total: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / total).collect();

    // Horizontal: each row padded by r clamped values on both sides.
    let mut padded = vec![0.0f32; w + 2 * r];
    let mut horizontal = vec![0.0f32; w * h];
    for (src, dst) in map.chunks_exact(w).zip(horizontal.chunks_exact_mut(w)) {
        padded[..r].fill(src[0]);
        padded[r..r + w].copy_from_slice(src);
        padded[r + w..].fill(src[w - 1]);
        for (k, &weight) in kernel.iter().enumerate() {
            for (d, s) in dst.iter_mut().zip(&padded[k..k + w]) {
                *d += weight * s;
            }
        }
    }
    // Vertical: whole rows at a time, source rows clamped.
    let mut out = vec![0.0f32; w * h];
    for (v, dst) in out.chunks_exact_mut(w).enumerate() {
        for (k, &weight) in kernel.iter().enumerate() {
            let row = (v + k).saturating_sub(r).min(h - 1);
            for (d, s) in dst.iter_mut().zip(&horizontal[row * w..(row + 1) * w]) {
                *d += weight * s;
            }
        }
    }
    out
}

/// Kernel radius of [`smooth`] for `sigma_px` (0 when smoothing is off).
fn kernel_radius(sigma_px: f32) -> usize {
    if sigma_px > 0.0 {
        (3.0 * sigma_px).ceil() as usize
    } else {
        0
    }
}

/// [`find_peaks`] of [`smooth`]ed `map` (`l x l`), with the same result, but
/// only the part of the map that can hold a peak is smoothed: a smoothed
/// value is a weighted mean of raw values within the kernel radius r, so it
/// can reach `threshold` only within r of a raw value that does. The map is
/// cropped to that box grown by 2r (the kernel's inputs), which is exact:
/// inside the crop's inner box every input is in the crop, and every value
/// outside it is under the threshold.
pub fn smoothed_peaks(
    map: &[f32],
    l: usize,
    sigma_px: f32,
    threshold: f32,
    radius_px: usize,
    k: usize,
) -> Vec<(usize, usize, f32)> {
    let (mut u0, mut u1, mut v0, mut v1) = (usize::MAX, 0, usize::MAX, 0);
    for (v, row) in map.chunks_exact(l).enumerate() {
        for (u, &q) in row.iter().enumerate() {
            if q >= threshold {
                (u0, u1, v0, v1) = (u0.min(u), u1.max(u), v0.min(v), v1.max(v));
            }
        }
    }
    if u0 > u1 {
        return Vec::new();
    }
    let grow = 2 * kernel_radius(sigma_px);
    let (u0, v0) = (u0.saturating_sub(grow), v0.saturating_sub(grow));
    let (u1, v1) = ((u1 + grow).min(l - 1), (v1 + grow).min(l - 1));
    let (w, h) = (u1 - u0 + 1, v1 - v0 + 1);
    let crop: Vec<f32> = (v0..=v1)
        .flat_map(|v| map[v * l + u0..=v * l + u1].iter().copied())
        .collect();
    let smoothed = smooth(&crop, w, h, sigma_px);
    find_peaks(&smoothed, w, h, threshold, radius_px, k)
        .into_iter()
        .map(|(u, v, q)| (u + u0, v + v0, q))
        .collect()
}

/// Up to `k` peaks `(u, v, value)` of a `w x h` map at or above `threshold`:
/// local maxima (>= their 8 neighbours), best first (ties by row-major
/// index), none within `radius_px` of a better one.
pub fn find_peaks(
    map: &[f32],
    w: usize,
    h: usize,
    threshold: f32,
    radius_px: usize,
    k: usize,
) -> Vec<(usize, usize, f32)> {
    suppress(local_maxima(map, w, h, threshold), w, radius_px, k)
}

/// Pixels `(row-major index, value)` at or above `threshold` that are >=
/// their 8 neighbours, in row-major order.
fn local_maxima(map: &[f32], w: usize, h: usize, threshold: f32) -> Vec<(usize, f32)> {
    if w == 0 || h == 0 || map.len() < w * h {
        return Vec::new();
    }
    // A pixel is a local maximum when it is >= the maximum of its 3 x 3
    // window (itself included). The window maximum is separable: a
    // horizontal max of 3, then a vertical one, each over whole rows (vector
    // code, no per-neighbour bounds tests). Edges clamp, which only repeats
    // pixels already in the window; `f32::max` skips NaN neighbours, as the
    // `>` of the definition does.
    let mut across = vec![0f32; w * h];
    for (src, dst) in map.chunks_exact(w).zip(across.chunks_exact_mut(w)).take(h) {
        row_max3(src, dst);
    }
    let mut window = vec![0f32; w];
    let mut candidates = Vec::new();
    for v in 0..h {
        let up = &across[v.saturating_sub(1) * w..][..w];
        let mid = &across[v * w..][..w];
        let down = &across[(v + 1).min(h - 1) * w..][..w];
        for (((m, a), b), c) in window.iter_mut().zip(up).zip(mid).zip(down) {
            *m = a.max(*b).max(*c);
        }
        for (u, (&q, &m)) in map[v * w..(v + 1) * w].iter().zip(&window).enumerate() {
            // NaN fails both comparisons.
            if q >= threshold && q >= m {
                candidates.push((v * w + u, q));
            }
        }
    }
    candidates
}

/// Best first (ties by index), dropping any candidate within `radius_px` of
/// a better kept one, up to `k`. The candidates are heaped, not sorted: a
/// map searched from `min_quality` 0 has hundreds, and only the first few
/// are looked at.
fn suppress(candidates: Vec<(usize, f32)>, w: usize, radius_px: usize, k: usize) -> Vec<(usize, usize, f32)> {
    let mut heap = BinaryHeap::from(candidates.into_iter().map(Ranked).collect::<Vec<_>>());
    let r2 = (radius_px * radius_px) as isize;
    let mut kept: Vec<(usize, usize, f32)> = Vec::new();
    while kept.len() < k {
        let Some(Ranked((i, q))) = heap.pop() else { break };
        let (u, v) = ((i % w) as isize, (i / w) as isize);
        let suppressed = kept.iter().any(|&(ku, kv, _)| {
            let (du, dv) = (ku as isize - u, kv as isize - v);
            du * du + dv * dv <= r2
        });
        if !suppressed {
            kept.push((u as usize, v as usize, q));
        }
    }
    kept
}

/// A candidate `(index, value)` ordered best first: the greater value, then
/// the lower index.
struct Ranked((usize, f32));

impl Ord for Ranked {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.1.total_cmp(&other.0.1).then(other.0.0.cmp(&self.0.0))
    }
}

impl PartialOrd for Ranked {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Ranked {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Ranked {}

/// `dst[u]` = the maximum of `src[u - 1..=u + 1]`, clamped at the ends.
fn row_max3(src: &[f32], dst: &mut [f32]) {
    let w = src.len();
    if w == 1 {
        dst[0] = src[0];
        return;
    }
    dst[0] = src[0].max(src[1]);
    dst[w - 1] = src[w - 2].max(src[w - 1]);
    for (((d, a), b), c) in dst[1..w - 1].iter_mut().zip(src).zip(&src[1..]).zip(&src[2..]) {
        *d = a.max(*b).max(*c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition read literally: >= every in-bounds 8-neighbour.
    fn local_maxima_reference(map: &[f32], w: usize, h: usize, threshold: f32) -> Vec<(usize, f32)> {
        let mut candidates: Vec<(usize, f32)> = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let q = map[v * w + u];
                if q.is_nan() || q < threshold {
                    continue;
                }
                let beaten = (-1isize..=1).any(|dv| {
                    (-1isize..=1).any(|du| {
                        let (x, y) = (u as isize + du, v as isize + dv);
                        (du, dv) != (0, 0)
                            && x >= 0
                            && y >= 0
                            && (x as usize) < w
                            && (y as usize) < h
                            && map[y as usize * w + x as usize] > q
                    })
                });
                if !beaten {
                    candidates.push((v * w + u, q));
                }
            }
        }
        candidates
    }

    /// Random maps with plateaus (values on a coarse grid), NaNs, thin maps
    /// and all thresholds: the window-maximum search finds what the
    /// definition finds.
    #[test]
    fn window_maximum_peaks_equal_the_definition() {
        let mut rng = crate::rng::SplitMix64::new(11);
        for trial in 0..300 {
            let (w, h) = (1 + rng.below(20), 1 + rng.below(20));
            let map: Vec<f32> = (0..w * h)
                .map(|_| match rng.below(20) {
                    0 => f32::NAN,
                    _ => rng.below(6) as f32 / 5.0,
                })
                .collect();
            for threshold in [0.0, 0.4, 1.0] {
                let expected = local_maxima_reference(&map, w, h, threshold);
                let context = format!("trial {trial}, {w} x {h}, threshold {threshold}");
                assert_eq!(local_maxima(&map, w, h, threshold), expected, "{context}");
                assert_eq!(
                    find_peaks(&map, w, h, threshold, 2, 5),
                    suppress(expected, w, 2, 5),
                    "{context}"
                );
            }
        }
    }

    /// Suppression read literally: every candidate sorted best first (ties
    /// by index), each kept unless within the radius of one kept before.
    fn suppress_reference(
        mut candidates: Vec<(usize, f32)>,
        w: usize,
        radius_px: usize,
        k: usize,
    ) -> Vec<(usize, usize, f32)> {
        candidates.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let mut kept: Vec<(usize, usize, f32)> = Vec::new();
        for (i, q) in candidates {
            let (u, v) = (i % w, i / w);
            let near = |&(ku, kv, _): &(usize, usize, f32)| {
                ku.abs_diff(u).pow(2) + kv.abs_diff(v).pow(2) <= radius_px.pow(2)
            };
            if kept.len() < k && !kept.iter().any(near) {
                kept.push((u, v, q));
            }
        }
        kept
    }

    /// The heap keeps what sorting keeps: many tied values, candidates in
    /// any order, every radius and count.
    #[test]
    fn heaped_suppression_keeps_what_sorting_keeps() {
        let mut rng = crate::rng::SplitMix64::new(5);
        for trial in 0..500 {
            let w = 1 + rng.below(30);
            let n = rng.below(200);
            let mut indices: Vec<usize> = (0..w * w).collect();
            let candidates: Vec<(usize, f32)> = (0..n.min(w * w))
                .map(|_| {
                    let at = indices.swap_remove(rng.below(indices.len()));
                    (at, rng.below(8) as f32 / 7.0)
                })
                .collect();
            let (radius, k) = (rng.below(6), rng.below(12));
            assert_eq!(
                suppress(candidates.clone(), w, radius, k),
                suppress_reference(candidates, w, radius, k),
                "trial {trial}: {w} px wide, radius {radius}, k {k}"
            );
        }
    }

    #[test]
    fn plateau_neighbours_are_suppressed_and_order_is_by_value() {
        let l = 16;
        let mut map = vec![0.0f32; l * l];
        map[3 * l + 3] = 0.9;
        map[3 * l + 4] = 0.9; // plateau twin of the first peak
        map[12 * l + 12] = 0.95;
        map[8 * l + 2] = 0.5; // under threshold
        let peaks = find_peaks(&map, l, l, 0.8, 3, 5);
        assert_eq!(peaks, vec![(12, 12, 0.95), (3, 3, 0.9)]);
    }

    #[test]
    fn smoothing_keeps_mass_and_peak_position() {
        let l = 21;
        let mut map = vec![0.0f32; l * l];
        map[10 * l + 10] = 1.0;
        let s = smooth(&map, l, l, 1.5);
        assert!((s.iter().sum::<f32>() - 1.0).abs() < 1e-4);
        let best = (0..l * l).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap();
        assert_eq!(best, 10 * l + 10);
    }

    /// The cropped search finds exactly what smoothing the whole map finds,
    /// on random maps with peaks anywhere, edges included.
    #[test]
    fn smoothed_peaks_equal_the_full_computation() {
        let mut rng = crate::rng::SplitMix64::new(3);
        let l = 40;
        for trial in 0..200 {
            let mut map = vec![0.0f32; l * l];
            for _ in 0..(1 + trial % 4) {
                let (cu, cv) = (rng.below(l) as f32, rng.below(l) as f32);
                let peak = 0.5 + 0.5 * (rng.below(1000) as f32 / 1000.0);
                for (i, q) in map.iter_mut().enumerate() {
                    let (du, dv) = ((i % l) as f32 - cu, (i / l) as f32 - cv);
                    *q = q.max(peak * (-(du * du + dv * dv) / 6.0).exp());
                }
            }
            for sigma in [0.0, 1.0, 2.0] {
                let full = find_peaks(&smooth(&map, l, l, sigma), l, l, 0.6, 3, 4);
                assert_eq!(
                    smoothed_peaks(&map, l, sigma, 0.6, 3, 4),
                    full,
                    "trial {trial} sigma {sigma}"
                );
            }
        }
    }
}
