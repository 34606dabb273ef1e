//! The planner's answer: grasps, objects, refusals by cause, timings.

use std::time::Duration;

use crate::decode::Grasp;
use crate::object::ObjectFrame;
use crate::segment::{OutsideObstacle, TablePlane};
use crate::view::{OrthoView, ViewAxis};

/// Wall time of each stage.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// Frame -> random world points in the workspace (for the table fit).
    pub sensor: Duration,
    /// Table plane fit.
    pub table: Duration,
    /// Block mask, then world points above the table at full resolution
    /// (and the obstacle boxes outside the workspace, when asked for).
    pub sensor_objects: Duration,
    /// Euclidean clustering, then the crease split.
    pub cluster: Duration,
    /// Object frames.
    pub frames: Duration,
    /// View rendering, with each view's entropy.
    pub views: Duration,
    /// View selection and batching (the entropy is summed during `views`).
    pub select: Duration,
    /// The network (as measured by whoever ran it).
    pub inference: Duration,
    /// Peaks -> grasps, ranking.
    pub decode: Duration,
}

impl StageTimings {
    /// Every stage except the network.
    pub fn without_inference(&self) -> Duration {
        self.sensor
            + self.table
            + self.sensor_objects
            + self.cluster
            + self.frames
            + self.views
            + self.select
            + self.decode
    }
}

/// A view's summary for the answer.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// Which view.
    pub axis: ViewAxis,
    /// Its viewpoint entropy (bits).
    pub entropy: f64,
    /// Whether it went through the network.
    pub inferred: bool,
}

/// An object found in the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedObject {
    /// Id, in the fixed cluster order (0-based).
    pub id: u32,
    /// Its gravity-aligned frame and extent.
    pub frame: ObjectFrame,
    /// Its views.
    pub views: Vec<ViewReport>,
    /// Its candidate grasps lost to decoding, the hand check, the approach
    /// cone or the arm's reach, by cause (among those checked: ranking stops
    /// checking once the answer is full). An object without a grasp says why here.
    pub refused: ObjectRefusals,
}

/// One object's candidate grasps lost, by cause.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ObjectRefusals {
    /// The hand would hit the table.
    pub table: usize,
    /// The hand would hit another object's points, or, where the approach
    /// starts, stand inside its box (`HandConfig::pregrasp_boxes`).
    pub neighbour: usize,
    /// The hand would hit the object's own points (no opening re-fit passed).
    pub own_points: usize,
    /// The approach lay outside [`PlanOptions::approach_cone`](super::PlanOptions::approach_cone).
    pub outside_approach_cone: usize,
    /// [`PlanOptions::arm_reach`](super::PlanOptions::arm_reach) did not reach the grasp.
    pub out_of_reach: usize,
    /// The quality peak's predicted opening was wider than the gripper's
    /// stroke (plus [`DecodeConfig::wide_slack_m`](crate::decode::DecodeConfig::wide_slack_m)).
    pub too_wide: usize,
    /// The quality peak gave no pose: no seen surface near it, pads that
    /// cannot clear the table at any insertion, or a width or angle that is
    /// not a number.
    pub no_pose: usize,
}

impl ObjectRefusals {
    /// The causes' names, in the order of [`Self::counts`].
    pub const CAUSES: [&'static str; 7] = [
        "table",
        "neighbour",
        "own_points",
        "outside_approach_cone",
        "out_of_reach",
        "too_wide",
        "no_pose",
    ];

    /// The count of each of [`Self::CAUSES`].
    pub fn counts(&self) -> [usize; 7] {
        [
            self.table,
            self.neighbour,
            self.own_points,
            self.outside_approach_cone,
            self.out_of_reach,
            self.too_wide,
            self.no_pose,
        ]
    }
}

/// A rendered view with its maps, when [`PlanOptions::keep_views`](super::PlanOptions::keep_views) is set.
#[derive(Debug, Clone, PartialEq)]
pub struct DebugView {
    /// The object.
    pub object_id: u32,
    /// The view.
    pub view: OrthoView,
    /// `4 x l x l` maps in the contract's order, if the view was inferred.
    pub maps: Option<Vec<f32>>,
}

/// Grasps the hand check refused, by what the hand would have hit (after
/// the opening re-fit, where one was tried: what the re-fitted hand hit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Refusals {
    /// The table.
    pub table: usize,
    /// The grasp's own object (its opening could not be re-fitted).
    pub own_object: usize,
    /// Another object.
    pub neighbour: usize,
}

/// Why a grasp is ranked after those that passed the hand check as
/// planned, in the order such grasps come.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum RankedLast {
    /// Turned about the approach until the hand passed
    /// ([`HandConfig::neighbour_turns_deg`](crate::decode::HandConfig::neighbour_turns_deg)).
    TurnedAway,
    /// Pads past the image border ([`HandConfig::out_of_view_last`](crate::decode::HandConfig::out_of_view_last)).
    OutOfView,
}

/// The answer for one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Ranked grasps, best first.
    pub grasps: Vec<Grasp>,
    /// Grasps dropped because the hand would hit an observed point or the
    /// table ([`HandConfig`](crate::decode::HandConfig)).
    pub refused_for_collision: usize,
    /// The same by what the hand would have hit.
    pub refusals: Refusals,
    /// Grasps after every grasp that passed the hand check as planned
    /// because they were turned about their approach until the hand passed
    /// a neighbour, or its own object at every opening
    /// ([`HandConfig::neighbour_turns_deg`](crate::decode::HandConfig::neighbour_turns_deg)); they come before the
    /// `ranked_last_out_of_view`.
    pub ranked_after_turned_away: usize,
    /// Grasps at the end of `grasps` because their pads reach past the
    /// image border ([`HandConfig::out_of_view_last`](crate::decode::HandConfig::out_of_view_last)).
    pub ranked_last_out_of_view: usize,
    /// Grasps dropped before ranking because their approach lay outside
    /// [`PlanOptions::approach_cone`](super::PlanOptions::approach_cone).
    pub outside_approach_cone: usize,
    /// Grasps dropped before ranking because
    /// [`PlanOptions::arm_reach`](super::PlanOptions::arm_reach) did not reach them.
    pub out_of_reach: usize,
    /// Grasps turned about their approach axis to square them to the
    /// surfaces their pads meet ([`HandConfig::square_turn_deg`](crate::decode::HandConfig::square_turn_deg)), among
    /// those checked.
    pub turned_square: usize,
    /// Every object found, by id.
    pub objects: Vec<DetectedObject>,
    /// The table the objects stand on.
    pub table: TablePlane,
    /// What stands on the table inside [`PlanOptions::obstacle_region`](super::PlanOptions::obstacle_region)
    /// but outside the workspace, as boxes, most points first (empty
    /// without a region).
    pub obstacles: Vec<OutsideObstacle>,
    /// Obstacle boxes past [`ObstacleConfig::max_obstacles`](crate::segment::ObstacleConfig::max_obstacles), not reported.
    pub obstacles_dropped: usize,
    /// Stage timings.
    pub timings: StageTimings,
    /// Views and maps, when asked for.
    pub debug_views: Vec<DebugView>,
}

/// What stands on the table: [`Planner::segment`](super::Planner::segment)'s answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// The table.
    pub table: TablePlane,
    /// The points above the table (world).
    pub points: Vec<[f32; 3]>,
    /// Each point's pixel (`v * width + u`) for a depth image; empty for a cloud.
    pub pixels: Vec<u32>,
    /// The objects, as indices into `points`, in the fixed order (object ids).
    pub clusters: Vec<Vec<u32>>,
}
