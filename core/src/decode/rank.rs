//! Ranking grasps across objects.

use super::grasp::Grasp;

/// Limits of the ranked list.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RankConfig {
    /// Grasps under this quality are dropped (the paper's tau).
    pub min_quality: f32,
    /// At most this many grasps per object.
    pub max_per_object: usize,
    /// At most this many grasps in all.
    pub max_grasps: usize,
}

/// Sorts best first (quality, then object id, view, pixel row and column:
/// a total order, so equal inputs always rank the same) and applies the limits.
pub fn rank_grasps(grasps: Vec<Grasp>, config: &RankConfig) -> Vec<Grasp> {
    rank_grasps_accepted(grasps, config, Some).0
}

/// [`rank_grasps`], keeping what `vet` returns for each grasp: the grasp
/// itself, a repaired one in its place (same rank), or `None` to refuse it.
/// `vet` is asked in rank order, and only while a grasp could still make
/// the list, so a costly check runs on few grasps. Also returns how many
/// were refused.
pub fn rank_grasps_accepted(
    mut grasps: Vec<Grasp>,
    config: &RankConfig,
    mut vet: impl FnMut(Grasp) -> Option<Grasp>,
) -> (Vec<Grasp>, usize) {
    grasps.retain(|g| g.quality >= config.min_quality);
    grasps.sort_by(|a, b| {
        b.quality
            .total_cmp(&a.quality)
            .then(a.object_id.cmp(&b.object_id))
            .then(a.view.cmp(&b.view))
            .then(a.pixel[1].cmp(&b.pixel[1]))
            .then(a.pixel[0].cmp(&b.pixel[0]))
    });
    let mut per_object: rustc_hash::FxHashMap<u32, usize> = rustc_hash::FxHashMap::default();
    let mut kept = Vec::with_capacity(config.max_grasps.min(grasps.len()));
    let mut refused = 0;
    for g in grasps {
        if kept.len() == config.max_grasps {
            break;
        }
        let n = per_object.entry(g.object_id).or_insert(0);
        if *n >= config.max_per_object {
            continue;
        }
        let Some(g) = vet(g) else {
            refused += 1;
            continue;
        };
        *n += 1;
        kept.push(g);
    }
    (kept, refused)
}

#[cfg(test)]
mod tests {
    use nalgebra::Isometry3;

    use super::*;
    use crate::view::ViewAxis;

    fn grasp(object_id: u32, quality: f32, u: u32) -> Grasp {
        Grasp {
            world_from_grasp: Isometry3::identity(),
            width_m: 0.05,
            quality,
            object_id,
            view: ViewAxis::Top,
            pixel: [u, 0],
            angle_rad: 0.0,
        }
    }

    #[test]
    fn sorted_limited_and_stable_on_ties() {
        let grasps = vec![
            grasp(2, 0.9, 1),
            grasp(1, 0.9, 5),
            grasp(1, 0.95, 2),
            grasp(1, 0.9, 3),
            grasp(3, 0.5, 0),
        ];
        let config = RankConfig {
            min_quality: 0.8,
            max_per_object: 2,
            max_grasps: 10,
        };
        let ranked = rank_grasps(grasps.clone(), &config);
        let keys: Vec<(u32, u32)> = ranked.iter().map(|g| (g.object_id, g.pixel[0])).collect();
        assert_eq!(keys, vec![(1, 2), (1, 3), (2, 1)]);
        let mut reversed = grasps;
        reversed.reverse();
        assert_eq!(rank_grasps(reversed, &config), ranked);
        let one = RankConfig {
            max_grasps: 1,
            ..config
        };
        assert_eq!(rank_grasps(ranked.clone(), &one).len(), 1);
    }

    #[test]
    fn refused_grasps_make_room_for_the_next_of_their_object() {
        let grasps = vec![
            grasp(1, 0.9, 1),
            grasp(1, 0.8, 2),
            grasp(1, 0.7, 3),
            grasp(2, 0.6, 4),
        ];
        let config = RankConfig {
            min_quality: 0.0,
            max_per_object: 2,
            max_grasps: 3,
        };
        let mut asked = Vec::new();
        let (kept, refused) = rank_grasps_accepted(grasps, &config, |mut g| {
            asked.push(g.pixel[0]);
            // Refuse pixel 2; widen pixel 3 (a repair keeps its rank).
            if g.pixel[0] == 3 {
                g.width_m = 0.08;
            }
            (g.pixel[0] != 2).then_some(g)
        });
        let keys: Vec<(u32, f64)> = kept.iter().map(|g| (g.pixel[0], g.width_m)).collect();
        assert_eq!(keys, vec![(1, 0.05), (3, 0.08), (4, 0.05)]);
        assert_eq!(refused, 1);
        // Each grasp was asked about once, in rank order.
        assert_eq!(asked, vec![1, 2, 3, 4]);
    }
}
