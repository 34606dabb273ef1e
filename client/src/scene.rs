//! Scene files: a 16-bit depth PNG (millimetres) or a PLY / PCD cloud, plus a
//! camera JSON, turned into a `PlanGraspsRequest`.
//!
//! `camera.json`: `{"width", "height", "intrinsics": {"fx","fy","cx","cy"},
//! "world_from_camera": {"position": [x,y,z], "orientation": [qx,qy,qz,qw]},
//! "workspace": {"min": [x,y,z], "max": [x,y,z]}}` (`intrinsics`, `width`
//! and `height` are not needed for clouds; `workspace` is optional).

use std::path::Path;

use serde_json::Value;

use crate::{Error, Result, cloud, pb};

/// A frame and its camera, ready to send.
#[derive(Debug, Clone)]
pub struct SceneFiles {
    /// The depth image or cloud.
    pub sensor: pb::plan_grasps_request::Sensor,
    /// The camera's pose.
    pub world_from_camera: pb::Pose,
    /// The workspace box, when the JSON gives one.
    pub workspace: Option<pb::Workspace>,
    /// Intrinsics (also for drawing), when the JSON gives them.
    pub intrinsics: Option<pb::CameraIntrinsics>,
}

fn input_error(file: &Path, reason: impl Into<String>) -> Error {
    Error::Input {
        file: file.display().to_string(),
        reason: reason.into(),
    }
}

fn numbers(json: &Value, key_path: &[&str], n: usize, file: &Path) -> Result<Vec<f64>> {
    let name = key_path.join(".");
    let value = key_path
        .iter()
        .try_fold(json, |v, k| v.get(k))
        .ok_or_else(|| input_error(file, format!("`{name}` is missing")))?;
    let list: Vec<f64> = match value {
        Value::Array(items) => items.iter().filter_map(Value::as_f64).collect(),
        other => other.as_f64().into_iter().collect(),
    };
    if list.len() != n {
        return Err(input_error(file, format!("`{name}` needs {n} number(s)")));
    }
    Ok(list)
}

fn vector(v: &[f64]) -> pb::Vector3 {
    pb::Vector3 {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

struct Camera {
    pose: pb::Pose,
    workspace: Option<pb::Workspace>,
    intrinsics: Option<pb::CameraIntrinsics>,
}

fn read_camera(camera_json: &Path) -> Result<Camera> {
    let text = std::fs::read_to_string(camera_json).map_err(|e| input_error(camera_json, e.to_string()))?;
    parse_camera(&text, camera_json)
}

/// Checks a camera JSON's text as [`SceneFiles`] reads it (`name` labels errors).
pub fn check_camera_json(text: &str, name: &Path) -> Result<()> {
    parse_camera(text, name).map(|_| ())
}

fn parse_camera(text: &str, camera_json: &Path) -> Result<Camera> {
    let json: Value = serde_json::from_str(text).map_err(|e| input_error(camera_json, e.to_string()))?;
    let p = numbers(&json, &["world_from_camera", "position"], 3, camera_json)?;
    let q = numbers(&json, &["world_from_camera", "orientation"], 4, camera_json)?;
    let pose = pb::Pose {
        position: Some(vector(&p)),
        orientation: Some(pb::Quaternion {
            x: q[0],
            y: q[1],
            z: q[2],
            w: q[3],
        }),
    };
    let workspace = match json.get("workspace") {
        None => None,
        Some(_) => Some(pb::Workspace {
            min: Some(vector(&numbers(&json, &["workspace", "min"], 3, camera_json)?)),
            max: Some(vector(&numbers(&json, &["workspace", "max"], 3, camera_json)?)),
        }),
    };
    let intrinsics = match json.get("intrinsics") {
        None => None,
        Some(_) => {
            let k = |name| numbers(&json, &["intrinsics", name], 1, camera_json).map(|v| v[0]);
            Some(pb::CameraIntrinsics {
                fx: k("fx")?,
                fy: k("fy")?,
                cx: k("cx")?,
                cy: k("cy")?,
            })
        }
    };
    Ok(Camera {
        pose,
        workspace,
        intrinsics,
    })
}

/// Most pixels of a depth PNG (8192 x 8192; the server takes 4096 x 4096 by default).
pub const MAX_DEPTH_PIXELS: u64 = 8192 * 8192;

/// Reads a 16-bit grey PNG: `(width, height, millimetres)`.
pub fn read_depth_png(path: &Path) -> Result<(u32, u32, Vec<u16>)> {
    let bytes = std::fs::read(path).map_err(|e| input_error(path, e.to_string()))?;
    decode_depth_png(&bytes).map_err(|e| input_error(path, e))
}

/// Decodes a 16-bit grey PNG's bytes: `(width, height, millimetres)`. The
/// decoder's memory limit (64 MiB) bounds what a hostile header can ask for.
pub fn decode_depth_png(bytes: &[u8]) -> Result<(u32, u32, Vec<u16>), String> {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .map_err(|e| e.to_string())?;
    let (width, height, color, depth) = {
        let info = reader.info();
        (info.width, info.height, info.color_type, info.bit_depth)
    };
    if color != png::ColorType::Grayscale || depth != png::BitDepth::Sixteen {
        return Err(format!(
            "a depth PNG must be 16-bit grey (millimetres), this one is {color:?} {depth:?}"
        ));
    }
    // The header alone sets the buffer: bound it before allocating.
    let pixels = u64::from(width) * u64::from(height);
    if pixels > MAX_DEPTH_PIXELS {
        return Err(format!(
            "{width}x{height} pixels: more than the {MAX_DEPTH_PIXELS} a depth image may have"
        ));
    }
    let mut buffer = vec![0u8; reader.output_buffer_size().unwrap_or(0)];
    let frame = reader.next_frame(&mut buffer).map_err(|e| e.to_string())?;
    // PNG stores 16-bit samples big-endian.
    let mm = buffer[..frame.buffer_size()]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    Ok((width, height, mm))
}

impl SceneFiles {
    /// A depth frame: `depth.png` (16-bit, mm) and its `camera.json` (with intrinsics).
    pub fn load_depth(depth_png: &Path, camera_json: &Path) -> Result<Self> {
        let camera = read_camera(camera_json)?;
        let intrinsics = camera
            .intrinsics
            .ok_or_else(|| input_error(camera_json, "`intrinsics` is needed for a depth image"))?;
        let (width, height, mm) = read_depth_png(depth_png)?;
        Ok(Self {
            sensor: pb::plan_grasps_request::Sensor::Depth(pb::DepthImage {
                width,
                height,
                encoding: pb::DepthEncoding::Uint16Mm as i32,
                data: mm.iter().flat_map(|d| d.to_le_bytes()).collect(),
                intrinsics: Some(intrinsics),
            }),
            world_from_camera: camera.pose,
            workspace: camera.workspace,
            intrinsics: Some(intrinsics),
        })
    }

    /// A cloud (`.ply` or `.pcd`, points in `frame`) and its `camera.json`.
    pub fn load_cloud(cloud_file: &Path, frame: pb::CloudFrame, camera_json: &Path) -> Result<Self> {
        let camera = read_camera(camera_json)?;
        let points = cloud::read_points(cloud_file)?;
        Ok(Self {
            sensor: pb::plan_grasps_request::Sensor::Cloud(pb::PointCloud {
                xyz: points.iter().flatten().flat_map(|v| v.to_le_bytes()).collect(),
                frame: frame as i32,
            }),
            world_from_camera: camera.pose,
            workspace: camera.workspace,
            intrinsics: camera.intrinsics,
        })
    }

    /// A request for this frame with the server's defaults for everything else.
    pub fn request(&self) -> pb::PlanGraspsRequest {
        pb::PlanGraspsRequest {
            sensor: Some(self.sensor.clone()),
            world_from_camera: Some(self.world_from_camera),
            workspace: self.workspace,
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by fuzzing (`fuzz/`, target `client_files`): a 238 x 4278190086
    /// header asked for 2 TB before the first pixel was read.
    #[test]
    fn a_huge_png_header_is_an_error_not_an_allocation() {
        let crash: &[u8] = include_bytes!("../../fuzz/regressions/client_files/png-huge-header.png");
        let err = decode_depth_png(crash).unwrap_err();
        assert!(err.contains("more than"), "{err}");
    }

    #[test]
    fn a_small_depth_png_decodes() {
        let seed: &[u8] = include_bytes!("../../fuzz/seeds/client_files/depth.png");
        let (w, h, mm) = decode_depth_png(seed).unwrap();
        assert_eq!((w, h, mm.len()), (8, 6, 48));
        assert_eq!(mm[0], 800);
    }
}
