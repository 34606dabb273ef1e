//! Quality peaks: optional Gaussian smoothing, local maxima, non-maximum suppression.

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
    let mut candidates: Vec<(usize, f32)> = Vec::new();
    for v in 0..h {
        for u in 0..w {
            let q = map[v * w + u];
            if q.is_nan() || q < threshold {
                continue;
            }
            let mut is_max = true;
            'neighbours: for dv in -1isize..=1 {
                for du in -1isize..=1 {
                    let (x, y) = (u as isize + du, v as isize + dv);
                    if (du, dv) != (0, 0)
                        && x >= 0
                        && y >= 0
                        && (x as usize) < w
                        && (y as usize) < h
                        && map[y as usize * w + x as usize] > q
                    {
                        is_max = false;
                        break 'neighbours;
                    }
                }
            }
            if is_max {
                candidates.push((v * w + u, q));
            }
        }
    }
    candidates.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let r2 = (radius_px * radius_px) as isize;
    let mut kept: Vec<(usize, usize, f32)> = Vec::new();
    for (i, q) in candidates {
        if kept.len() >= k {
            break;
        }
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

#[cfg(test)]
mod tests {
    use super::*;

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
