//! Grasps and obstacles for the bridge, from a depth PNG and a camera JSON:
//! planned by a running mvgrasp service over gRPC ([`plan_remotely`]), or
//! in-process with `mvgrasp-core` and its analytic baseline network
//! ([`plan_locally`], no service needed; its grasps come from the baseline,
//! not from a trained model).
//!
//! `camera.json`: `{"width", "height", "intrinsics": {"fx","fy","cx","cy"},
//! "world_from_camera": {"position": [x,y,z], "orientation": [qx,qy,qz,qw]},
//! "workspace": {"min": [..], "max": [..]}}`; `depth.png`: 16-bit grey,
//! millimetres, 0 = no reading. Both are read by `mvgrasp-client`.

use std::{path::Path, time::Duration};

use mvgrasp_client::{PlannerClient, pb};
use mvgrasp_core::{
    ApproachCone, ArmReach, BodyCapsule, DepthEncoding, DepthFrame, GraspNet, Intrinsics, MomentsNet,
    PlanOptions, Planner, PlannerConfig, SceneInput, SensorInput, Workspace, pose_from_parts,
};
use nalgebra::{Isometry3, Point3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::collision::BoxObstacle;
use crate::error::{Error, Result};
use crate::pick::GraspTarget;

/// A depth frame with its camera, read from files.
#[derive(Debug, Clone)]
pub struct SceneFiles {
    /// The frame as the planner service takes it.
    pub request: pb::PlanGraspsRequest,
    /// Little-endian uint16 millimetres, row-major.
    pub depth_le: Vec<u8>,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Camera pose in the world.
    pub world_from_camera: Isometry3<f64>,
    /// Workspace box (world).
    pub workspace: Workspace,
}

fn bad(field: &'static str, reason: impl Into<String>) -> Error {
    Error::InvalidInput {
        field,
        reason: reason.into(),
    }
}

impl SceneFiles {
    /// A frame straight from a camera driver: `depth_mm` row-major (0 = no
    /// reading), the driver's intrinsics, the camera's calibrated pose in the
    /// world, and the workspace box. This is where a live camera plugs in.
    pub fn from_depth_frame(
        width: u32,
        height: u32,
        depth_mm: &[u16],
        intrinsics: Intrinsics,
        world_from_camera: Isometry3<f64>,
        workspace: Workspace,
    ) -> Result<Self> {
        if depth_mm.len() != width as usize * height as usize {
            return Err(bad(
                "depth",
                format!(
                    "{width}x{height} needs {} readings, got {}",
                    width as usize * height as usize,
                    depth_mm.len()
                ),
            ));
        }
        let request = mvgrasp_client::request::depth_request(
            width,
            height,
            depth_mm,
            pb::CameraIntrinsics {
                fx: intrinsics.fx,
                fy: intrinsics.fy,
                cx: intrinsics.cx,
                cy: intrinsics.cy,
            },
            &world_from_camera,
            Some((workspace.min, workspace.max)),
        );
        let depth_le: Vec<u8> = depth_mm.iter().flat_map(|d| d.to_le_bytes()).collect();
        Ok(Self {
            request,
            depth_le,
            width,
            height,
            intrinsics,
            world_from_camera,
            workspace,
        })
    }
}

/// Reads `depth_png` and `camera_json` (the file route to
/// [`SceneFiles::from_depth_frame`]); errors name the file and the field.
pub fn load_scene(depth_png: &Path, camera_json: &Path) -> Result<SceneFiles> {
    let files = mvgrasp_client::scene::SceneFiles::load_depth(depth_png, camera_json)
        .map_err(|e| bad("scene", e.to_string()))?;
    let pb::plan_grasps_request::Sensor::Depth(depth) = &files.sensor else {
        return Err(bad("depth_png", "not a depth image"));
    };
    let k = depth.intrinsics.unwrap_or_default();
    let (p, q) = (
        files.world_from_camera.position.unwrap_or_default(),
        files.world_from_camera.orientation.unwrap_or_default(),
    );
    let world_from_camera = pose_from_parts("world_from_camera", [p.x, p.y, p.z], [q.x, q.y, q.z, q.w])
        .map_err(|e| bad("world_from_camera", e.to_string()))?;
    let ws = files.workspace.ok_or_else(|| {
        bad(
            "workspace",
            format!("{}: `workspace` is needed", camera_json.display()),
        )
    })?;
    let (lo, hi) = (ws.min.unwrap_or_default(), ws.max.unwrap_or_default());
    let workspace = Workspace::new([lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z])
        .map_err(|e| bad("workspace", e.to_string()))?;
    let depth_mm: Vec<u16> = depth
        .data
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let intrinsics = Intrinsics {
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
    };
    SceneFiles::from_depth_frame(
        depth.width,
        depth.height,
        &depth_mm,
        intrinsics,
        world_from_camera,
        workspace,
    )
}

/// Grasps and obstacles of one frame.
#[derive(Debug, Clone)]
pub struct PlannedScene {
    /// Ranked grasps (best first), each pointing at its object.
    pub grasps: Vec<GraspTarget>,
    /// Detected objects as boxes (their visible extent, object frame).
    pub objects: Vec<BoxObstacle>,
    /// The table under them: a 5 cm slab below the fitted plane, as wide as the workspace.
    pub table: BoxObstacle,
    /// What stands on the table around the workspace (within
    /// [`Ask::obstacle_margin_m`]), as the planner boxed it: `obstacle k`,
    /// with the detected object it continues past the workspace's border,
    /// if any. Not grasped; some may be the cell itself
    /// ([`crate::collision::foreign_obstacles`] tells).
    pub outside: Vec<(BoxObstacle, Option<usize>)>,
    /// Which planner produced them (model version and where it ran).
    pub planner: String,
}

/// A detected object as the planner reports it.
pub(crate) struct ObjectBox {
    pub(crate) id: u32,
    pub(crate) world_from_object: Isometry3<f64>,
    pub(crate) extent_min_m: Vector3<f64>,
    pub(crate) extent_max_m: Vector3<f64>,
}

/// Obstacles from detected objects and the table plane `normal . p + offset_m = 0`.
pub(crate) fn obstacles(
    objects: &[ObjectBox],
    normal: Vector3<f64>,
    offset_m: f64,
    ws: &Workspace,
) -> (Vec<BoxObstacle>, BoxObstacle) {
    let boxes = objects
        .iter()
        .map(|o| {
            let centre = o.world_from_object * Point3::from((o.extent_min_m + o.extent_max_m) / 2.0);
            BoxObstacle {
                name: format!("object {}", o.id),
                world_from_box: Isometry3::from_parts(
                    Translation3::from(centre.coords),
                    o.world_from_object.rotation,
                ),
                half_extents_m: (o.extent_max_m - o.extent_min_m) / 2.0,
            }
        })
        .collect();
    let (cx, cy) = ((ws.min.x + ws.max.x) / 2.0, (ws.min.y + ws.max.y) / 2.0);
    let n = normal;
    // The plane's height at the workspace centre, then 2.5 cm down along the normal.
    let surface = Vector3::new(cx, cy, -(offset_m + n.x * cx + n.y * cy) / n.z);
    let rotation = UnitQuaternion::from_rotation_matrix(
        &Rotation3::rotation_between(&Vector3::z(), &n).unwrap_or_else(Rotation3::identity),
    );
    let table = BoxObstacle {
        name: "table".to_owned(),
        world_from_box: Isometry3::from_parts(Translation3::from(surface - 0.025 * n), rotation),
        half_extents_m: Vector3::new(
            (ws.max.x - ws.min.x) / 2.0 + 0.3,
            (ws.max.y - ws.min.y) / 2.0 + 0.3,
            0.025,
        ),
    };
    (boxes, table)
}

/// What the bridge asks of either planner besides the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Ask {
    /// At most this many grasps.
    pub max_grasps: usize,
    /// Only grasps of at least this quality (`planner.min_quality`).
    pub min_quality: f32,
    /// Only approaches within this cone (`planner.approach_cone`).
    pub approach_cone: Option<ApproachCone>,
    /// Only grasps the arm reaches (`planner.arm_reach`).
    pub arm_reach: Option<ArmReach>,
    /// What stands within this of the workspace, sideways and above it, is
    /// asked for as obstacle boxes (`planner.obstacle_margin_m`; 0: not).
    pub obstacle_margin_m: f64,
    /// The robot's body where it stands as the frame is taken
    /// (`PickConfig::robot_body`; `planner.robot_body`): its points are
    /// neither objects nor obstacles. Empty: none.
    pub robot_body: Vec<BodyCapsule>,
}

impl Ask {
    /// `max_grasps` grasps, with no constraint.
    pub fn any(max_grasps: usize) -> Self {
        Self {
            max_grasps,
            min_quality: 0.0,
            approach_cone: None,
            arm_reach: None,
            obstacle_margin_m: 0.0,
            robot_body: Vec::new(),
        }
    }

    /// The obstacle region around `workspace`: grown by
    /// `obstacle_margin_m` in x, y and upwards; `None` at 0.
    pub fn obstacle_region(&self, workspace: &Workspace) -> Option<Workspace> {
        let m = self.obstacle_margin_m;
        (m > 0.0).then(|| Workspace {
            min: Point3::new(workspace.min.x - m, workspace.min.y - m, workspace.min.z),
            max: Point3::new(workspace.max.x + m, workspace.max.y + m, workspace.max.z + m),
        })
    }
}

/// An obstacle box of the planner (world, axis-aligned) as the bridge's
/// box; `None` unless its corners are finite and `min <= max`.
pub(crate) fn outside_box(index: usize, min: Vector3<f64>, max: Vector3<f64>) -> Option<BoxObstacle> {
    if !(min.iter().chain(max.iter()).all(|v| v.is_finite()) && (0..3).all(|i| min[i] <= max[i])) {
        return None;
    }
    Some(BoxObstacle {
        name: format!("obstacle {index}"),
        world_from_box: Isometry3::from_parts(
            Translation3::from((min + max) / 2.0),
            UnitQuaternion::identity(),
        ),
        half_extents_m: (max - min) / 2.0,
    })
}

/// [`outside_box`] from corner arrays, for tests; panics on a bad box.
#[cfg(test)]
pub(crate) fn outside_box_of(index: usize, min: [f64; 3], max: [f64; 3]) -> BoxObstacle {
    outside_box(index, min.into(), max.into()).expect("a box")
}

/// `v` as a message.
fn message(v: &Vector3<f64>) -> pb::Vector3 {
    pb::Vector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// Plans on `scene` with `mvgrasp-core` and the analytic baseline network.
pub fn plan_locally(scene: &SceneFiles, ask: &Ask) -> Result<PlannedScene> {
    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone())
        .map_err(|e| Error::Controller(e.to_string()))?;
    let input = SceneInput {
        sensor: SensorInput::Depth(DepthFrame {
            width: scene.width,
            height: scene.height,
            encoding: DepthEncoding::U16Millimetres,
            data: &scene.depth_le,
            intrinsics: scene.intrinsics,
        }),
        world_from_camera: scene.world_from_camera,
        workspace: scene.workspace,
    };
    let options = PlanOptions {
        max_grasps: ask.max_grasps,
        min_quality: ask.min_quality,
        approach_cone: ask.approach_cone,
        arm_reach: ask.arm_reach,
        obstacle_region: ask.obstacle_region(&scene.workspace),
        robot_body: ask.robot_body.clone(),
        ..PlanOptions::default()
    };
    let plan = planner
        .plan(&input, &options, &mut net)
        .map_err(|e| Error::Controller(format!("planner: {e}")))?;
    let grasps = plan
        .grasps
        .iter()
        .map(|g| GraspTarget {
            world_from_grasp: g.world_from_grasp,
            width_m: g.width_m,
            quality: g.quality,
            object: Some(g.object_id as usize),
        })
        .collect();
    let boxes: Vec<ObjectBox> = plan
        .objects
        .iter()
        .map(|o| ObjectBox {
            id: o.id,
            world_from_object: o.frame.world_from_object,
            extent_min_m: o.frame.extent_min_m,
            extent_max_m: o.frame.extent_max_m,
        })
        .collect();
    let (objects, table) = obstacles(&boxes, plan.table.normal, plan.table.offset_m, &scene.workspace);
    let outside = plan
        .obstacles
        .iter()
        .enumerate()
        // The planner's own boxes: finite, min <= max.
        .filter_map(|(k, o)| Some((outside_box(k, o.min, o.max)?, o.object_id.map(|id| id as usize))))
        .collect();
    Ok(PlannedScene {
        grasps,
        objects,
        table,
        outside,
        planner: format!("in-process {}", net.contract().model_version),
    })
}

fn isometry(p: Option<&pb::Pose>) -> Result<Isometry3<f64>> {
    let p = p.ok_or_else(|| Error::Protocol("the planner sent a grasp without a pose".into()))?;
    let (t, q) = (p.position.unwrap_or_default(), p.orientation.unwrap_or_default());
    let quaternion = Quaternion::new(q.w, q.x, q.y, q.z);
    if !(quaternion.norm() - 1.0).abs().lt(&1e-6) || ![t.x, t.y, t.z].iter().all(|v| v.is_finite()) {
        return Err(Error::Protocol(format!("the planner sent a bad pose: {p:?}")));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(t.x, t.y, t.z),
        UnitQuaternion::from_quaternion(quaternion),
    ))
}

fn vector(v: Option<pb::Vector3>) -> Vector3<f64> {
    let v = v.unwrap_or_default();
    Vector3::new(v.x, v.y, v.z)
}

/// Plans on `scene` with the mvgrasp service at `endpoint` (e.g.
/// `http://127.0.0.1:50051`, or several replicas), with `credentials` if it
/// asks for them, waiting at most `timeout`. A planner that is down or
/// answers an error is an [`Error::Io`] / [`Error::Controller`] naming it;
/// nothing moves.
pub fn plan_remotely(
    endpoint: &str,
    credentials: &mvgrasp_client::Credentials,
    scene: &SceneFiles,
    ask: &Ask,
    timeout: Duration,
) -> Result<PlannedScene> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| Error::Io(format!("async runtime: {e}")))?;
    let request = pb::PlanGraspsRequest {
        max_grasps: ask.max_grasps as u32,
        min_quality: Some(ask.min_quality),
        approach_cone: ask.approach_cone.map(|c| pb::ApproachCone {
            axis: Some(message(&c.axis)),
            half_angle_rad: c.half_angle_rad,
        }),
        arm_reach: ask.arm_reach.map(|r| pb::ArmReach {
            shoulder: Some(message(&r.shoulder)),
            axis: Some(message(&r.axis)),
            wrist_back_m: r.wrist_back_m,
            approach_m: r.approach_m,
            max_m: r.max_m,
            min_axis_m: r.min_axis_m,
        }),
        obstacle_region: ask.obstacle_region(&scene.workspace).map(|w| pb::Workspace {
            min: Some(message(&w.min.coords)),
            max: Some(message(&w.max.coords)),
        }),
        robot_body: ask
            .robot_body
            .iter()
            .map(|c| pb::Capsule {
                a: Some(message(&c.a)),
                b: Some(message(&c.b)),
                radius_m: c.radius_m,
            })
            .collect(),
        ..scene.request.clone()
    };
    let (response, info) = runtime.block_on(async {
        let connect = PlannerClient::connect_with(endpoint, credentials);
        let mut client = tokio::time::timeout(timeout, connect)
            .await
            .map_err(|_| Error::Io(format!("planner at {endpoint}: no connection within {timeout:?}")))?
            .map_err(|e| Error::Io(format!("planner: {e}")))?
            .with_timeout(timeout);
        let response = client
            .plan(request)
            .await
            .map_err(|e| Error::Controller(format!("planner at {endpoint}: {e}")))?;
        let info = client
            .model_info()
            .await
            .map_err(|e| Error::Controller(format!("planner at {endpoint}: {e}")))?;
        Ok::<_, Error>((response, info))
    })?;
    let grasps = response
        .grasps
        .iter()
        .map(|g| {
            Ok(GraspTarget {
                world_from_grasp: isometry(g.pose.as_ref())?,
                width_m: g.width_m,
                quality: g.quality,
                object: Some(g.object_id as usize),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let boxes = response
        .objects
        .iter()
        .map(|o| {
            Ok(ObjectBox {
                id: o.id,
                world_from_object: isometry(o.world_from_object.as_ref())?,
                extent_min_m: vector(o.extent_min_m),
                extent_max_m: vector(o.extent_max_m),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let table = response
        .table
        .ok_or_else(|| Error::Protocol("the planner sent no table plane".into()))?;
    let (objects, table) = obstacles(&boxes, vector(table.normal), table.offset_m, &scene.workspace);
    let outside = response
        .obstacles
        .iter()
        .enumerate()
        .map(|(k, o)| {
            let b = outside_box(k, vector(o.min), vector(o.max))
                .ok_or_else(|| Error::Protocol(format!("the planner sent a bad obstacle box: {o:?}")))?;
            Ok((b, o.object_id.map(|id| id as usize)))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(PlannedScene {
        grasps,
        objects,
        table,
        outside,
        planner: format!("{} ({} at {endpoint})", info.model_version, info.backend),
    })
}
