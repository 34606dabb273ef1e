//! The hand as the planner checks it: boxes in the grasp frame (DESIGN.md:
//! +z the approach, +x the closing direction, origin midway between the
//! fingertips), the Robotiq 2F-140 as the robot-bridge models it
//! (`robot-bridge/src/collision.rs`, `HandModel`):
//!
//! - two fingers, `pad_thickness_m` thick along x and the gripper's finger
//!   width along y, their inner faces half the opening from the origin,
//!   from the fingertips back `finger_length_m` (at least the pads' depth);
//!   the opening is the grasp's width plus `opening_clearance_m`, as the
//!   executor opens before closing;
//! - the palm behind them (the linkage and the housing), `palm_depth_m`
//!   along z, `palm_width_m` along y, spanning both fingers along x and at
//!   least `palm_min_span_m`;
//! - the gap between the fingers, where only the grasp's own object may be.
//!
//! [`HandConfig`] holds the shape and how strictly it is checked
//! (`collision`) and repaired (`repair`).

use nalgebra::Vector3;

use crate::gripper::Gripper;

/// The hand's shape beyond the pads' contact faces, and how strictly to check.
#[derive(Debug, Clone, PartialEq)]
pub struct HandConfig {
    /// Check the hand at all (off: every grasp passes).
    pub enabled: bool,
    /// Pad thickness along the closing direction (m).
    pub pad_thickness_m: f64,
    /// How much wider than the grasp's width the pads open before closing
    /// (m, within the stroke): the executor's margin (`sim`'s
    /// `GripperModel::clearance_m`). The hand is checked at that opening.
    pub opening_clearance_m: f64,
    /// From the fingertips back to the palm, the first part of the hand
    /// that spans the gap between the fingers (m; at least the gripper's
    /// pad depth): the fingers, and the gap only the grasp's own object may
    /// be in, reach this far.
    pub finger_length_m: f64,
    /// Gripper body behind the fingers: depth along the approach (m).
    pub palm_depth_m: f64,
    /// Gripper body extent across the closing direction (m).
    pub palm_width_m: f64,
    /// Gripper body extent along the closing direction, at least (m; it
    /// spans the fingers at any opening).
    pub palm_min_span_m: f64,
    /// How far back along the approach the hand is swept (m).
    pub approach_m: f64,
    /// Extra opening while approaching (m), within the stroke.
    pub preshape_margin_m: f64,
    /// Observed points inside the hand that make a collision.
    pub min_points: usize,
    /// Below this height above the table a box corner is a collision (m;
    /// negative: that far into the table).
    pub table_margin_m: f64,
    /// Re-fit a refused grasp's opening to its object's points
    /// ([`fit_opening`](super::fit_opening)) and check it again.
    pub fit_opening: bool,
    /// Air between each pad and the object's points after a re-fit (m).
    pub fit_clearance_m: f64,
    /// Rank a grasp whose pads, where the hand ends, reach outside the
    /// camera's field of view after every grasp that stays inside (depth
    /// images only: [`hand_out_of_view`](super::hand_out_of_view)).
    pub out_of_view_last: bool,
    /// Turn a grasp about its approach axis, up to this far (degrees), to
    /// square it to the surfaces its pads would meet as seen
    /// ([`squaring_turn`](super::squaring_turn)), when the turned grasp passes the check; 0: never.
    pub square_turn_deg: f64,
    /// How deep a slab of the object's points, from the point nearest each
    /// pad, stands for the surface the pad meets (m).
    pub patch_slab_m: f64,
    /// Turns about the approach axis (degrees, tried in order) for a grasp
    /// the check refused for a neighbour or its own object ([`turn_away`](super::turn_away));
    /// empty: none.
    pub neighbour_turns_deg: Vec<f64>,
    /// Push a grasp that passes the check this much further along its
    /// approach, or half as far, where the hand still passes and the pads
    /// stay clear of the table ([`deepen`](super::deepen); m, 0: never): pads that reach
    /// lower on a tall, round object hold it below its widest section.
    pub deepen_m: f64,
    /// Push a grasp that passes the check and whose fingertips stop above
    /// the middle of its object's height (between its highest point
    /// between the pads and the table) towards that middle, at most this
    /// far, or half as far, where the hand still passes and the pads stay
    /// clear of the table ([`deepen_to_middle`](super::deepen_to_middle);
    /// m, 0: never). Tried before [`deepen`](super::deepen).
    pub deepen_to_middle_m: f64,
    /// Check the hand where the approach starts (`approach_m` back,
    /// pre-shaped) against every other object's box (its seen extent in
    /// its own frame, as the robot-bridge takes it), each hand box grown by
    /// `pregrasp_box_margin_m`: the bridge refuses a grasp whose hand there
    /// is inside a taller neighbour's box, though the points there are
    /// free ([`hand_collision`](super::hand_collision)).
    pub pregrasp_boxes: bool,
    /// How much each hand box grows for that check (m; the bridge's
    /// `ArmModel::margin_m`).
    pub pregrasp_box_margin_m: f64,
}

impl Default for HandConfig {
    /// The Robotiq 2F-140; a 10 cm approach. The fingers and the palm are
    /// the robot-bridge's `HandModel` (the referee's collision meshes,
    /// bounded over the stroke): the linkage, which spans the gap at least
    /// 14 cm wide, begins 72 mm behind the fingertips when fully open
    /// (97 mm at a 6 cm opening); the palm (linkage, then housing) reaches
    /// 136 mm further back, to the flange when fully open.
    fn default() -> Self {
        Self {
            enabled: true,
            pad_thickness_m: 0.01,
            opening_clearance_m: 0.02,
            finger_length_m: 0.072,
            palm_depth_m: 0.136,
            palm_width_m: 0.075,
            palm_min_span_m: 0.14,
            approach_m: 0.10,
            preshape_margin_m: 0.02,
            min_points: 3,
            table_margin_m: -0.002,
            fit_opening: true,
            fit_clearance_m: 0.005,
            out_of_view_last: true,
            square_turn_deg: 15.0,
            patch_slab_m: 0.006,
            // Smallest turns first, either way, up to a quarter turn.
            neighbour_turns_deg: vec![20.0, -20.0, 45.0, -45.0, 70.0, -70.0, 90.0],
            // sim/README.md: of top-down grasps stopping above the middle of
            // their object's height 0.87 held, reaching below it 0.96.
            deepen_m: 0.005,
            // Chosen on the referee's train pools
            // (docs/experiments/2026-12-02-towards-the-middle.md).
            deepen_to_middle_m: 0.04,
            pregrasp_boxes: true,
            pregrasp_box_margin_m: 0.01,
        }
    }
}

/// An axis-aligned box in the grasp frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct GraspBox {
    pub(super) lo: Vector3<f64>,
    pub(super) hi: Vector3<f64>,
}

impl GraspBox {
    pub(super) fn corners(&self) -> impl Iterator<Item = Vector3<f64>> + '_ {
        (0..8).map(move |i| {
            Vector3::new(
                if i & 1 == 0 { self.lo.x } else { self.hi.x },
                if i & 2 == 0 { self.lo.y } else { self.hi.y },
                if i & 4 == 0 { self.lo.z } else { self.hi.z },
            )
        })
    }
}

/// `width_m` opened `by` more, within the stroke (never narrower).
pub(super) fn widen(width_m: f64, by: f64, gripper: &Gripper) -> f64 {
    (width_m + by).min(gripper.max_width_m).max(width_m)
}

/// How far back from the fingertips the fingers reach before the palm (m).
pub(super) fn finger_reach(gripper: &Gripper, hand: &HandConfig) -> f64 {
    hand.finger_length_m.max(gripper.finger_depth_m)
}

/// The hand's boxes for an opening `width_m`, the fingertips at `tip_z`,
/// the fingers `reach` long and swept back to `tip_z - sweep` (grasp
/// frame): the two fingers, then the palm.
pub(super) fn hand_boxes(
    width_m: f64,
    tip_z: f64,
    sweep: f64,
    reach: f64,
    gripper: &Gripper,
    hand: &HandConfig,
) -> [GraspBox; 3] {
    let (half_w, t) = (width_m / 2.0, hand.pad_thickness_m);
    let half_pad_y = gripper.finger_width_m / 2.0;
    let pad_lo_z = tip_z - reach - sweep;
    let pad = |sign: f64| {
        let (a, b) = (sign * half_w, sign * (half_w + t));
        GraspBox {
            lo: Vector3::new(a.min(b), -half_pad_y, pad_lo_z),
            hi: Vector3::new(a.max(b), half_pad_y, tip_z),
        }
    };
    let palm_hi_z = tip_z - reach;
    let half_span = (half_w + t).max(hand.palm_min_span_m / 2.0);
    let palm = GraspBox {
        lo: Vector3::new(
            -half_span,
            -hand.palm_width_m / 2.0,
            palm_hi_z - hand.palm_depth_m - sweep,
        ),
        hi: Vector3::new(half_span, hand.palm_width_m / 2.0, palm_hi_z),
    };
    [pad(-1.0), pad(1.0), palm]
}

/// The space between the fingers for an opening `width_m`, the fingertips
/// at `tip_z`, `reach` back from them and swept back to `tip_z - sweep`
/// (grasp frame).
pub(super) fn gap_box(width_m: f64, tip_z: f64, sweep: f64, reach: f64, gripper: &Gripper) -> GraspBox {
    let (half_w, half_pad_y) = (width_m / 2.0, gripper.finger_width_m / 2.0);
    GraspBox {
        lo: Vector3::new(-half_w, -half_pad_y, tip_z - reach - sweep),
        hi: Vector3::new(half_w, half_pad_y, tip_z),
    }
}
