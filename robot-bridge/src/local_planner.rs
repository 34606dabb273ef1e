//! Grasps for the bridge from a depth PNG and a camera JSON, planned
//! in-process with `mvgrasp-core` and its analytic baseline network. This
//! stands in until the gRPC planner client (issue 5) exists; the grasps it
//! gives come from the baseline, not from a trained model.
//!
//! `camera.json`: `{"width", "height", "intrinsics": {"fx","fy","cx","cy"},
//! "world_from_camera": {"position": [x,y,z], "orientation": [qx,qy,qz,qw]},
//! "workspace": {"min": [..], "max": [..]}}`; `depth.png`: 16-bit grey,
//! millimetres, 0 = no reading.

use std::path::Path;

use mvgrasp_core::{
    DepthEncoding, DepthFrame, GraspNet, Intrinsics, MomentsNet, PlanOptions, Planner, PlannerConfig,
    SceneInput, SensorInput, Workspace, pose_from_parts,
};
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;

use crate::collision::BoxObstacle;
use crate::error::{Error, Result};
use crate::pick::GraspTarget;

/// A depth frame with its camera, read from files.
#[derive(Debug, Clone)]
pub struct SceneFiles {
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

/// Reads `depth_png` and `camera_json`; errors name the file and the field.
pub fn load_scene(depth_png: &Path, camera_json: &Path) -> Result<SceneFiles> {
    let text = std::fs::read_to_string(camera_json)
        .map_err(|e| bad("camera_json", format!("{}: {e}", camera_json.display())))?;
    let json: Value = serde_json::from_str(&text)
        .map_err(|e| bad("camera_json", format!("{}: {e}", camera_json.display())))?;
    let number = |path: &[&str], field: &'static str| -> Result<f64> {
        path.iter()
            .try_fold(&json, |v, key| v.get(key))
            .and_then(Value::as_f64)
            .ok_or_else(|| bad(field, "missing or not a number"))
    };
    let array = |path: &[&str], n: usize, field: &'static str| -> Result<Vec<f64>> {
        let values = path
            .iter()
            .try_fold(&json, |v, key| v.get(key))
            .and_then(Value::as_array)
            .ok_or_else(|| bad(field, "missing or not an array"))?;
        let numbers: Vec<f64> = values.iter().filter_map(Value::as_f64).collect();
        if numbers.len() == n {
            Ok(numbers)
        } else {
            Err(bad(field, format!("needs {n} numbers")))
        }
    };
    let intrinsics = Intrinsics {
        fx: number(&["intrinsics", "fx"], "intrinsics.fx")?,
        fy: number(&["intrinsics", "fy"], "intrinsics.fy")?,
        cx: number(&["intrinsics", "cx"], "intrinsics.cx")?,
        cy: number(&["intrinsics", "cy"], "intrinsics.cy")?,
    };
    let position = array(
        &["world_from_camera", "position"],
        3,
        "world_from_camera.position",
    )?;
    let orientation = array(
        &["world_from_camera", "orientation"],
        4,
        "world_from_camera.orientation",
    )?;
    let world_from_camera = pose_from_parts(
        "world_from_camera",
        [position[0], position[1], position[2]],
        [orientation[0], orientation[1], orientation[2], orientation[3]],
    )
    .map_err(|e| bad("world_from_camera", e.to_string()))?;
    let lo = array(&["workspace", "min"], 3, "workspace.min")?;
    let hi = array(&["workspace", "max"], 3, "workspace.max")?;
    let workspace = Workspace::new([lo[0], lo[1], lo[2]], [hi[0], hi[1], hi[2]])
        .map_err(|e| bad("workspace", e.to_string()))?;

    let file = std::fs::File::open(depth_png)
        .map_err(|e| bad("depth_png", format!("{}: {e}", depth_png.display())))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad("depth_png", format!("{}: {e}", depth_png.display())))?;
    let info = reader.info().clone();
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(bad(
            "depth_png",
            format!("{}: must be 16-bit grey (millimetres)", depth_png.display()),
        ));
    }
    let mut buffer = vec![0u8; reader.output_buffer_size().unwrap_or(0)];
    let frame = reader
        .next_frame(&mut buffer)
        .map_err(|e| bad("depth_png", format!("{}: {e}", depth_png.display())))?;
    // PNG stores 16-bit samples big-endian; the pipeline takes little-endian.
    let depth_le: Vec<u8> = buffer[..frame.buffer_size()]
        .chunks_exact(2)
        .flat_map(|b| [b[1], b[0]])
        .collect();
    Ok(SceneFiles {
        depth_le,
        width: info.width,
        height: info.height,
        intrinsics,
        world_from_camera,
        workspace,
    })
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
}

/// Plans on `scene` with `mvgrasp-core` and the analytic baseline network.
pub fn plan_locally(scene: &SceneFiles, max_grasps: usize) -> Result<PlannedScene> {
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
        max_grasps,
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
    let objects = plan
        .objects
        .iter()
        .map(|o| {
            let centre =
                o.frame.world_from_object * Point3::from((o.frame.extent_min_m + o.frame.extent_max_m) / 2.0);
            BoxObstacle {
                name: format!("object {}", o.id),
                world_from_box: Isometry3::from_parts(
                    Translation3::from(centre.coords),
                    o.frame.world_from_object.rotation,
                ),
                half_extents_m: (o.frame.extent_max_m - o.frame.extent_min_m) / 2.0,
            }
        })
        .collect();
    let ws = &scene.workspace;
    let (cx, cy) = ((ws.min.x + ws.max.x) / 2.0, (ws.min.y + ws.max.y) / 2.0);
    let n = plan.table.normal;
    // The plane's height at the workspace centre, then 2.5 cm down along the normal.
    let surface = Vector3::new(cx, cy, -(plan.table.offset_m + n.x * cx + n.y * cy) / n.z);
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
    Ok(PlannedScene {
        grasps,
        objects,
        table,
    })
}
