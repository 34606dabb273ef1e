//! The bridge's configuration file (TOML): the cell calibration, motion
//! limits, the planner and what recovery the bridge may do on its own.
//! `robot-bridge/bridge.toml` lists every key with its default.

use std::path::Path;

use mvgrasp_core::pose_from_parts;
use nalgebra::{Isometry3, Vector3};
use serde::Deserialize;

use crate::collision::BoxObstacle;
use crate::error::{Error, Result};
use crate::pick::PickConfig;

/// A pose as `position` (m) and `orientation` (quaternion x, y, z, w).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseConfig {
    /// x, y, z (m).
    pub position: [f64; 3],
    /// x, y, z, w (unit).
    pub orientation: [f64; 4],
}

impl PoseConfig {
    fn isometry(&self, field: &'static str) -> Result<Isometry3<f64>> {
        pose_from_parts(field, self.position, self.orientation).map_err(|e| Error::InvalidInput {
            field,
            reason: e.to_string(),
        })
    }
}

/// An axis-aligned box in the world (an obstacle of the cell).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxConfig {
    /// Centre, world (m).
    pub centre: [f64; 3],
    /// Half sizes along world x, y, z (m).
    pub half_extents_m: [f64; 3],
}

/// The robot and its calibration.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotSection {
    /// Controller host (RTDE 30004, scripts 30002, dashboard 29999, gripper 63352).
    pub host: String,
    /// Robot base in the world (cell calibration).
    pub world_from_base: PoseConfig,
    /// Gripper TCP relative to the flange (tool calibration).
    pub flange_from_tcp: PoseConfig,
    /// How far the fingertips sit along the approach from the calibrated TCP
    /// at each opening: `[[opening_m, along_m], ...]`, openings ascending
    /// (a linkage gripper's tips travel as it closes; empty: they do not).
    pub fingertip_travel: Vec<[f64; 2]>,
    /// Joint moves: speed (rad/s).
    pub joint_speed: f64,
    /// Joint moves: acceleration (rad/s^2).
    pub joint_accel: f64,
    /// Linear moves: speed (m/s).
    pub tool_speed: f64,
    /// Linear moves: acceleration (m/s^2).
    pub tool_accel: f64,
    /// Timeout of one exchange with the controller (s).
    pub io_timeout_s: f64,
    /// Timeout of one chunk of arm motion (s).
    pub motion_timeout_s: f64,
}

/// The pick itself.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PickSection {
    /// Pre-grasp distance back along the approach (m).
    pub pregrasp_m: f64,
    /// Where no pick works from the pre-grasp, it may move further back in
    /// 5 cm steps by up to this (m; 0: never; `PickConfig::pregrasp_extra_m`).
    pub pregrasp_extra_m: f64,
    /// Where no pick works from the pre-grasp on the nearest arm branch, try
    /// the others (`PickConfig::pregrasp_any_branch`).
    pub pregrasp_any_branch: bool,
    /// Lift after closing (m).
    pub lift_m: f64,
    /// The lift leans towards the base, up to this angle from the vertical
    /// (degrees, 0-60), where straight up is out of reach
    /// (`PickConfig::max_lift_tilt_deg`).
    pub max_lift_tilt_deg: f64,
    /// The fingers open this much wider than the grasp's width for the
    /// approach (m; `PickConfig::approach_clearance_m`).
    pub approach_clearance_m: f64,
    /// TCP pose over the basket where the object is released (world).
    pub world_from_drop: PoseConfig,
    /// The basket, an obstacle for the arm.
    pub basket: BoxConfig,
    /// Before letting go the TCP goes straight down from `world_from_drop`,
    /// stopping where what the hand holds meets something, at the lowest
    /// this high over the basket's floor (the bottom of `basket`; m; 0:
    /// let go at `world_from_drop`; `PickConfig::release_lowest_z_m`;
    /// default 0.15).
    pub release_height_m: f64,
    /// Let go over four spots of the basket in turn rather than over
    /// `world_from_drop` alone: that pose moved this far along the world's
    /// x and y both ways, opposite corners one after the other, so what
    /// the cell puts in the basket spreads over it (m; 0: off; the spots
    /// within the basket; `PickConfig::release_offsets_m`; default 0.05).
    pub release_spread_m: f64,
    /// Grasps asked of the planner (the best feasible one is picked).
    pub max_grasps: usize,
    /// Check the fingers against the other detected objects on the approach
    /// and the lift too (`PickConfig::check_fingers_near_grasp`).
    pub check_fingers_near_grasp: bool,
    /// Check the palm (housing and linkage) against the other detected
    /// objects on the approach and the lift too
    /// (`PickConfig::check_palm_near_grasp`).
    pub check_palm_near_grasp: bool,
    /// A grasp this near (m) a pick that came up empty is tried last
    /// (`PickConfig::failed_radius_m`; 0: never).
    pub failed_radius_m: f64,
    /// See `failed_radius_m` (degrees, 0-90).
    pub failed_angle_deg: f64,
}

/// Where grasps come from.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlannerSection {
    /// The mvgrasp service, e.g. `http://127.0.0.1:50051`; unset: in-process baseline.
    pub endpoint: Option<String>,
    /// Deadline of one planning call (s).
    pub timeout_s: f64,
    /// Only approaches within this cone are asked of the planner (what this
    /// cell's arm can execute); by default from above within 60 degrees,
    /// as the referee judges the cell (`half_angle_deg = 180`: any).
    pub approach_cone: Option<ConeConfig>,
    /// Smallest grasp quality asked of the planner (0: every grasp that
    /// passes its checks, as the referee judges the cell;
    /// docs/experiments/2026-11-30-carried-and-the-bridges-request.md).
    pub min_quality: f32,
    /// Ask the planner only for grasps this arm reaches at the pre-grasp
    /// (`PickConfig::arm_reach`, from the calibration); false: any position.
    pub arm_reach: bool,
    /// Ask the planner for what stands on the table within this of the
    /// workspace (sideways and above it; m) as obstacle boxes, and keep the
    /// arm clear of those that are not the cell itself (0: not asked).
    pub obstacle_margin_m: f64,
    /// Tell the planner where the robot's body stands as the frame is
    /// taken (`PickConfig::robot_body`, the arm at the joints read before
    /// planning), so its points are neither objects nor obstacle boxes.
    pub robot_body: bool,
    /// PEM CA that signed the planner's certificate: call it over TLS.
    pub tls_ca: Option<std::path::PathBuf>,
    /// PEM certificate of this bridge (mutual TLS; with `tls_key`).
    pub tls_cert: Option<std::path::PathBuf>,
    /// PEM private key of `tls_cert`.
    pub tls_key: Option<std::path::PathBuf>,
    /// The name on the planner's certificate, if the endpoint differs.
    pub tls_domain: Option<String>,
    /// File with the bearer token the planner asks for.
    pub token_file: Option<std::path::PathBuf>,
}

/// A cone of approach directions: `axis` (world) and its half-angle.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConeConfig {
    /// Axis x, y, z (world; any length > 0).
    pub axis: [f64; 3],
    /// Half the opening angle (degrees, in (0, 180]).
    pub half_angle_deg: f64,
}

/// Recovery the bridge may do by itself through the dashboard (29999).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RecoverySection {
    /// After a protective stop, unlock it (the pick still ends; nothing moves).
    pub unlock_protective_stop: bool,
    /// Wait before unlocking (s; the controller refuses an unlock within 5 s of the stop).
    pub unlock_after_s: f64,
}

/// The whole file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BridgeConfig {
    /// `[robot]`.
    pub robot: RobotSection,
    /// `[pick]`.
    pub pick: PickSection,
    /// `[planner]`.
    pub planner: PlannerSection,
    /// `[recovery]`.
    pub recovery: RecoverySection,
}

const DOWN: [f64; 4] = [1.0, 0.0, 0.0, 0.0]; // TCP z pointing down (180 deg about x)

impl Default for BridgeConfig {
    fn default() -> Self {
        let pick = PickConfig::default();
        Self {
            robot: RobotSection {
                host: "127.0.0.1".to_owned(),
                world_from_base: PoseConfig {
                    position: [0.0, 0.5, 0.0],
                    orientation: [0.0, 0.0, 0.0, 1.0],
                },
                flange_from_tcp: PoseConfig {
                    position: [0.0, 0.0, 0.233],
                    orientation: [0.0, 0.0, 0.0, 1.0],
                },
                fingertip_travel: pick.fingertip_travel.clone(),
                joint_speed: pick.joint_speed,
                joint_accel: pick.joint_accel,
                tool_speed: pick.tool_speed,
                tool_accel: pick.tool_accel,
                io_timeout_s: 2.0,
                motion_timeout_s: 60.0,
            },
            pick: PickSection {
                pregrasp_m: pick.pregrasp_m,
                pregrasp_extra_m: pick.pregrasp_extra_m,
                pregrasp_any_branch: pick.pregrasp_any_branch,
                lift_m: pick.lift_m,
                max_lift_tilt_deg: pick.max_lift_tilt_deg,
                approach_clearance_m: pick.approach_clearance_m,
                world_from_drop: PoseConfig {
                    position: [0.45, 0.45, 0.3],
                    orientation: DOWN,
                },
                basket: BoxConfig {
                    centre: [0.45, 0.45, 0.05],
                    half_extents_m: [0.15, 0.15, 0.05],
                },
                release_height_m: 0.15,
                release_spread_m: 0.05,
                max_grasps: 10,
                check_fingers_near_grasp: pick.check_fingers_near_grasp,
                check_palm_near_grasp: pick.check_palm_near_grasp,
                failed_radius_m: pick.failed_radius_m,
                failed_angle_deg: pick.failed_angle_deg,
            },
            planner: PlannerSection {
                endpoint: None,
                timeout_s: 5.0,
                approach_cone: Some(ConeConfig {
                    axis: [0.0, 0.0, -1.0],
                    half_angle_deg: 60.0,
                }),
                min_quality: 0.0,
                arm_reach: true,
                obstacle_margin_m: 0.5,
                robot_body: true,
                tls_ca: None,
                tls_cert: None,
                tls_key: None,
                tls_domain: None,
                token_file: None,
            },
            recovery: RecoverySection {
                unlock_protective_stop: false,
                unlock_after_s: 5.0,
            },
        }
    }
}

// Each section's defaults are those of the whole file (so a file may give
// only some keys of a section).
impl Default for RobotSection {
    fn default() -> Self {
        BridgeConfig::default().robot
    }
}

impl Default for PickSection {
    fn default() -> Self {
        BridgeConfig::default().pick
    }
}

impl Default for PlannerSection {
    fn default() -> Self {
        BridgeConfig::default().planner
    }
}

impl Default for RecoverySection {
    fn default() -> Self {
        BridgeConfig::default().recovery
    }
}

fn bad(field: &'static str, reason: String) -> Error {
    Error::InvalidInput { field, reason }
}

impl BridgeConfig {
    /// Reads and validates `path`.
    pub fn load(path: &Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).map_err(|e| bad("config", format!("{}: {e}", path.display())))?;
        let config = Self::from_toml(&text).map_err(|e| bad("config", format!("{}: {e}", path.display())))?;
        Ok(config)
    }

    /// Parses and validates TOML text; unknown keys are errors.
    pub fn from_toml(text: &str) -> Result<Self> {
        let config: Self = toml::from_str(text).map_err(|e| bad("config", e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// Checks every value, naming the key that is off. Speeds are capped well
    /// under the UR5e's limits (pi rad/s, 1 m/s).
    pub fn validate(&self) -> Result<()> {
        let r = &self.robot;
        for (field, value, max) in [
            ("robot.joint_speed", r.joint_speed, std::f64::consts::PI),
            ("robot.joint_accel", r.joint_accel, 10.0),
            ("robot.tool_speed", r.tool_speed, 1.0),
            ("robot.tool_accel", r.tool_accel, 5.0),
            ("robot.io_timeout_s", r.io_timeout_s, 60.0),
            ("robot.motion_timeout_s", r.motion_timeout_s, 600.0),
            ("pick.pregrasp_m", self.pick.pregrasp_m, 0.5),
            ("pick.lift_m", self.pick.lift_m, 0.5),
            ("planner.timeout_s", self.planner.timeout_s, 60.0),
        ] {
            if !(value.is_finite() && value > 0.0 && value <= max) {
                return Err(bad(field, format!("{value} is not in (0, {max}]")));
            }
        }
        self.approach_cone()?;
        for (field, value, max) in [
            ("pick.approach_clearance_m", self.pick.approach_clearance_m, 0.1),
            ("pick.max_lift_tilt_deg", self.pick.max_lift_tilt_deg, 60.0),
            ("pick.pregrasp_extra_m", self.pick.pregrasp_extra_m, 0.5),
            ("pick.failed_radius_m", self.pick.failed_radius_m, 0.1),
            ("pick.failed_angle_deg", self.pick.failed_angle_deg, 90.0),
            ("recovery.unlock_after_s", self.recovery.unlock_after_s, 60.0),
            ("planner.min_quality", f64::from(self.planner.min_quality), 1.0),
            ("planner.obstacle_margin_m", self.planner.obstacle_margin_m, 5.0),
        ] {
            if !(value.is_finite() && (0.0..=max).contains(&value)) {
                return Err(bad(field, format!("{value} is not in [0, {max}]")));
            }
        }
        let b = &self.pick.basket;
        if !(b.centre.iter().all(|v| v.is_finite())
            && b.half_extents_m.iter().all(|&v| v.is_finite() && v > 0.0))
        {
            return Err(bad(
                "pick.basket",
                format!("{b:?}: a finite centre and positive half extents needed"),
            ));
        }
        let h = self.pick.release_height_m;
        let drop_z = self.pick.world_from_drop.position[2];
        if !(h.is_finite() && (h == 0.0 || h > 0.0 && self.basket_floor_z() + h < drop_z)) {
            return Err(bad(
                "pick.release_height_m",
                format!(
                    "{h}: 0 (off) or a height over the basket's floor ({:.3} m) below the drop pose ({drop_z:.3} m)",
                    self.basket_floor_z()
                ),
            ));
        }
        if !(1..=100).contains(&self.pick.max_grasps) {
            return Err(bad(
                "pick.max_grasps",
                format!("{} is not in 1..=100", self.pick.max_grasps),
            ));
        }
        // After the poses are read, so a bad drop pose is named as such.
        self.pick_config()?;
        let s = self.pick.release_spread_m;
        let drop = self.pick.world_from_drop.position;
        let inside = (0..2).all(|i| (drop[i] - b.centre[i]).abs() + s < b.half_extents_m[i]);
        if !(s.is_finite() && s >= 0.0 && (s == 0.0 || inside)) {
            return Err(bad(
                "pick.release_spread_m",
                format!(
                    "{s}: 0 (off) or a distance that keeps the spots around the drop pose within the basket ({:?} +- {:?})",
                    &b.centre[..2],
                    &b.half_extents_m[..2]
                ),
            ));
        }
        Ok(())
    }

    /// The pick settings (calibration and limits) this file describes.
    pub fn pick_config(&self) -> Result<PickConfig> {
        Ok(PickConfig {
            world_from_base: self.robot.world_from_base.isometry("robot.world_from_base")?,
            flange_from_tcp: self.robot.flange_from_tcp.isometry("robot.flange_from_tcp")?,
            fingertip_travel: self.fingertip_travel()?,
            pregrasp_m: self.pick.pregrasp_m,
            pregrasp_extra_m: self.pick.pregrasp_extra_m,
            pregrasp_any_branch: self.pick.pregrasp_any_branch,
            lift_m: self.pick.lift_m,
            max_lift_tilt_deg: self.pick.max_lift_tilt_deg,
            approach_clearance_m: self.pick.approach_clearance_m,
            world_from_drop: self.pick.world_from_drop.isometry("pick.world_from_drop")?,
            release_lowest_z_m: (self.pick.release_height_m > 0.0)
                .then(|| self.basket_floor_z() + self.pick.release_height_m),
            release_offsets_m: match self.pick.release_spread_m {
                0.0 => Vec::new(),
                s => vec![[s, s], [-s, -s], [s, -s], [-s, s]],
            },
            joint_speed: self.robot.joint_speed,
            joint_accel: self.robot.joint_accel,
            tool_speed: self.robot.tool_speed,
            tool_accel: self.robot.tool_accel,
            obstacles: vec![self.basket()],
            check_fingers_near_grasp: self.pick.check_fingers_near_grasp,
            check_palm_near_grasp: self.pick.check_palm_near_grasp,
            failed_radius_m: self.pick.failed_radius_m,
            failed_angle_deg: self.pick.failed_angle_deg,
            ..PickConfig::default()
        })
    }

    /// `robot.fingertip_travel`, checked: finite, openings ascending within
    /// 0-0.3 m, offsets within 0.1 m.
    fn fingertip_travel(&self) -> Result<Vec<[f64; 2]>> {
        let travel = &self.robot.fingertip_travel;
        let sane = travel
            .iter()
            .all(|[w, d]| (0.0..=0.3).contains(w) && d.abs() <= 0.1)
            && travel.windows(2).all(|p| p[0][0] < p[1][0]);
        if !sane {
            return Err(bad(
                "robot.fingertip_travel",
                format!(
                    "{travel:?}: [opening_m, along_m] pairs, openings ascending in 0-0.3 m, |along_m| <= 0.1"
                ),
            ));
        }
        Ok(travel.clone())
    }

    /// `planner.approach_cone` as the planner's cone, checked.
    pub fn approach_cone(&self) -> Result<Option<mvgrasp_core::ApproachCone>> {
        self.planner
            .approach_cone
            .map(|c| {
                mvgrasp_core::ApproachCone::new(Vector3::from(c.axis), c.half_angle_deg.to_radians())
                    .map_err(|e| bad("planner.approach_cone", e.to_string()))
            })
            .transpose()
    }

    /// What to ask of the planner: `pick.max_grasps`, `planner.min_quality`,
    /// `planner.approach_cone`, with `planner.arm_reach` where `arm`
    /// reaches, and with `planner.robot_body` its body at `current`.
    pub fn ask(&self, arm: &crate::ur5e::Ur5e, current: &crate::ur5e::Joints) -> Result<crate::planner::Ask> {
        Ok(crate::planner::Ask {
            max_grasps: self.pick.max_grasps,
            min_quality: self.planner.min_quality,
            approach_cone: self.approach_cone()?,
            arm_reach: match self.planner.arm_reach {
                true => Some(self.pick_config()?.arm_reach(arm)?),
                false => None,
            },
            obstacle_margin_m: self.planner.obstacle_margin_m,
            robot_body: match self.planner.robot_body {
                true => self.pick_config()?.robot_body(arm, current),
                false => Vec::new(),
            },
        })
    }

    /// What the planner asks for: `planner.tls_*` and `planner.token_file`, read.
    pub fn planner_credentials(&self) -> Result<mvgrasp_client::Credentials> {
        let p = &self.planner;
        let identity = match (&p.tls_cert, &p.tls_key) {
            (Some(cert), Some(key)) => Some((cert.as_path(), key.as_path())),
            (None, None) => None,
            _ => return Err(bad("planner.tls_cert", "tls_cert and tls_key go together".into())),
        };
        mvgrasp_client::Credentials::from_files(
            p.tls_ca.as_deref(),
            identity,
            p.tls_domain.clone(),
            p.token_file.as_deref(),
        )
        .map_err(|e| bad("planner", e.to_string()))
    }

    /// The basket's floor: the bottom of its box (world z, m).
    fn basket_floor_z(&self) -> f64 {
        self.pick.basket.centre[2] - self.pick.basket.half_extents_m[2]
    }

    /// The basket as an obstacle.
    pub fn basket(&self) -> BoxObstacle {
        let b = &self.pick.basket;
        BoxObstacle {
            name: "basket".to_owned(),
            world_from_box: Isometry3::translation(b.centre[0], b.centre[1], b.centre[2]),
            half_extents_m: Vector3::from(b.half_extents_m),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_file_states_the_defaults() {
        let documented = BridgeConfig::from_toml(include_str!("../bridge.toml")).unwrap();
        assert_eq!(documented, BridgeConfig::default());
        let pick = documented.pick_config().unwrap();
        assert_eq!(pick.flange_from_tcp, PickConfig::default().flange_from_tcp);
    }

    #[test]
    fn bad_values_name_their_key() {
        for (text, key) in [
            ("[robot]\njoint_speed = 9.0\n", "robot.joint_speed"),
            ("[robot]\nhots = \"x\"\n", "hots"),
            (
                "[pick]\nworld_from_drop = { position = [0, 0, 0.3], orientation = [0, 0, 0, 2] }\n",
                "pick.world_from_drop",
            ),
            ("[recovery]\nunlock_after_s = -1.0\n", "recovery.unlock_after_s"),
            ("[recovery]\nunlock_after_s = nan\n", "recovery.unlock_after_s"),
            ("[pick]\nmax_lift_tilt_deg = 75.0\n", "pick.max_lift_tilt_deg"),
            ("[pick]\npregrasp_extra_m = 0.6\n", "pick.pregrasp_extra_m"),
            ("[pick]\npregrasp_extra_m = -0.05\n", "pick.pregrasp_extra_m"),
            ("[pick]\nfailed_radius_m = -0.01\n", "pick.failed_radius_m"),
            ("[pick]\nrelease_height_m = 0.3\n", "pick.release_height_m"),
            ("[pick]\nrelease_height_m = -0.1\n", "pick.release_height_m"),
            ("[pick]\nrelease_spread_m = 0.15\n", "pick.release_spread_m"),
            ("[pick]\nrelease_spread_m = -0.05\n", "pick.release_spread_m"),
            ("[pick]\nrelease_spread_m = nan\n", "pick.release_spread_m"),
            ("[pick]\nfailed_angle_deg = 120.0\n", "pick.failed_angle_deg"),
            (
                "[pick]\napproach_clearance_m = -0.01\n",
                "pick.approach_clearance_m",
            ),
            (
                "[planner]\napproach_cone = { axis = [0.0, 0.0, 0.0], half_angle_deg = 60.0 }\n",
                "planner.approach_cone",
            ),
            (
                "[planner]\napproach_cone = { axis = [0.0, 0.0, -1.0], half_angle_deg = 0.0 }\n",
                "planner.approach_cone",
            ),
            ("[planner]\nmin_quality = 1.5\n", "planner.min_quality"),
            ("[planner]\nmin_quality = nan\n", "planner.min_quality"),
            (
                "[robot]\nfingertip_travel = [[0.1, 0.0], [0.05, 0.01]]\n",
                "robot.fingertip_travel",
            ),
            (
                "[robot]\nfingertip_travel = [[0.1, 0.5]]\n",
                "robot.fingertip_travel",
            ),
        ] {
            let err = BridgeConfig::from_toml(text).unwrap_err().to_string();
            assert!(err.contains(key), "{key}: {err}");
        }
    }

    #[test]
    fn the_approach_cone_is_read_in_degrees() {
        let config = BridgeConfig::from_toml(
            "[planner]\napproach_cone = { axis = [0.0, 0.0, -2.0], half_angle_deg = 60.0 }\n",
        )
        .unwrap();
        let cone = config.approach_cone().unwrap().unwrap();
        assert!((cone.axis - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        assert!((cone.half_angle_rad - 60f64.to_radians()).abs() < 1e-12);
        let default = BridgeConfig::default()
            .approach_cone()
            .unwrap()
            .expect("from above by default");
        assert!((default.axis - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        assert!((default.half_angle_rad - 60f64.to_radians()).abs() < 1e-12);
        let any = BridgeConfig::from_toml(
            "[planner]\napproach_cone = { axis = [0.0, 0.0, -1.0], half_angle_deg = 180.0 }\n",
        )
        .unwrap();
        let any = any.approach_cone().unwrap().unwrap();
        assert!(
            any.allows(&Vector3::new(0.0, 0.0, 1.0)),
            "180 degrees: any approach"
        );
    }

    #[test]
    fn the_min_quality_asked_is_every_grasp_unless_set() {
        let arm = crate::ur5e::Ur5e::default();
        assert_eq!(
            BridgeConfig::default()
                .ask(&arm, &crate::ur5e::HOME)
                .unwrap()
                .min_quality,
            0.0
        );
        let set = BridgeConfig::from_toml("[planner]\nmin_quality = 0.5\n").unwrap();
        assert_eq!(set.ask(&arm, &crate::ur5e::HOME).unwrap().min_quality, 0.5);
    }

    #[test]
    fn the_arm_reach_is_asked_unless_turned_off() {
        let arm = crate::ur5e::Ur5e::default();
        let on = BridgeConfig::default().ask(&arm, &crate::ur5e::HOME).unwrap();
        let reach = on.arm_reach.expect("on by default");
        // The documented cell: the base at (0, 0.5, 0), the shoulder over it.
        assert!((reach.shoulder - Vector3::new(0.0, 0.5, 0.1625)).norm() < 1e-12);
        assert_eq!(reach.approach_m, BridgeConfig::default().pick.pregrasp_m);
        let off = BridgeConfig::from_toml("[planner]\narm_reach = false\n").unwrap();
        assert_eq!(off.ask(&arm, &crate::ur5e::HOME).unwrap().arm_reach, None);
    }
}
