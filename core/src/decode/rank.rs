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
/// a total order, so equal inputs always rank the same) and applies the
/// limits. A full list still makes room for every object's best grasp: it
/// replaces the lowest-ranked grasp of an object that has two or more.
pub fn rank_grasps(grasps: Vec<Grasp>, config: &RankConfig) -> Vec<Grasp> {
    rank_grasps_vetted::<()>(grasps, config, Verdict::Accept).grasps
}

/// What a check says of one grasp. `T` says why a grasp is deferred; the
/// deferred are kept in `T`'s order, each kind in rank order.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict<T = ()> {
    /// Keep it (or a repaired grasp in its place) at its rank.
    Accept(Grasp),
    /// Keep it, but after every accepted grasp, if room is left.
    Defer(Grasp, T),
    /// Drop it.
    Refuse,
}

/// The ranked list and what the check did to get it.
#[derive(Debug, Clone, PartialEq)]
pub struct Ranked<T = ()> {
    /// Best first: the accepted, then the deferred.
    pub grasps: Vec<Grasp>,
    /// Grasps refused.
    pub refused: usize,
    /// Why each deferred grasp in `grasps` (at its end, in this order) was
    /// deferred.
    pub deferred: Vec<T>,
}

/// [`rank_grasps`], with `vet`'s verdict on each grasp. `vet` is asked in
/// rank order, and only while a grasp could still make the list, so a
/// costly check runs on few grasps.
pub fn rank_grasps_vetted<T: Ord>(
    grasps: Vec<Grasp>,
    config: &RankConfig,
    vet: impl FnMut(Grasp) -> Verdict<T>,
) -> Ranked<T> {
    rank_grasps_scored(grasps, config, |g| g.quality, vet)
}

/// [`rank_grasps_vetted`], ranked by `score` (higher first) instead of the
/// quality; `min_quality` still applies to the quality.
pub fn rank_grasps_scored<T: Ord>(
    mut grasps: Vec<Grasp>,
    config: &RankConfig,
    score: impl Fn(&Grasp) -> f32,
    mut vet: impl FnMut(Grasp) -> Verdict<T>,
) -> Ranked<T> {
    grasps.retain(|g| g.quality >= config.min_quality);
    let mut scored: Vec<(f32, Grasp)> = grasps.into_iter().map(|g| (score(&g), g)).collect();
    scored.sort_by(|(sa, a), (sb, b)| {
        sb.total_cmp(sa)
            .then(a.object_id.cmp(&b.object_id))
            .then(a.view.cmp(&b.view))
            .then(a.pixel[1].cmp(&b.pixel[1]))
            .then(a.pixel[0].cmp(&b.pixel[0]))
    });
    let grasps = scored.into_iter().map(|(_, g)| g);
    let mut per_object: rustc_hash::FxHashMap<u32, usize> = rustc_hash::FxHashMap::default();
    // Accepted grasps with their rank, and (once the list is full) the best
    // accepted grasp of each object that has none in it yet.
    let mut kept: Vec<(usize, Grasp)> = Vec::with_capacity(config.max_grasps.min(grasps.len()));
    let mut missing: Vec<(usize, Grasp)> = Vec::new();
    let (mut refused, mut deferred) = (0, Vec::new());
    for (rank, g) in grasps.enumerate() {
        let count = per_object.get(&g.object_id).copied().unwrap_or(0);
        if count >= config.max_per_object {
            continue;
        }
        let full = kept.len() == config.max_grasps;
        if full && (count > 0 || missing.iter().any(|(_, m)| m.object_id == g.object_id)) {
            continue;
        }
        match vet(g) {
            Verdict::Accept(g) if full => missing.push((rank, g)),
            Verdict::Accept(g) => {
                *per_object.entry(g.object_id).or_insert(0) += 1;
                kept.push((rank, g));
            }
            Verdict::Defer(g, why) => deferred.push((why, g)),
            Verdict::Refuse => refused += 1,
        }
    }
    // Every object with an accepted grasp gets one in the list: each missing
    // one takes the place of the lowest-ranked grasp of an object that has
    // two or more, while there is one.
    for (rank, g) in missing {
        let spare = kept
            .iter()
            .rposition(|(_, k)| per_object.get(&k.object_id).is_some_and(|&n| n > 1));
        let Some(spare) = spare else {
            break;
        };
        let (_, out) = kept.remove(spare);
        if let Some(n) = per_object.get_mut(&out.object_id) {
            *n -= 1;
        }
        *per_object.entry(g.object_id).or_insert(0) += 1;
        kept.push((rank, g));
    }
    kept.sort_by_key(|(rank, _)| *rank);
    let mut kept: Vec<Grasp> = kept.into_iter().map(|(_, g)| g).collect();
    // Stable: each kind keeps its rank order.
    deferred.sort_by(|a, b| a.0.cmp(&b.0));
    let mut kept_deferred = Vec::new();
    for (why, g) in deferred {
        if kept.len() == config.max_grasps {
            break;
        }
        let n = per_object.entry(g.object_id).or_insert(0);
        if *n < config.max_per_object {
            *n += 1;
            kept.push(g);
            kept_deferred.push(why);
        }
    }
    Ranked {
        grasps: kept,
        refused,
        deferred: kept_deferred,
    }
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
            repairs: Default::default(),
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
    fn a_full_list_makes_room_for_every_object_s_best_grasp() {
        // Objects 1 and 2 fill a list of 4 with two grasps each; object 3's
        // best (quality 0.5) takes the place of the lowest of them, object
        // 4's only grasp is refused and takes nothing.
        let grasps = vec![
            grasp(1, 0.9, 1),
            grasp(1, 0.85, 2),
            grasp(2, 0.8, 3),
            grasp(2, 0.75, 4),
            grasp(3, 0.5, 5),
            grasp(3, 0.4, 6),
            grasp(4, 0.3, 7),
        ];
        let config = RankConfig {
            min_quality: 0.0,
            max_per_object: 2,
            max_grasps: 4,
        };
        let mut asked = Vec::new();
        let ranked = rank_grasps_vetted::<()>(grasps.clone(), &config, |g| {
            asked.push(g.pixel[0]);
            if g.object_id == 4 {
                Verdict::Refuse
            } else {
                Verdict::Accept(g)
            }
        });
        let keys: Vec<u32> = ranked.grasps.iter().map(|g| g.pixel[0]).collect();
        assert_eq!(keys, [1, 2, 3, 5]);
        assert_eq!(ranked.refused, 1);
        // Once full, only objects without a grasp in the list are checked.
        assert_eq!(asked, [1, 2, 3, 4, 5, 7]);
        // With no object holding two, nothing is replaced.
        let one_each = RankConfig {
            max_per_object: 1,
            max_grasps: 2,
            ..config
        };
        let keys: Vec<u32> = rank_grasps(grasps, &one_each)
            .iter()
            .map(|g| g.pixel[0])
            .collect();
        assert_eq!(keys, [1, 3]);
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
        let ranked = rank_grasps_vetted::<()>(grasps, &config, |mut g| {
            asked.push(g.pixel[0]);
            // Refuse pixel 2; widen pixel 3 (a repair keeps its rank).
            if g.pixel[0] == 3 {
                g.width_m = 0.08;
            }
            if g.pixel[0] == 2 {
                Verdict::Refuse
            } else {
                Verdict::Accept(g)
            }
        });
        let keys: Vec<(u32, f64)> = ranked.grasps.iter().map(|g| (g.pixel[0], g.width_m)).collect();
        assert_eq!(keys, vec![(1, 0.05), (3, 0.08), (4, 0.05)]);
        assert_eq!((ranked.refused, ranked.deferred.len()), (1, 0));
        // Each grasp was asked about once, in rank order.
        assert_eq!(asked, vec![1, 2, 3, 4]);
    }

    #[test]
    fn deferred_grasps_come_after_every_accepted_one_by_kind_within_the_limits() {
        let grasps = vec![
            grasp(1, 0.9, 1),
            grasp(1, 0.8, 2),
            grasp(2, 0.7, 3),
            grasp(1, 0.6, 4),
            grasp(3, 0.5, 5),
            grasp(4, 0.4, 6),
        ];
        let config = RankConfig {
            min_quality: 0.0,
            max_per_object: 2,
            max_grasps: 5,
        };
        // Pixels 1 and 3 deferred as kind 1, pixel 6 as kind 0: the rest
        // keep their order, then 6 (kind 0 first), then 1 and 3.
        let defer = |g: Grasp| match g.pixel[0] {
            1 | 3 => Verdict::Defer(g, 1u8),
            6 => Verdict::Defer(g, 0u8),
            _ => Verdict::Accept(g),
        };
        let ranked = rank_grasps_vetted(grasps.clone(), &config, defer);
        let keys: Vec<u32> = ranked.grasps.iter().map(|g| g.pixel[0]).collect();
        // Object 1 has two accepted grasps (2 and 4): its deferred 1 finds no room.
        assert_eq!(keys, vec![2, 4, 5, 6, 3]);
        assert_eq!((ranked.refused, ranked.deferred), (0, vec![0, 1]));
        let four = RankConfig {
            max_grasps: 4,
            ..config
        };
        let ranked = rank_grasps_vetted(grasps.clone(), &four, defer);
        assert_eq!(ranked.grasps.last().map(|g| g.pixel[0]), Some(6));
        assert_eq!(ranked.deferred, vec![0]);
        // With the list full of accepted grasps the deferred never show.
        let three = RankConfig {
            max_grasps: 3,
            ..config
        };
        let ranked = rank_grasps_vetted(grasps, &three, defer);
        let keys: Vec<u32> = ranked.grasps.iter().map(|g| g.pixel[0]).collect();
        assert_eq!(keys, vec![2, 4, 5]);
        assert!(ranked.deferred.is_empty());
    }

    #[test]
    fn a_score_reorders_but_min_quality_still_reads_the_quality() {
        let grasps = vec![
            grasp(1, 0.9, 1),
            grasp(1, 0.8, 2),
            grasp(2, 0.7, 3),
            grasp(2, 0.3, 4),
        ];
        let config = RankConfig {
            min_quality: 0.5,
            max_per_object: 5,
            max_grasps: 10,
        };
        // Pixel u 1 is penalised most: it goes last; 0.3 stays out whatever its score.
        let ranked = rank_grasps_scored::<()>(
            grasps,
            &config,
            |g| if g.pixel[0] == 1 { 0.1 } else { 1.0 - g.quality },
            Verdict::Accept,
        );
        let keys: Vec<u32> = ranked.grasps.iter().map(|g| g.pixel[0]).collect();
        assert_eq!(keys, vec![3, 2, 1]);
    }
}
