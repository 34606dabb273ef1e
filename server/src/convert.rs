//! Conversions between `mvgrasp.v1` messages and `mvgrasp-core` types: the
//! edge where every field is validated and named in errors.

use mvgrasp_core::{
    ApproachCone, ArmReach, BodyCapsule, Channel, CloudFrame, DebugView, DepthEncoding, DepthFrame,
    DetectedObject, Grasp, Gripper, Intrinsics, ModelContract, OutsideObstacle, Plan, PlanOptions,
    PointCloud, SceneInput, SensorInput, StageTimings, TablePlane, ViewAxis, ViewPolicy, Workspace,
    pose_from_parts,
};
use mvgrasp_proto::v1 as pb;
use nalgebra::{Isometry3, Vector3};

use crate::{
    error::{Error, Result},
    settings::{Limits, RequestDefaults},
};

/// The default workspace: everything within a kilometre.
const UNBOUNDED_M: f64 = 1000.0;

/// The sensor, pose and workspace of `request`, borrowing its buffers.
pub fn scene_of<'a>(request: &'a pb::PlanGraspsRequest, limits: &Limits) -> Result<SceneInput<'a>> {
    let sensor = match &request.sensor {
        None => return Err(Error::invalid("sensor", "set `depth` or `cloud`")),
        Some(pb::plan_grasps_request::Sensor::Depth(depth)) => SensorInput::Depth(depth_of(depth, limits)?),
        Some(pb::plan_grasps_request::Sensor::Cloud(cloud)) => SensorInput::Cloud(cloud_of(cloud, limits)?),
    };
    let pose = request
        .world_from_camera
        .as_ref()
        .ok_or_else(|| Error::invalid("world_from_camera", "required (the camera's pose in the world)"))?;
    let world_from_camera = pose_of("world_from_camera", pose)?;
    let workspace = match &request.workspace {
        None => Workspace::new([-UNBOUNDED_M; 3], [UNBOUNDED_M; 3])?,
        Some(w) => box_of("workspace", w)?,
    };
    Ok(SceneInput {
        sensor,
        world_from_camera,
        workspace,
    })
}

fn depth_of<'a>(depth: &'a pb::DepthImage, limits: &Limits) -> Result<DepthFrame<'a>> {
    let encoding = match pb::DepthEncoding::try_from(depth.encoding) {
        Ok(pb::DepthEncoding::Uint16Mm) => DepthEncoding::U16Millimetres,
        Ok(pb::DepthEncoding::Float32M) => DepthEncoding::F32Metres,
        Ok(pb::DepthEncoding::Unspecified) => {
            return Err(Error::invalid(
                "depth.encoding",
                "unspecified; use DEPTH_ENCODING_UINT16_MM or DEPTH_ENCODING_FLOAT32_M",
            ));
        }
        Err(_) => {
            return Err(Error::invalid(
                "depth.encoding",
                format!("unknown value {}", depth.encoding),
            ));
        }
    };
    let pixels = depth.width as usize * depth.height as usize;
    if pixels > limits.max_image_pixels {
        return Err(Error::LimitExceeded {
            field: "depth".into(),
            reason: format!(
                "{}x{} = {pixels} pixels; at most {}",
                depth.width, depth.height, limits.max_image_pixels
            ),
        });
    }
    let k = depth
        .intrinsics
        .as_ref()
        .ok_or_else(|| Error::invalid("depth.intrinsics", "required"))?;
    Ok(DepthFrame {
        width: depth.width,
        height: depth.height,
        encoding,
        data: &depth.data,
        intrinsics: Intrinsics {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        },
    })
}

fn cloud_of<'a>(cloud: &'a pb::PointCloud, limits: &Limits) -> Result<PointCloud<'a>> {
    let frame = match pb::CloudFrame::try_from(cloud.frame) {
        Ok(pb::CloudFrame::Camera) => CloudFrame::Camera,
        Ok(pb::CloudFrame::World) => CloudFrame::World,
        Err(_) => {
            return Err(Error::invalid(
                "cloud.frame",
                format!("unknown value {}", cloud.frame),
            ));
        }
    };
    let points = cloud.xyz.len() / 12;
    if points > limits.max_cloud_points {
        return Err(Error::LimitExceeded {
            field: "cloud.xyz".into(),
            reason: format!("{points} points; at most {}", limits.max_cloud_points),
        });
    }
    if cloud.xyz.is_empty() {
        return Err(Error::invalid("cloud.xyz", "empty cloud"));
    }
    Ok(PointCloud {
        xyz: &cloud.xyz,
        frame,
    })
}

/// The part `part` of the message `field`, which must be set.
fn required<'m, T>(field: &str, part: &str, value: &'m Option<T>) -> Result<&'m T> {
    value
        .as_ref()
        .ok_or_else(|| Error::invalid(format!("{field}.{part}"), "required"))
}

/// A request's world-frame box, errors naming `field`.
fn box_of(field: &'static str, w: &pb::Workspace) -> Result<Workspace> {
    let min = required(field, "min", &w.min)?;
    let max = required(field, "max", &w.max)?;
    Ok(Workspace::named(field, array_of(min), array_of(max))?)
}

/// The capsules of `robot_body`, each end required (field `robot_body[i].a`);
/// `PlanOptions::validate` checks the values and the count.
fn body_of(capsules: &[pb::Capsule]) -> Result<Vec<BodyCapsule>> {
    capsules
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let field = format!("robot_body[{i}]");
            let a = required(&field, "a", &c.a)?;
            let b = required(&field, "b", &c.b)?;
            Ok(BodyCapsule {
                a: Vector3::from(array_of(a)),
                b: Vector3::from(array_of(b)),
                radius_m: c.radius_m,
            })
        })
        .collect()
}

fn array_of(v: &pb::Vector3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn pose_of(field: &'static str, pose: &pb::Pose) -> Result<Isometry3<f64>> {
    let p = required(field, "position", &pose.position)?;
    let q = required(field, "orientation", &pose.orientation)?;
    Ok(pose_from_parts(field, array_of(p), [q.x, q.y, q.z, q.w])?)
}

/// The plan options of `request`, filling unset fields from `defaults`.
pub fn options_of(request: &pb::PlanGraspsRequest, defaults: &RequestDefaults) -> Result<PlanOptions> {
    let gripper = match &request.gripper {
        None => Gripper::robotiq_2f_140(),
        Some(g) => Gripper {
            max_width_m: g.max_width_m,
            finger_width_m: g.finger_width_m,
            finger_depth_m: g.finger_depth_m,
        },
    };
    let view_policy = match pb::ViewPolicy::try_from(request.view_policy) {
        Ok(pb::ViewPolicy::Unspecified | pb::ViewPolicy::Entropy) => ViewPolicy::Entropy,
        Ok(pb::ViewPolicy::All) => ViewPolicy::All,
        Ok(pb::ViewPolicy::TopDown) => ViewPolicy::TopDown,
        Ok(pb::ViewPolicy::Random) => ViewPolicy::Random {
            seed: request.random_seed,
        },
        Err(_) => {
            return Err(Error::invalid(
                "view_policy",
                format!("unknown value {}", request.view_policy),
            ));
        }
    };
    let options = PlanOptions {
        gripper,
        max_grasps: match request.max_grasps {
            0 => defaults.max_grasps as usize,
            n => n as usize,
        },
        min_quality: request.min_quality.unwrap_or(defaults.min_quality),
        view_policy,
        keep_views: request.include_debug_views,
        view_cascade: request.view_cascade.unwrap_or(true),
        approach_cone: match &request.approach_cone {
            None => None,
            Some(cone) => {
                let axis = cone
                    .axis
                    .ok_or_else(|| Error::invalid("approach_cone.axis", "missing"))?;
                Some(ApproachCone::new(
                    Vector3::new(axis.x, axis.y, axis.z),
                    cone.half_angle_rad,
                )?)
            }
        },
        arm_reach: match &request.arm_reach {
            None => None,
            Some(reach) => {
                let shoulder = reach
                    .shoulder
                    .ok_or_else(|| Error::invalid("arm_reach.shoulder", "missing"))?;
                let axis = reach.axis.map_or(Vector3::z(), |a| Vector3::new(a.x, a.y, a.z));
                Some(ArmReach::new(
                    Vector3::new(shoulder.x, shoulder.y, shoulder.z),
                    axis,
                    reach.wrist_back_m,
                    reach.approach_m,
                    reach.max_m,
                    reach.min_axis_m,
                )?)
            }
        },
        obstacle_region: request
            .obstacle_region
            .as_ref()
            .map(|w| box_of("obstacle_region", w))
            .transpose()?,
        robot_body: body_of(&request.robot_body)?,
    };
    options.validate()?;
    Ok(options)
}

fn vector(v: &Vector3<f64>) -> pb::Vector3 {
    pb::Vector3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// `pose` as a message (unit quaternion).
pub fn pose_message(pose: &Isometry3<f64>) -> pb::Pose {
    let q = pose.rotation.quaternion();
    pb::Pose {
        position: Some(vector(&pose.translation.vector)),
        orientation: Some(pb::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

fn axis_message(axis: ViewAxis) -> pb::ViewAxis {
    match axis {
        ViewAxis::Top => pb::ViewAxis::Top,
        ViewAxis::Front => pb::ViewAxis::Front,
        ViewAxis::Side => pb::ViewAxis::Side,
        ViewAxis::TopFront => pb::ViewAxis::TopFront,
        ViewAxis::TopSide => pb::ViewAxis::TopSide,
    }
}

fn grasp_message(g: &Grasp) -> pb::Grasp {
    pb::Grasp {
        pose: Some(pose_message(&g.world_from_grasp)),
        width_m: g.width_m,
        quality: g.quality,
        object_id: g.object_id,
        view: axis_message(g.view) as i32,
        pixel_u: g.pixel[0],
        pixel_v: g.pixel[1],
        angle_rad: g.angle_rad,
        repairs: Some(pb::GraspRepairs {
            refit: g.repairs.refit,
            turned_away: g.repairs.turned_away,
            squared: g.repairs.squared,
            deepened: g.repairs.deepened,
            out_of_view: g.repairs.out_of_view,
        }),
    }
}

fn object_message(o: &DetectedObject) -> pb::DetectedObject {
    pb::DetectedObject {
        id: o.id,
        world_from_object: Some(pose_message(&o.frame.world_from_object)),
        extent_min_m: Some(vector(&o.frame.extent_min_m)),
        extent_max_m: Some(vector(&o.frame.extent_max_m)),
        point_count: o.frame.point_count as u32,
        views: o
            .views
            .iter()
            .map(|v| pb::ViewEntropy {
                axis: axis_message(v.axis) as i32,
                entropy: v.entropy,
                inferred: v.inferred,
            })
            .collect(),
        refused: Some(pb::ObjectRefusals {
            table: o.refused.table as u32,
            neighbour: o.refused.neighbour as u32,
            own_points: o.refused.own_points as u32,
            outside_approach_cone: o.refused.outside_approach_cone as u32,
            out_of_reach: o.refused.out_of_reach as u32,
            too_wide: o.refused.too_wide as u32,
            no_pose: o.refused.no_pose as u32,
        }),
    }
}

fn table_message(t: &TablePlane) -> pb::TablePlane {
    pb::TablePlane {
        normal: Some(vector(&t.normal)),
        offset_m: t.offset_m,
        support: t.support,
    }
}

fn timings_message(t: &StageTimings, total_s: f64) -> pb::StageTimings {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    pb::StageTimings {
        sensor_ms: ms(t.sensor),
        table_ms: ms(t.table),
        objects_ms: ms(t.sensor_objects),
        cluster_ms: ms(t.cluster),
        frames_ms: ms(t.frames),
        views_ms: ms(t.views),
        select_ms: ms(t.select),
        inference_ms: ms(t.inference),
        decode_ms: ms(t.decode),
        total_ms: total_s * 1e3,
    }
}

fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn debug_message(d: &DebugView) -> pb::DebugView {
    let m = &d.view.object_from_view;
    pb::DebugView {
        object_id: d.object_id,
        axis: axis_message(d.view.axis) as i32,
        size_px: d.view.size_px as u32,
        pixel_size_m: f64::from(d.view.pixel_size_m),
        image: f32_bytes(&d.view.image),
        maps: d.maps.as_deref().map(f32_bytes).unwrap_or_default(),
        object_from_view: (0..3).flat_map(|r| (0..3).map(move |c| m[(r, c)])).collect(),
    }
}

/// The response for `plan`; `total_s` is the time inside the server.
pub fn response_of(
    plan: &Plan,
    model_version: &str,
    request_id: &str,
    total_s: f64,
) -> pb::PlanGraspsResponse {
    pb::PlanGraspsResponse {
        grasps: plan.grasps.iter().map(grasp_message).collect(),
        objects: plan.objects.iter().map(object_message).collect(),
        table: Some(table_message(&plan.table)),
        timings: Some(timings_message(&plan.timings, total_s)),
        model_version: model_version.to_owned(),
        debug_views: plan.debug_views.iter().map(debug_message).collect(),
        request_id: request_id.to_owned(),
        ranked_last_out_of_view: plan.ranked_last_out_of_view as u32,
        ranked_after_turned_away: plan.ranked_after_turned_away as u32,
        outside_approach_cone: plan.outside_approach_cone as u32,
        out_of_reach: plan.out_of_reach as u32,
        obstacles: plan.obstacles.iter().map(obstacle_message).collect(),
        obstacles_dropped: plan.obstacles_dropped as u32,
    }
}

fn obstacle_message(o: &OutsideObstacle) -> pb::Obstacle {
    pb::Obstacle {
        min: Some(vector(&o.min)),
        max: Some(vector(&o.max)),
        point_count: o.point_count as u32,
        object_id: o.object_id,
    }
}

/// What `GetModelInfo` answers.
pub fn model_info(contract: &ModelContract, backend: &str, max_batch_views: usize) -> pb::ModelInfo {
    pb::ModelInfo {
        model_version: contract.model_version.clone(),
        data_version: contract.data_version.clone(),
        input_size_px: contract.input_size_px as u32,
        pixel_size_m: f64::from(contract.pixel_size_m),
        width_scale_m: f64::from(contract.width_scale_m),
        normalisation: contract.normalisation.clone(),
        outputs: contract
            .outputs
            .iter()
            .map(|c: &Channel| c.name().to_owned())
            .collect(),
        backend: backend.to_owned(),
        max_batch_views: max_batch_views as u32,
        server_version: env!("CARGO_PKG_VERSION").to_owned(),
    }
}
