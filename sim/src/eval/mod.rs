//! Clear-the-table in simulation (DESIGN.md, method step 8; issue 6): the
//! planner in the loop, every grasp tried in rapier3d.
//!
//! An episode: a scene and one camera, both fixed by the seed; the camera is
//! the first of up to [`CAMERA_DRAWS`] random ones whose field of view holds
//! every object's bounding box (else the draw that cuts fewest), as a
//! camera is mounted to see the workspace (the first draw alone left
//! objects out of view or cut by the border). Until the
//! table is clear, three attempts in a row fail, no grasp clears tau, or
//! `2 n + 3` attempts are spent (n objects): render a noisy frame, plan,
//! take the best grasp, and try it:
//!
//! 1. the grasp is matched to a scene object (its detection's centroid
//!    inside that object's box, 1 cm margin); none: *object missed*;
//! 2. the hand is checked for collisions along the approach: at the grasp
//!    and 2.5, 5, 7.5 and 10 cm back along the approach, pre-shaped to the
//!    planned width plus 2 cm (analytic, [`crate::grasp::label_grasp`]);
//!    any hit: *collision on approach*;
//! 3. the rapier3d trial ([`crate::physics::run_trial`]) closes, lifts
//!    15 cm, shakes, carries the object over the obstacles to a basket
//!    beside the table and lets go. In the basket: a success, and the
//!    object leaves the scene. The pads never got a grip: *width too small*
//!    when the object is wider than the stroke where the pads are, else
//!    *object missed*. Lost on the way up, during the carry, or landed
//!    outside the basket: *slip during lift*.
//!
//! After every physics trial the scene is what the trial left: pushed
//! neighbours stay pushed and a dropped object lies where it fell; then
//! everything settles ([`crate::pile::settle`]: what leaned on the taken
//! object falls), and objects that left the table are gone (counted as
//! `fell_off`, not removed). An attempt stopped by the approach check
//! leaves the scene as it was (a real arm's planner would not move there),
//! and so does one that matched no object. Until an object is next taken,
//! the executor takes the best of the planner's ranked grasps that is not
//! one it already tried and failed ([`same_grasp`]), as a robot would,
//! rather than failing the same grasp three times over; a grasp that
//! slipped but moved its object plans elsewhere anyway. Why each rule:
//! docs/experiments/2026-11-24-sim-eval-loop.md.
//!
//! Files: `setting` (what a run asks of the planner), `episode` (what an
//! episode is and records), `source` and `remote` (where grasps come from:
//! in process, or a running service: `remote` only with the `service`
//! feature), `run` (the loop), `judge` (the
//! approach check against physics), `stats` (summaries, the bootstrap),
//! `report` (JSON and tables).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{
    ClusterConfig, CreaseConfig, FieldOfView, Grasp, GraspNet, ModelContract, Plan, PlanOptions, Planner,
    PlannerConfig, Repairs, ViewAxis, ViewPolicy, Workspace,
};
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use parry3d::math::Pose;

use crate::camera::{Camera, Frame, NoiseModel, render};
use crate::error::{Error, Result};
use crate::grasp::{GraspLabel, GripperModel, HandPart, Obstacle, label_grasp, pose_of, weight_torque_nm};
use crate::objects::{Catalog, Family};
use crate::physics::{Basket, TrialConfig, TrialOutcome, run_trial};
use crate::pile::{SettleConfig, settle};
use crate::scene::{Scenario, Scene};

mod episode;
mod judge;
#[cfg(feature = "service")]
mod remote;
mod report;
mod run;
mod setting;
mod source;
mod stats;

pub use episode::*;
pub use judge::*;
#[cfg(feature = "service")]
pub use remote::*;
pub use report::*;
pub use run::*;
pub use setting::*;
pub use source::*;
pub use stats::*;

/// Consecutive failed attempts that end an episode (the paper's rule).
pub const MAX_CONSECUTIVE_FAILURES: usize = 3;

/// Opening beyond the planned width while the hand approaches (m).
const APPROACH_MARGIN_M: f64 = 0.02;

/// Grasps asked of the planner per frame, best first: after the best
/// fails, the executor takes the next (see [`same_grasp`]).
pub const RANKED_GRASPS: usize = 8;

/// Two grasps count as the same within this distance (m) and turn (deg);
/// turned half round about the approach a parallel-jaw grasp is the same.
pub const SAME_GRASP_M: f64 = 0.01;
/// See [`SAME_GRASP_M`].
pub const SAME_GRASP_DEG: f64 = 15.0;

/// Whether `a` and `b` are the same grasp (within [`SAME_GRASP_M`] and
/// [`SAME_GRASP_DEG`], the jaws' half-turn symmetry included).
pub fn same_grasp(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
    let flip = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
    let turn = |b: &nalgebra::UnitQuaternion<f64>| a.rotation.angle_to(b).to_degrees();
    (a.translation.vector - b.translation.vector).norm() < SAME_GRASP_M
        && turn(&b.rotation).min(turn(&(b.rotation * flip))) < SAME_GRASP_DEG
}

/// Approach distances checked for collisions (m back from the grasp).
const APPROACH_CHECKS_M: [f64; 5] = [0.0, 0.025, 0.05, 0.075, 0.10];
