//! A frame made ready for the network, between `Planner::prepare` and
//! `Planner::finish`, and the view cascade's order.

use super::options::PlanOptions;
use super::plan::{DetectedObject, ObjectRefusals, Plan, RankedLast, StageTimings};
use super::vet::Verdicts;
use std::time::Duration;

use crate::decode::{Grasp, Ranked};
use crate::infer::{GraspMaps, ViewBatch};
use crate::segment::{OutsideObstacle, TablePlane};
use crate::sensor::FieldOfView;
use crate::view::OrthoView;

pub(super) struct PreparedObject {
    pub(super) object: DetectedObject,
    pub(super) views: Vec<OrthoView>,
    /// Its points in its own frame, for the hand check.
    pub(super) points: Vec<[f32; 3]>,
}

/// A frame made ready for the network: its views, and what comes after.
pub struct Prepared {
    pub(super) objects: Vec<PreparedObject>,
    pub(super) table: TablePlane,
    /// What stands outside the workspace, and the boxes past the cap.
    pub(super) obstacles: (Vec<OutsideObstacle>, usize),
    /// Where the camera looked (depth images; a cloud has no border).
    pub(super) view: Option<FieldOfView>,
    /// `(object index, view index)` of each batch entry.
    pub(super) inferred: Vec<(usize, usize)>,
    pub(super) batch: ViewBatch,
    /// Each object's views not inferred yet, best entropy first (the cascade's order).
    pub(super) untried: Vec<Vec<usize>>,
    /// Earlier rounds of the cascade: each one's entries and maps.
    pub(super) earlier: Vec<Round>,
    /// The candidate grasps the earlier rounds' views gave, decoded once.
    pub(super) decoded: Vec<Grasp>,
    /// Objects with a grasp that clears the hand check in an earlier round.
    pub(super) covered: Vec<bool>,
    /// The hand check's answers so far, by grasp.
    pub(super) verdicts: Verdicts,
    pub(super) options: PlanOptions,
    pub(super) timings: StageTimings,
}

/// The hand check's and the ranking's answer over the views inferred so far.
pub(super) struct Vetted {
    pub(super) ranked: Ranked<RankedLast>,
    pub(super) turned_square: usize,
    /// What each object's candidates were lost to; the plan's totals are their sums.
    pub(super) per_object: Vec<ObjectRefusals>,
}

/// One round of the cascade: `(object index, view index)` of each batch
/// entry, and the network's maps of that batch.
pub(super) type Round = (Vec<(usize, usize)>, GraspMaps);

impl Prepared {
    /// Every round so far, the earlier ones and this one (`maps`, of the
    /// current batch), in the order they were inferred.
    pub(super) fn rounds_so_far<'a>(
        &'a self,
        maps: &'a GraspMaps,
    ) -> Vec<(&'a [(usize, usize)], &'a GraspMaps)> {
        self.earlier
            .iter()
            .map(|(entries, maps)| (entries.as_slice(), maps))
            .chain([(self.inferred.as_slice(), maps)])
            .collect()
    }
}

/// The views not chosen, by entropy, highest first (ties: the earlier view).
pub(super) fn cascade_order(entropies: &[f64], chosen: &[usize]) -> Vec<usize> {
    let mut rest: Vec<usize> = (0..entropies.len()).filter(|v| !chosen.contains(v)).collect();
    rest.sort_by(|&a, &b| entropies[b].total_cmp(&entropies[a]).then(a.cmp(&b)));
    rest
}

/// What [`Planner::finish_or_cascade`](super::Planner::finish_or_cascade) gives: the plan, or more views to
/// run through the network first (the next round of the cascade).
pub enum Finished {
    /// Every object has a grasp, or no view is left to try.
    Plan(Box<Plan>),
    /// Run `Prepared::batch` through the network and finish again.
    More(Box<Prepared>),
}

impl Prepared {
    /// The views to run through the network, in batch order.
    pub fn batch(&self) -> &ViewBatch {
        &self.batch
    }

    /// Objects found so far.
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// Records how long the network took (for the timings in the plan).
    pub fn set_inference_time(&mut self, elapsed: Duration) {
        self.timings.inference = elapsed;
    }
}
