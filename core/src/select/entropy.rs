//! Viewpoint entropy (DESIGN.md, method step 4).
//!
//! The view image is read as a distribution over its pixels,
//! `p_k = value_k / sum(values)`, and `H = -sum p_k log2 p_k`. A view that
//! shows more of the object, with more depth variation, scores higher. The
//! bounds are `0` (one lit pixel, or an empty view) and `log2(l * l)` (every
//! pixel equal).

/// Entropy in bits of the view image `values` (all >= 0).
///
/// Computed as `H = log2(T) - sum(v log2 v) / T` with `T = sum(v)`: one
/// logarithm per lit pixel, in f32 (sums in f64).
pub fn view_entropy(values: &[f32]) -> f64 {
    let (mut total, mut weighted) = (0.0f64, 0.0f64);
    for &v in values {
        if v > 0.0 {
            total += f64::from(v);
            weighted += f64::from(v * v.log2());
        }
    }
    if total <= 0.0 {
        return 0.0;
    }
    (total.log2() - weighted / total).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_reached() {
        assert_eq!(view_entropy(&[0.0; 16]), 0.0);
        let mut one = [0.0f32; 16];
        one[3] = 0.7;
        assert!(view_entropy(&one).abs() < 1e-6);
        assert!((view_entropy(&[0.4; 16]) - 4.0).abs() < 1e-6);
    }
}
