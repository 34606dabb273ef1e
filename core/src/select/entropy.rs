//! Viewpoint entropy (DESIGN.md, method step 4).
//!
//! The view image is read as a distribution over its pixels,
//! `p_k = value_k / sum(values)`, and `H = -sum p_k log2 p_k`. A view that
//! shows more of the object, with more depth variation, scores higher. The
//! bounds are `0` (one lit pixel, or an empty view) and `log2(l * l)` (every
//! pixel equal).

/// Entropy in bits of the view image `values` (all >= 0).
pub fn view_entropy(values: &[f32]) -> f64 {
    let total: f64 = values.iter().map(|&v| f64::from(v.max(0.0))).sum();
    if total <= 0.0 {
        return 0.0;
    }
    let h: f64 = values
        .iter()
        .filter(|&&v| v > 0.0)
        .map(|&v| {
            let p = f64::from(v) / total;
            -p * p.log2()
        })
        .sum();
    h.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_reached() {
        assert_eq!(view_entropy(&[0.0; 16]), 0.0);
        let mut one = [0.0f32; 16];
        one[3] = 0.7;
        assert_eq!(view_entropy(&one), 0.0);
        assert!((view_entropy(&[0.4; 16]) - 4.0).abs() < 1e-12);
    }
}
