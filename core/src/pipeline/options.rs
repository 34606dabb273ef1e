//! What a request asks of the planner, and how the planner is configured.

use nalgebra::{Isometry3, Vector3};

use crate::decode::{DecodeConfig, HandConfig};
use crate::error::{Error, Result};
use crate::geometry::Workspace;
use crate::gripper::Gripper;
use crate::segment::{ClusterConfig, TableConfig};
use crate::select::ViewPolicy;
use crate::sensor::SensorInput;
use crate::view::ViewAxis;

/// One sensor frame and where it was taken from.
#[derive(Debug, Clone, Copy)]
pub struct SceneInput<'a> {
    /// The depth image or cloud.
    pub sensor: SensorInput<'a>,
    /// Camera pose in the world (z up).
    pub world_from_camera: Isometry3<f64>,
    /// Only points inside this box are considered.
    pub workspace: Workspace,
}

/// Per-request choices.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// The gripper to plan for.
    pub gripper: Gripper,
    /// At most this many grasps in the answer.
    pub max_grasps: usize,
    /// Grasps under this quality are dropped (tau).
    pub min_quality: f32,
    /// Which views go through the network.
    pub view_policy: ViewPolicy,
    /// Keep the rendered views and their maps in the plan (debugging).
    pub keep_views: bool,
    /// An object whose chosen views give no grasp that clears `min_quality`
    /// and the hand check goes on to its next view by entropy, until one
    /// does or its views run out ([`Planner::finish_or_cascade`](super::Planner::finish_or_cascade)). Off: the
    /// paper's one pass over the policy's views.
    pub view_cascade: bool,
    /// Only grasps approaching within this cone are planned (the robot's
    /// reachable approaches); `None`: any. Views whose direction lies
    /// outside it are not inferred, unless none of an object's views lies
    /// within it (their grasps approach along that direction).
    pub approach_cone: Option<ApproachCone>,
}

/// A cone of approach directions (world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApproachCone {
    /// The cone's axis (unit).
    pub axis: Vector3<f64>,
    /// Half its opening angle (rad), in (0, pi].
    pub half_angle_rad: f64,
}

impl ApproachCone {
    /// A cone around `axis` (any length > 0), checked.
    pub fn new(axis: Vector3<f64>, half_angle_rad: f64) -> Result<Self> {
        let norm = axis.norm();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(Error::invalid(
                "approach_cone.axis",
                format!("must be finite and non-zero, got {axis:?}"),
            ));
        }
        if !(half_angle_rad.is_finite() && half_angle_rad > 0.0 && half_angle_rad <= std::f64::consts::PI) {
            return Err(Error::invalid(
                "approach_cone.half_angle_rad",
                format!("must be in (0, pi], got {half_angle_rad}"),
            ));
        }
        Ok(Self {
            axis: axis / norm,
            half_angle_rad,
        })
    }

    /// True when `approach` (unit) lies within the cone.
    pub fn allows(&self, approach: &Vector3<f64>) -> bool {
        approach.dot(&self.axis) >= self.half_angle_rad.cos() - 1e-12
    }
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            gripper: Gripper::default(),
            max_grasps: 10,
            min_quality: 0.5,
            view_policy: ViewPolicy::Entropy,
            keep_views: false,
            view_cascade: true,
            approach_cone: None,
        }
    }
}

impl PlanOptions {
    /// Checks the gripper and the limits.
    pub fn validate(&self) -> Result<()> {
        self.gripper.validate()?;
        if !(self.min_quality.is_finite() && (0.0..=1.0).contains(&self.min_quality)) {
            return Err(Error::invalid(
                "min_quality",
                format!("must be in [0, 1], got {}", self.min_quality),
            ));
        }
        if self.max_grasps == 0 {
            return Err(Error::invalid("max_grasps", "must be at least 1"));
        }
        Ok(())
    }
}

/// Service-wide settings of the pipeline (not per request).
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerConfig {
    /// Table stage.
    pub table: TableConfig,
    /// Clustering stage.
    pub cluster: ClusterConfig,
    /// Decoding stage.
    pub decode: DecodeConfig,
    /// The hand checked against the observed points before a grasp is kept.
    pub hand: HandConfig,
    /// Views rendered per object.
    pub views: Vec<ViewAxis>,
    /// At most this many grasps per object.
    pub max_grasps_per_object: usize,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        Self {
            table: TableConfig::default(),
            cluster: ClusterConfig::default(),
            decode: DecodeConfig::default(),
            hand: HandConfig::default(),
            views: ViewAxis::ALL.to_vec(),
            max_grasps_per_object: 3,
        }
    }
}
