//! # mvgrasp-core
//!
//! The MVGrasp method (Kasaei & Kasaei, RAS 2023), pure and synchronous: a
//! depth frame or point cloud and the camera pose in, ranked 6-DoF
//! parallel-jaw grasps out. No I/O, no async, no wire types: the server, the
//! simulator and the tests all run this one copy.
//!
//! ```text
//! sensor -> world points (cropped) -> table plane removed -> clusters
//!        -> object frames -> orthographic views -> entropy / policy
//!        -> [GraspNet: batch of views -> quality, cos2phi, sin2phi, width]
//!        -> peaks -> 6-DoF grasps -> ranked
//! ```
//!
//! ```
//! use mvgrasp_core::{
//!     DepthEncoding, DepthFrame, GraspNet, Intrinsics, MomentsNet, PlanOptions, Planner,
//!     PlannerConfig, SceneInput, SensorInput, Workspace, pose_from_parts,
//! };
//!
//! // A 64x48 frame of a flat table 0.7 m below a camera looking straight down.
//! let (w, h) = (64u32, 48u32);
//! let data: Vec<u8> = (0..w * h).flat_map(|_| 700u16.to_le_bytes()).collect();
//! let frame = DepthFrame {
//!     width: w,
//!     height: h,
//!     encoding: DepthEncoding::U16Millimetres,
//!     data: &data,
//!     intrinsics: Intrinsics { fx: 60.0, fy: 60.0, cx: 32.0, cy: 24.0 },
//! };
//! // Camera at 0.7 m, optical axis (+z) pointing down: a half turn about x.
//! let world_from_camera = pose_from_parts("world_from_camera", [0.0, 0.0, 0.7], [1.0, 0.0, 0.0, 0.0])?;
//! let scene = SceneInput {
//!     sensor: SensorInput::Depth(frame),
//!     world_from_camera,
//!     workspace: Workspace::new([-1.0, -1.0, -0.1], [1.0, 1.0, 0.5])?,
//! };
//! let mut net = MomentsNet::default();
//! let planner = Planner::new(PlannerConfig::default(), net.contract().clone())?;
//! let plan = planner.plan(&scene, &PlanOptions::default(), &mut net)?;
//! assert!(plan.objects.is_empty() && plan.grasps.is_empty()); // an empty table
//! # Ok::<(), mvgrasp_core::Error>(())
//! ```

pub mod decode;
mod error;
mod geometry;
mod gripper;
pub mod infer;
pub mod object;
mod pipeline;
pub mod rng;
pub mod segment;
pub mod select;
pub mod sensor;
pub mod view;

pub use decode::{DecodeConfig, Grasp, Repairs};
pub use error::{Error, Result};
pub use geometry::{QUATERNION_NORM_TOLERANCE, Workspace, camera_looking_at, pose_from_parts, world_up};
pub use gripper::Gripper;
pub use infer::{Channel, GraspMaps, GraspNet, ModelContract, MomentsNet, ViewBatch};
pub use object::ObjectFrame;
pub use pipeline::{
    ApproachCone, ArmReach, DebugView, DetectedObject, Finished, ObjectRefusals, Plan, PlanOptions, Planner,
    PlannerConfig, Prepared, Refusals, SceneInput, Segmentation, StageTimings, ViewReport, approach_of,
};
pub use segment::{
    BodyCapsule, ClusterConfig, CreaseConfig, ObstacleConfig, OutsideObstacle, Reattach, TableConfig,
    TablePlane,
};
pub use select::ViewPolicy;
pub use sensor::{CloudFrame, DepthEncoding, DepthFrame, FieldOfView, Intrinsics, PointCloud, SensorInput};
pub use view::{OBLIQUE_TILT_DEG, OrthoView, ViewAxis};
