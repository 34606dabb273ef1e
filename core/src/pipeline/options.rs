//! What a request asks of the planner, and how the planner is configured.

use nalgebra::{Isometry3, Vector3};

use crate::decode::{DecodeConfig, HandConfig};
use crate::error::{Error, Result};
use crate::geometry::Workspace;
use crate::gripper::Gripper;
use crate::segment::{BodyCapsule, ClusterConfig, ObstacleConfig, TableConfig, check_body};
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
    /// Only grasps this arm reaches are planned; `None`: any position. An
    /// object whose views give none goes on to its next view under the
    /// cascade.
    pub arm_reach: Option<ArmReach>,
    /// What stands on the table inside this box but outside the scene's
    /// workspace is reported as obstacle boxes ([`Plan::obstacles`](super::Plan::obstacles)), not
    /// planned; `None`: nothing outside the workspace is looked at.
    pub obstacle_region: Option<Workspace>,
    /// The robot's own body where it stands as the frame was taken (world
    /// frame): the points within these capsules are left out of the
    /// objects and of the obstacle boxes. Empty: none.
    pub robot_body: Vec<BodyCapsule>,
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

/// Where an arm reaches, as its wrist sees it (world frame): a grasp is
/// reached when its wrist points, from `wrist_back_m` behind the grasp's
/// origin along its approach to `approach_m` further back (the wrist at the
/// pre-grasp), lie within `max_m` of the shoulder, and the straight line
/// between them keeps `min_axis_m` from the base axis through the shoulder.
/// A necessary condition for a 6-axis arm's inverse kinematics along the
/// approach, not a sufficient one: the robot's own check stays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmReach {
    /// The shoulder joint's centre.
    pub shoulder: Vector3<f64>,
    /// The base axis through the shoulder (unit).
    pub axis: Vector3<f64>,
    /// From the grasp's origin back along its approach to the wrist point (m).
    pub wrist_back_m: f64,
    /// The straight approach: how much further back the wrist starts (m).
    pub approach_m: f64,
    /// Farthest a wrist point may lie from the shoulder (m).
    pub max_m: f64,
    /// Nearest the wrist may come to the base axis (m).
    pub min_axis_m: f64,
}

impl ArmReach {
    /// An arm's reach, checked: finite, `axis` non-zero (normalised),
    /// `wrist_back_m` and `approach_m` >= 0, `0 <= min_axis_m < max_m`.
    pub fn new(
        shoulder: Vector3<f64>,
        axis: Vector3<f64>,
        wrist_back_m: f64,
        approach_m: f64,
        max_m: f64,
        min_axis_m: f64,
    ) -> Result<Self> {
        if !shoulder.iter().all(|v| v.is_finite()) {
            return Err(Error::invalid(
                "arm_reach.shoulder",
                format!("must be finite, got {shoulder:?}"),
            ));
        }
        let norm = axis.norm();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(Error::invalid(
                "arm_reach.axis",
                format!("must be finite and non-zero, got {axis:?}"),
            ));
        }
        for (field, value) in [
            ("arm_reach.wrist_back_m", wrist_back_m),
            ("arm_reach.approach_m", approach_m),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(Error::invalid(
                    field,
                    format!("must be finite and >= 0, got {value}"),
                ));
            }
        }
        if !(max_m.is_finite() && max_m > 0.0) {
            return Err(Error::invalid(
                "arm_reach.max_m",
                format!("must be finite and > 0, got {max_m}"),
            ));
        }
        if !(min_axis_m.is_finite() && min_axis_m >= 0.0 && min_axis_m < max_m) {
            return Err(Error::invalid(
                "arm_reach.min_axis_m",
                format!("must be in [0, max_m = {max_m}), got {min_axis_m}"),
            ));
        }
        Ok(Self {
            shoulder,
            axis: axis / norm,
            wrist_back_m,
            approach_m,
            max_m,
            min_axis_m,
        })
    }

    /// True when the arm reaches a grasp at `origin` approaching along
    /// `approach` (unit).
    pub fn reaches(&self, origin: &Vector3<f64>, approach: &Vector3<f64>) -> bool {
        let at_grasp = origin - self.wrist_back_m * approach - self.shoulder;
        let at_start = at_grasp - self.approach_m * approach;
        if at_grasp.norm() > self.max_m || at_start.norm() > self.max_m {
            return false;
        }
        // Nearest the segment between them comes to the axis: across it.
        let across = |v: Vector3<f64>| v - v.dot(&self.axis) * self.axis;
        let (a, b) = (across(at_grasp), across(at_start));
        let run = b - a;
        let t = if run.norm_squared() > 1e-18 {
            (-a.dot(&run) / run.norm_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a + t * run).norm() >= self.min_axis_m
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
            arm_reach: None,
            obstacle_region: None,
            robot_body: Vec::new(),
        }
    }
}

impl PlanOptions {
    /// Checks the gripper, the robot's body and the limits.
    pub fn validate(&self) -> Result<()> {
        self.gripper.validate()?;
        check_body(&self.robot_body)?;
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
    /// The obstacle boxes of [`PlanOptions::obstacle_region`].
    pub obstacles: ObstacleConfig,
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
            obstacles: ObstacleConfig::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wrist's distance from the shoulder at both ends of the approach,
    /// and the straight line between them passing the base axis.
    #[test]
    fn an_arm_reaches_within_its_sphere_and_outside_its_axis() {
        let reach = ArmReach::new(
            Vector3::new(0.0, 0.0, 0.2),
            Vector3::new(0.0, 0.0, 3.0),
            0.3,
            0.1,
            0.9,
            0.13,
        )
        .unwrap();
        assert_eq!(reach.axis, Vector3::z());
        let down = -Vector3::z();
        // From above, 0.5 m out: wrist 0.3-0.4 m over the grasp.
        assert!(reach.reaches(&Vector3::new(0.5, 0.0, 0.0), &down));
        // 0.9 m out the wrist lies beyond 0.9 m.
        assert!(!reach.reaches(&Vector3::new(0.9, 0.0, 0.0), &down));
        // Sideways towards the base: the wrist at the pre-grasp is 0.4 m
        // further out than the grasp, which alone would be in reach.
        let towards_base = -Vector3::x();
        assert!(!reach.reaches(&Vector3::new(0.55, 0.0, 0.2), &towards_base));
        assert!(reach.reaches(&Vector3::new(0.55, 0.0, 0.2), &-towards_base));
        // A straight approach whose wrist would cross the base axis between
        // the pre-grasp and the grasp, both ends clear of it.
        let across = ArmReach::new(Vector3::zeros(), Vector3::z(), 0.0, 0.4, 0.9, 0.13).unwrap();
        assert!(!across.reaches(&Vector3::new(0.0, -0.2, 0.0), &-Vector3::y()));
        assert!(across.reaches(&Vector3::new(0.2, -0.2, 0.0), &-Vector3::y()));
        for bad in [
            ArmReach::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::z(), 0.3, 0.1, 0.9, 0.1),
            ArmReach::new(Vector3::zeros(), Vector3::zeros(), 0.3, 0.1, 0.9, 0.1),
            ArmReach::new(Vector3::zeros(), Vector3::z(), -0.1, 0.1, 0.9, 0.1),
            ArmReach::new(Vector3::zeros(), Vector3::z(), 0.3, f64::INFINITY, 0.9, 0.1),
            ArmReach::new(Vector3::zeros(), Vector3::z(), 0.3, 0.1, 0.0, 0.0),
            ArmReach::new(Vector3::zeros(), Vector3::z(), 0.3, 0.1, 0.9, 0.9),
        ] {
            assert!(bad.is_err(), "{bad:?}");
        }
    }
}
