//! Which views of an object go through the network.

use crate::rng::SplitMix64;
use crate::view::ViewAxis;

/// View selection policies (the paper's method and its ablations).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewPolicy {
    /// The view of highest viewpoint entropy (the paper's method).
    Entropy,
    /// Every view; the best grasp across them wins.
    All,
    /// The top view only.
    TopDown,
    /// One view drawn at random from a stream seeded with `seed` and the object id.
    Random {
        /// Seed of the draw.
        seed: u64,
    },
}

/// Indices (into `axes`) of the views to infer for object `object_id`.
/// Ties in entropy go to the earlier view in `axes`.
pub fn select_views(policy: ViewPolicy, axes: &[ViewAxis], entropies: &[f64], object_id: u32) -> Vec<usize> {
    if axes.is_empty() {
        return Vec::new();
    }
    match policy {
        ViewPolicy::All => (0..axes.len()).collect(),
        ViewPolicy::TopDown => vec![axes.iter().position(|&a| a == ViewAxis::Top).unwrap_or(0)],
        ViewPolicy::Random { seed } => {
            let mut rng = SplitMix64::new(seed ^ (u64::from(object_id) << 32 | 0x5EED));
            vec![rng.below(axes.len())]
        }
        ViewPolicy::Entropy => {
            let mut best = 0;
            for (i, h) in entropies.iter().enumerate().take(axes.len()) {
                if *h > entropies[best] {
                    best = i;
                }
            }
            vec![best]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_policy_picks_what_it_says() {
        let axes = ViewAxis::ALL;
        let h = [3.0, 5.0, 5.0];
        assert_eq!(
            select_views(ViewPolicy::Entropy, &axes, &h, 0),
            vec![1],
            "tie -> earlier"
        );
        assert_eq!(select_views(ViewPolicy::All, &axes, &h, 0), vec![0, 1, 2]);
        assert_eq!(
            select_views(ViewPolicy::TopDown, &[ViewAxis::Side, ViewAxis::Top], &h, 0),
            vec![1]
        );
        let a = select_views(ViewPolicy::Random { seed: 9 }, &axes, &h, 4);
        assert_eq!(
            a,
            select_views(ViewPolicy::Random { seed: 9 }, &axes, &h, 4),
            "seeded"
        );
        let drawn: std::collections::HashSet<usize> = (0..64)
            .map(|id| select_views(ViewPolicy::Random { seed: 9 }, &axes, &h, id)[0])
            .collect();
        assert_eq!(drawn.len(), 3, "every view gets drawn for some object");
    }
}
