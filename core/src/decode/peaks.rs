//! Quality peaks: optional Gaussian smoothing, local maxima, non-maximum suppression.

/// Separable Gaussian blur of an `l x l` map (edges clamp); `sigma_px <= 0` copies.
pub fn smooth(map: &[f32], l: usize, sigma_px: f32) -> Vec<f32> {
    if sigma_px <= 0.0 {
        return map.to_vec();
    }
    let r = (3.0 * sigma_px).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let total: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / total).collect();
    let clamp = |i: isize| i.clamp(0, l as isize - 1) as usize;
    let mut tmp = vec![0.0; l * l];
    for v in 0..l {
        for u in 0..l {
            tmp[v * l + u] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| w * map[v * l + clamp(u as isize + k as isize - r)])
                .sum();
        }
    }
    let mut out = vec![0.0; l * l];
    for v in 0..l {
        for u in 0..l {
            out[v * l + u] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| w * tmp[clamp(v as isize + k as isize - r) * l + u])
                .sum();
        }
    }
    out
}

/// Up to `k` peaks `(u, v, value)` of an `l x l` map at or above `threshold`:
/// local maxima (>= their 8 neighbours), best first (ties by row-major
/// index), none within `radius_px` of a better one.
pub fn find_peaks(
    map: &[f32],
    l: usize,
    threshold: f32,
    radius_px: usize,
    k: usize,
) -> Vec<(usize, usize, f32)> {
    let mut candidates: Vec<(usize, f32)> = Vec::new();
    for v in 0..l {
        for u in 0..l {
            let q = map[v * l + u];
            if !(q >= threshold) {
                continue;
            }
            let mut is_max = true;
            'neighbours: for dv in -1isize..=1 {
                for du in -1isize..=1 {
                    let (x, y) = (u as isize + du, v as isize + dv);
                    if (du, dv) != (0, 0)
                        && x >= 0
                        && y >= 0
                        && (x as usize) < l
                        && (y as usize) < l
                        && map[y as usize * l + x as usize] > q
                    {
                        is_max = false;
                        break 'neighbours;
                    }
                }
            }
            if is_max {
                candidates.push((v * l + u, q));
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
        let (u, v) = ((i % l) as isize, (i / l) as isize);
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
        let peaks = find_peaks(&map, l, 0.8, 3, 5);
        assert_eq!(peaks, vec![(12, 12, 0.95), (3, 3, 0.9)]);
    }

    #[test]
    fn smoothing_keeps_mass_and_peak_position() {
        let l = 21;
        let mut map = vec![0.0f32; l * l];
        map[10 * l + 10] = 1.0;
        let s = smooth(&map, l, 1.5);
        assert!((s.iter().sum::<f32>() - 1.0).abs() < 1e-4);
        let best = (0..l * l).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap();
        assert_eq!(best, 10 * l + 10);
    }
}
