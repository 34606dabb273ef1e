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
    let mut sums = EntropySums::default();
    for &v in values {
        sums.add(v);
    }
    sums.bits()
}

/// The running sums behind [`view_entropy`], fed one pixel at a time (the
/// view renderer accumulates them while it writes the image).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EntropySums {
    total: f64,
    weighted: f64,
}

impl EntropySums {
    /// Adds one pixel value (values <= 0 add nothing).
    #[inline]
    pub fn add(&mut self, v: f32) {
        if v > 0.0 {
            self.total += f64::from(v);
            self.weighted += f64::from(v * v.log2());
        }
    }

    /// The entropy in bits of the values added so far.
    pub fn bits(&self) -> f64 {
        if self.total <= 0.0 {
            return 0.0;
        }
        (self.total.log2() - self.weighted / self.total).max(0.0)
    }
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
